//! The forest render pass: trunk triangles, screen-space lines of integer widths, leaf
//! points of integer sizes and leaf triangles, drawn from each instance's
//! [`TreeDrawList`] with one instanced draw per primitive kind and view, two for points
//! (small squares and larger discs; see [`crate::draw`] and `batch.rs`).
//!
//! The pass is a system in Bevy's `Core3d` schedule, after the main opaque pass, so it
//! depth-tests against Bevy's own opaque geometry (reverse-Z) and writes depth for what
//! comes after. Geometry of every [`TreeModel`] lives on the GPU once (re-packed when a
//! model is added, changed or removed); per frame only instance records, chunk records and
//! ring offsets are uploaded.
//!
//! Shading is Blinn–Phong in linear colour with the first [`DirectionalLight`]'s
//! direction and colour (its illuminance is ignored: the light has unit strength), and
//! each instance's [`TreeShading`] (or its model's colours). It is not physically based
//! and ignores shadows, exposure and tonemapping.
//!
//! The [`TreeDrawList`] describes one selection per instance, shared by every view: with
//! several cameras each view draws the same ranges, with its own line and point widths in
//! its own pixels. The forest is on render layer 0: a camera whose `RenderLayers` leave
//! it out (a minimap) does not draw it.

mod append_buffer;
mod batch;
mod calibrate;
#[cfg(feature = "hud")]
mod hud;

use std::sync::{Arc, Mutex};

use bevy::asset::{embedded_asset, load_embedded_asset};
use bevy::camera::{MainPassResolutionOverride, Viewport};
use bevy::core_pipeline::{Core3dSystems, core_3d::main_opaque_pass_3d, schedule::Core3d};
use bevy::diagnostic::{DiagnosticPath, DiagnosticsStore};
use bevy::math::{Affine3A, FloatOrd};
use bevy::platform::time::Instant;
use bevy::prelude::*;
use bevy::render::{
    Extract, ExtractSchedule, Render, RenderApp, RenderStartup, RenderSystems,
    camera::ExtractedCamera,
    diagnostic::RecordDiagnostics,
    render_resource::{
        BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries,
        BufferUsages, CachedRenderPipelineId, ColorTargetState, ColorWrites, CompareFunction,
        DepthStencilState, FragmentState, IndexFormat, MultisampleState, PipelineCache,
        PrimitiveState, RawBufferVec, RenderPassDescriptor, RenderPipelineDescriptor, ShaderStages,
        SpecializedRenderPipeline, SpecializedRenderPipelines, StoreOp, TextureFormat, VertexState,
        binding_types::{storage_buffer_read_only_sized, uniform_buffer, uniform_buffer_sized},
    },
    renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery},
    view::{
        ExtractedView, Msaa, ViewDepthTexture, ViewTarget, ViewUniform, ViewUniformOffset,
        ViewUniforms,
    },
};
use bytemuck::{Pod, Zeroable};

pub use calibrate::{
    CalibrationProgress, CalibrationRunPlugin, CalibrationRunSystems, CalibrationSettings,
};
#[cfg(feature = "hud")]
pub use hud::{ForestHud, ForestHudPlugin};

use crate::draw::{ModelSlot, PrimitiveCounts, TreeDrawList, TreeShading};

use crate::draw::packing::{FrameChunks, GeometryAtlas, PrimitiveKind};
use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
use crate::tree::{FollowedModels, NO_RING, TreeModel, TreeModelsVersion};
use crate::wind::RingOffsetTable;
use append_buffer::AppendBuffer;
use batch::{CORNER_INDICES, DrawBatch};

/// Name of the pass in Bevy's render diagnostics: its GPU time is published as
/// `render/sherwood_forest/elapsed_gpu` when `RenderDiagnosticsPlugin` is present.
pub(crate) const PASS_NAME: &str = "sherwood_forest";

/// Draws tree instances with the forest render pass. Part of [`SherwoodPlugins`](crate::SherwoodPlugins)
/// with the `render` feature; without Bevy's render app (a headless app) it only keeps
/// [`ForestRenderStats`].
#[derive(Default)]
pub struct ForestRenderPlugin;

/// What the forest pass drew in the last rendered frame (one frame late: it comes back
/// from the render world).
#[derive(Resource, Clone, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource, Default)]
pub struct ForestRenderStats {
    /// Tree instances with something to draw.
    pub instances: u32,
    /// Trees with something to draw that were left out (after the first such frame, the
    /// farthest from the cameras), because their records needed more than the device binds in one buffer (a
    /// forest of millions in view); a warning is logged when it starts.
    pub left_out: u32,
    /// Primitives drawn per view.
    pub counts: PrimitiveCounts,
    /// Chunks per primitive kind (trunk triangles, leaf triangles, lines, points).
    pub chunks: [u32; 4],
    /// Draw calls per view (at most one per primitive kind, two for points: squares and discs).
    pub draw_calls_per_view: u32,
    /// Views the pass drew into.
    pub views: u32,
    /// CPU time of the forest's extraction into the render world (every tree's draw list,
    /// transform and ring offsets gathered into the frame's records), milliseconds. It
    /// runs while neither world runs anything else.
    pub extract_ms: f32,
    /// CPU time of preparing the frame's records for the GPU (handing them to the buffers
    /// the pass binds and writing those), milliseconds; in the render world, beside the
    /// next frame's main world.
    pub prepare_ms: f32,
    /// GPU time of the pass in milliseconds, summed over views, when Bevy's
    /// `RenderDiagnosticsPlugin` is present and the adapter has timestamp queries. The
    /// cost model learns from it which part of the rendering the budgeted primitives take
    /// (`FrameSamples::push_pass`); the whole
    /// frame's GPU time is measured apart ([`FrameSample::gpu`](crate::cost::FrameSample::gpu)).
    pub gpu_time_ms: Option<f64>,
}

