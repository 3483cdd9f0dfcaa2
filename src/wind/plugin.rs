//! The wind stage (`SherwoodSystems::Animate`): springs stepped on a fixed time step and,
//! for instances that were visible last frame, their rings' offsets in one flat table —
//! the table the render pass uploads and applies per ring on the GPU.

use bevy::math::Vec3A;
use bevy::prelude::*;

use super::asset::{SpringSet, SpringSetLoader};
use super::table::RingOffsetTable;
use std::collections::HashMap;

use super::motion::{WindRig, associate, moved_bounds, ring_offsets, update_interval};
use super::share::{LEVELS, SwayBin, borrowing_level, representatives};
use super::spring::{FixedStepper, Spring};
use crate::culling::{ForestCulling, InstanceVisibility, MovedShapes};
use crate::instance::{ForestInstances, LayoutEdits};
use crate::schedule::SherwoodSystems;
use crate::tree::TreeModel;
use crate::view::LodView;

/// Wind configuration. Changing it at run time takes effect on the next frame.
#[derive(Resource, Clone, Debug, Reflect)]
#[reflect(Resource)]
pub struct WindSettings {
    /// Move trees at all. Default: `true`.
    pub enabled: bool,
    /// The spring set of each motion index (a tree's `TreeInstance::motion`); instances
    /// whose index has no set stay still. Default: `wind/default.wind.ron` for index 0,
    /// loaded at start-up when the list is empty.
    pub sets: Vec<Handle<SpringSet>>,
    /// Update-rate level of detail: a moving tree whose farthest ring moves at least this
    /// many pixels from rest is updated every frame, one moving half as far every second
    /// frame, and so on up to `max_update_interval` (see
    /// `update_interval`); in between it keeps its last
    /// offsets. Updates are staggered across instances so the cost is even frame to
    /// frame. 0 updates every moving tree every frame. Default: `8.0`.
    pub full_rate_pixels: f32,
    /// The most frames between two updates of a moving tree (rounded down to a power of
    /// two). Default: `8`.
    pub max_update_interval: u32,
    /// How far, in pixels, a far tree's rings may land from its own sway when it borrows
    /// the offsets of a representative tree of its type, heading and size (one block of
    /// offsets computed for every tree of the bin): a moving tree whose borrowed sway
    /// stays within this many pixels of its own (its motion on screen times how far its
    /// heading, tilt and size are from the representative's) borrows it, so the wind's
    /// per-tree work and memory follow the trees that move visibly, not the forest.
    /// 0 computes every moving tree's own offsets. Default: `0.5` (as the default spring
    /// set's `pixel_threshold`, below which a tree is not moved at all).
    pub shared_sway_pixels: f32,
}

impl Default for WindSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            sets: Vec::new(),
            full_rate_pixels: 8.0,
            max_update_interval: 8,
            shared_sway_pixels: 0.5,
        }
    }
}

/// What the wind stage did in the last frame.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource, Default)]
pub struct WindStats {
    /// Visible instances with a spring set (candidates for motion).
    pub candidates: u32,
    /// Instances moving: bent by the wind this frame (`updated`), holding an earlier
    /// frame's bend (`held`) or borrowing a representative's (`shared`).
    pub moved: u32,
    /// Moving instances whose own offsets were computed this frame.
    pub updated: u32,
    /// Moving instances borrowing a representative's offsets
    /// ([`WindSettings::shared_sway_pixels`]).
    pub shared: u32,
    /// Representatives' blocks of offsets computed this frame.
    pub shared_updated: u32,
    /// Moving instances that kept their last offsets (update-rate level of detail).
    pub held: u32,
    /// Candidates left still by the motion level of detail (their farthest ring's motion,
    /// the largest spring displacement × the rig's reach, projects below the set's pixel
    /// threshold).
    pub skipped: u32,
    /// Time of the per-instance work (ring offsets and moved bounds, own and shared), milliseconds;
    /// stepping the springs themselves (a few per set) is not included.
    pub update_ms: f32,
    /// Ring offsets held for the moving instances after this frame (their memory:
    /// 12 bytes each).
    pub rings_held: u32,
}

#[derive(Resource, Default)]
struct WindState {
    /// Per motion index: the set it was built from and its running springs.
    sets: Vec<Option<(AssetId<SpringSet>, Vec<Spring>, FixedStepper)>>,
}

