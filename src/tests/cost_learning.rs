//! The cost model learning its machine in a headless app: a synthetic renderer with known
//! costs (per family, fixed, logic, overlap), noise and changes of speed answers each
//! frame's selection, and the real systems learn from what it "measured". No timing is
//! asserted: every time is synthetic.

use crate::testing as common;

use std::collections::VecDeque;

use crate::cost::{
    Calibration, CalibrationChoice, CostModel, CostSettings, FramePrediction, FrameSample,
    FrameSamples,
};
use crate::culling::CullView;
use crate::draw::TreeDrawList;
use crate::prelude::*;
use bevy::prelude::*;

/// What the synthetic machine really costs.
#[derive(Clone, Copy, Debug)]
struct Truth {
    /// The render world's fixed time, seconds.
    fixed: f32,
    /// Factors on the calibration: triangles, triangle pixels, lines, points.
    scales: [f32; 4],
    /// The logic after the Budget stage.
    logic_fixed: f32,
    logic_per_instance: f32,
    /// Handing a frame to the render world, seconds.
    sync: f32,
    /// The share of the shorter world's time the longer does not hide.
    serial: f32,
    /// Everything (rendering and logic) takes this much longer.
    speed: f32,
}

impl Truth {
    fn render(&self, p: &FramePrediction) -> f32 {
        let c = p.calibrated;
        let [t, px, l, pt] = self.scales;
        self.speed
            * (self.fixed + t * c.triangles + px * c.triangle_pixels + l * c.lines + pt * c.points)
    }

    fn logic(&self, p: &FramePrediction) -> f32 {
        self.speed * (self.logic_fixed + self.logic_per_instance * p.visible_instances as f32)
    }

    fn sample(&self, p: &FramePrediction, noise: f32) -> FrameSample {
        let render = self.render(p) * noise;
        // What had run when the budget was handed out was measured then; the rest is the
        // synthetic machine's.
        let logic = p.logic_so_far + self.logic(p) * noise;
        FrameSample {
            frame: p.frame,
            logic,
            render,
            interval: logic.max(render) + self.serial * logic.min(render) + self.sync,
            complete: true,
            ..Default::default()
        }
    }
}

/// The default calibration's machine, a little different per family.
const MACHINE: Truth = Truth {
    fixed: 0.008,
    scales: [1.6, 0.5, 2.2, 0.7],
    logic_fixed: 0.003,
    logic_per_instance: 2e-6,
    sync: 0.001,
    serial: 0.0,
    speed: 1.0,
};

/// A forest with a view, predicting with `calibration`.
fn app(calibration: Calibration) -> (App, f32) {
    let (mut app, size) = common::forest_of(300);
    {
        let world = app.world_mut();
        world.resource_mut::<CostSettings>().calibration = CalibrationChoice::Keep;
        // Still trees: swaying ones would change the selection with the real clock.
        world.resource_mut::<WindSettings>().enabled = false;
        world
            .resource_mut::<CostModel>()
            .set_calibration(calibration);
    }
    common::look_from(
        &mut app,
        Vec3::new(-0.1 * size, 20.0, -0.1 * size),
        Vec3::new(0.5 * size, 0.0, 0.5 * size),
    );
    common::until_visible(&mut app);
    (app, size)
}

/// Drives `app` for `frames` frames against `truth(frame index)`: each frame's selection
/// is "rendered" and its sample arrives two frames later, as with pipelined rendering.
/// `pose(k)` moves the view and sets the target. Returns per frame the prediction and
/// the sample.
struct Driver {
    pending: VecDeque<FrameSample>,
    noise: Box<dyn FnMut() -> f32>,
}

impl Driver {
    fn new(noise: f32) -> Self {
        let mut uniform = common::unit_noise();
        Self {
            pending: VecDeque::new(),
            noise: Box::new(move || 1.0 + noise * (2.0 * uniform() - 1.0)),
        }
    }

    fn frame(&mut self, app: &mut App, truth: &Truth) -> (FramePrediction, FrameSample) {
        let prediction = common::predicted_frame(app);
        let sample = truth.sample(&prediction, (self.noise)());
        self.pending.push_back(sample);
        if self.pending.len() > 2 {
            let arrived = self.pending.pop_front().unwrap();
            app.world_mut().resource_mut::<FrameSamples>().push(arrived);
        }
        (prediction, sample)
    }
}

/// Moves the view along the forest's diagonal and varies the target, so that the
/// selection's mix of families changes from frame to frame.
fn vary(app: &mut App, size: f32, k: u32) {
    let t = (k % 240) as f32 / 240.0;
    let eye = Vec3::new((-0.1 + 0.6 * t) * size, 20.0, (-0.1 + 0.3 * t) * size);
    // Now and then a glance along the edge, with far fewer trees in view.
    let at = if k % 5 == 4 {
        Vec3::new(0.6 * size, 0.0, -0.5 * size)
    } else {
        Vec3::new(0.6 * size, 0.0, 0.7 * size)
    };
    common::look_from(app, eye, at);
    let targets = [25.0, 60.0, 140.0, 40.0, 300.0, 90.0, 15.0];
    app.world_mut().resource_mut::<FrameBudget>().target_ms = targets[(k % 7) as usize];
}

fn relative_error(predicted: f32, measured: f32) -> f32 {
    (predicted - measured).abs() / measured
}

