//! Any Bevy mesh under the forest's budget: discrete level-of-detail ladders.
//!
//! A [`LodLadder`] on an entity with a `Mesh3d` lists its levels, best first, each a
//! `Mesh` handle with its triangle count. The entity is an object of the same Robin Hood
//! hand-out as the trees: valued from its bounds with the same value function (times
//! its [`LadderImportance`]), priced on Bevy's own mesh path (a draw's fixed cost plus
//! its triangles, families the cost model learns like the forest pass's), never dropped
//! (its cheapest level is its floor). The level chosen is shown by swapping the entity's
//! `Mesh3d`; its material is untouched. With a `StandardMaterial` and
//! [`LadderSettings::fade_frames`] above 0, a change of level is a dithered cross-fade
//! over that many frames: a second entity of
//! the crate's own ([`LadderGhost`]) draws the old mesh while the new one dithers in,
//! and the budget pays for both while it runs. Other materials, and entities with a
//! `VisibilityRange` of the app's own, switch at once. The first fade of a material
//! compiles its dithered pipeline; on a slow shader compiler the two levels are not drawn
//! until it is ready.
//!
//! Levels are given ([`LodLadder::new`], or nodes named `X_LOD0`, `X_LOD1`, … under a
//! [`LadderFromLodNames`] scene) or generated from one mesh by simplification
//! ([`generate_ladder`]).
//!
//! Two things keep levels from flickering. The budget keeps the level shown while it
//! fits the entity's time and moves to a better one only when that costs at most
//! `LADDER_UPGRADE_FRACTION` of it; and a
//! level one step better or cheaper than the one shown is shown only once the choice has
//! stayed for [`LadderSettings::hysteresis_frames`] frames (`LadderState::settle`); a
//! level two or more steps away shows at once. The budget pays for the level shown, not
//! the one chosen, so a held dearer level takes its time from the objects after it in
//! the hand-out and the frame stays on time.

mod app_meshes;
pub(crate) mod fade;
mod generate;
mod names;

pub use fade::LadderGhost;
pub use generate::{GeneratedLevel, LadderError, generate_ladder};
pub use names::LadderFromLodNames;

pub(crate) use names::mesh_triangles;

use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::VisibilityRange;
use bevy::prelude::*;

use crate::culling::transform_bounds;
use crate::lod::select::LadderHold;
use crate::lod::{LadderEntry, LadderObjects};
use crate::schedule::SherwoodSystems;
use crate::tree::Bounds;

/// One level of a [`LodLadder`].
#[derive(Clone, Debug, PartialEq, Reflect)]
pub struct LadderLevel {
    /// The mesh shown at this level.
    pub mesh: Handle<Mesh>,
    /// Its triangle count: what the budget prices it by.
    pub triangles: u32,
}

/// Discrete levels of detail of a mesh entity, best first. The budget picks one each
/// frame; [`LadderState`] holds what is shown.
#[derive(Component, Clone, Debug, PartialEq, Reflect)]
#[reflect(Component)]
#[require(LadderState)]
pub struct LodLadder {
    levels: Vec<LadderLevel>,
}

impl LodLadder {
    /// A ladder from levels best first. `None` when there are none or a level has more
    /// triangles than the one before it (a ladder must get cheaper as it goes).
    pub fn new(levels: Vec<LadderLevel>) -> Option<Self> {
        let descending = levels.windows(2).all(|w| w[1].triangles <= w[0].triangles);
        (!levels.is_empty() && descending).then_some(Self { levels })
    }

    /// Adds generated levels to `meshes` and makes them a ladder.
    pub fn from_generated(meshes: &mut Assets<Mesh>, levels: Vec<GeneratedLevel>) -> Option<Self> {
        Self::new(
            levels
                .into_iter()
                .map(|level| LadderLevel {
                    triangles: level.triangles,
                    mesh: meshes.add(level.mesh),
                })
                .collect(),
        )
    }

    /// The levels, best first.
    pub fn levels(&self) -> &[LadderLevel] {
        &self.levels
    }
}

/// How much a ladder entity's detail matters against the trees' (which have
/// [`FrameBudget::trunk_importance`](crate::lod::FrameBudget::trunk_importance) and
/// `leaf_importance`). Default: 1.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component)]
pub struct LadderImportance(pub f32);

impl Default for LadderImportance {
    fn default() -> Self {
        Self(1.0)
    }
}

/// Settings of the ladders.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct LadderSettings {
    /// Frames the budget's choice must stay one level better, or one level cheaper, than
    /// what is shown before it is shown. Default: 5. A choice two or more levels away
    /// shows at once. The budget pays for the level actually shown, so a held dearer level
    /// takes its time from the objects after it.
    pub hysteresis_frames: u32,
    /// Frames a change of the level shown takes to cross-fade, both levels dithered into
    /// each other (a `StandardMaterial` only; see the [module](self)). Default: `0`, a
    /// change shows at once: each fade spawns an entity and re-specialises two pipelines,
    /// and with 200 ladders changing level often 8-frame fades let 12–20% of frames over
    /// 1.1 × target where switching at once let 6–8% (lavapipe). 8 is a good value
    /// where levels change rarely.
    pub fade_frames: u32,
}