/// Shared between the worlds: stats written by the render world, read by the main world.
#[derive(Resource, Clone, Default)]
struct StatsMailbox(Arc<Mutex<ForestRenderStats>>);

impl Plugin for ForestRenderPlugin {
    fn finish(&self, app: &mut App) {
        crate::schedule::require_plugin::<crate::tree::TreePlugin>(
            app,
            "ForestRenderPlugin",
            "TreePlugin",
        );
    }

    fn build(&self, app: &mut App) {
        embedded_asset!(app, "forest.wgsl");
        let mailbox = StatsMailbox::default();
        app.register_type::<TreeDrawList>()
            .register_type::<TreeShading>()
            .register_type::<ForestRenderStats>()
            .init_resource::<ForestRenderStats>()
            .init_resource::<TreeModelsVersion>()
            .insert_resource(mailbox.clone())
            .add_systems(
                PreUpdate,
                (
                    receive_stats,
                    identify_adapter.before(crate::cost::CostSystems::LoadCalibration),
                ),
            );
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            return;
        };
        render_app
            .insert_resource(mailbox)
            .init_resource::<crate::cost::DrawIncomplete>()
            .init_resource::<ForestFrame>()
            .init_resource::<ForestBuffers>()
            .init_resource::<SpecializedRenderPipelines<ForestPipeline>>()
            .add_systems(RenderStartup, init_pipeline)
            .add_systems(ExtractSchedule, extract_forest)
            .add_systems(
                Render,
                (
                    specialize_pipelines.in_set(RenderSystems::Queue),
                    upload_buffers.in_set(RenderSystems::PrepareResources),
                    create_bind_groups.in_set(RenderSystems::PrepareBindGroups),
                ),
            )
            .add_systems(
                Core3d,
                draw_forest
                    .after(main_opaque_pass_3d)
                    .in_set(Core3dSystems::MainPass),
            );
    }
}

/// Names the adapter for the cost model's calibration lookup, once it is known.
fn identify_adapter(
    mut commands: Commands,
    info: Option<Res<bevy::render::renderer::RenderAdapterInfo>>,
    identity: Option<Res<crate::cost::AdapterIdentity>>,
) {
    if let (Some(info), None) = (info, identity) {
        commands.insert_resource(crate::cost::AdapterIdentity {
            name: info.name.clone(),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_owned(),
            // wgpu's `DeviceType` is not re-exported by Bevy; its `Debug` name is stable.
            cpu: format!("{:?}", info.device_type) == "Cpu",
        });
    }
}

fn receive_stats(
    mailbox: Res<StatsMailbox>,
    mut stats: ResMut<ForestRenderStats>,
    store: Option<Res<DiagnosticsStore>>,
    samples: Option<ResMut<crate::cost::FrameSamples>>,
) {
    let Ok(latest) = mailbox.0.lock() else {
        return;
    };
    let mut latest = latest.clone();
    const GPU_TIME: DiagnosticPath =
        DiagnosticPath::const_new("render/sherwood_forest/elapsed_gpu");
    latest.gpu_time_ms = store
        .as_deref()
        .and_then(|s| s.get(&GPU_TIME))
        .and_then(bevy::diagnostic::Diagnostic::value);
    // The cost model learns from each new pass time once (the store keeps the latest
    // until the next arrives).
    if let (Some(mut samples), Some(gpu_ms)) = (samples, latest.gpu_time_ms)
        && latest.gpu_time_ms != stats.gpu_time_ms
    {
        samples.push_pass((gpu_ms / 1000.0) as f32);
    }
    stats.set_if_neq(latest);
}

#[repr(C)]
#[derive(Clone, Copy, Default, Pod, Zeroable)]
struct GpuShading {
    ambient_shininess: [f32; 4],
    diffuse: [f32; 4],
    specular: [f32; 4],
}

impl From<crate::draw::Shading> for GpuShading {
    fn from(s: crate::draw::Shading) -> Self {
        Self {
            ambient_shininess: s.ambient.extend(s.shininess).to_array(),
            diffuse: s.diffuse.extend(1.0).to_array(),
            specular: s.specular.extend(0.0).to_array(),
        }
    }
}