#[test]
fn each_family_s_cost_is_learned_within_five_percent() {
    let _measuring = common::measuring();
    let (mut app, size) = app(Calibration::default());
    let mut driver = Driver::new(0.02);
    // Each family's share of the true rendering time over the run.
    let mut shares = [0.0f32; 5];
    for k in 0..1200 {
        vary(&mut app, size, k);
        let (p, _) = driver.frame(&mut app, &MACHINE);
        let c = p.calibrated;
        let [t, px, l, pt] = MACHINE.scales;
        let parts = [
            MACHINE.fixed,
            t * c.triangles,
            px * c.triangle_pixels,
            l * c.lines,
            pt * c.points,
        ];
        let total: f32 = parts.iter().sum();
        for (share, part) in shares.iter_mut().zip(parts) {
            *share += part / total / 1200.0;
        }
    }
    let learned = app.world().resource::<CostModel>().learned();
    let got = [
        learned.render_fixed_ms / 1000.0,
        learned.scales.triangles,
        learned.scales.triangle_pixels,
        learned.scales.lines,
        learned.scales.points,
    ];
    let truth = [
        MACHINE.fixed,
        MACHINE.scales[0],
        MACHINE.scales[1],
        MACHINE.scales[2],
        MACHINE.scales[3],
    ];
    let names = ["fixed", "triangles", "triangle pixels", "lines", "points"];
    // A part that is a few percent of every frame cannot be told from the noise: it
    // only has to stay finite. The others are what the budget spends.
    let mut checked = 0;
    for j in 0..5 {
        assert!(got[j].is_finite() && got[j] >= 0.0, "{learned:?}");
        if shares[j] >= 0.05 {
            checked += 1;
            assert!(
                (got[j] - truth[j]).abs() <= 0.05 * truth[j],
                "{}: learned {} for {} (share {:.3}): {learned:?}",
                names[j],
                got[j],
                truth[j],
                shares[j]
            );
        }
    }
    assert!(checked >= 4, "the run excites too few families: {shares:?}");
    let logic_fixed = learned.logic_fixed_ms / 1000.0;
    assert!(
        (logic_fixed - MACHINE.logic_fixed).abs() <= 0.05 * MACHINE.logic_fixed,
        "logic {logic_fixed}: {learned:?}"
    );
    let per_instance = learned.logic_per_instance_us / 1e6;
    assert!(
        (per_instance - MACHINE.logic_per_instance).abs() <= 0.05 * MACHINE.logic_per_instance,
        "logic per instance {per_instance}: {learned:?}"
    );
    assert!(
        (learned.overlap.sync - MACHINE.sync).abs() <= 0.05 * MACHINE.sync,
        "{learned:?}"
    );
}

/// Frames until the prediction stays within `tolerance` of what is measured, and the
/// largest error after that.
fn settle(errors: &[(f32, f32)], tolerance: f32) -> (f32, f32) {
    let last_bad = errors
        .iter()
        .rposition(|&(_, e)| e > tolerance)
        .map_or(0, |i| i + 1);
    let time = errors[..last_bad].iter().map(|e| e.0).sum();
    let worst = errors[last_bad..].iter().map(|e| e.1).fold(0.0, f32::max);
    (time, worst)
}

/// (With still trees, so that the run is the same every time: the last frames to settle
/// are the glances along the forest's edge, few trees and a mix the rest does not have;
/// ×3 is within 5.2% after 1.7 s and within 5% after 2.5 s.)
#[test]
fn a_calibration_three_times_off_either_way_is_learned_within_three_seconds() {
    let _measuring = common::measuring();
    for factor in [3.0, 1.0 / 3.0] {
        let (mut app, size) = app(Calibration::default().scaled(factor));
        let truth = Truth {
            scales: [1.0; 4],
            ..MACHINE
        };
        let mut driver = Driver::new(0.0);
        let mut errors = Vec::new();
        for k in 0..200 {
            vary(&mut app, size, k);
            let (p, s) = driver.frame(&mut app, &truth);
            errors.push((s.interval, relative_error(p.frame_time, s.interval)));
        }
        let (time, worst) = settle(&errors, 0.05);
        assert!(
            time <= 3.0,
            "×{factor}: the prediction settled within 5% only after {time} s"
        );
        assert!(worst <= 0.05, "×{factor}: {worst}");
    }
}

#[test]
fn a_step_in_speed_is_followed_within_a_second_without_overshoot() {
    let _measuring = common::measuring();
    let (mut app, size) = app(Calibration::default());
    let mut driver = Driver::new(0.0);
    // Before the step: how far predictions stray as the mix of families changes.
    let mut band = 0.0f32;
    for k in 0..400 {
        vary(&mut app, size, k);
        let (p, s) = driver.frame(&mut app, &MACHINE);
        if k >= 340 {
            band = band.max((s.interval / p.frame_time - 1.0).abs());
        }
    }
    assert!(band < 0.05, "not settled before the step: {band}");
    // The machine slows down by ×1.4 (another process woke up), then speeds up again.
    for speed in [1.4, 1.0] {
        let truth = Truth { speed, ..MACHINE };
        let mut ratios = Vec::new();
        let mut errors = Vec::new();
        for k in 0..60 {
            vary(&mut app, size, 400 + k);
            let (p, s) = driver.frame(&mut app, &truth);
            ratios.push(s.interval / p.frame_time);
            errors.push((s.interval, relative_error(p.frame_time, s.interval)));
        }
        let (time, worst) = settle(&errors, 0.05);
        assert!(time <= 1.0, "×{speed}: settled within 5% after {time} s");
        assert!(worst <= 0.05, "{worst}");
        // No overshoot: measured / predicted approaches 1 from one side, beyond it by no
        // more than the stray before the step.
        let side = (ratios[0] - 1.0).signum();
        assert!(
            ratios.iter().all(|r| (r - 1.0) * side >= -band - 0.01),
            "×{speed}: overshoot beyond {band}: {ratios:?}"
        );
    }
}