/// Registers spring-set assets and runs the wind stage in `SherwoodSystems::Animate`
/// (see [`WindSettings`] and `RingOffsetTable`).
#[derive(Default)]
pub struct WindPlugin;

impl Plugin for WindPlugin {
    fn finish(&self, app: &mut App) {
        crate::core_plugin::warn_without_core(app, "WindPlugin");
        crate::schedule::require_plugin::<crate::tree::TreePlugin>(app, "WindPlugin", "TreePlugin");
        crate::schedule::require_plugin::<crate::culling::CullingPlugin>(
            app,
            "WindPlugin",
            "CullingPlugin",
        );
    }

    fn build(&self, app: &mut App) {
        crate::core_plugin::use_instance_table(app);
        crate::schedule::require_plugin::<AssetPlugin>(app, "WindPlugin", "Bevy's AssetPlugin");
        app.init_asset::<SpringSet>()
            .register_asset_loader(SpringSetLoader)
            .init_resource::<WindSettings>()
            .register_type::<WindSettings>()
            .register_type::<WindStats>()
            .init_resource::<WindState>()
            .init_resource::<RingOffsetTable>()
            .init_resource::<MovedShapes>()
            .init_resource::<WindStats>()
            .add_systems(Startup, load_default_set)
            .add_systems(
                PostUpdate,
                (step_springs, move_rings)
                    .chain()
                    .in_set(SherwoodSystems::Animate),
            );
    }
}

fn load_default_set(mut settings: ResMut<WindSettings>, server: Res<AssetServer>) {
    if settings.sets.is_empty() {
        settings.sets.push(server.load("wind/default.wind.ron"));
    }
}

fn step_springs(
    settings: Res<WindSettings>,
    sets: Res<Assets<SpringSet>>,
    time: Res<Time>,
    mut state: ResMut<WindState>,
) {
    state.sets.resize_with(settings.sets.len(), || None);
    for (slot, handle) in state.sets.iter_mut().zip(&settings.sets) {
        let Some(set) = sets.get(handle) else {
            *slot = None;
            continue;
        };
        let arrived = slot.as_ref().is_none_or(|(id, _, _)| *id != handle.id());
        if arrived || sets.is_changed() {
            let mut springs: Vec<Spring> = set.springs.iter().cloned().map(Spring::new).collect();
            let mut stepper = FixedStepper::new(set.time_step);
            if arrived {
                // A set whose file loaded a few frames in stands where it would have had
                // it been there from the start: the wind at a given time does not depend
                // on when loading finished (runs that compare pictures rely on it).
                stepper.catch_up(&mut springs, time.elapsed_secs() - time.delta_secs());
            } else if let Some((_, old, _)) = slot.as_ref() {
                // An edited set keeps its springs' motion, so trees do not snap to rest.
                for (new, old) in springs.iter_mut().zip(old) {
                    new.displacement = old.displacement;
                    new.velocity = old.velocity;
                }
            }
            *slot = Some((handle.id(), springs, stepper));
        }
        if let Some((_, springs, stepper)) = slot.as_mut() {
            stepper.advance(springs, time.delta_secs());
        }
    }
}

/// What the stage keeps of one instance between frames (in the culling order): enough to
/// decide whether it moves without touching the ECS, and whether its offsets are not zero.
#[derive(Clone, Copy, Debug)]
struct InstanceWind {
    model: AssetId<TreeModel>,
    motion: u32,
    scale: f32,
    rotation: Quat,
    translation: Vec3,
    /// Index into [`WindCache::rigs`], or [`UNRESOLVED`].
    rig: u32,
    /// Its model's ring count.
    rings: u32,
    /// Its offsets (and moved culling shape) are not at rest.
    moving: bool,
    /// Per representative level, how far its rings land from its own per pixel of motion
    /// when it borrows that level's representative (infinite: it cannot).
    borrow_errors: [f32; LEVELS],
    /// Per level, its representative's block ([`Representatives::blocks`]), or
    /// [`UNRESOLVED`] until it first borrows at that level.
    blocks: [u32; LEVELS],
}

