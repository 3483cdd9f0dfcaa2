//! Dithered cross-fades between a ladder's levels, through the visibility-range dither of
//! Bevy's `StandardMaterial` (the one Unity's `LODGroup` cross-fade and Unreal's dithered
//! LOD transition draw).
//!
//! When the level shown changes, the entity shows its new mesh and a *ghost* — an entity
//! of the crate's own with the old mesh, the same material and the same place — shows the
//! old one; over [`LadderSettings::fade_frames`](super::LadderSettings::fade_frames)
//! frames the new mesh covers 1/16, 2/16, … of a 4×4 dither pattern and the ghost the
//! complement, then the ghost is despawned. The budget pays for both while the fade runs.
//!
//! Bevy's dither reads a fade from the camera's distance to the mesh within a
//! `VisibilityRange` margin. A fade here is a step of time, not of distance: the margins
//! are [`FADE_WIDTH`] wide and placed so that every distance in a scene (up to a
//! thirty-second of the width, 300 km) falls on the same sixteenth — one fade looks the
//! same from every camera, and only 30 distinct ranges ever exist (Bevy keeps a GPU slot
//! for each distinct range for the app's lifetime).

use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::{RenderLayers, VisibilityRange};
use bevy::ecs::query::QueryItem;
use bevy::light::NotShadowCaster;
use bevy::prelude::*;

use super::{LadderDiagnostics, LadderSettings, LadderState, LodLadder};

/// Width of a fade's margin, world units: far beyond any distance between a camera and
/// a mesh, so the distance moves the dither by less than half a sixteenth.
const FADE_WIDTH: f32 = 1.0e7;

/// A running cross-fade from the level shown before (`from`, drawn by `ghost`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Reflect)]
pub(crate) struct LadderFade {
    /// The entity drawing the old level.
    pub ghost: Entity,
    /// The level faded out.
    pub from: u32,
    /// Frames of the fade drawn so far.
    pub frame: u32,
}

/// Marks the entity that draws a fading ladder level beside its `owner`.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct LadderGhost {
    /// The ladder entity whose old level this draws.
    pub owner: Entity,
}

/// Marks a `VisibilityRange` a fade put on a ladder entity (one the app put there itself
/// is never touched: such an entity does not fade).
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub(crate) struct FadeRange;

/// Sixteenths of the new level shown on frame `frame` (1-based) of a fade lasting
/// `frames` frames: evenly spaced, never 0 or 16 (both levels drawn every frame of it).
pub(crate) fn step(frame: u32, frames: u32) -> u32 {
    let frames = frames.max(1);
    ((16 * frame + frames.div_ceil(2)) / (frames + 1)).clamp(1, 15)
}

/// The range of the level fading in, `step` sixteenths shown.
pub(crate) fn incoming_range(step: u32) -> VisibilityRange {
    let shown = step.min(16) as f32 / 16.0;
    VisibilityRange {
        start_margin: -shown * FADE_WIDTH..(1.0 - shown) * FADE_WIDTH,
        end_margin: 2.0 * FADE_WIDTH..2.0 * FADE_WIDTH,
        use_aabb: false,
    }
}

/// The range of the level fading out while the new one shows `step` sixteenths: the
/// complement of [`incoming_range`]'s on Bevy's dither pattern.
pub(crate) fn outgoing_range(step: u32) -> VisibilityRange {
    let shown = step.min(16) as f32 / 16.0;
    VisibilityRange {
        start_margin: -2.0 * FADE_WIDTH..-2.0 * FADE_WIDTH,
        end_margin: -shown * FADE_WIDTH..(1.0 - shown) * FADE_WIDTH,
        use_aabb: false,
    }
}

/// Whether a change of `entity`'s level can fade: fades are on, its material is a
/// `StandardMaterial` (whose shader dithers) and the app has put no `VisibilityRange` of
/// its own on it.
pub(crate) fn can_fade(
    settings: &LadderSettings,
    material: bool,
    range: Option<&VisibilityRange>,
    ours: bool,
) -> bool {
    settings.fade_frames > 0 && material && (range.is_none() || ours)
}

/// Components of a ladder entity a fade reads.
pub(super) type FadeSource = (
    &'static GlobalTransform,
    Option<&'static InheritedVisibility>,
    Option<&'static Aabb>,
    Option<&'static RenderLayers>,
    Has<NotShadowCaster>,
    Option<&'static MeshMaterial3d<StandardMaterial>>,
);

/// Starts a fade of `owner` from `from` (whose mesh is `mesh`): the running fade's ghost
/// takes the old mesh, or a new ghost is spawned with it.
pub(super) fn start(
    commands: &mut Commands,
    owner: Entity,
    state: &mut LadderState,
    from: u32,
    mesh: Handle<Mesh>,
    source: QueryItem<'_, '_, FadeSource>,
) {
    let (transform, visible, aabb, layers, no_shadow, material) = source;
    let Some(material) = material else {
        return;
    };
    if let Some(fade) = &mut state.fade {
        commands.entity(fade.ghost).try_insert(Mesh3d(mesh));
        fade.from = from;
        fade.frame = 0;
        return;
    }
    let mut ghost = commands.spawn((
        Name::new("ladder fade"),
        LadderGhost { owner },
        Mesh3d(mesh),
        material.clone(),
        transform.compute_transform(),
        *transform,
        // Visible in the frame it is spawned (visibility was propagated before).
        visible.copied().unwrap_or(InheritedVisibility::VISIBLE),
        outgoing_range(1),
    ));
    if let Some(aabb) = aabb {
        ghost.insert(*aabb);
    }
    if let Some(layers) = layers {
        ghost.insert(layers.clone());
    }
    if no_shadow {
        ghost.insert(NotShadowCaster);
    }
    state.fade = Some(LadderFade {
        ghost: ghost.id(),
        from,
        frame: 0,
    });
}