#[test]
fn one_hitch_barely_moves_the_model() {
    let _measuring = common::measuring();
    let (mut app, size) = app(Calibration::default());
    let mut driver = Driver::new(0.0);
    for k in 0..300 {
        vary(&mut app, size, k);
        driver.frame(&mut app, &MACHINE);
    }
    let mut hitch = MACHINE;
    hitch.speed = 10.0;
    vary(&mut app, size, 300);
    driver.frame(&mut app, &hitch);
    let mut worst = 0.0f32;
    for k in 301..320 {
        vary(&mut app, size, k);
        let (p, s) = driver.frame(&mut app, &MACHINE);
        worst = worst.max(relative_error(p.frame_time, s.interval));
    }
    assert!(
        worst < 0.03,
        "one 10× frame moved the predictions by {worst}"
    );
}

#[test]
fn a_family_never_drawn_keeps_its_prior_and_constant_counts_stay_finite() {
    let _measuring = common::measuring();
    // Triangles only (TC), one view, one target: lines and points are never drawn and
    // the counts do not vary.
    let (mut app, _) = app(Calibration::default());
    {
        let mut budget = app.world_mut().resource_mut::<FrameBudget>();
        budget.mode = LodMode::Tc;
        budget.target_ms = 80.0;
    }
    let mut driver = Driver::new(0.0);
    let mut last = (FramePrediction::default(), FrameSample::default());
    for _ in 0..300 {
        last = driver.frame(&mut app, &MACHINE);
    }
    let learned = app.world().resource::<CostModel>().learned();
    let speed = learned.render_speed;
    assert_eq!(learned.scales.lines / speed, 1.0, "{learned:?}");
    assert_eq!(learned.scales.points / speed, 1.0, "{learned:?}");
    for v in [
        learned.scales.triangles,
        learned.scales.triangle_pixels,
        learned.render_fixed_ms,
        learned.logic_fixed_ms,
        learned.logic_per_instance_us,
    ] {
        assert!(v.is_finite() && v >= 0.0, "{learned:?}");
    }
    let (p, s) = last;
    assert!(
        relative_error(p.frame_time, s.interval) < 0.02,
        "{p:?} {s:?}"
    );
}

#[test]
fn incomplete_and_absurd_frames_are_not_learned() {
    let _measuring = common::measuring();
    let (mut app, size) = app(Calibration::default());
    let before = app.world().resource::<CostModel>().learned();
    for k in 0..20 {
        vary(&mut app, size, k);
        let p = common::predicted_frame(&mut app);
        let mut sample = MACHINE.sample(&p, 1.0);
        match k % 4 {
            0 => sample.complete = false,
            1 => sample.render = f32::NAN,
            2 => sample.interval = -1.0,
            _ => sample.logic = 0.0,
        }
        app.world_mut().resource_mut::<FrameSamples>().push(sample);
    }
    app.update();
    let after = app.world().resource::<CostModel>().learned();
    assert_eq!(after.frames_learned, 0);
    assert_eq!(before.scales, after.scales);
}

/// A window minimised (the view the budget follows goes away: nothing is drawn, the
/// render world's frames take next to nothing) and a stall (a 10 s frame, as under a
/// debugger): neither is learned from, and the model is where it was when they end.
#[test]
fn a_minimised_window_and_a_stall_are_not_learned() {
    let _measuring = common::measuring();
    let (mut app, size) = app(Calibration::default());
    let mut driver = Driver::new(0.02);
    for k in 0..200 {
        vary(&mut app, size, k);
        driver.frame(&mut app, &MACHINE);
    }
    // The two samples still in flight arrive, so that only the faults follow.
    for sample in driver.pending.drain(..) {
        app.world_mut().resource_mut::<FrameSamples>().push(sample);
    }
    app.update();
    let before = app.world().resource::<CostModel>().learned();
    let view = app
        .world_mut()
        .query_filtered::<Entity, With<LodView>>()
        .single(app.world())
        .unwrap();
    app.world_mut()
        .entity_mut(view)
        .remove::<(LodView, CullView)>();
    for _ in 0..10 {
        let p = common::predicted_frame(&mut app);
        assert_eq!(p.calibrated.total(), 0.0, "a frame without a view drew");
        let mut sample = MACHINE.sample(&p, 1.0);
        sample.render = 1e-4;
        sample.interval = 0.016;
        app.world_mut().resource_mut::<FrameSamples>().push(sample);
    }
    vary(&mut app, size, 0);
    for stall in [10.0, 3.0, 30.0] {
        let p = common::predicted_frame(&mut app);
        let mut sample = MACHINE.sample(&p, 1.0);
        sample.render = stall;
        sample.interval = stall;
        app.world_mut().resource_mut::<FrameSamples>().push(sample);
    }
    app.update();
    let after = app.world().resource::<CostModel>().learned();
    assert_eq!(after.frames_learned, before.frames_learned);
    assert_eq!(after.scales, before.scales);
    assert_eq!(after.render_fixed_ms, before.render_fixed_ms);
}