impl InstanceWind {
    /// Sets its place and orientation, and the representatives' errors they give.
    fn place(&mut self, rotation: Quat, translation: Vec3) {
        self.rotation = rotation;
        self.translation = translation;
        self.borrow_errors = [f32::INFINITY; LEVELS];
        for (error, r) in self
            .borrow_errors
            .iter_mut()
            .zip(representatives(rotation, self.scale))
        {
            *error = r.error_per_pixel;
        }
        self.blocks = [UNRESOLVED; LEVELS];
    }
}

const UNRESOLVED: u32 = u32::MAX;

/// A motion index's spring set as the stage sees it this frame.
#[derive(Default)]
struct SetThisFrame {
    set: AssetId<SpringSet>,
    /// Each spring's displacement (world space).
    displacements: Vec<Vec3>,
    /// The largest displacement's length: the motion level of detail's measure.
    largest: f32,
    /// The set's motion level-of-detail threshold, pixels.
    pixel_threshold: f32,
}

/// The stage's memory across frames. The offset table is kept too: an instance updated at
/// a lower rate keeps its offsets in between, and a still one is zeroed once.
#[derive(Default)]
struct WindCache {
    /// `(instance layout version, the instances' models version)` the instances were
    /// laid out for.
    layout: Option<(u64, u64)>,
    /// `None` for an instance whose tree is missing (it never moves).
    instances: Vec<Option<InstanceWind>>,
    rigs: Vec<WindRig>,
    rig_index: HashMap<(AssetId<TreeModel>, AssetId<SpringSet>), u32>,
    /// Per motion index, its spring set this frame (`None`: no set, or not loaded).
    springs: Vec<Option<SetThisFrame>>,
    frame: u32,
    scratch: Vec<Vec3A>,
    representatives: Representatives,
}

/// The blocks of offsets of the representatives far trees borrow.
#[derive(Default)]
struct Representatives {
    blocks: Vec<SharedBlock>,
    /// Index into `blocks` by rig and bin.
    index: HashMap<(u32, SwayBin), u32>,
}

impl Representatives {
    /// Forgets every block (the caller releases their offsets first, or resets the table).
    fn clear(&mut self) {
        self.blocks.clear();
        self.index.clear();
    }
}

/// A representative tree's block of offsets, which the trees of its bin borrow.
#[derive(Clone, Copy, Debug)]
struct SharedBlock {
    /// Its start in the offset table, and its length (its rig's ring count).
    start: u32,
    len: u32,
    /// The representative's rotation and scale.
    rotation: Quat,
    scale: f32,
    /// The frame it was last computed.
    updated: Option<u32>,
    /// The last frame a tree borrowed it.
    used: Option<u32>,
}

impl WindCache {
    /// Lays out the offset table for the instance table (every tree at rest).
    fn lay_out(
        &mut self,
        instances: &ForestInstances,
        models: &Assets<TreeModel>,
        table: &mut RingOffsetTable,
    ) {
        self.instances.clear();
        self.representatives.clear();
        table.reset(instances.len());
        self.instances
            .extend((0..instances.len()).map(|i| instance_wind(instances, models, i)));
    }

    /// Replays the table's `edits`: the trees that stay keep swaying, the new ones start
    /// at rest.
    fn follow_edits(
        &mut self,
        edits: &LayoutEdits,
        instances: &ForestInstances,
        models: &Assets<TreeModel>,
        table: &mut RingOffsetTable,
        moved: &mut MovedShapes,
    ) {
        for &i in edits.removed() {
            let i = i as usize;
            table.swap_remove(i);
            moved.swap_remove(i, self.instances.len());
            if i < self.instances.len() {
                self.instances.swap_remove(i);
            }
        }
        for i in edits.added() {
            table.push();
            self.instances.push(instance_wind(instances, models, i));
        }
    }

    /// Follows the instance table: its edits, or a new layout, and the instances that
    /// moved. Whether the instances' models changed.
    fn follow_layout(
        &mut self,
        instances: &ForestInstances,
        models: &Assets<TreeModel>,
        table: &mut RingOffsetTable,
        moved: &mut MovedShapes,
    ) -> bool {
        let layout = (instances.layout_version(), instances.models_version());
        let models_changed = self.layout.is_some_and(|(_, models)| models != layout.1);
        match self.layout {
            Some(kept) if kept == layout => {}
            Some((kept, models_version))
                if models_version == layout.1
                    && let Some(edits) = instances.edits_since(kept) =>
            {
                self.follow_edits(edits, instances, models, table, moved);
            }
            _ => {
                self.lay_out(instances, models, table);
                moved.clear();
            }
        }
        self.layout = Some(layout);
        self.follow_moves(instances);
        models_changed
    }

