//! Measuring real frames: how long the main world's update took (the logic), how long the
//! render world took to render it, and the interval between that frame's end of
//! rendering and the previous one's (the frame time the frame is charged with).
//!
//! With Bevy's pipelined rendering the render world draws frame `k` while the main world
//! updates frame `k + 1`, so the time between two main-world updates belongs to the
//! *previous* selection. Every measurement here is tagged with the main-world frame that
//! produced it ([`FrameClock::frame`]), so the cost model pairs each prediction with the
//! times of the frame it was made for, pipelined or not.

use std::collections::VecDeque;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use bevy::app::MainScheduleOrder;
use bevy::ecs::schedule::ScheduleLabel;
use bevy::prelude::*;
use serde::{Deserialize, Serialize};

/// One measured frame: the *work* of each world, with the waits that are not work (the
/// swapchain's vertical blank, a frame pacer) measured apart.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameSample {
    /// The frame's number ([`FrameClock::frame`] while its main-world update ran).
    pub frame: u64,
    /// Seconds the main world's update took, `First` to `Last`: everything but the wait
    /// for the render world (app logic, culling, the Sherwood stages and their search,
    /// wind, UI layout).
    pub logic: f32,
    /// Seconds the render world worked on this frame: its `Render` schedule up to the end
    /// of [`RenderSystems::Render`](bevy::render::RenderSystems::Render) (where Bevy
    /// submits and presents; a wait for the GPU an app inserts there counts), less the
    /// wait for the next swapchain image (the vertical blank under FIFO). What runs in
    /// `RenderSystems::Cleanup` and `PostCleanup` is not counted: a frame pacer or an
    /// emulated vertical blank belongs there.
    pub render: f32,
    /// Seconds the GPU took for the whole frame (every pass, the app's own included),
    /// from timestamps written at the start and the end of the frame's command buffers,
    /// when the adapter has timestamp queries. It arrives a frame or two after the rest.
    pub gpu: Option<f32>,
    /// Seconds the render world waited in this frame rather than worked: for the next
    /// swapchain image, and in `RenderSystems::Cleanup`/`PostCleanup` (a frame pacer, an
    /// emulated vertical blank).
    pub waited: f32,
    /// Seconds from the end of the previous frame's rendering to the end of this one's:
    /// the frame time the user sees, waits included.
    pub interval: f32,
    /// Every renderer drew all it was asked to. False while pipelines still compile:
    /// such a frame is fast because nothing was drawn, and is neither learned from nor
    /// measured.
    pub complete: bool,
    /// A window was resized in this frame: its swapchain was rebuilt and the pixel costs
    /// changed, so its times are not a steady frame's.
    pub resized: bool,
    /// Seconds the main world idled before this frame's update by choice rather than
    /// waited for the render world: winit's reactive update modes, a pacer in the main
    /// world. Part of [`FrameSample::interval`], not of the work. NaN when unknown (the
    /// previous frame was not reported): such a frame is not usable.
    pub idle: f32,
}

/// Waits shorter than this are not a wait for the display: Bevy's own `Cleanup` and
/// `PostCleanup` systems, counted with the waits, take up to about a millisecond in a
/// debug build.
pub(crate) const WAIT_THRESHOLD: f32 = 2e-3;
/// Main-world idling shorter than this is the event loop's own overhead (measured at
/// 0.05–0.3 ms on lavapipe with winit), not an app idling by choice.
pub(crate) const IDLE_THRESHOLD: f32 = 1e-3;

/// Which part of a frame took longest, as the frames overlap in Bevy's pipelined
/// rendering.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Reflect, Serialize, Deserialize)]
pub enum FrameBound {
    /// Nothing measured yet.
    #[default]
    Unknown,
    /// The main world's update (the app's logic and the Sherwood stages).
    Logic,
    /// The render world's work on the CPU.
    RenderCpu,
    /// The GPU.
    Gpu,
}

impl FrameSample {
    /// Whether the times are usable: finite, positive, the frame complete and no window
    /// resized.
    pub fn is_usable(&self) -> bool {
        self.complete
            && !self.resized
            && [self.logic, self.render, self.interval]
                .iter()
                .all(|t| t.is_finite() && *t > 0.0)
            && self.waited.is_finite()
            && self.idle.is_finite()
            && self.gpu.is_none_or(|g| g.is_finite() && g >= 0.0)
    }