#[repr(C)]
#[derive(Clone, Copy, Default, Pod, Zeroable)]
struct GpuInstance {
    rows: [[f32; 4]; 3],
    trunk: GpuShading,
    leaves: GpuShading,
    ring_base: u32,
    pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Default, Pod, Zeroable)]
struct GpuLight {
    direction: [f32; 4],
    color: [f32; 4],
}

/// The frame's records, filled during extraction.
#[derive(Resource, Default)]
struct ForestFrame {
    /// The models added since the last upload, packed after those already uploaded.
    atlas: GeometryAtlas,
    atlas_dirty: bool,
    /// The uploaded atlas is to be let go before `atlas` is (the atlas is packed anew).
    atlas_reset: bool,
    /// Where each model's geometry is in the atlas.
    slots: ModelSlots,
    light: GpuLight,
    records: FrameRecords,
    /// The last extraction's CPU time, milliseconds.
    extract_ms: f32,
}

/// The frame's per-tree records.
#[derive(Default)]
struct FrameRecords {
    instances: Vec<GpuInstance>,
    chunks: FrameChunks,
    ring_offsets: Vec<[f32; 4]>,
    counts: PrimitiveCounts,
    /// Bytes the device binds in one storage buffer.
    binding_limit: u64,
    /// Trees with something to draw that did not fit in this frame's buffers.
    left_out: u32,
}

impl FrameRecords {
    /// Whether the records fit in what the device binds at once (instances, chunks and
    /// gathered slots each in one binding).
    fn fits(&self) -> bool {
        let (chunks, gathered) = self.chunks.len_bound();
        let bytes = |n: usize, size: usize| (n * size) as u64;
        bytes(self.instances.len(), size_of::<GpuInstance>()) <= self.binding_limit
            && bytes(chunks, size_of::<crate::draw::packing::GpuChunk>()) <= self.binding_limit
            && bytes(gathered, size_of::<[u32; 2]>()) <= self.binding_limit
            && bytes(self.ring_offsets.len(), size_of::<[f32; 4]>()) <= self.binding_limit
    }
}

/// Each model's place in the atlas, at its index in `models`.
#[derive(Default)]
struct ModelSlots {
    models: FollowedModels,
    slots: Vec<ModelSlot>,
}

impl ModelSlots {
    fn get(&self, id: AssetId<TreeModel>) -> Option<&ModelSlot> {
        self.slots.get(self.models.index(id)? as usize)
    }
}

/// Brings the atlas up to the models ([`FollowedModels`]): the models added since are
/// appended; packed anew, it is uploaded anew.
fn follow_models(frame: &mut ForestFrame, models: &Assets<TreeModel>, version: TreeModelsVersion) {
    let Some(change) = frame.slots.models.follow(models, version) else {
        return;
    };
    if change.anew {
        frame.atlas = GeometryAtlas::default();
        frame.slots.slots.clear();
        frame.atlas_reset = true;
    }
    for (_, model) in change.added() {
        frame.slots.slots.push(frame.atlas.push(model));
    }
    frame.atlas_dirty = true;
}

#[expect(
    clippy::type_complexity,
    reason = "an extraction query names what it reads"
)]
fn extract_forest(
    mut frame: ResMut<ForestFrame>,
    version: Extract<Res<TreeModelsVersion>>,
    models: Extract<Res<Assets<TreeModel>>>,
    trees: Extract<
        Query<(
            Entity,
            &TreeInstance,
            &GlobalTransform,
            Option<&TreeDrawList>,
            Option<&TreeShading>,
            (Has<FixedDrawList>, Option<&Transform>, Has<ChildOf>),
        )>,
    >,
    table: Extract<Option<Res<ForestInstances>>>,
    offsets: Extract<Option<Res<RingOffsetTable>>>,
    lights: Extract<Query<(&DirectionalLight, &GlobalTransform)>>,
    cameras: Extract<Query<(&Camera, &GlobalTransform)>>,
    device: Res<RenderDevice>,
    mut warned_offsets: Local<bool>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    follow_models(frame, &models, **version);
    frame.light = lights.iter().next().map_or(
        GpuLight {
            direction: Vec3::new(0.3, 1.0, 0.2).normalize().extend(0.0).to_array(),
            color: [1.0; 4],
        },
        |(light, transform)| GpuLight {
            direction: transform.back().extend(0.0).to_array(),
            color: light.color.to_linear().to_f32_array(),
        },
    );

    let records = &mut frame.records;
    records.instances.clear();
    records.chunks.clear();
    records.ring_offsets.clear();
    records.counts = PrimitiveCounts::default();
    records.binding_limit = device.limits().max_storage_buffer_binding_size;
    // The wind's offsets go up whole, as the wind keeps them (a block per moving
    // instance, in the instance table's order); each moving tree's record points at its
    // block. Copying them tree by tree cost more than the rest of the extraction.
    let moving = offsets
        .as_deref()
        .filter(|t| t.moving() > 0)
        .zip(table.as_deref())
        .filter(|(rings, _)| {
            let fits = (rings.all_offsets().len() * size_of::<[f32; 4]>()) as u64
                <= records.binding_limit;
            if !fits && !*warned_offsets {
                *warned_offsets = true;
                warn!(
                    "bevy_sherwood: the wind's ring offsets ({} rings) need more than this device binds in one buffer ({} bytes): the trees are drawn at rest",
                    rings.all_offsets().len(),
                    records.binding_limit
                );
            }
            fits
        });
    if let Some((rings, _)) = moving {
        records
            .ring_offsets
            .extend(rings.all_offsets().iter().map(|o| o.extend(0.0).to_array()));
    }
    let overflowed = records.left_out > 0;
    records.left_out = 0;
    let slots = &frame.slots;
    // More trees to draw than the device binds at once (a forest of millions, all in
    // view): the nearest are drawn, the farthest left out, rather than none.
    if overflowed {
        let eyes: Vec<Vec3> = cameras
            .iter()
            .filter(|(camera, _)| camera.is_active)
            .map(|(_, t)| t.translation())
            .collect();
        let distance = |t: &GlobalTransform| {
            let p = t.translation();
            eyes.iter()
                .map(|e| e.distance_squared(p))
                .fold(f32::INFINITY, f32::min)
        };
        let mut nearest_first: Vec<ExtractedTree> = trees.iter().collect();
        nearest_first.sort_by_cached_key(|tree| FloatOrd(distance(tree.2)));
        for tree in nearest_first {
            extract_tree(records, slots, &models, moving, tree);
        }
    } else {
        for tree in &trees {
            extract_tree(records, slots, &models, moving, tree);
        }
    }
    records.chunks.finish();
    if records.left_out > 0 && !overflowed {
        warn!(
            "bevy_sherwood: {} of the {} trees to draw are left out (from the next frame on, the farthest) while their records need more than this device binds in one buffer ({} bytes); fewer trees in view bring them back",
            records.left_out,
            records.left_out as usize + records.instances.len(),
            records.binding_limit
        );
    }
    frame.extract_ms = start.elapsed().as_secs_f32() * 1000.0;
}