    /// Follows the instances that moved.
    fn follow_moves(&mut self, instances: &ForestInstances) {
        for &i in instances.moved() {
            if let Some(Some(wind)) = self.instances.get_mut(i as usize) {
                let (_, rotation, translation) =
                    instances.transforms[i as usize].to_scale_rotation_translation();
                wind.place(rotation, translation);
            }
        }
    }

    /// Forgets every rig (rules or models changed), and the representatives' blocks
    /// built on them: the trees that borrowed one are put at rest first.
    fn forget_rigs(&mut self, table: &mut RingOffsetTable, moved: &mut MovedShapes) {
        self.rigs.clear();
        self.rig_index.clear();
        for (i, instance) in self.instances.iter_mut().enumerate() {
            let Some(instance) = instance else { continue };
            instance.rig = UNRESOLVED;
            instance.blocks = [UNRESOLVED; LEVELS];
            if table.is_shared(i) {
                come_to_rest(instance, table, moved, i);
            }
        }
        for block in &self.representatives.blocks {
            table.release_shared_block(block.start, block.len);
        }
        self.representatives.clear();
    }
}

/// Instance `i`'s wind state at rest (`None` while its model loads).
fn instance_wind(
    instances: &ForestInstances,
    models: &Assets<TreeModel>,
    i: usize,
) -> Option<InstanceWind> {
    let id = instances.model_id(i)?;
    let model = models.get(id)?;
    let (_, rotation, translation) = instances.transforms[i].to_scale_rotation_translation();
    let mut wind = InstanceWind {
        model: id,
        motion: instances.motions[i],
        scale: instances.scales[i],
        rotation,
        translation,
        rig: UNRESOLVED,
        rings: model.rings.len() as u32,
        moving: false,
        borrow_errors: [f32::INFINITY; LEVELS],
        blocks: [UNRESOLVED; LEVELS],
    };
    wind.place(rotation, translation);
    Some(wind)
}

