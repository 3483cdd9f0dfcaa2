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

/// One measured frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameSample {
    /// The frame's number ([`FrameClock::frame`] while its main-world update ran).
    pub frame: u64,
    /// Seconds the main world's update took, `First` to `Last`: everything but the wait
    /// for the render world (app logic, culling, the Sherwood stages and their search,
    /// wind, UI layout).
    pub logic: f32,
    /// Seconds the render world's `Render` schedule took for this frame, with any wait
    /// for the GPU an app inserts there (a headless app waits for each frame's work).
    pub render: f32,
    /// Seconds from the end of the previous frame's rendering to the end of this one's:
    /// the frame time this frame is charged with.
    pub interval: f32,
    /// Every renderer drew all it was asked to. False while pipelines still compile:
    /// such a frame is fast because nothing was drawn, and is neither learned from nor
    /// measured.
    pub complete: bool,
}

impl FrameSample {
    /// Whether the times are usable: finite, positive, and the frame complete.
    pub fn is_usable(&self) -> bool {
        self.complete
            && [self.logic, self.render, self.interval]
                .iter()
                .all(|t| t.is_finite() && *t > 0.0)
    }
}

/// Measured frames, for the cost model and anyone else who wants them (the forest example
/// records them). Producers [`push`](FrameSamples::push) samples as they arrive; at the
/// start of each update ([`CostSystems::Measure`](super::CostSystems::Measure)) they
/// become [`FrameSamples::arrived`] for that update.
///
/// The measurement [`CostPlugin`](super::CostPlugin) adds with Bevy's render app is one
/// producer; a test or a custom renderer can push its own.
///
/// A renderer that knows its own GPU time also [`push_pass`](FrameSamples::push_pass)es it:
/// the cost model learns from it which part of the rendering its primitives take, and
/// which part is fixed (the forest pass does, when Bevy's `RenderDiagnosticsPlugin` is
/// added and the adapter has timestamp queries).
#[derive(Resource, Debug, Default)]
pub struct FrameSamples {
    pending: Vec<FrameSample>,
    arrived: Vec<FrameSample>,
    pending_passes: Vec<f32>,
    arrived_passes: Vec<f32>,
}

impl FrameSamples {
    /// Queues a sample; it arrives at the start of the next update.
    pub fn push(&mut self, sample: FrameSample) {
        self.pending.push(sample);
    }

    /// The samples that arrived at the start of this update, oldest first (with pipelined
    /// rendering, usually last-but-one frame's).
    pub fn arrived(&self) -> &[FrameSample] {
        &self.arrived
    }

    /// Queues the GPU time, in seconds, of the pass that draws the budgeted primitives, for
    /// a recent frame (GPU timings arrive a few frames late, and are not tied to a frame
    /// number: the cost model pairs each with the latest frame it learned from).
    pub fn push_pass(&mut self, seconds: f32) {
        self.pending_passes.push(seconds);
    }

    /// The pass times that arrived at the start of this update, oldest first.
    pub fn arrived_passes(&self) -> &[f32] {
        &self.arrived_passes
    }

    fn deliver(&mut self) {
        self.arrived.clear();
        core::mem::swap(&mut self.arrived, &mut self.pending);
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
    /// Logic time of recent frames whose rendering has not been reported yet.
    logic: VecDeque<(u64, f32)>,
}

/// How many recent frames' logic times wait for their rendering to be reported.
const PENDING_FRAMES: usize = 64;

/// Runs before `First`: starts the frame's clock.
#[derive(ScheduleLabel, Debug, Clone, PartialEq, Eq, Hash)]
pub struct FrameStart;

/// Runs after `Last`: stops it.
#[derive(ScheduleLabel, Debug, Clone, PartialEq, Eq, Hash)]
pub struct FrameEnd;

/// A frame as the render world reports it.
#[derive(Clone, Copy, Debug)]
struct RenderedFrame {
    frame: u64,
    render: f32,
    interval: f32,
    complete: bool,
}

/// Rendered frames, handed from the render world to the main world.
#[derive(Resource, Clone, Default)]
struct RenderedFrames(Arc<Mutex<Vec<RenderedFrame>>>);

/// Set in the render world by a renderer that was asked to draw something this frame and
/// could not (a pipeline still compiling): the frame's times are not a real frame's.
/// Cleared when the render world starts a frame.
#[derive(Resource, Debug, Default)]
pub struct DrawIncomplete(pub bool);

/// The render world's view of the clock.
#[cfg(feature = "render")]
#[derive(Resource, Debug, Default)]
struct RenderClock {
    frame: u64,
    started: Option<Instant>,
    last_end: Option<Instant>,
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
    clock.logic.push_back((frame, logic));
}

fn deliver_samples(
    mut samples: ResMut<FrameSamples>,
    mut clock: ResMut<FrameClock>,
    rendered: Option<Res<RenderedFrames>>,
) {
    if let Some(rendered) = rendered {
        let frames: Vec<RenderedFrame> = rendered
            .0
            .lock()
            .map(|mut queue| core::mem::take(&mut *queue))
            .unwrap_or_default();
        for r in frames {
            // Logic records older than this frame have no rendering coming any more.
            while clock.logic.front().is_some_and(|(f, _)| *f < r.frame) {
                clock.logic.pop_front();
            }
            if let Some(&(_, logic)) = clock.logic.front().filter(|(f, _)| *f == r.frame) {
                clock.logic.pop_front();
                samples.push(FrameSample {
                    frame: r.frame,
                    logic,
                    render: r.render,
                    interval: r.interval,
                    complete: r.complete,
                });
            }
        }
    }
    samples.deliver();
}

#[cfg(feature = "render")]
fn build_render(app: &mut App) {
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
                end_rendering.in_set(RenderSystems::PostCleanup),
            ),
        );
}

#[cfg(feature = "render")]
fn extract_frame_number(
    mut clock: ResMut<RenderClock>,
    main: bevy::render::Extract<Res<FrameClock>>,
) {
    clock.frame = main.frame;
}

#[cfg(feature = "render")]
fn start_rendering(mut clock: ResMut<RenderClock>, mut incomplete: ResMut<DrawIncomplete>) {
    clock.started = Some(Instant::now());
    incomplete.0 = false;
}

#[cfg(feature = "render")]
fn end_rendering(
    mut clock: ResMut<RenderClock>,
    incomplete: Res<DrawIncomplete>,
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
    if let Ok(mut queue) = mailbox.0.lock() {
        // Nobody reads while the main world is not updating (a paused app): keep the
        // queue bounded.
        if queue.len() >= PENDING_FRAMES {
            queue.remove(0);
        }
        queue.push(RenderedFrame {
            frame: clock.frame,
            render: (now - started).as_secs_f32(),
            interval: (now - previous).as_secs_f32(),
            complete: !incomplete.0,
        });
    }
}