/// What the extraction reads of one tree.
type ExtractedTree<'a> = (
    Entity,
    &'a TreeInstance,
    &'a GlobalTransform,
    Option<&'a TreeDrawList>,
    Option<&'a TreeShading>,
    (bool, Option<&'a Transform>, bool),
);

/// Adds one tree's records to the frame's, or counts it left out.
fn extract_tree(
    records: &mut FrameRecords,
    slots: &ModelSlots,
    models: &Assets<TreeModel>,
    moving: Option<(&RingOffsetTable, &ForestInstances)>,
    (entity, instance, global, list, shading, (fixed, local, has_parent)): ExtractedTree,
) {
    // Most trees of a large forest are out of view, their lists empty: left before the
    // lookups below.
    if list.is_some_and(TreeDrawList::is_empty) {
        return;
    }
    let (Some(slot), Some(model)) = (slots.get(instance.model.id()), models.get(&instance.model))
    else {
        return;
    };
    let mut affine = global.affine();
    let unlisted;
    let list = match list {
        Some(list) => list,
        None if fixed => {
            unlisted = TreeDrawList::full(model);
            &unlisted
        }
        None => {
            // Spawned after the Sherwood stages (in `Last`, say): no list yet, and a
            // root's global transform not propagated yet either.
            if let (Some(local), false) = (local, has_parent) {
                affine = local.compute_affine();
            }
            unlisted = TreeDrawList::coarsest(model);
            &unlisted
        }
    };
    // A tree the instance table left out for its transform keeps the last list it
    // was given; it is not drawn where it cannot be.
    if list.is_empty() || !affine.is_finite() {
        return;
    }
    let ring_base = moving
        .and_then(|(rings, table)| rings.block(table.index_of(entity)? as usize, slot.rings))
        .unwrap_or(NO_RING);
    let shading = shading
        .copied()
        .unwrap_or_else(|| TreeShading::of_model(model));
    if !records.push(slot, list, affine, ring_base, shading) {
        records.left_out += 1;
    }
}

impl FrameRecords {
    /// Adds one tree's records, or nothing and `false` when they would not fit;
    /// `ring_base` is where its ring offsets start in `ring_offsets` ([`NO_RING`]: at
    /// rest).
    fn push(
        &mut self,
        slot: &ModelSlot,
        list: &TreeDrawList,
        affine: Affine3A,
        ring_base: u32,
        shading: TreeShading,
    ) -> bool {
        if self.left_out > 0 {
            // Full: the rest is left out too, and not tried one by one.
            return false;
        }
        let chunks = self.chunks.mark();
        let index = self.instances.len() as u32;
        let (m, t) = (affine.matrix3, affine.translation);
        self.instances.push(GpuInstance {
            rows: [
                [m.x_axis.x, m.y_axis.x, m.z_axis.x, t.x],
                [m.x_axis.y, m.y_axis.y, m.z_axis.y, t.y],
                [m.x_axis.z, m.y_axis.z, m.z_axis.z, t.z],
            ],
            trunk: shading.trunk.into(),
            leaves: shading.leaves.into(),
            ring_base,
            pad: [0; 3],
        });
        self.chunks.push(index, slot, list);
        if !self.fits() {
            self.instances.pop();
            self.chunks.truncate(chunks);
            return false;
        }
        self.counts += slot.counts(list);
        true
    }
}