#[expect(
    clippy::too_many_arguments,
    reason = "one system gathering the stage's inputs"
)]
fn move_rings(
    settings: Res<WindSettings>,
    state: Res<WindState>,
    sets: Res<Assets<SpringSet>>,
    culling: Res<ForestCulling>,
    mut moved: ResMut<MovedShapes>,
    instances: Res<ForestInstances>,
    models: Res<Assets<TreeModel>>,
    views: Query<&LodView>,
    mut table: ResMut<RingOffsetTable>,
    mut stats: ResMut<WindStats>,
    mut cache: Local<WindCache>,
) {
    let start_time = std::time::Instant::now();
    let cache = &mut *cache;
    let table = &mut *table;
    let moved = &mut *moved;
    let models_changed = cache.follow_layout(&instances, &models, table, moved);
    // Last frame's visibility, when it is indexed like this frame's instances.
    let visibility = if culling.layout_version() == Some(instances.layout_version()) {
        &culling.result.visibility[..]
    } else {
        &[]
    };
    // A rig is derived from a tree model and a set's rules: an edited (hot-reloaded) one
    // must not keep moving its rings the old way, not even for a held frame.
    let refresh = sets.is_changed() || models_changed || settings.is_changed();
    if refresh {
        cache.forget_rigs(table, moved);
    }
    refill_springs(&mut cache.springs, &settings, &state, &sets);
    let frame = cache.frame;
    cache.frame = cache.frame.wrapping_add(1);
    let view = views.iter().next();
    let mut counts = WindStats::default();
    for i in 0..cache.instances.len() {
        let Some(instance) = cache.instances[i].as_mut() else {
            continue;
        };
        let visible = visibility
            .get(i)
            .is_some_and(|v| *v != InstanceVisibility::Invisible);
        let springs = cache
            .springs
            .get(instance.motion as usize)
            .and_then(Option::as_ref)
            .filter(|_| settings.enabled && visible);
        let Some(SetThisFrame {
            set: set_id,
            displacements,
            largest,
            pixel_threshold,
        }) = springs
        else {
            come_to_rest(instance, table, moved, i);
            continue;
        };
        counts.candidates += 1;
        let Some(rig) = resolve_rig(
            &mut cache.rigs,
            &mut cache.rig_index,
            instance,
            &models,
            *set_id,
            &sets,
        ) else {
            continue;
        };
        // Motion LOD: still when the farthest-moving ring (the largest spring
        // displacement times the rig's reach) projects below the threshold.
        let pixels_per_unit =
            view.map(|v| v.focal_pixels / v.position.distance(instance.translation).max(1e-3));
        let motion_pixels =
            pixels_per_unit.map_or(f32::INFINITY, |ppu| largest * rig.reach() * ppu);
        if motion_pixels < *pixel_threshold {
            counts.skipped += 1;
            come_to_rest(instance, table, moved, i);
            continue;
        }
        // Update-rate LOD, staggered by instance so each frame updates a similar share.
        let interval = update_interval(
            motion_pixels,
            settings.full_rate_pixels,
            settings.max_update_interval,
        );
        if let Some(level) = borrowing_level(
            &instance.borrow_errors,
            motion_pixels,
            settings.shared_sway_pixels,
        ) {
            let sway = Borrowed {
                level,
                rig,
                displacements,
                frame,
                interval,
            };
            let Some(computed) = borrow_sway(
                &mut cache.representatives,
                &mut cache.scratch,
                table,
                moved,
                i,
                instance,
                sway,
            ) else {
                come_to_rest(instance, table, moved, i);
                continue;
            };
            counts.shared_updated += u32::from(computed);
            counts.shared += 1;
            counts.moved += 1;
            continue;
        }
        if table.is_shared(i) {
            // Too near to borrow now: its own offsets this frame (from rest, so that it
            // never points at a block it no longer borrows).
            come_to_rest(instance, table, moved, i);
        }
        if instance.moving && !refresh && !frame.wrapping_add(i as u32).is_multiple_of(interval) {
            counts.held += 1;
            counts.moved += 1;
            continue;
        }
        let threshold = pixels_per_unit.map_or(0.0, |ppu| pixel_threshold / ppu / instance.scale);
        ring_offsets(
            rig,
            displacements,
            instance.rotation,
            instance.scale,
            threshold,
            &mut cache.scratch,
        );
        if cache.scratch.len() == instance.rings as usize {
            table.set(i, &cache.scratch);
            moved_bounds(rig, &cache.scratch, moved.shape_mut(i));
            instance.moving = true;
            counts.updated += 1;
            counts.moved += 1;
        } else {
            come_to_rest(instance, table, moved, i);
        }
    }
    *stats = WindStats {
        update_ms: start_time.elapsed().as_secs_f32() * 1000.0,
        rings_held: table.rings_held() as u32,
        ..counts
    };
}

/// The rig of `instance`'s tree under the set `set_id`, built on first use.
fn resolve_rig<'a>(
    rigs: &'a mut Vec<WindRig>,
    rig_index: &mut HashMap<(AssetId<TreeModel>, AssetId<SpringSet>), u32>,
    instance: &mut InstanceWind,
    models: &Assets<TreeModel>,
    set_id: AssetId<SpringSet>,
    sets: &Assets<SpringSet>,
) -> Option<&'a WindRig> {
    if instance.rig == UNRESOLVED {
        let key = (instance.model, set_id);
        instance.rig = match rig_index.get(&key) {
            Some(&index) => index,
            None => {
                let set = sets.get(set_id)?;
                let model = models.get(instance.model)?;
                let motions = associate(model, &set.rules, set.springs.len());
                rigs.push(WindRig::new(model, &motions));
                let index = rigs.len() as u32 - 1;
                rig_index.insert(key, index);
                index
            }
        };
    }
    rigs.get(instance.rig as usize)
}

/// Refills each motion index's springs as the stage sees them this frame, in place (the
/// displacement lists keep their allocations frame to frame).
fn refill_springs(
    slots: &mut Vec<Option<SetThisFrame>>,
    settings: &WindSettings,
    state: &WindState,
    sets: &Assets<SpringSet>,
) {
    slots.resize_with(settings.sets.len(), || None);
    for (i, (slot, handle)) in slots.iter_mut().zip(&settings.sets).enumerate() {
        let running = state.sets.get(i).and_then(Option::as_ref);
        let (Some((_, springs, _)), Some(set)) = (running, sets.get(handle)) else {
            *slot = None;
            continue;
        };
        let now = slot.get_or_insert_default();
        now.set = handle.id();
        now.displacements.clear();
        now.displacements
            .extend(springs.iter().map(|s| s.displacement));
        now.largest = now
            .displacements
            .iter()
            .map(|d| d.length())
            .fold(0.0, f32::max);
        now.pixel_threshold = set.pixel_threshold;
    }
}