/// A machine whose GPU paces the frame: the render world's CPU takes a third of what the
/// GPU takes, and each frame's GPU time is reported two updates after the rest of its
/// measurement (as timestamps read back from frames in flight are).
#[test]
fn a_gpu_bound_frame_is_predicted_by_its_gpu_time_reported_two_frames_late() {
    let _measuring = common::measuring();
    // The largest error of the settled frames with GPU times, the smallest without.
    let mut final_error = [0.0f32; 2];
    for (run, report_gpu) in [true, false].into_iter().enumerate() {
        let (mut app, size) = app(Calibration::default());
        let mut pending: VecDeque<FrameSample> = VecDeque::new();
        let mut late_gpu: VecDeque<(u64, f32)> = VecDeque::new();
        let mut errors = Vec::new();
        for k in 0..400 {
            vary(&mut app, size, k);
            let p = common::predicted_frame(&mut app);
            let gpu = MACHINE.render(&p);
            let logic = p.logic_so_far + MACHINE.logic(&p);
            pending.push_back(FrameSample {
                frame: p.frame,
                logic,
                render: gpu / 3.0,
                interval: logic.max(gpu) + MACHINE.sync,
                complete: true,
                ..Default::default()
            });
            late_gpu.push_back((p.frame, gpu));
            let mut samples = app.world_mut().resource_mut::<FrameSamples>();
            if pending.len() > 2 {
                let sample = pending.pop_front().unwrap();
                if report_gpu {
                    samples.push_awaiting_gpu(sample);
                } else {
                    samples.push(sample);
                }
            }
            if report_gpu && late_gpu.len() > 4 {
                let (frame, seconds) = late_gpu.pop_front().unwrap();
                samples.push_gpu(frame, seconds);
            }
            errors.push(relative_error(p.render, gpu));
        }
        let settled = errors[300..].iter().copied();
        final_error[run] = if report_gpu {
            settled.fold(0.0, f32::max)
        } else {
            settled.fold(f32::INFINITY, f32::min)
        };
    }
    assert!(
        final_error[0] < 0.05,
        "with its GPU time the rendering is predicted within {}",
        final_error[0]
    );
    // Without it the model can only learn the render world's CPU (a third): the GPU time
    // is what makes the prediction follow the GPU.
    assert!(
        final_error[1] > 0.5,
        "without its GPU time the prediction came within {} of the GPU",
        final_error[1]
    );
}

/// With one still view the scene's mix does not change: a fixed part and per-primitive
/// costs that rise and fall together predict every frame equally well. The pass's own
/// time (the rendering minus the fixed part) tells them apart.
#[test]
fn a_still_view_learns_its_fixed_part_from_the_pass_time() {
    let _measuring = common::measuring();
    let calibration = Calibration {
        render_fixed: 4.0 * MACHINE.fixed,
        ..Calibration::default()
    };
    let (mut app, size) = app(calibration);
    common::look_from(
        &mut app,
        Vec3::new(-0.1 * size, 20.0, -0.1 * size),
        Vec3::new(0.6 * size, 0.0, 0.7 * size),
    );
    app.world_mut().resource_mut::<FrameBudget>().target_ms = 60.0;
    let mut uniform = common::unit_noise();
    let mut pending = VecDeque::new();
    for _ in 0..600 {
        let prediction = common::predicted_frame(&mut app);
        let noise = 1.0 + 0.02 * (2.0 * uniform() - 1.0);
        pending.push_back((prediction, MACHINE.sample(&prediction, noise), noise));
        if pending.len() > 2 {
            let (p, sample, noise) = pending.pop_front().unwrap();
            let pass = (MACHINE.render(&p) - MACHINE.speed * MACHINE.fixed) * noise;
            let mut samples = app.world_mut().resource_mut::<FrameSamples>();
            samples.push(sample);
            samples.push_pass(pass);
        }
    }
    let learned = app.world().resource::<CostModel>().learned();
    let fixed = learned.render_fixed_ms / 1000.0;
    assert!(
        (fixed - MACHINE.fixed).abs() <= 0.1 * MACHINE.fixed,
        "learned a fixed part of {fixed} s for {} s: {learned:?}",
        MACHINE.fixed
    );
}

/// The worlds' overlap is learned from the frames, not kept from the prior: a machine on
/// which a third of the shorter world's time shows (two cores shared by both worlds and
/// the driver) and handing over takes 4 ms, learned from the pipelined prior.
#[test]
fn the_overlap_of_the_two_worlds_is_learned_from_the_frames() {
    let _measuring = common::measuring();
    use crate::cost::FrameOverlap;
    let (mut app, size) = app(Calibration::default());
    app.world_mut()
        .resource_mut::<CostModel>()
        .set_prior_overlap(FrameOverlap::PIPELINED);
    let truth = Truth {
        sync: 0.004,
        serial: 0.33,
        ..MACHINE
    };
    let mut driver = Driver::new(0.02);
    let mut errors = Vec::new();
    for k in 0..1200 {
        vary(&mut app, size, k);
        let (p, s) = driver.frame(&mut app, &truth);
        errors.push(relative_error(p.frame_time, s.interval));
    }
    let learned = app.world().resource::<CostModel>().learned();
    assert!(
        (learned.overlap.serial - truth.serial).abs() <= 0.1,
        "{:?}",
        learned.overlap
    );
    assert!(
        (learned.overlap.sync - truth.sync).abs() <= 0.2 * truth.sync,
        "{:?}",
        learned.overlap
    );
    let late = &errors[errors.len() - 200..];
    let mean = late.iter().sum::<f32>() / late.len() as f32;
    assert!(
        mean <= 0.03,
        "frames predicted {mean} off on average once learned"
    );
}