/// GPU copies of the frame's records and the shared geometry.
#[derive(Resource)]
struct ForestBuffers {
    vertices: AppendBuffer<crate::draw::packing::GpuVertex>,
    indices: AppendBuffer<u32>,
    primitives: AppendBuffer<crate::draw::packing::GpuPrimitive>,
    instances: RawBufferVec<GpuInstance>,
    chunks: RawBufferVec<crate::draw::packing::GpuChunk>,
    ring_offsets: RawBufferVec<[f32; 4]>,
    gathered: RawBufferVec<[u32; 2]>,
    light: RawBufferVec<GpuLight>,
    /// [`CORNER_INDICES`], for lines and points.
    corner_indices: RawBufferVec<u16>,
    /// First chunk of each [`DrawBatch`] in `chunks`, and the end.
    batch_starts: [u32; DrawBatch::ALL.len() + 1],
}

impl Default for ForestBuffers {
    fn default() -> Self {
        let storage = || BufferUsages::STORAGE | BufferUsages::COPY_DST;
        Self {
            vertices: AppendBuffer::new("sherwood_forest_vertices"),
            indices: AppendBuffer::new("sherwood_forest_indices"),
            primitives: AppendBuffer::new("sherwood_forest_primitives"),
            instances: RawBufferVec::new(storage()),
            chunks: RawBufferVec::new(storage()),
            ring_offsets: RawBufferVec::new(storage()),
            gathered: RawBufferVec::new(storage()),
            light: RawBufferVec::new(BufferUsages::UNIFORM | BufferUsages::COPY_DST),
            corner_indices: RawBufferVec::new(BufferUsages::INDEX | BufferUsages::COPY_DST),
            batch_starts: [0; DrawBatch::ALL.len() + 1],
        }
    }
}

/// Storage buffers may not be empty: pad with one default element.
fn fill<T: Pod + Default>(buffer: &mut RawBufferVec<T>, values: &[T]) {
    let out = buffer.values_mut();
    out.clear();
    out.extend_from_slice(values);
    if out.is_empty() {
        out.push(T::default());
    }
}

/// Gives `values` to `buffer` (padded as [`fill`] pads) instead of copying them, and takes
/// back the buffer's last values for `values` to be filled anew (it is cleared before it
/// is).
fn take_into<T: Pod + Default>(buffer: &mut RawBufferVec<T>, values: &mut Vec<T>) {
    let out = buffer.values_mut();
    core::mem::swap(out, values);
    if out.is_empty() {
        out.push(T::default());
    }
}

fn upload_buffers(
    mut frame: ResMut<ForestFrame>,
    mut buffers: ResMut<ForestBuffers>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mailbox: Res<StatsMailbox>,
    views: Query<(), With<ForestViewPipelines>>,
) {
    let start = Instant::now();
    let frame = &mut *frame;
    let buffers = &mut *buffers;
    if core::mem::take(&mut frame.atlas_reset) {
        buffers.vertices.clear();
        buffers.indices.clear();
        buffers.primitives.clear();
    }
    if core::mem::take(&mut frame.atlas_dirty) {
        // The shared geometry is written once, models appended as they come, and its CPU
        // copies let go once written: with a hierarchical strategy's group impostors it
        // is hundreds of megabytes, and on a software renderer the GPU's copy is process
        // memory too. (A change or removal of a model packs the atlas anew.)
        let limit = device.limits().max_storage_buffer_binding_size;
        let (vertices, indices, primitives) = frame.atlas.take();
        buffers.vertices.append(&vertices, limit, &device, &queue);
        buffers.indices.append(&indices, limit, &device, &queue);
        buffers
            .primitives
            .append(&primitives, limit, &device, &queue);
    }
    if buffers.corner_indices.buffer().is_none() {
        fill(&mut buffers.corner_indices, &CORNER_INDICES);
        buffers.corner_indices.write_buffer(&device, &queue);
    }
    let instances = frame.records.instances.len() as u32;
    take_into(&mut buffers.instances, &mut frame.records.instances);
    take_into(&mut buffers.ring_offsets, &mut frame.records.ring_offsets);
    take_into(&mut buffers.gathered, &mut frame.records.chunks.gathered);
    fill(&mut buffers.light, &[frame.light]);
    let chunks = buffers.chunks.values_mut();
    chunks.clear();
    for (b, batch) in DrawBatch::ALL.into_iter().enumerate() {
        buffers.batch_starts[b] = chunks.len() as u32;
        let kind = batch.kind();
        chunks.extend(
            frame
                .records
                .chunks
                .of(kind)
                .iter()
                .filter(|chunk| DrawBatch::of(kind, chunk) == batch),
        );
    }
    buffers.batch_starts[DrawBatch::ALL.len()] = chunks.len() as u32;
    if chunks.is_empty() {
        chunks.push(crate::draw::packing::GpuChunk::default());
    }
    buffers.instances.write_buffer(&device, &queue);
    buffers.ring_offsets.write_buffer(&device, &queue);
    buffers.gathered.write_buffer(&device, &queue);
    buffers.light.write_buffer(&device, &queue);
    buffers.chunks.write_buffer(&device, &queue);

    if let Ok(mut stats) = mailbox.0.lock() {
        let s = buffers.batch_starts;
        *stats = ForestRenderStats {
            instances,
            left_out: frame.records.left_out,
            counts: frame.records.counts,
            chunks: PrimitiveKind::ALL.map(|kind| kind_chunks(&s, kind)),
            draw_calls_per_view: s.windows(2).filter(|w| w[1] > w[0]).count() as u32,
            views: views.iter().count() as u32,
            extract_ms: frame.extract_ms,
            prepare_ms: start.elapsed().as_secs_f32() * 1000.0,
            gpu_time_ms: None,
        };
    }
}