impl Default for LadderSettings {
    fn default() -> Self {
        Self {
            hysteresis_frames: 5,
            fade_frames: 0,
        }
    }
}

/// The level a ladder entity shows (index into [`LodLadder::levels`], 0 = best) and the
/// hysteresis' memory.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Component)]
pub struct LadderState {
    /// The level shown.
    pub shown: u32,
    /// A better level the budget has chosen, and for how many frames in a row.
    candidate: Option<(u32, u32)>,
    /// The cross-fade from the level shown before, while it runs.
    fade: Option<fade::LadderFade>,
}

impl LadderState {
    /// A state showing `level`.
    pub fn showing(level: u32) -> Self {
        Self {
            shown: level,
            candidate: None,
            fade: None,
        }
    }

    /// Takes this frame's choice (`wanted`, 0 = best) and returns whether the shown level
    /// changed: at once for a level two or more steps away; for one step better or
    /// cheaper only once it has been chosen `frames` frames in a row.
    pub(crate) fn settle(&mut self, wanted: u32, frames: u32) -> bool {
        if wanted == self.shown {
            self.candidate = None;
            return false;
        }
        if self.holds(wanted, frames) {
            self.candidate = Some((wanted, self.streak_with(wanted)));
            return false;
        }
        self.shown = wanted;
        self.candidate = None;
        true
    }

    /// The level the budget chose instead of the one shown, held back by the hysteresis,
    /// and for how many frames in a row it has been chosen.
    #[cfg(test)]
    pub(crate) fn pending(&self) -> Option<(u32, u32)> {
        self.candidate
    }

    /// Whether a choice of `wanted` this frame would still keep the level shown: it is
    /// one step away and, counting this frame, has not yet been chosen `frames` frames in
    /// a row. What [`settle`](Self::settle) decides, without deciding it.
    pub(crate) fn holds(&self, wanted: u32, frames: u32) -> bool {
        wanted.abs_diff(self.shown) == 1 && self.streak_with(wanted) < frames
    }

    /// Frames in a row `wanted` will have been chosen, counting this one.
    fn streak_with(&self, wanted: u32) -> u32 {
        match self.candidate {
            Some((level, streak)) if level == wanted => streak + 1,
            _ => 1,
        }
    }
}

/// What the ladders showed this frame.
#[derive(Resource, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource)]
pub struct LadderDiagnostics {
    /// Ladder entities in the hand-out (with bounds), in view or not.
    pub entities: u32,
    /// Of those in view, how many show each level (index 0 = best).
    pub shown_per_level: Vec<u32>,
    /// Shown levels that changed this frame.
    pub switches: u32,
    /// Cross-fades running this frame (each draws two levels).
    pub fades: u32,
}

/// Adds [`LodLadder`] entities to the hand-out and shows the levels chosen for them.
/// Part of [`SherwoodPlugins`](crate::SherwoodPlugins) (feature `render`); needs the
/// [`LodPlugin`](crate::lod::LodPlugin).
#[derive(Default)]
pub struct LadderPlugin;

impl Plugin for LadderPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<LodLadder>()
            .register_type::<LadderState>()
            .register_type::<LadderImportance>()
            .register_type::<LadderSettings>()
            .register_type::<LadderFromLodNames>()
            .register_type::<LadderDiagnostics>()
            .register_type::<LadderGhost>()
            .register_type::<fade::FadeRange>()
            .init_resource::<LadderSettings>()
            .init_resource::<LadderDiagnostics>()
            .add_systems(
                PostUpdate,
                (
                    (names::ladders_from_lod_names, gather_ladders)
                        .chain()
                        .in_set(SherwoodSystems::Instances),
                    // Before Bevy checks visibility, so that a ghost spawned and the
                    // ranges set this frame count this frame (an entity with a
                    // range not yet checked would be culled).
                    (show_ladder_levels, fade::advance_fades)
                        .chain()
                        .in_set(SherwoodSystems::DrawLists)
                        .before(bevy::camera::visibility::VisibilitySystems::CheckVisibility),
                    // After Bevy has computed new meshes' bounds and visibility, so a mesh
                    // spawned this frame counts this frame.
                    // An app without Bevy's meshes (a headless test) has none to count.
                    app_meshes::count_app_meshes
                        .run_if(resource_exists::<Assets<Mesh>>)
                        .in_set(SherwoodSystems::Value)
                        .after(bevy::camera::visibility::VisibilitySystems::CalculateBounds)
                        .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate),
                ),
            );
    }

    fn finish(&self, app: &mut App) {
        crate::schedule::require_plugin::<crate::lod::LodPlugin>(app, "LadderPlugin", "LodPlugin");
    }
}