    /// The rendering side's time: the longer of the render world's CPU work and the GPU's.
    pub(crate) fn rendering(&self) -> f32 {
        self.render.max(self.gpu.unwrap_or(0.0))
    }

    /// The render world waited for the display or a pacer in this frame, or the main
    /// world idled before it: its interval is not its work.
    pub fn waited_for_display(&self) -> bool {
        self.waited > WAIT_THRESHOLD || self.idle > IDLE_THRESHOLD
    }

    /// The frame's work: its interval less the render world's waits and the main world's
    /// idling, and at least the longer of the logic and the rendering (when the main world
    /// binds, the render world's wait overlapped it).
    pub fn work_interval(&self) -> f32 {
        let waits = self.waited.max(0.0) + self.idle.max(0.0);
        (self.interval - waits).max(self.logic.max(self.rendering()))
    }

    /// Which part took longest.
    pub fn bound(&self) -> FrameBound {
        let gpu = self.gpu.unwrap_or(0.0);
        if self.logic >= self.render && self.logic >= gpu {
            FrameBound::Logic
        } else if gpu > self.render {
            FrameBound::Gpu
        } else {
            FrameBound::RenderCpu
        }
    }
}

/// Measured frames, for the cost model and anyone else who wants them (the lab's forest tool
/// records them). Producers `push` samples as they arrive; at the
/// start of each update ([`CostSystems::Measure`](super::CostSystems::Measure)) they
/// become [`FrameSamples::arrived`] for that update, in the order pushed.
///
/// The measurement [`CostPlugin`](super::CostPlugin) adds with Bevy's render app is one
/// producer; a test or a custom renderer can push its own. A sample whose GPU time comes
/// later is pushed with `push_awaiting_gpu` and held
/// (with every sample pushed after it) until `push_gpu` brings
/// its GPU time, or for at most `GPU_WAIT_UPDATES` updates.
///
/// A renderer that knows its own GPU time also `push_pass`es it:
/// the cost model learns from it which part of the rendering its primitives take, and
/// which part is fixed (the forest pass does, when Bevy's `RenderDiagnosticsPlugin` is
/// added and the adapter has timestamp queries).
#[derive(Resource, Debug, Default)]
pub struct FrameSamples {
    pending: VecDeque<PendingSample>,
    gpu_times: Vec<(u64, f32, u32)>,
    arrived: Vec<FrameSample>,
    pending_passes: Vec<f32>,
    arrived_passes: Vec<f32>,
}

/// How many updates a sample waits for its GPU time before it is delivered without.
pub(crate) const GPU_WAIT_UPDATES: u32 = 8;

#[derive(Debug)]
struct PendingSample {
    sample: FrameSample,
    awaits_gpu: bool,
    updates: u32,
}

impl FrameSamples {
    /// Queues a sample; it arrives at the start of the next update.
    pub(crate) fn push(&mut self, sample: FrameSample) {
        self.pending.push_back(PendingSample {
            sample,
            awaits_gpu: false,
            updates: 0,
        });
    }

    /// Queues a sample whose [`FrameSample::gpu`] time will come with
    /// [`push_gpu`](FrameSamples::push_gpu); it arrives once that has come (or after
    /// [`GPU_WAIT_UPDATES`] updates, without it).
    pub(crate) fn push_awaiting_gpu(&mut self, sample: FrameSample) {
        self.pending.push_back(PendingSample {
            sample,
            awaits_gpu: true,
            updates: 0,
        });
    }

    /// The GPU time, seconds, of frame `frame`'s whole frame. A time for a frame that no
    /// sample awaits is kept for [`GPU_WAIT_UPDATES`] updates, then dropped.
    pub(crate) fn push_gpu(&mut self, frame: u64, seconds: f32) {
        self.gpu_times.push((frame, seconds, 0));
    }

    /// The samples that arrived at the start of this update, oldest first (with pipelined
    /// rendering, usually last-but-one frame's).
    pub fn arrived(&self) -> &[FrameSample] {
        &self.arrived
    }

