//! The GPU time of a whole frame: a timestamp before the first of the frame's command
//! buffers and one after the last, read back a frame or two later and handed to the
//! main world with the frame's number ([`FrameSample::gpu`](super::FrameSample::gpu)).
//!
//! With frames in flight the GPU may still be drawing frame `k` while the CPU prepares
//! `k + 1`: the render world's CPU time then misses it, the timestamps do not. Each
//! timestamp is written by an empty compute pass, which needs only
//! `Features::TIMESTAMP_QUERY` (not the "inside encoders" extension WebGPU lacks).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use bevy::prelude::*;
use bevy::render::RenderStartup;
use bevy::render::render_resource::{ComputePassDescriptor, MapMode, WgpuFeatures};
use bevy::render::renderer::{
    PendingCommandBuffers, RenderDevice, RenderGraph, RenderGraphSystems, RenderQueue, WgpuWrapper,
};

use super::measure::{RenderClock, RenderedFrames};

/// Frames whose timestamps can be in flight at once; a frame finding none free is not
/// timed (its sample is learned without a GPU time).
const SLOTS: u32 = 4;
/// `resolve_query_set` writes at offsets that are multiples of this.
const RESOLVE_STRIDE: u64 = 256;
/// Two timestamps of 8 bytes.
const SLOT_BYTES: u64 = 16;

const FREE: u8 = 0;
const WRITTEN: u8 = 1;
const MAPPING: u8 = 2;
const MAPPED: u8 = 3;

struct Slot {
    readback: wgpu::Buffer,
    /// [`FREE`], [`WRITTEN`], [`MAPPING`] or [`MAPPED`]; the map callback sets the last
    /// (or [`FREE`] when mapping failed).
    state: Arc<AtomicU8>,
    frame: u64,
}

/// Writes and reads back the frame timestamps. Present in the render world when the
/// device has timestamp queries.
#[derive(Resource)]
pub(super) struct GpuFrameTimer(WgpuWrapper<Timer>);

struct Timer {
    queries: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    slots: Vec<Slot>,
    period_ns: f32,
    /// The slot this frame writes into.
    current: Option<usize>,
    /// The last frame whose timestamps were submitted.
    last_timed: Option<u64>,
}

impl GpuFrameTimer {
    /// Whether `frame`'s timestamps were submitted (its GPU time will follow).
    pub(super) fn timed(&self, frame: u64) -> bool {
        self.0.last_timed == Some(frame)
    }
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(RenderStartup, create_timer)
        .add_systems(
            RenderGraph,
            (
                begin_frame.in_set(RenderGraphSystems::Begin),
                end_frame
                    .after(RenderGraphSystems::Render)
                    .before(RenderGraphSystems::Submit),
                map_frame.in_set(RenderGraphSystems::Finish),
            ),
        );
}

fn create_timer(mut commands: Commands, device: Res<RenderDevice>, queue: Res<RenderQueue>) {
    if !device.features().contains(WgpuFeatures::TIMESTAMP_QUERY) {
        commands.remove_resource::<GpuFrameTimer>();
        return;
    }
    let wgpu_device = device.wgpu_device();
    let queries = wgpu_device.create_query_set(&wgpu::QuerySetDescriptor {
        label: Some("sherwood_frame_timestamps"),
        ty: wgpu::QueryType::Timestamp,
        count: 2 * SLOTS,
    });
    let resolve = wgpu_device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("sherwood_frame_timestamps_resolve"),
        size: RESOLVE_STRIDE * u64::from(SLOTS),
        usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    });
    let slots = (0..SLOTS)
        .map(|_| Slot {
            readback: wgpu_device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("sherwood_frame_timestamps_readback"),
                size: SLOT_BYTES,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            }),
            state: Arc::new(AtomicU8::new(FREE)),
            frame: 0,
        })
        .collect();
    commands.insert_resource(GpuFrameTimer(WgpuWrapper::new(Timer {
        queries,
        resolve,
        slots,
        period_ns: queue.get_timestamp_period(),
        current: None,
        last_timed: None,
    })));
}

