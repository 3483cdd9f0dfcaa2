//! The wind stage (`SherwoodSystems::Animate`): springs stepped on a fixed time step and,
//! for instances that were visible last frame, their rings' offsets in one flat table —
//! the table the render pass uploads and applies per ring on the GPU.

use bevy::prelude::*;

use super::asset::SpringSet;
use std::collections::HashMap;

use super::motion::{WindRig, associate, moved_bounds, ring_offsets};
use super::spring::{FixedStepper, Spring};
use crate::SherwoodSystems;
use crate::culling::{ForestCulling, InstanceVisibility};
use crate::ecosystem::TreeInstance;
use crate::tree::{TreeModel, TreeModelsVersion};
use crate::view::LodView;

/// Wind configuration. Changing it at run time takes effect on the next frame.
#[derive(Resource, Clone, Debug)]
pub struct WindSettings {
    /// Move trees at all. Default: `true`.
    pub enabled: bool,
    /// The spring set of each motion index (a tree's `TreeInstance::motion`); instances
    /// whose index has no set stay still. Default: `wind/default.wind.ron` for index 0,
    /// loaded at start-up when the list is empty.
    pub sets: Vec<Handle<SpringSet>>,
}

impl Default for WindSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            sets: Vec::new(),
        }
    }
}

/// Ring offsets of every instance, in the order of [`ForestCulling::entities`]: instance
/// `i`'s rings are `offsets[starts[i]..starts[i + 1]]`, in its model's ring order (model
/// space). Instances that do not move have all-zero offsets.
#[derive(Resource, Clone, Debug, Default)]
pub struct RingOffsetTable {
    /// Per-ring offsets, instance after instance.
    pub offsets: Vec<Vec3>,
    /// Where each instance's rings start; one more entry than instances.
    pub starts: Vec<u32>,
    /// Instances moved this frame (the rest were invisible or below the motion LOD).
    pub moved: u32,
}

/// What the wind stage did in the last frame.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq)]
pub struct WindStats {
    /// Visible instances with a spring set (candidates for motion).
    pub candidates: u32,
    /// Instances moved.
    pub moved: u32,
    /// Candidates left still by the motion level of detail (their farthest ring's motion,
    /// the largest spring displacement × the rig's reach, projects below the set's pixel
    /// threshold).
    pub skipped: u32,
    /// Time of the per-instance work (ring offsets and moved bounds), milliseconds;
    /// stepping the springs themselves (a few per set) is not included.
    pub update_ms: f32,
}

#[derive(Resource, Default)]
struct WindState {
    /// Per motion index: the set it was built from and its running springs.
    sets: Vec<Option<(AssetId<SpringSet>, Vec<Spring>, FixedStepper)>>,
}

pub(super) fn build(app: &mut App) {
    app.init_resource::<WindSettings>()
        .init_resource::<WindState>()
        .init_resource::<RingOffsetTable>()
        .init_resource::<WindStats>()
        .init_resource::<TreeModelsVersion>()
        .add_systems(Startup, load_default_set)
        .add_systems(
            PostUpdate,
            (step_springs, move_rings)
                .chain()
                .in_set(SherwoodSystems::Animate),
        );
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
        if slot.as_ref().is_none_or(|(id, _, _)| *id != handle.id()) || sets.is_changed() {
            let mut springs: Vec<Spring> = set.springs.iter().cloned().map(Spring::new).collect();
            // An edited set keeps its springs' motion, so trees do not snap to rest.
            if let Some((id, old, _)) = slot.as_ref()
                && *id == handle.id()
            {
                for (new, old) in springs.iter_mut().zip(old) {
                    new.displacement = old.displacement;
                    new.velocity = old.velocity;
                }
            }
            *slot = Some((handle.id(), springs, FixedStepper::new(set.time_step)));
        }
        if let Some((_, springs, stepper)) = slot.as_mut() {
            stepper.advance(springs, time.delta_secs());
        }
    }
}