    /// Queues the GPU time, in seconds, of the pass that draws the budgeted primitives, for
    /// a recent frame (GPU timings arrive a few frames late, and are not tied to a frame
    /// number: the cost model pairs each with the latest frame it learned from).
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn push_pass(&mut self, seconds: f32) {
        self.pending_passes.push(seconds);
    }

    /// The pass times that arrived at the start of this update, oldest first.
    pub(crate) fn arrived_passes(&self) -> &[f32] {
        &self.arrived_passes
    }

    fn deliver(&mut self) {
        let pending = &mut self.pending;
        self.gpu_times.retain_mut(|(frame, seconds, updates)| {
            if let Some(p) = pending
                .iter_mut()
                .find(|p| p.awaits_gpu && p.sample.frame == *frame)
            {
                p.sample.gpu = Some(*seconds);
                p.awaits_gpu = false;
                return false;
            }
            *updates += 1;
            *updates <= GPU_WAIT_UPDATES
        });
        self.arrived.clear();
        // In the order pushed: the cost model learns frames oldest first.
        while let Some(head) = self.pending.front() {
            if head.awaits_gpu && head.updates < GPU_WAIT_UPDATES {
                break;
            }
            if let Some(p) = self.pending.pop_front() {
                self.arrived.push(p.sample);
            }
        }
        for p in &mut self.pending {
            p.updates += 1;
        }
        self.arrived_passes.clear();
        core::mem::swap(&mut self.arrived_passes, &mut self.pending_passes);
    }
}

/// The main world's frame counter and the clock of its update.
#[derive(Resource, Debug, Default)]
pub struct FrameClock {
    /// The current frame's number, counted from 1 at the first update.
    pub frame: u64,
    started: Option<Instant>,
    /// Logic time and start of recent frames whose rendering has not been reported yet.
    logic: VecDeque<(u64, f32, Instant)>,
    /// The render world runs beside the main world (Bevy's pipelined rendering): it is
    /// handed a frame at its extraction, and the main world goes on at once.
    pipelined: bool,
    /// When the main world was last free to start its next update: the previous
    /// frame's hand-over to the render world (pipelined) or the end of its rendering.
    released: Option<(u64, Instant)>,
}

impl FrameClock {
    /// Seconds since this frame's update started (`First`); 0 outside an update.
    pub(crate) fn elapsed(&self) -> f32 {
        self.started.map_or(0.0, |s| s.elapsed().as_secs_f32())
    }

    /// Tells the clock whether the render world runs beside the main world.
    pub(super) fn set_pipelined(&mut self, pipelined: bool) {
        self.pipelined = pipelined;
    }
}

/// How many recent frames' logic times wait for their rendering to be reported.
const PENDING_FRAMES: usize = 64;

/// Runs before `First`: starts the frame's clock.
#[derive(ScheduleLabel, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct FrameStart;

/// Runs after `Last`: stops it.
#[derive(ScheduleLabel, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct FrameEnd;

/// A frame as the render world reports it.
#[derive(Clone, Copy, Debug)]
struct RenderedFrame {
    frame: u64,
    render: f32,
    waited: f32,
    interval: f32,
    complete: bool,
    resized: bool,
    /// Its GPU time was recorded and will follow.
    timed_on_gpu: bool,
    /// When the render world started it and finished it.
    started: Instant,
    ended: Instant,
}

/// Rendered frames and GPU times, handed from the render world to the main world.
#[derive(Resource, Clone, Default)]
pub(super) struct RenderedFrames(Arc<Mutex<Reports>>);

impl RenderedFrames {
    /// Hands frame `frame`'s GPU time to the main world.
    #[cfg(feature = "render")]
    pub(super) fn report_gpu(&self, frame: u64, seconds: f32) {
        if let Ok(mut queue) = self.0.lock() {
            if queue.gpu.len() >= PENDING_FRAMES {
                queue.gpu.remove(0);
            }
            queue.gpu.push((frame, seconds));
        }
    }
}

#[derive(Default)]
struct Reports {
    frames: Vec<RenderedFrame>,
    gpu: Vec<(u64, f32)>,
}