/// Frames of `goal` at a 60 ms target on a machine whose frame times scatter
/// log-normally around the prediction by `sigma(k)` in frame `k`, a still scene kept by
/// `steady`: per frame, whether it was longer than 1.1 × target, what its work was aimed
/// at and how long it took (ms).
fn frames_under_noise(
    goal: FrameGoal,
    steady: SteadySelection,
    frames: u32,
    sigma: impl Fn(u32) -> f32 + 'static,
) -> Vec<(bool, f32, f32)> {
    let mut uniform = common::unit_noise();
    frames_scattered(goal, steady, frames, move |k| {
        sigma(k) * normal(&mut uniform)
    })
}

/// A standard normal number from two of `uniform`'s, by Box–Muller.
fn normal(uniform: &mut impl FnMut() -> f32) -> f32 {
    let (u, v) = (uniform().max(1e-7), uniform());
    (-2.0 * u.ln()).sqrt() * (core::f32::consts::TAU * v).cos()
}

/// [`frames_under_noise`] on a machine whose frame `k` takes `exp(scatter(k))` times
/// its prediction.
fn frames_scattered(
    goal: FrameGoal,
    steady: SteadySelection,
    frames: u32,
    scatter: impl FnMut(u32) -> f32 + 'static,
) -> Vec<(bool, f32, f32)> {
    frames_reacting(goal, steady, OverrunCut::OFF, frames, scatter)
}

/// [`frames_scattered`] with the aim cut by `overrun_cut`.
fn frames_reacting(
    goal: FrameGoal,
    steady: SteadySelection,
    overrun_cut: OverrunCut,
    frames: u32,
    mut scatter: impl FnMut(u32) -> f32 + 'static,
) -> Vec<(bool, f32, f32)> {
    let target = 0.060;
    let (mut app, size) = app(Calibration::default());
    common::look_from(
        &mut app,
        Vec3::new(-0.1 * size, 20.0, -0.1 * size),
        Vec3::new(0.6 * size, 0.0, 0.7 * size),
    );
    {
        let mut budget = app.world_mut().resource_mut::<FrameBudget>();
        budget.target_ms = target * 1000.0;
        budget.goal = goal;
        budget.steady = steady;
        budget.overrun_cut = overrun_cut;
    }
    let mut frame = 0;
    let noise = move || {
        frame += 1;
        scatter(frame - 1).exp()
    };
    let mut driver = Driver {
        pending: VecDeque::new(),
        noise: Box::new(noise),
    };
    (0..frames)
        .map(|_| {
            let (_, sample) = driver.frame(&mut app, &MACHINE);
            let aimed = app.world().resource::<LodDiagnostics>().work_target_ms;
            (
                sample.interval > 1.1 * target,
                aimed,
                sample.interval * 1000.0,
            )
        })
        .collect()
}

/// The share of `frames` that were over.
fn share_over(frames: &[(bool, f32, f32)]) -> f32 {
    frames.iter().filter(|(over, ..)| *over).count() as f32 / frames.len() as f32
}

/// The mean work target of `frames`, ms.
fn mean_aim(frames: &[(bool, f32, f32)]) -> f32 {
    frames.iter().map(|(_, aim, _)| aim).sum::<f32>() / frames.len() as f32
}

/// The mean frame time of `frames`, ms.
fn mean_frame(frames: &[(bool, f32, f32)]) -> f32 {
    frames.iter().map(|(.., ms)| ms).sum::<f32>() / frames.len() as f32
}

/// The default goal holds its tail: with frame times scattered log-normally around their
/// prediction, about its share of frames (5%) is longer than 1.1 × target once the
/// scatter is learned, on a quiet and on a noisy machine, when every frame is handed out
/// anew; the paper's mean goal, aimed at the target itself, leaves more over on the
/// noisy one. A still scene that keeps its selection (the default) keeps the promise
/// too, at most 7% over, and gives up at most its band below (8%) of the frame time for
/// it (a kept selection may sit below the aim, and then fewer frames are over).
#[test]
fn the_tail_goal_keeps_its_share_of_frames_over_the_slack() {
    for sigma in [0.03, 0.10] {
        let every_frame = frames_under_noise(
            FrameGoal::default(),
            SteadySelection::OFF,
            1600,
            move |_| sigma,
        );
        let share = share_over(&every_frame[400..]);
        assert!(
            (0.03..=0.07).contains(&share),
            "σ = {sigma}: {:.1}% of frames over 1.1 × target",
            share * 100.0
        );
        let kept = frames_under_noise(
            FrameGoal::default(),
            SteadySelection::default(),
            1600,
            move |_| sigma,
        );
        let (share, mean) = (share_over(&kept[400..]), mean_frame(&kept[400..]));
        let fresh = mean_frame(&every_frame[400..]);
        eprintln!(
            "σ = {sigma}, kept: {:.1}% over, {mean:.2} ms against {fresh:.2} ms",
            share * 100.0
        );
        // A still scene takes up time left unused only past its band below: it may give
        // up that much of the detail, no more.
        let below = SteadySelection::default().below;
        assert!(
            share <= 0.07 && mean >= (1.0 - below) * fresh,
            "σ = {sigma}, a still scene kept: {:.1}% of frames over 1.1 × target, \
             {mean:.2} ms a frame against {fresh:.2} ms handed out every frame",
            share * 100.0
        );
    }
    let mean = share_over(
        &frames_under_noise(FrameGoal::Mean, SteadySelection::OFF, 1600, |_| 0.10)[400..],
    );
    assert!(
        mean >= 0.10,
        "the mean goal: {:.1}% of frames over 1.1 × target",
        mean * 100.0
    );
}