/// How a borrower sways this frame: at which level it borrows, and what moves its rig.
#[derive(Clone, Copy)]
struct Borrowed<'a> {
    level: usize,
    rig: &'a WindRig,
    displacements: &'a [Vec3],
    frame: u32,
    interval: u32,
}

/// Instance `i` borrows the offsets of its representative at `sway.level`, brought up to
/// date. Whether the representative was computed this frame; `None` when its rig's
/// offsets do not fit the block (the caller puts the instance at rest).
fn borrow_sway(
    representatives: &mut Representatives,
    scratch: &mut Vec<Vec3A>,
    table: &mut RingOffsetTable,
    moved: &mut MovedShapes,
    i: usize,
    instance: &mut InstanceWind,
    sway: Borrowed,
) -> Option<bool> {
    let b = shared_block(representatives, table, instance, sway.level) as usize;
    let block = &mut representatives.blocks[b];
    let at = BlockUse {
        index: b,
        frame: sway.frame,
        interval: sway.interval,
    };
    let computed = keep_up(
        block,
        at,
        sway.rig,
        sway.displacements,
        scratch,
        table,
        moved,
    )?;
    table.share(i, block.start, block.len);
    moved.share(i, b);
    instance.moving = true;
    Some(computed)
}

/// Which shared block a borrower uses, on which frame, at which update interval.
#[derive(Clone, Copy)]
struct BlockUse {
    index: usize,
    frame: u32,
    interval: u32,
}

/// Brings `block` up to date for a borrower: a representative is computed at the rate of
/// its fastest-moving borrower, staggered by block as instances are (on a grid of frames,
/// so the same frames show the same wind in every run), and anew when it comes back into
/// use. Whether it was computed; `None` when the rig's offsets do not fit the block.
fn keep_up(
    block: &mut SharedBlock,
    at: BlockUse,
    rig: &WindRig,
    displacements: &[Vec3],
    scratch: &mut Vec<Vec3A>,
    table: &mut RingOffsetTable,
    moved: &mut MovedShapes,
) -> Option<bool> {
    let BlockUse {
        index,
        frame,
        interval,
    } = at;
    let kept_up = block
        .used
        .is_some_and(|used| used == frame || used.wrapping_add(1) == frame);
    let due = block.updated != Some(frame)
        && (!kept_up || frame.wrapping_add(index as u32).is_multiple_of(interval));
    block.used = Some(frame);
    if !due {
        return Some(false);
    }
    ring_offsets(
        rig,
        displacements,
        block.rotation,
        block.scale,
        0.0,
        scratch,
    );
    if scratch.len() != block.len as usize {
        return None;
    }
    table.write_block(block.start, scratch);
    moved_bounds(rig, scratch, moved.shared_mut(index));
    block.updated = Some(frame);
    Some(true)
}

/// The block of `instance`'s representative at `level` (under its resolved rig), made on
/// first use.
fn shared_block(
    shared: &mut Representatives,
    table: &mut RingOffsetTable,
    instance: &mut InstanceWind,
    level: usize,
) -> u32 {
    if instance.blocks[level] == UNRESOLVED {
        let representative = representatives(instance.rotation, instance.scale)[level];
        let Representatives { blocks, index } = shared;
        instance.blocks[level] = *index
            .entry((instance.rig, representative.bin))
            .or_insert_with(|| {
                blocks.push(SharedBlock {
                    start: table.new_shared_block(instance.rings),
                    len: instance.rings,
                    rotation: representative.rotation,
                    scale: representative.scale,
                    updated: None,
                    used: None,
                });
                blocks.len() as u32 - 1
            });
    }
    instance.blocks[level]
}

/// Puts a still instance back at rest, once.
fn come_to_rest(
    instance: &mut InstanceWind,
    table: &mut RingOffsetTable,
    moved: &mut MovedShapes,
    i: usize,
) {
    if instance.moving {
        table.rest(i);
        moved.remove(i);
        instance.moving = false;
    }
}