/// Advances every running fade by a frame: sets both ranges to this frame's step and
/// keeps the ghost where its owner is, or ends the fade (the ghost despawned, the range
/// taken off, the entity's mesh marked changed so Bevy draws it without the dither
/// again). A ghost whose owner is gone, or no longer a ladder, goes with it.
pub(super) fn advance_fades(
    settings: Res<LadderSettings>,
    mut diagnostics: ResMut<LadderDiagnostics>,
    mut ladders: Query<(
        Entity,
        &mut LadderState,
        Has<LodLadder>,
        &GlobalTransform,
        Option<&InheritedVisibility>,
        Option<&mut Mesh3d>,
    )>,
    mut ghosts: Query<
        (
            Entity,
            &LadderGhost,
            &mut Transform,
            &mut GlobalTransform,
            &mut Visibility,
        ),
        Without<LadderState>,
    >,
    mut commands: Commands,
) {
    diagnostics.fades = 0;
    for (owner, mut state, ladder, transform, visible, mesh) in &mut ladders {
        let Some(fade) = state.fade else {
            continue;
        };
        let frame = fade.frame + 1;
        if !ladder || frame > settings.fade_frames {
            state.fade = None;
            commands.entity(fade.ghost).try_despawn();
            commands
                .entity(owner)
                .try_remove::<(VisibilityRange, FadeRange)>();
            if let Some(mut mesh) = mesh {
                mesh.set_changed();
            }
            continue;
        }
        state.fade = Some(LadderFade { frame, ..fade });
        diagnostics.fades += 1;
        let step = step(frame, settings.fade_frames);
        commands
            .entity(owner)
            .try_insert((incoming_range(step), FadeRange));
        commands.entity(fade.ghost).try_insert(outgoing_range(step));
        if let Ok((_, _, mut ghost_transform, mut ghost_global, mut ghost_visibility)) =
            ghosts.get_mut(fade.ghost)
        {
            *ghost_transform = transform.compute_transform();
            *ghost_global = *transform;
            *ghost_visibility = if visible.is_none_or(|v| v.get()) {
                Visibility::Inherited
            } else {
                Visibility::Hidden
            };
        }
    }
    for (ghost, of, ..) in &ghosts {
        let owned = ladders
            .get(of.owner)
            .is_ok_and(|(_, state, ..)| state.fade.is_some_and(|f| f.ghost == ghost));
        if !owned {
            commands.entity(ghost).try_despawn();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bevy's `get_visibility_range_dither_level` (`bevy_pbr`, `mesh_functions.wgsl`): -16
    /// to 0 fading in across the start margin, 0 to 16 fading out across the end margin.
    fn dither_level(range: &VisibilityRange, distance: f32) -> i32 {
        let (offset, bounds) = if distance >= range.end_margin.start {
            (0, &range.end_margin)
        } else {
            (-16, &range.start_margin)
        };
        let level = ((distance - bounds.start) / (bounds.end - bounds.start) * 16.0).round();
        offset + (level as i32).clamp(0, 16)
    }

    #[test]
    fn the_two_levels_of_a_fade_share_the_dither_pattern_at_every_distance() {
        for step in 1..16 {
            let (incoming, outgoing) = (incoming_range(step), outgoing_range(step));
            for distance in [0.0, 0.5, 3.0, 100.0, 2_000.0, 50_000.0, 300_000.0] {
                let (in_level, out_level) = (
                    dither_level(&incoming, distance),
                    dither_level(&outgoing, distance),
                );
                // Bevy's dither draws level -16 + k and level k on complementary pixels.
                assert_eq!(out_level, step as i32, "step {step} at {distance}");
                assert_eq!(in_level, out_level - 16, "step {step} at {distance}");
                // Neither is culled on the CPU.
                assert!(incoming.is_visible_at_all(distance));
                assert!(outgoing.is_visible_at_all(distance));
            }
        }
    }

    #[test]
    fn a_fade_steps_evenly_and_always_draws_both_levels() {
        for frames in 1..40 {
            let steps: Vec<u32> = (1..=frames).map(|f| step(f, frames)).collect();
            assert!(
                steps.iter().all(|s| (1..16).contains(s)),
                "{frames}: {steps:?}"
            );
            assert!(
                steps.windows(2).all(|w| w[0] <= w[1]),
                "{frames}: {steps:?}"
            );
        }
        assert_eq!(
            (1..=7).map(|f| step(f, 7)).collect::<Vec<_>>(),
            [2, 4, 6, 8, 10, 12, 14]
        );
        assert_eq!(step(1, 1), 8);
    }

    #[test]
    fn only_a_standard_material_without_the_app_s_own_range_fades() {
        let on = LadderSettings {
            fade_frames: 8,
            ..LadderSettings::default()
        };
        let off = LadderSettings {
            fade_frames: 0,
            ..on
        };
        let theirs = VisibilityRange::abrupt(0.0, 10.0);
        assert!(can_fade(&on, true, None, false));
        assert!(can_fade(&on, true, Some(&incoming_range(3)), true));
        assert!(!can_fade(&on, true, Some(&theirs), false));
        assert!(!can_fade(&on, false, None, false));
        assert!(!can_fade(&off, true, None, false));
    }
}
