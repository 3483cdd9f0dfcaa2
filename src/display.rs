//! What the display does with a finished frame: whether it waits for the vertical blank
//! (vsync), and how long a refresh period is. The Budget stage aims each frame's work at
//! the vertical blank its target falls on;
//! what is *measured* of a frame never depends on it (the cost model always learns the
//! work, not the wait).
//!
//! By default ([`VsyncMode::FromWindow`]) the budget believes what the frames show: frames
//! are paced when most of them wait for the display (or for a pacer), at the period their
//! intervals follow (`MeasuredPacing`). [`DisplayTiming`]
//! says what the primary window claims — Bevy's `PresentMode::AutoVsync` (the default),
//! `Fifo` and `FifoRelaxed` wait, the others do not; the period is the refresh rate of the
//! window's monitor (or the primary monitor's) — and the measured period is snapped to the
//! monitor's grid when it fits. A claim is not enough: under Xvfb a window presenting with
//! FIFO is not held to anything. [`VsyncSettings::mode`] overrides the measurement.
//!
//! [`EmulatedVsyncPlugin`] makes a display without a vertical blank (Xvfb, a headless
//! app) behave like one, for measuring what a player with vsync would see.

use bevy::prelude::*;

pub use crate::budget::deadline::{allowed_periods, periods_taken};

/// Whether frames are paced by a vertical blank, and how many may miss it.
/// Changes take effect on the next frame.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Resource, Default)]
pub struct VsyncSettings {
    /// Where the display's pacing comes from. Default: [`VsyncMode::FromWindow`].
    pub mode: VsyncMode,
    /// Under vsync, the share of frames the budget lets miss their vertical blank: the
    /// work is aimed below the deadline by the measured scatter of frame times at this
    /// share. Smaller costs detail, larger costs whole periods. Default: `0.01`.
    pub missed_vblank_share: f32,
}

impl Default for VsyncSettings {
    fn default() -> Self {
        Self {
            mode: VsyncMode::FromWindow,
            missed_vblank_share: 0.01,
        }
    }
}

/// Where the display's pacing comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Reflect)]
pub enum VsyncMode {
    /// As the frames show it (`MeasuredPacing`): paced
    /// when most recent frames waited for the display or a pacer, at the period their
    /// intervals follow, snapped to the monitor's when it fits.
    #[default]
    FromWindow,
    /// Frames never wait for a vertical blank.
    Off,
    /// Frames wait for a vertical blank `refresh_hz` times a second, whatever the window
    /// says (a monitor that misreports its rate, an emulated vsync).
    On {
        /// Refresh rate, Hz.
        refresh_hz: f32,
    },
}

/// What the primary window says of its display (or [`VsyncSettings::mode`] when it is
/// `On` or `Off`). Kept by [`SherwoodCorePlugin`](crate::SherwoodCorePlugin) in `First`.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Reflect)]
#[reflect(Resource, Default)]
pub struct DisplayTiming {
    /// Frames are presented with a mode that waits for the vertical blank.
    pub vsync: bool,
    /// The monitor's refresh period, seconds (0 when unknown).
    pub period: f32,
}

impl DisplayTiming {
    /// The monitor's refresh period, when known.
    pub fn refresh_period(&self) -> Option<f32> {
        (self.period > 0.0 && self.period.is_finite()).then_some(self.period)
    }
}

/// A refresh rate as a period; rates that are not positive and finite give none.
fn period_of(hz: f32) -> Option<f32> {
    (hz > 0.0 && hz.is_finite()).then(|| 1.0 / hz)
}

pub(crate) fn build(app: &mut App) {
    app.register_type::<VsyncSettings>()
        .register_type::<DisplayTiming>()
        .init_resource::<VsyncSettings>()
        .init_resource::<DisplayTiming>()
        .add_systems(First, update_display_timing);
}

#[cfg(feature = "render")]
fn update_display_timing(
    settings: Res<VsyncSettings>,
    mut timing: ResMut<DisplayTiming>,
    windows: Query<(&Window, Option<&bevy::window::OnMonitor>), With<bevy::window::PrimaryWindow>>,
    monitors: Query<&bevy::window::Monitor>,
    primary_monitor: Query<&bevy::window::Monitor, With<bevy::window::PrimaryMonitor>>,
) {
    use bevy::window::PresentMode;
    let window = || {
        let Some((window, on)) = windows.iter().next() else {
            return DisplayTiming::default();
        };
        let rate = |m: &bevy::window::Monitor| m.refresh_rate_millihertz.map(|r| r as f32 / 1000.0);
        let hz = on
            .and_then(|on| monitors.get(on.0).ok())
            .and_then(rate)
            .or_else(|| primary_monitor.iter().next().and_then(rate));
        DisplayTiming {
            vsync: matches!(
                window.present_mode,
                PresentMode::AutoVsync | PresentMode::Fifo | PresentMode::FifoRelaxed
            ),
            period: hz.and_then(period_of).unwrap_or(0.0),
        }
    };
    timing.set_if_neq(match settings.mode {
        VsyncMode::Off => DisplayTiming::default(),
        VsyncMode::On { refresh_hz } => DisplayTiming {
            vsync: period_of(refresh_hz).is_some(),
            period: period_of(refresh_hz).unwrap_or(0.0),
        },
        VsyncMode::FromWindow => window(),
    });
}