/// The ladder entities with bounds (a mesh not loaded yet has none, and waits), as the
/// Value stage reads them.
fn gather_ladders(
    mut objects: ResMut<LadderObjects>,
    settings: Res<LadderSettings>,
    ladders: Query<(
        Entity,
        &LodLadder,
        &GlobalTransform,
        Option<&Aabb>,
        Option<&LadderImportance>,
        &LadderState,
        (
            Has<MeshMaterial3d<StandardMaterial>>,
            Option<&VisibilityRange>,
            Has<fade::FadeRange>,
        ),
    )>,
) {
    let LadderObjects {
        entries, triangles, ..
    } = &mut *objects;
    entries.clear();
    triangles.clear();
    for (entity, ladder, transform, aabb, importance, state, (material, range, ours)) in &ladders {
        let Some(aabb) = aabb else {
            continue;
        };
        let local = Bounds {
            min: (aabb.center - aabb.half_extents).into(),
            max: (aabb.center + aabb.half_extents).into(),
        };
        let world = transform_bounds(&transform.affine(), &local);
        let size = world.max - world.min;
        let start = triangles.len() as u32;
        triangles.extend(ladder.levels().iter().map(|level| level.triangles));
        entries.push(LadderEntry {
            entity,
            center: world.center(),
            radius: world.half_extents().length(),
            area: 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x),
            importance: importance.map_or(1.0, |i| i.0.max(0.0)),
            hold: LadderHold {
                shown: state.shown,
                better: state.shown > 0 && state.holds(state.shown - 1, settings.hysteresis_frames),
                cheaper: state.holds(state.shown + 1, settings.hysteresis_frames),
                // Advanced after the hand-out: drawn this frame unless this is its last.
                fading: state
                    .fade
                    .filter(|f| f.frame < settings.fade_frames)
                    .map(|f| f.from),
                fades: fade::can_fade(&settings, material, range, ours),
            },
            levels: start..triangles.len() as u32,
        });
    }
}

/// A mesh entity's [`LodLadder`] now shows another level (after the hysteresis; once per
/// change, not once a frame). Observe it on the entity or globally:
/// `app.add_observer(|change: On<LadderLevelChanged>| …)`.
#[derive(EntityEvent, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
pub struct LadderLevelChanged {
    /// The entity with the ladder.
    pub entity: Entity,
    /// The level shown before (0 = best).
    pub from: u32,
    /// The level shown now.
    pub to: u32,
}

/// Shows the level the budget chose, through the hysteresis, by swapping `Mesh3d`, and
/// starts a cross-fade from the level shown before where one can run.
fn show_ladder_levels(
    objects: Res<LadderObjects>,
    settings: Res<LadderSettings>,
    mut diagnostics: ResMut<LadderDiagnostics>,
    mut ladders: Query<(
        &LodLadder,
        &mut LadderState,
        Option<&mut Mesh3d>,
        fade::FadeSource,
    )>,
    mut commands: Commands,
) {
    let diagnostics = &mut *diagnostics;
    diagnostics.entities = objects.entries.len() as u32;
    diagnostics.shown_per_level.clear();
    diagnostics.switches = 0;
    for (entry, chosen) in objects.entries.iter().zip(&objects.chosen) {
        let Some(wanted) = *chosen else {
            continue;
        };
        let Ok((ladder, mut state, mesh, source)) = ladders.get_mut(entry.entity) else {
            continue;
        };
        let last = ladder.levels().len().saturating_sub(1) as u32;
        let from = state.shown;
        let switched = state.settle(wanted.min(last), settings.hysteresis_frames);
        diagnostics.switches += u32::from(switched);
        if switched {
            commands.trigger(LadderLevelChanged {
                entity: entry.entity,
                from,
                to: state.shown,
            });
            // Whether it fades was decided when the budget paid for it.
            if entry.hold.fades
                && let Some(old) = ladder.levels().get(from as usize)
            {
                fade::start(
                    &mut commands,
                    entry.entity,
                    &mut state,
                    from,
                    old.mesh.clone(),
                    source,
                );
            }
        }
        let shown = state.shown.min(last) as usize;
        if diagnostics.shown_per_level.len() <= shown {
            diagnostics.shown_per_level.resize(shown + 1, 0);
        }
        diagnostics.shown_per_level[shown] += 1;
        let Some(level) = ladder.levels().get(shown) else {
            continue;
        };
        match mesh {
            Some(mut mesh) if mesh.0 != level.mesh => mesh.0 = level.mesh.clone(),
            Some(_) => {}
            None => {
                commands
                    .entity(entry.entity)
                    .try_insert(Mesh3d(level.mesh.clone()));
            }
        }
    }
}