/// A command buffer holding one empty compute pass that writes timestamp `index`.
fn timestamp_pass(
    device: &RenderDevice,
    queries: &wgpu::QuerySet,
    index: u32,
    at_start: bool,
) -> wgpu::CommandEncoder {
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("sherwood_frame_timestamp"),
    });
    let index = Some(index);
    drop(encoder.begin_compute_pass(&ComputePassDescriptor {
        label: Some("sherwood_frame_timestamp"),
        timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
            query_set: queries,
            beginning_of_pass_write_index: if at_start { index } else { None },
            end_of_pass_write_index: if at_start { None } else { index },
        }),
    }));
    encoder
}

/// Reads back the frames whose timestamps have arrived, then opens this frame's.
fn begin_frame(
    timer: Option<ResMut<GpuFrameTimer>>,
    device: Res<RenderDevice>,
    mailbox: Res<RenderedFrames>,
    mut pending: ResMut<PendingCommandBuffers>,
) {
    let Some(mut timer) = timer else {
        return;
    };
    let timer = &mut *timer.0;
    for slot in &mut timer.slots {
        if slot.state.load(Ordering::Acquire) != MAPPED {
            continue;
        }
        let seconds = {
            let data = slot.readback.slice(..).get_mapped_range();
            let stamp = |i: usize| {
                let mut bytes = [0u8; 8];
                bytes.copy_from_slice(&data[8 * i..8 * i + 8]);
                u64::from_le_bytes(bytes)
            };
            let (start, end) = (stamp(0), stamp(1));
            (end > start).then(|| ((end - start) as f64 * f64::from(timer.period_ns) * 1e-9) as f32)
        };
        slot.readback.unmap();
        slot.state.store(FREE, Ordering::Release);
        if let Some(seconds) = seconds {
            mailbox.report_gpu(slot.frame, seconds);
        }
    }
    timer.current = timer
        .slots
        .iter()
        .position(|s| s.state.load(Ordering::Acquire) == FREE);
    if let Some(i) = timer.current {
        let encoder = timestamp_pass(&device, &timer.queries, 2 * i as u32, true);
        pending.push([encoder.finish()]);
    }
}

/// Closes this frame's timestamps after every pass, before the frame is submitted.
fn end_frame(
    timer: Option<ResMut<GpuFrameTimer>>,
    device: Res<RenderDevice>,
    clock: Res<RenderClock>,
    mut pending: ResMut<PendingCommandBuffers>,
) {
    let Some(mut timer) = timer else {
        return;
    };
    let timer = &mut *timer.0;
    let Some(i) = timer.current else {
        return;
    };
    let first = 2 * i as u32;
    let mut encoder = timestamp_pass(&device, &timer.queries, first + 1, false);
    let offset = RESOLVE_STRIDE * i as u64;
    encoder.resolve_query_set(&timer.queries, first..first + 2, &timer.resolve, offset);
    encoder.copy_buffer_to_buffer(
        &timer.resolve,
        offset,
        &timer.slots[i].readback,
        0,
        SLOT_BYTES,
    );
    pending.push([encoder.finish()]);
    timer.slots[i].frame = clock.frame;
    timer.slots[i].state.store(WRITTEN, Ordering::Release);
}

/// Once the frame is submitted, asks for its timestamps.
fn map_frame(timer: Option<ResMut<GpuFrameTimer>>) {
    let Some(mut timer) = timer else {
        return;
    };
    let timer = &mut *timer.0;
    let Some(i) = timer.current.take() else {
        return;
    };
    let slot = &timer.slots[i];
    if slot.state.load(Ordering::Acquire) != WRITTEN {
        return;
    }
    slot.state.store(MAPPING, Ordering::Release);
    let state = slot.state.clone();
    slot.readback
        .slice(..)
        .map_async(MapMode::Read, move |result| {
            state.store(
                if result.is_ok() { MAPPED } else { FREE },
                Ordering::Release,
            );
        });
    timer.last_timed = Some(slot.frame);
}