/// Set in the render world by a renderer that was asked to draw something this frame and
/// could not (a pipeline still compiling), and whenever any render pipeline is still
/// compiling (for at most [`COMPILING_SECONDS`]): the frame's times are not a real
/// frame's. Cleared when the render world starts a frame.
#[derive(Resource, Debug, Default)]
#[cfg(feature = "render")]
pub(crate) struct DrawIncomplete(pub bool);

/// The render world's view of the clock.
#[cfg(feature = "render")]
#[derive(Resource, Debug, Default)]
pub(super) struct RenderClock {
    /// The main-world frame being rendered.
    pub(super) frame: u64,
    started: Option<Instant>,
    acquire_started: Option<Instant>,
    acquired: f32,
    work_ended: Option<Instant>,
    last_end: Option<Instant>,
    resized: bool,
}

pub(super) fn build(app: &mut App) {
    app.init_resource::<FrameSamples>()
        .init_resource::<FrameClock>()
        .init_schedule(FrameStart)
        .init_schedule(FrameEnd)
        .add_systems(FrameStart, start_frame)
        .add_systems(FrameEnd, end_frame);
    {
        let mut order = app.world_mut().resource_mut::<MainScheduleOrder>();
        order.insert_before(First, FrameStart);
        order.insert_after(Last, FrameEnd);
    }
    app.add_systems(
        PreUpdate,
        deliver_samples.in_set(super::CostSystems::Measure),
    );
    #[cfg(feature = "render")]
    build_render(app);
}

fn start_frame(mut clock: ResMut<FrameClock>) {
    clock.frame += 1;
    clock.started = Some(Instant::now());
}

fn end_frame(mut clock: ResMut<FrameClock>) {
    let Some(started) = clock.started.take() else {
        return;
    };
    let logic = started.elapsed().as_secs_f32();
    let frame = clock.frame;
    if clock.logic.len() >= PENDING_FRAMES {
        clock.logic.pop_front();
    }
    clock.logic.push_back((frame, logic, started));
}

fn deliver_samples(
    mut samples: ResMut<FrameSamples>,
    mut clock: ResMut<FrameClock>,
    rendered: Option<Res<RenderedFrames>>,
) {
    if let Some(rendered) = rendered {
        let reports = rendered
            .0
            .lock()
            .map(|mut queue| core::mem::take(&mut *queue))
            .unwrap_or_default();
        for r in reports.frames {
            // Logic records older than this frame have no rendering coming any more.
            while clock.logic.front().is_some_and(|(f, ..)| *f < r.frame) {
                clock.logic.pop_front();
            }
            let released = if clock.pipelined { r.started } else { r.ended };
            let previous = clock.released.replace((r.frame, released));
            if let Some(&(_, logic, started)) = clock.logic.front().filter(|(f, ..)| *f == r.frame)
            {
                clock.logic.pop_front();
                // The main world could have started this frame when the previous one
                // released it; any later start is idling (the event loop's own overhead
                // is below `IDLE_THRESHOLD`). Without the previous frame's report the
                // idling is unknown, and so is the frame's work: NaN, not usable.
                let idle = previous
                    .filter(|(f, _)| *f + 1 == r.frame)
                    .map_or(f32::NAN, |(_, at)| {
                        started.saturating_duration_since(at).as_secs_f32()
                    });
                let sample = FrameSample {
                    frame: r.frame,
                    logic,
                    render: r.render,
                    gpu: None,
                    waited: r.waited,
                    interval: r.interval,
                    complete: r.complete,
                    resized: r.resized,
                    idle,
                };
                if r.timed_on_gpu {
                    samples.push_awaiting_gpu(sample);
                } else {
                    samples.push(sample);
                }
            }
        }
        for (frame, seconds) in reports.gpu {
            samples.push_gpu(frame, seconds);
        }
    }
    samples.deliver();
}