#[derive(Resource)]
struct ForestPipeline {
    view_layout: BindGroupLayoutDescriptor,
    geometry_layout: BindGroupLayoutDescriptor,
    frame_layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
}

fn init_pipeline(mut commands: Commands, asset_server: Res<AssetServer>) {
    let storage = || storage_buffer_read_only_sized(false, None);
    commands.insert_resource(ForestPipeline {
        view_layout: BindGroupLayoutDescriptor::new(
            "sherwood_forest_view",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::VERTEX_FRAGMENT,
                (
                    uniform_buffer::<ViewUniform>(true),
                    uniform_buffer_sized(false, None),
                ),
            ),
        ),
        geometry_layout: BindGroupLayoutDescriptor::new(
            "sherwood_forest_geometry",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::VERTEX,
                (storage(), storage(), storage()),
            ),
        ),
        frame_layout: BindGroupLayoutDescriptor::new(
            "sherwood_forest_frame",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::VERTEX_FRAGMENT,
                (storage(), storage(), storage(), storage()),
            ),
        ),
        shader: load_embedded_asset!(asset_server.as_ref(), "forest.wgsl"),
    });
}

/// Chunks of `kind` among the batches starting at `starts`.
fn kind_chunks(starts: &[u32], kind: PrimitiveKind) -> u32 {
    DrawBatch::ALL
        .iter()
        .zip(starts.windows(2))
        .filter(|(batch, _)| batch.kind() == kind)
        .map(|(_, w)| w[1] - w[0])
        .sum()
}

#[derive(Clone, Copy, PartialEq, Eq, Hash)]
struct PipelineKey {
    batch: DrawBatch,
    samples: u32,
    format: TextureFormat,
}

impl SpecializedRenderPipeline for ForestPipeline {
    type Key = PipelineKey;

    fn specialize(&self, key: Self::Key) -> RenderPipelineDescriptor {
        let (vertex, fragment, cull_mode) = key.batch.shaders();
        RenderPipelineDescriptor {
            label: Some(format!("sherwood_forest_{:?}", key.batch).into()),
            layout: vec![
                self.view_layout.clone(),
                self.geometry_layout.clone(),
                self.frame_layout.clone(),
            ],
            vertex: VertexState {
                shader: self.shader.clone(),
                entry_point: Some(vertex.into()),
                ..default()
            },
            fragment: Some(FragmentState {
                shader: self.shader.clone(),
                entry_point: Some(fragment.into()),
                targets: vec![Some(ColorTargetState {
                    format: key.format,
                    blend: None,
                    write_mask: ColorWrites::ALL,
                })],
                ..default()
            }),
            primitive: PrimitiveState {
                cull_mode,
                ..default()
            },
            depth_stencil: Some(DepthStencilState {
                format: bevy::core_pipeline::core_3d::CORE_3D_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(CompareFunction::GreaterEqual),
                stencil: default(),
                bias: default(),
            }),
            multisample: MultisampleState {
                count: key.samples,
                ..default()
            },
            ..default()
        }
    }
}

/// The pass's pipelines for one view, per [`DrawBatch`].
#[derive(Component)]
struct ForestViewPipelines([CachedRenderPipelineId; DrawBatch::ALL.len()]);

fn specialize_pipelines(
    mut commands: Commands,
    pipeline: Option<Res<ForestPipeline>>,
    mut pipelines: ResMut<SpecializedRenderPipelines<ForestPipeline>>,
    cache: Res<PipelineCache>,
    views: Query<
        (
            Entity,
            &ViewTarget,
            &Msaa,
            Option<&bevy::camera::visibility::RenderLayers>,
        ),
        With<ExtractedView>,
    >,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    let forest_layers = bevy::camera::visibility::RenderLayers::default();
    for (entity, target, msaa, layers) in &views {
        // The forest is on layer 0: a camera that leaves it out does not draw it.
        if layers.is_some_and(|l| !l.intersects(&forest_layers)) {
            commands.entity(entity).remove::<ForestViewPipelines>();
            continue;
        }
        let ids = DrawBatch::ALL.map(|batch| {
            pipelines.specialize(
                &cache,
                &pipeline,
                PipelineKey {
                    batch,
                    samples: msaa.samples(),
                    format: target.main_texture_format(),
                },
            )
        });
        commands.entity(entity).insert(ForestViewPipelines(ids));
    }
}