/// Frame times with a longer tail than a log-normal one (3% noise, and one frame in 25
/// a hitch of an exponentially distributed 20% on average — the 99th percentile of
/// such frames is further out than their deviation says): the default goal, its
/// quantiles calibrated by the frames that passed them, keeps at most its 5% over 1.1 ×
/// target and its 1% over 1.25 × target (each within a point of sampling), and does
/// not give up more than it must (at least 3% over 1.1 × target, or the rare bound
/// binding at about its 1%).
#[test]
fn the_tail_goal_keeps_its_shares_where_frame_times_have_a_long_tail() {
    let mut uniform = common::unit_noise();
    let scatter = move |_| {
        let normal = normal(&mut uniform);
        let hitch = if uniform() < 0.04 {
            -0.2 * (1.0 - uniform()).max(1e-7).ln()
        } else {
            0.0
        };
        0.03 * normal + hitch
    };
    let frames = frames_scattered(FrameGoal::default(), SteadySelection::OFF, 3000, scatter);
    let settled = &frames[600..];
    let over = share_over(settled);
    let rare =
        settled.iter().filter(|(.., ms)| *ms > 1.25 * 60.0).count() as f32 / settled.len() as f32;
    eprintln!(
        "{:.1}% over 1.1 × target, {:.2}% over 1.25 × target, aimed at {:.1} ms",
        over * 100.0,
        rare * 100.0,
        mean_aim(settled)
    );
    assert!(
        over <= 0.06 && rare <= 0.016,
        "{:.1}% of frames over 1.1 × target, {:.2}% over 1.25 × target",
        over * 100.0,
        rare * 100.0
    );
    assert!(
        over >= 0.03 || rare >= 0.006,
        "{:.1}% over 1.1 × target and {:.2}% over 1.25 × target: detail given up for nothing",
        over * 100.0,
        rare * 100.0
    );
}

/// A regime switch: the machine's scatter jumps from 3% to 12% and falls back (every
/// frame handed out anew, as in a moving scene). In each settled stretch the tail goal
/// keeps its share over (5% ± 2 points); the work is aimed lower while the scatter is
/// high (over a third of the way there within a second — 17 frames of 60 ms — most of
/// it within three) and higher again once it falls (more slowly: half the way within
/// four seconds). Each stretch is counted over its last 1 800 frames: the goal aims
/// inside its share (at 4%), and over 900 frames the count alone scatters by ±0.65
/// points about it.
#[test]
fn the_tail_goal_follows_a_regime_switch_of_the_machine_s_scatter() {
    const STRETCH: usize = 2400;
    let sigma = |k: u32| {
        if (STRETCH as u32..2 * STRETCH as u32).contains(&k) {
            0.12
        } else {
            0.03
        }
    };
    let frames = frames_under_noise(
        FrameGoal::default(),
        SteadySelection::OFF,
        3 * STRETCH as u32,
        sigma,
    );
    let settle = STRETCH / 4;
    let (quiet, noisy, quiet_again) = (
        &frames[settle..STRETCH],
        &frames[STRETCH + settle..2 * STRETCH],
        &frames[2 * STRETCH + settle..],
    );
    for (name, stretch) in [
        ("quiet", quiet),
        ("noisy", noisy),
        ("quiet again", quiet_again),
    ] {
        let share = share_over(stretch);
        eprintln!(
            "{name}: {:.1}% over, aimed at {:.1} ms",
            share * 100.0,
            mean_aim(stretch)
        );
        assert!(
            (0.03..=0.07).contains(&share),
            "{name}: {:.1}% of frames over 1.1 × target",
            share * 100.0
        );
    }
    let (high, low) = (mean_aim(quiet), mean_aim(noisy));
    assert!(
        low < 0.9 * high,
        "aimed at {low:.1} ms when noisy, {high:.1} ms when quiet"
    );
    assert!(mean_aim(quiet_again) > 0.95 * high);
    // The scatter is learned over about two seconds of frames (`FRAME_SPREAD_SECONDS`).
    let moved = |switch: usize, frames_after: usize, from: f32, to: f32| {
        let window = &frames[switch + frames_after..switch + frames_after + 5];
        (mean_aim(window) - from) / (to - from)
    };
    let second = 17;
    for k in [1, 2, 3, 4] {
        eprintln!(
            "{k} s after: cut {:.0}%, restored {:.0}%",
            100.0 * moved(STRETCH, k * second, high, low),
            100.0 * moved(2 * STRETCH, k * second, low, high)
        );
    }
    // Cut quickly (long frames widen the scatter at once), restore at the scatter's pace.
    let (one, three) = (
        moved(STRETCH, second, high, low),
        moved(STRETCH, 3 * second, high, low),
    );
    assert!(
        one > 0.35 && three > 0.8,
        "after the scatter grew: {:.0}% of the way in a second, {:.0}% in three",
        one * 100.0,
        three * 100.0
    );
    let four = moved(2 * STRETCH, 4 * second, low, high);
    assert!(
        four > 0.5,
        "after the scatter fell: {:.0}% of the way in four seconds",
        four * 100.0
    );
}