#[cfg(not(feature = "render"))]
fn update_display_timing(settings: Res<VsyncSettings>, mut timing: ResMut<DisplayTiming>) {
    let period = match settings.mode {
        VsyncMode::On { refresh_hz } => period_of(refresh_hz),
        VsyncMode::Off | VsyncMode::FromWindow => None,
    };
    timing.set_if_neq(DisplayTiming {
        vsync: period.is_some(),
        period: period.unwrap_or(0.0),
    });
}

/// Makes a display without a vertical blank behave like one that has: after each frame's
/// work the render world waits until the next multiple of `1 / refresh_hz` seconds, as
/// acquiring the next swapchain image does under FIFO presentation. It also sets
/// [`VsyncSettings::mode`] to that rate, as a real display reports its own.
///
/// For measuring what a player with vsync would see where the display has none: Xvfb
/// (where `PresentMode::Fifo` does not throttle) or a headless app. The wait runs in
/// `RenderSystems::Cleanup`, after the frame is submitted and presented, where any frame
/// pacer belongs; the measurement does not know it is there.
#[cfg(feature = "render")]
#[derive(Clone, Copy, Debug)]
pub struct EmulatedVsyncPlugin {
    /// The emulated refresh rate, Hz.
    pub refresh_hz: f32,
}

#[cfg(feature = "render")]
#[derive(Resource, Clone, Copy)]
struct EmulatedPeriod(std::time::Duration);

#[cfg(feature = "render")]
impl Plugin for EmulatedVsyncPlugin {
    fn build(&self, app: &mut App) {
        use bevy::render::{Render, RenderApp, RenderSystems};
        let Some(period) = period_of(self.refresh_hz) else {
            error!(
                "EmulatedVsyncPlugin: refresh rate {} Hz is not a positive number; no vsync is emulated",
                self.refresh_hz
            );
            return;
        };
        let settings = app
            .world()
            .get_resource::<VsyncSettings>()
            .copied()
            .unwrap_or_default();
        app.insert_resource(VsyncSettings {
            mode: VsyncMode::On {
                refresh_hz: self.refresh_hz,
            },
            ..settings
        });
        let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
            warn!("EmulatedVsyncPlugin: no render app; no vsync is emulated");
            return;
        };
        render_app
            .insert_resource(EmulatedPeriod(std::time::Duration::from_secs_f32(period)))
            .add_systems(Render, wait_for_vblank.in_set(RenderSystems::Cleanup));
    }
}

/// Blocks until the next vertical blank of the emulated display.
#[cfg(feature = "render")]
fn wait_for_vblank(period: Res<EmulatedPeriod>, mut epoch: Local<Option<std::time::Instant>>) {
    use std::time::Instant;
    let now = Instant::now();
    let epoch = *epoch.get_or_insert(now);
    let period = period.0.as_secs_f64();
    let blanks = ((now - epoch).as_secs_f64() / period).floor() + 1.0;
    let next = epoch + std::time::Duration::from_secs_f64(blanks * period);
    // Sleep most of the way, spin the rest: a sleep can overshoot by a fraction of a
    // millisecond, a vertical blank does not.
    let spin = std::time::Duration::from_micros(1500);
    if let Some(sleep) = next.checked_duration_since(Instant::now() + spin) {
        std::thread::sleep(sleep);
    }
    while Instant::now() < next {
        std::hint::spin_loop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn timing_after(settings: VsyncSettings) -> DisplayTiming {
        let mut app = App::new();
        app.insert_resource(settings);
        build(&mut app);
        app.update();
        *app.world().resource::<DisplayTiming>()
    }

    #[test]
    fn the_settings_decide_the_timing() {
        let on = timing_after(VsyncSettings {
            mode: VsyncMode::On { refresh_hz: 20.0 },
            ..default()
        });
        assert!(on.vsync);
        assert!((on.period - 0.05).abs() < 1e-6);
        assert_eq!(on.refresh_period(), Some(on.period));
        let off = timing_after(VsyncSettings {
            mode: VsyncMode::Off,
            ..default()
        });
        assert!(!off.vsync);
        // No window: no vsync, no period.
        assert_eq!(
            timing_after(VsyncSettings::default()),
            DisplayTiming::default()
        );
        // A rate that is no rate: no vsync rather than a NaN period.
        let bad = timing_after(VsyncSettings {
            mode: VsyncMode::On { refresh_hz: 0.0 },
            ..default()
        });
        assert!(!bad.vsync);
        assert_eq!(bad.refresh_period(), None);
    }
}