#[derive(Resource)]
struct ForestBindGroups {
    view: BindGroup,
    geometry: BindGroup,
    frame: BindGroup,
}

fn create_bind_groups(
    mut commands: Commands,
    pipeline: Option<Res<ForestPipeline>>,
    buffers: Res<ForestBuffers>,
    view_uniforms: Res<ViewUniforms>,
    device: Res<RenderDevice>,
    cache: Res<PipelineCache>,
    mut warned: Local<bool>,
) {
    let (
        Some(pipeline),
        Some(view),
        Some(light),
        Some(vertices),
        Some(indices),
        Some(primitives),
        Some(instances),
        Some(chunks),
        Some(ring_offsets),
        Some(gathered),
    ) = (
        pipeline,
        view_uniforms.uniforms.binding(),
        buffers.light.binding(),
        buffers.vertices.binding(),
        buffers.indices.binding(),
        buffers.primitives.binding(),
        buffers.instances.binding(),
        buffers.chunks.binding(),
        buffers.ring_offsets.binding(),
        buffers.gathered.binding(),
    )
    else {
        commands.remove_resource::<ForestBindGroups>();
        return;
    };
    // Shared geometry past what the device binds at once would fail validation and quit
    // the app: draw nothing and say why instead. (The frame's records are kept within it
    // by the extraction, which leaves the farthest trees out.)
    let limit = device.limits().max_storage_buffer_binding_size;
    let too_large = [
        ("geometry vertices", buffers.vertices.buffer()),
        ("geometry indices", buffers.indices.buffer()),
        ("lines and points", buffers.primitives.buffer()),
    ]
    .into_iter()
    .find_map(|(name, buffer)| {
        let size = buffer.map_or(0, |b| b.size());
        (size > limit).then_some((name, size))
    });
    if let Some((name, size)) = too_large {
        if !*warned {
            error!(
                "bevy_sherwood: the forest's {name} take {size} bytes, more than this device binds at once ({limit}): the forest is not drawn. Fewer or smaller tree models (for group impostors: a lower GroupImpostorSettings::max_vertices) bring it back."
            );
            *warned = true;
        }
        commands.remove_resource::<ForestBindGroups>();
        return;
    }
    *warned = false;
    commands.insert_resource(ForestBindGroups {
        view: device.create_bind_group(
            "sherwood_forest_view",
            &cache.get_bind_group_layout(&pipeline.view_layout),
            &BindGroupEntries::sequential((view, light)),
        ),
        geometry: device.create_bind_group(
            "sherwood_forest_geometry",
            &cache.get_bind_group_layout(&pipeline.geometry_layout),
            &BindGroupEntries::sequential((vertices, indices, primitives)),
        ),
        frame: device.create_bind_group(
            "sherwood_forest_frame",
            &cache.get_bind_group_layout(&pipeline.frame_layout),
            &BindGroupEntries::sequential((instances, chunks, ring_offsets, gathered)),
        ),
    });
}