#[expect(
    clippy::too_many_arguments,
    reason = "one system gathering the stage's inputs"
)]
fn move_rings(
    settings: Res<WindSettings>,
    state: Res<WindState>,
    sets: Res<Assets<SpringSet>>,
    mut culling: ResMut<ForestCulling>,
    instances: Query<(&TreeInstance, &GlobalTransform)>,
    models: Res<Assets<TreeModel>>,
    views: Query<&LodView>,
    mut table: ResMut<RingOffsetTable>,
    mut stats: ResMut<WindStats>,
    version: Res<TreeModelsVersion>,
    mut rigs: Local<HashMap<(AssetId<TreeModel>, AssetId<SpringSet>), WindRig>>,
) {
    let start_time = std::time::Instant::now();
    // A rig is derived from a tree model and a set's rules: an edited (hot-reloaded) one
    // must not keep moving its rings the old way.
    if sets.is_changed() || version.is_changed() {
        rigs.clear();
    }
    let table = &mut *table;
    table.offsets.clear();
    table.starts.clear();
    table.moved = 0;
    let mut counts = WindStats::default();
    let ForestCulling {
        entities,
        result,
        moved,
        ..
    } = &mut *culling;
    moved.clear();
    let view = views.iter().next();
    let mut scratch = Vec::new();
    let mut displacements = Vec::new();
    for (i, &entity) in entities.iter().enumerate() {
        table.starts.push(table.offsets.len() as u32);
        let Ok((instance, transform)) = instances.get(entity) else {
            continue;
        };
        let Some(model) = models.get(&instance.model) else {
            continue;
        };
        let start = table.offsets.len();
        table.offsets.resize(start + model.rings.len(), Vec3::ZERO);
        let visible = result
            .visibility
            .get(i)
            .is_some_and(|v| *v != InstanceVisibility::Invisible);
        let running = state
            .sets
            .get(instance.motion as usize)
            .and_then(Option::as_ref);
        let set = settings
            .sets
            .get(instance.motion as usize)
            .and_then(|h| sets.get(h));
        let (Some((_, springs, _)), Some(set)) = (running, set) else {
            continue;
        };
        if !settings.enabled || !visible {
            continue;
        }
        counts.candidates += 1;
        displacements.clear();
        displacements.extend(springs.iter().map(|s| s.displacement));
        // Association depends only on the tree type and the set: computed once.
        let set_id = settings.sets[instance.motion as usize].id();
        let rig = rigs
            .entry((instance.model.id(), set_id))
            .or_insert_with(|| WindRig::new(model, &associate(model, &set.rules, springs.len())));
        // Motion LOD: skip the tree when its farthest-moving ring (the largest spring
        // displacement times the rig's reach) projects below the threshold.
        let (_, rotation, translation) = transform.to_scale_rotation_translation();
        let pixels_per_unit =
            view.map(|v| v.focal_pixels / v.position.distance(translation).max(1e-3));
        if let Some(ppu) = pixels_per_unit {
            let largest = displacements.iter().map(|d| d.length()).fold(0.0, f32::max);
            if largest * rig.reach() * ppu < set.pixel_threshold {
                counts.skipped += 1;
                continue;
            }
        }
        let threshold =
            pixels_per_unit.map_or(0.0, |ppu| set.pixel_threshold / ppu / instance.scale);
        ring_offsets(
            rig,
            &displacements,
            rotation,
            instance.scale,
            threshold,
            &mut scratch,
        );
        table.offsets[start..].copy_from_slice(&scratch);
        table.moved += 1;
        moved_bounds(model, &scratch, moved.shape_mut(i));
    }
    table.starts.push(table.offsets.len() as u32);
    *stats = WindStats {
        moved: table.moved,
        update_ms: start_time.elapsed().as_secs_f32() * 1000.0,
        ..counts
    };
}