#[cfg(feature = "render")]
fn build_render(app: &mut App) {
    use bevy::render::view::window::prepare_windows;
    use bevy::render::{ExtractSchedule, Render, RenderApp, RenderSystems};
    let mailbox = RenderedFrames::default();
    app.insert_resource(mailbox.clone());
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .insert_resource(mailbox)
        .init_resource::<RenderClock>()
        .init_resource::<DrawIncomplete>()
        .add_systems(ExtractSchedule, extract_frame_number)
        .add_systems(
            Render,
            (
                start_rendering.in_set(RenderSystems::ExtractCommands),
                // The swapchain image is acquired in `prepare_windows`; with FIFO that is
                // where the wait for the vertical blank is. Timed from the start of
                // `PrepareViews`, so a system that blocks there on purpose counts too.
                start_acquire
                    .after(RenderSystems::Specialize)
                    .before(RenderSystems::PrepareViews),
                end_acquire
                    .in_set(RenderSystems::PrepareViews)
                    .after(prepare_windows),
                note_compiling_pipelines
                    .in_set(RenderSystems::Render)
                    .after(bevy::render::renderer::render_system),
                end_work
                    .after(RenderSystems::Render)
                    .before(RenderSystems::Cleanup),
                end_rendering.in_set(RenderSystems::PostCleanup),
            ),
        );
    super::gpu_frame::build(render_app);
}

/// How long pipelines may keep compiling before their frames count as real again,
/// seconds: a shader that never loads keeps its pipeline queued for ever, and the model
/// must not stop learning for it.
#[cfg(feature = "render")]
pub(crate) const COMPILING_SECONDS: f32 = 10.0;

/// A frame rendered while some pipeline was still compiling is incomplete: what needs it
/// (a material's first mesh, say) was not drawn, and its time is not the scene's.
#[cfg(feature = "render")]
fn note_compiling_pipelines(
    cache: Res<bevy::render::render_resource::PipelineCache>,
    mut incomplete: ResMut<DrawIncomplete>,
    mut since: Local<Option<Instant>>,
) {
    use bevy::render::render_resource::CachedPipelineState;
    let compiling = cache.pipelines().any(|p| {
        matches!(
            p.state,
            CachedPipelineState::Queued | CachedPipelineState::Creating(_)
        )
    });
    if !compiling {
        *since = None;
        return;
    }
    let since = *since.get_or_insert_with(Instant::now);
    if since.elapsed().as_secs_f32() < COMPILING_SECONDS {
        incomplete.0 = true;
    }
}

#[cfg(feature = "render")]
fn extract_frame_number(
    mut clock: ResMut<RenderClock>,
    main: bevy::render::Extract<Res<FrameClock>>,
) {
    clock.frame = main.frame;
}

#[cfg(feature = "render")]
fn start_rendering(
    mut clock: ResMut<RenderClock>,
    mut incomplete: ResMut<DrawIncomplete>,
    windows: Option<Res<bevy::render::view::ExtractedWindows>>,
) {
    clock.started = Some(Instant::now());
    clock.acquired = 0.0;
    clock.work_ended = None;
    clock.resized = windows.is_some_and(|w| w.values().any(|w| w.size_changed));
    incomplete.0 = false;
}

#[cfg(feature = "render")]
fn start_acquire(mut clock: ResMut<RenderClock>) {
    clock.acquire_started = Some(Instant::now());
}

#[cfg(feature = "render")]
fn end_acquire(mut clock: ResMut<RenderClock>) {
    if let Some(started) = clock.acquire_started.take() {
        clock.acquired += started.elapsed().as_secs_f32();
    }
}

#[cfg(feature = "render")]
fn end_work(mut clock: ResMut<RenderClock>) {
    clock.work_ended = Some(Instant::now());
}