fn draw_forest(
    view: ViewQuery<(
        &ExtractedCamera,
        &ViewTarget,
        &ViewDepthTexture,
        &ViewUniformOffset,
        &ForestViewPipelines,
        Option<&MainPassResolutionOverride>,
    )>,
    buffers: Res<ForestBuffers>,
    bind_groups: Option<Res<ForestBindGroups>>,
    cache: Res<PipelineCache>,
    mut incomplete: ResMut<crate::cost::DrawIncomplete>,
    mut ctx: RenderContext,
) {
    let starts = buffers.batch_starts;
    if starts[DrawBatch::ALL.len()] == 0 {
        return;
    }
    let (Some(bind_groups), Some(corner_indices)) = (bind_groups, buffers.corner_indices.buffer())
    else {
        incomplete.0 = true;
        return;
    };
    let (camera, target, depth, view_offset, pipelines, resolution_override) = view.into_inner();
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let color_attachments = [Some(target.get_color_attachment())];
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some(PASS_NAME),
        color_attachments: &color_attachments,
        depth_stencil_attachment: Some(depth.get_attachment(StoreOp::Store)),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    let span = diagnostics.pass_span(&mut pass, PASS_NAME);
    if let Some(viewport) =
        Viewport::from_viewport_and_override(camera.viewport.as_ref(), resolution_override)
    {
        pass.set_camera_viewport(&viewport);
    }
    pass.set_bind_group(0, &bind_groups.view, &[view_offset.offset]);
    pass.set_bind_group(1, &bind_groups.geometry, &[]);
    pass.set_bind_group(2, &bind_groups.frame, &[]);
    pass.set_index_buffer(corner_indices.slice(..), IndexFormat::Uint16);
    for (b, batch) in DrawBatch::ALL.into_iter().enumerate() {
        let chunks = starts[b]..starts[b + 1];
        if chunks.is_empty() {
            continue;
        }
        // Pipelines compile asynchronously: skip a kind until its pipeline is ready.
        let Some(pipeline) = cache.get_render_pipeline(pipelines.0[b]) else {
            // This frame's time is not a real frame's (see `DrawIncomplete`).
            incomplete.0 = true;
            continue;
        };
        pass.set_render_pipeline(pipeline);
        match batch.corners() {
            (Some(first), count) => pass.draw_indexed(first..first + count, 0, chunks),
            (None, count) => pass.draw(0..count, chunks),
        }
    }
    span.end(&mut pass);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::draw::packing::GpuChunk;
    use crate::draw::{LineRun, PointRun};
    use crate::tree::grand_model as model;

    /// Records whose buffers bind `limit` bytes, and the model's place in an atlas.
    fn frame(model: &TreeModel, limit: u64) -> (FrameRecords, ModelSlot) {
        let records = FrameRecords {
            binding_limit: limit,
            ..default()
        };
        (records, GeometryAtlas::default().push(model))
    }

    /// A few lines and points of several widths and sizes: leftovers in several chunks.
    fn list(model: &TreeModel, k: u32) -> TreeDrawList {
        let segments = model.segments.len() as u32;
        let leaves = model.leaves.len() as u32;
        TreeDrawList {
            trunk_lines: vec![LineRun {
                segments: 0..(7 + k) % segments,
                width: 1 + k % 3,
            }],
            leaf_points: vec![PointRun {
                leaves: 0..(40 + 13 * k) % leaves,
                size: 1 + k % 7,
            }],
            ..default()
        }
    }

    /// The gathered slots and chunks as the pass reads them.
    fn chunks(frame: &FrameRecords) -> Vec<GpuChunk> {
        PrimitiveKind::ALL
            .iter()
            .flat_map(|&kind| frame.chunks.of(kind).iter().copied())
            .collect()
    }

    #[test]
    fn the_chunk_bound_is_never_below_what_finishing_leaves() {
        let model = model();
        let (mut frame, slot) = frame(&model, u64::MAX);
        for k in 0..200 {
            frame.chunks.push(k, &slot, &list(&model, k));
            let bound = frame.chunks.len_bound();
            let mut done = frame.chunks.clone();
            done.finish();
            let total: usize = PrimitiveKind::ALL
                .iter()
                .map(|&kind| done.of(kind).len())
                .sum();
            assert!(
                total <= bound.0 && done.gathered.len() <= bound.1,
                "{k}: {bound:?}"
            );
        }
    }

    /// One 1-pixel line: a tree that takes one gathered slot.
    fn twig() -> TreeDrawList {
        TreeDrawList {
            trunk_lines: vec![LineRun {
                segments: 0..1,
                width: 1,
            }],
            ..default()
        }
    }

    /// Pushes `lists` as the extraction does; the trees drawn.
    fn push_all(
        records: &mut FrameRecords,
        model: &TreeModel,
        slot: &ModelSlot,
        lists: &[TreeDrawList],
    ) -> usize {
        let shading = TreeShading::of_model(model);
        let mut drawn = 0;
        for list in lists {
            if records.push(slot, list, Affine3A::IDENTITY, NO_RING, shading) {
                drawn += 1;
            } else {
                records.left_out += 1;
            }
        }
        records.chunks.finish();
        drawn
    }

    #[test]
    fn trees_past_what_the_device_binds_are_left_out_whole() {
        let model = model();
        // Room for ten instance records.
        let limit = 10 * size_of::<GpuInstance>() as u64;
        let (mut records, slot) = frame(&model, limit);
        let twigs = vec![twig(); 25];
        assert_eq!(push_all(&mut records, &model, &slot, &twigs), 10);
        assert_eq!((records.instances.len(), records.left_out), (10, 15));
        assert_eq!(records.counts.lines, 10);

        // Trees of many leftovers: the gathered slots fill first. Nothing of a left-out
        // tree stays behind, and what is kept binds.
        let (mut records, slot) = frame(&model, 4096);
        let lists: Vec<TreeDrawList> = (0..25).map(|k| list(&model, k)).collect();
        let drawn = push_all(&mut records, &model, &slot, &lists);
        assert!(drawn > 0 && drawn < 25, "{drawn}");
        assert_eq!(records.instances.len(), drawn);
        let mut counts = PrimitiveCounts::default();
        for list in &lists[..drawn] {
            counts += slot.counts(list);
        }
        assert_eq!(records.counts, counts);
        let chunks = chunks(&records);
        for chunk in &chunks {
            for (instance, _) in records.chunks.slots(chunk) {
                assert!((instance as usize) < drawn, "{chunk:?}");
            }
        }
        assert!((chunks.len() * size_of::<GpuChunk>()) as u64 <= records.binding_limit);
        assert!((records.chunks.gathered.len() * 8) as u64 <= records.binding_limit);
    }
}