/// A machine that turns 40% slower at once, at a still camera (the default steady
/// selection): the cost model learns the new speed within about a second, and until then
/// frames run over. Cutting the aim after 2 consecutive frames over ends the run sooner
/// (measured: 4 frames over 1.1 × target after the step against 7–8 without); once the
/// speed is learned the cut has faded and the aim is where it is without it (within 3%).
/// Fails when the cut never acts.
#[test]
fn cutting_after_two_frames_over_ends_a_slowdown_s_run_of_long_frames_sooner() {
    let step = 400;
    let run = |cut: OverrunCut| {
        let mut uniform = common::unit_noise();
        let scatter = move |k: u32| {
            let slower = if k >= step { 0.4f32.ln_1p() } else { 0.0 };
            slower + 0.02 * normal(&mut uniform)
        };
        frames_reacting(
            FrameGoal::default(),
            SteadySelection::default(),
            cut,
            700,
            scatter,
        )
    };
    let (plain, cut) = (run(OverrunCut::OFF), run(OverrunCut::AFTER_TWO));
    let after = |frames: &[(bool, f32, f32)]| {
        frames[step as usize..step as usize + 30]
            .iter()
            .filter(|(over, ..)| *over)
            .count()
    };
    let (over_plain, over_cut) = (after(&plain), after(&cut));
    let (aim_plain, aim_cut) = (mean_aim(&plain[600..]), mean_aim(&cut[600..]));
    eprintln!(
        "frames over after the step: {over_cut} cut, {over_plain} not; \
         aimed at {aim_cut:.1} against {aim_plain:.1} ms once learned"
    );
    assert!(
        over_cut < over_plain,
        "after the step: {over_cut} frames over with the cut, {over_plain} without"
    );
    assert!(
        (aim_cut - aim_plain).abs() <= 0.03 * aim_plain,
        "once the speed is learned: aimed at {aim_cut:.1} ms with the cut, {aim_plain:.1} without"
    );
}

/// Every instance's draw list, in instance order.
fn all_lists(app: &mut App) -> Vec<TreeDrawList> {
    let world = app.world_mut();
    let entities = world.resource::<ForestInstances>().entities.clone();
    entities
        .into_iter()
        .map(|e| world.get::<TreeDrawList>(e).cloned().unwrap_or_default())
        .collect()
}

/// At a still camera, frames measured with ±10% noise: how many of `frames` frames
/// changed some tree's draw list, with `steady` (after the learning has settled).
fn list_changes_at_a_still_camera(steady: SteadySelection, frames: u32) -> (u32, App, f32) {
    list_changes_on(&MACHINE, steady, frames, 150)
}

/// [`list_changes_at_a_still_camera`] on the machine `truth`, after `settling` frames.
fn list_changes_on(
    truth: &Truth,
    steady: SteadySelection,
    frames: u32,
    settling: u32,
) -> (u32, App, f32) {
    let (mut app, size) = app(Calibration::default());
    {
        let mut budget = app.world_mut().resource_mut::<FrameBudget>();
        budget.target_ms = 60.0;
        budget.steady = steady;
    }
    let mut driver = Driver::new(0.10);
    for _ in 0..settling {
        driver.frame(&mut app, truth);
    }
    let mut last = all_lists(&mut app);
    let mut changes = 0;
    for _ in 0..frames {
        driver.frame(&mut app, truth);
        let lists = all_lists(&mut app);
        changes += u32::from(lists != last);
        last = lists;
    }
    (changes, app, size)
}

/// The still-camera shimmer where the trees are a small part of the render world (an
/// app whose own rendering takes most of it: a 45 ms fixed part at a 60 ms target, the
/// trees' time about a tenth of the render world's). While the fixed part is learned
/// from noisy frames, what is learned of it moves the trees' rendering time by several
/// times as much as it moves the frame; the selection is kept all the same, as the band
/// is a share of the render world's time (measured: lists changed in 3 of 60 frames;
/// with the band a share of the trees' time, 14).
#[test]
fn a_still_camera_keeps_its_selection_when_the_trees_are_a_small_part_of_the_frame() {
    let _measuring = common::measuring();
    let frames = 60;
    let heavy_app = Truth {
        fixed: 0.045,
        ..MACHINE
    };
    // Measured from the 10th frame, while the fixed part is still being learned (the
    // forest example's warm-up), as a still camera after a cut is.
    let (steady, app, _) =
        list_changes_on(&heavy_app, SteadySelection::KEEP_WHILE_STILL, frames, 10);
    let d = app.world().resource::<LodDiagnostics>().clone();
    eprintln!(
        "lists changed in {steady} of {frames} frames; trees' time {:.2} of the render world's {:.2} ms",
        d.render_budget_ms, d.predicted_render_ms
    );
    assert!(
        d.render_budget_ms > 0.0 && d.render_budget_ms < 0.5 * d.predicted_render_ms,
        "the trees are not a small part of the render world: {d:?}"
    );
    assert!(
        steady <= frames / 10,
        "a still camera changed its lists in {steady} of {frames} frames"
    );
}