#[cfg(feature = "render")]
fn end_rendering(
    mut clock: ResMut<RenderClock>,
    incomplete: Res<DrawIncomplete>,
    timer: Option<Res<super::gpu_frame::GpuFrameTimer>>,
    mailbox: Res<RenderedFrames>,
) {
    let now = Instant::now();
    let Some(started) = clock.started.take() else {
        return;
    };
    let previous = clock.last_end.replace(now);
    let Some(previous) = previous else {
        return;
    };
    let work_ended = clock.work_ended.unwrap_or(now);
    let acquired = clock.acquired;
    let render = ((work_ended - started).as_secs_f32() - acquired).max(0.0);
    let waited = acquired + (now - work_ended).as_secs_f32();
    let timed_on_gpu = timer.is_some_and(|t| t.timed(clock.frame));
    if let Ok(mut queue) = mailbox.0.lock() {
        // Nobody reads while the main world is not updating (a paused app): keep the
        // queue bounded.
        if queue.frames.len() >= PENDING_FRAMES {
            queue.frames.remove(0);
        }
        queue.frames.push(RenderedFrame {
            frame: clock.frame,
            render,
            waited,
            interval: (now - previous).as_secs_f32(),
            complete: !incomplete.0,
            resized: clock.resized,
            timed_on_gpu,
            started,
            ended: now,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(frame: u64) -> FrameSample {
        FrameSample {
            frame,
            logic: 0.01,
            render: 0.02,
            interval: 0.021,
            complete: true,
            ..Default::default()
        }
    }

    fn frames(samples: &FrameSamples) -> Vec<(u64, Option<f32>)> {
        samples.arrived().iter().map(|s| (s.frame, s.gpu)).collect()
    }

    #[test]
    fn a_sample_waits_for_its_gpu_time_and_nothing_overtakes_it() {
        let mut samples = FrameSamples::default();
        samples.push_awaiting_gpu(sample(1));
        samples.deliver();
        assert!(samples.arrived().is_empty());
        // Frame 2 has no GPU time coming, but waits behind frame 1.
        samples.push(sample(2));
        samples.push_awaiting_gpu(sample(3));
        samples.deliver();
        assert!(samples.arrived().is_empty());
        // Frame 1's GPU time arrives two frames late: 1 and 2 arrive, 3 still waits.
        samples.push_gpu(1, 0.03);
        samples.deliver();
        assert_eq!(frames(&samples), [(1, Some(0.03)), (2, None)]);
        samples.push_gpu(3, 0.04);
        samples.deliver();
        assert_eq!(frames(&samples), [(3, Some(0.04))]);
        samples.deliver();
        assert!(samples.arrived().is_empty());
    }

    #[test]
    fn a_gpu_time_that_never_comes_delays_a_sample_a_bounded_number_of_updates() {
        let mut samples = FrameSamples::default();
        samples.push_awaiting_gpu(sample(7));
        let mut updates = 0;
        while samples.arrived().is_empty() {
            samples.deliver();
            updates += 1;
            assert!(updates <= GPU_WAIT_UPDATES + 1, "never delivered");
        }
        assert_eq!(frames(&samples), [(7, None)]);
        assert!(updates > GPU_WAIT_UPDATES / 2, "delivered after {updates}");
        // A GPU time for a frame nobody waits for is dropped, not kept forever.
        samples.push_gpu(99, 0.01);
        for _ in 0..=GPU_WAIT_UPDATES {
            samples.deliver();
        }
        assert!(samples.gpu_times.is_empty());
    }

    #[test]
    fn the_work_is_the_interval_less_the_waits_and_the_gpu_can_bind() {
        let waited = FrameSample {
            waited: 0.030,
            interval: 0.050,
            ..sample(1)
        };
        assert!(waited.waited_for_display());
        assert!((waited.work_interval() - 0.020).abs() < 1e-6);
        // When the main world binds, its wait overlapped the logic: at least the logic.
        let logic_bound = FrameSample {
            logic: 0.035,
            ..waited
        };
        assert!((logic_bound.work_interval() - 0.035).abs() < 1e-6);
        assert_eq!(logic_bound.bound(), FrameBound::Logic);
        let gpu_bound = FrameSample {
            gpu: Some(0.045),
            ..sample(2)
        };
        assert_eq!(gpu_bound.rendering(), 0.045);
        assert_eq!(gpu_bound.bound(), FrameBound::Gpu);
        assert_eq!(sample(3).bound(), FrameBound::RenderCpu);
        assert!(!sample(3).waited_for_display());
        assert!(
            !FrameSample {
                resized: true,
                ..sample(4)
            }
            .is_usable()
        );
        assert!(
            !FrameSample {
                gpu: Some(f32::NAN),
                ..sample(4)
            }
            .is_usable()
        );
    }
}