/// A hitch in the app's own update (one frame's logic before the Budget stage far past
/// the target) makes that frame late whatever is drawn: a still scene's trees keep what
/// they drew, where handing out only what the hitch left would drop every tree to its
/// floor for that frame and restore it the next (a flash over the whole forest).
#[test]
fn a_hitch_in_the_apps_logic_does_not_drop_the_forest_to_its_floors() {
    #[derive(Resource)]
    struct Hitch(std::time::Duration);
    let _measuring = common::measuring();
    let (_, mut app, _) = list_changes_at_a_still_camera(SteadySelection::KEEP_WHILE_STILL, 10);
    let before = all_lists(&mut app);
    // 150 ms of the app's own logic at a 60 ms target, once.
    app.insert_resource(Hitch(std::time::Duration::from_millis(150)));
    app.add_systems(First, |mut hitch: ResMut<Hitch>| {
        std::thread::sleep(core::mem::take(&mut hitch.0));
    });
    Driver::new(0.0).frame(&mut app, &MACHINE);
    let d = app.world().resource::<LodDiagnostics>().clone();
    assert!(d.logic_ms > 100.0, "the hitch was not seen: {d:?}");
    assert!(
        d.render_budget_ms > 0.0 && all_lists(&mut app) == before,
        "a hitch changed the forest: {d:?}"
    );
}

/// A still camera whose machine turns 15% slower: the kept selection leaves its band
/// and is handed out anew within a few frames, and the new selection fits; gradually
/// (the default), only the trees the price needs change, at most two thirds as many as
/// when every tree takes its fresh share (measured: 134 against 270; how many change all
/// at once depends on the frame the band is left). (A kept selection may sit up to its
/// band below the time, 8%, so a 10% slowdown may still fit it and rightly change
/// nothing: the tail goal's aim moved it there once.)
#[test]
fn a_still_camera_on_a_slower_machine_changes_only_the_trees_the_price_needs() {
    let _measuring = common::measuring();
    let changed_trees = |gradual: bool| {
        let steady = SteadySelection {
            gradual,
            ..SteadySelection::default()
        };
        let (_, mut app, _) = list_changes_at_a_still_camera(steady, 10);
        let before = all_lists(&mut app);
        let slower = Truth {
            speed: 1.15,
            ..MACHINE
        };
        let mut driver = Driver::new(0.0);
        let changed = (0..40).find_map(|_| {
            driver.frame(&mut app, &slower);
            let lists = all_lists(&mut app);
            (lists != before).then(|| lists.iter().zip(&before).filter(|(a, b)| a != b).count())
        });
        let d = app.world().resource::<LodDiagnostics>().clone();
        let changed = changed.expect("a slower machine gets a new selection");
        assert!(
            d.predicted_render_ms - d.render_fixed_ms <= 1.03 * d.render_budget_ms,
            "gradual {gradual}: {d:?}"
        );
        changed
    };
    let (sudden, gradual) = (changed_trees(false), changed_trees(true));
    eprintln!("trees changed: {gradual} gradually, {sudden} all at once");
    assert!(
        gradual > 0 && 3 * gradual <= 2 * sudden,
        "a slower machine changed {gradual} trees gradually, {sudden} all at once"
    );
}

/// The still-camera shimmer: with measurements that scatter by ±10%, the learned costs
/// move every frame; a still scene keeps its selection (at most 1 frame in 10 hands out
/// anew, when the kept selection's price leaves its band), where handing out every frame
/// changes the lists in most frames. A change of the target or of the view still
/// changes the selection at once.
#[test]
fn a_still_camera_keeps_its_selection_under_noisy_measurements() {
    let _measuring = common::measuring();
    let frames = 60;
    let (every_frame, ..) = list_changes_at_a_still_camera(SteadySelection::OFF, frames);
    let (steady, mut app, size) =
        list_changes_at_a_still_camera(SteadySelection::KEEP_WHILE_STILL, frames);
    eprintln!("lists changed in {steady} of {frames} frames kept, {every_frame} handed out anew");
    assert!(
        every_frame >= frames / 2,
        "without steadiness the noise changed only {every_frame} of {frames} frames"
    );
    assert!(
        steady <= frames / 10,
        "a still camera changed its lists in {steady} of {frames} frames"
    );
    let mut driver = Driver::new(0.10);
    let before = all_lists(&mut app);
    app.world_mut().resource_mut::<FrameBudget>().target_ms = 45.0;
    driver.frame(&mut app, &MACHINE);
    let kept = app.world().resource::<LodDiagnostics>().selection_kept;
    assert!(
        !kept && all_lists(&mut app) != before,
        "a new target is handed out at once"
    );
    let before = all_lists(&mut app);
    common::look_from(
        &mut app,
        Vec3::new(-0.1 * size, 21.0, -0.1 * size),
        Vec3::new(0.6 * size, 0.0, 0.7 * size),
    );
    driver.frame(&mut app, &MACHINE);
    let kept = app.world().resource::<LodDiagnostics>().selection_kept;
    assert!(
        !kept && all_lists(&mut app) != before,
        "a moved view is handed out at once"
    );
}
