//! Springs driven by wind (thesis §5.3.1): `f = −k·x` plus the wind's force, accumulated,
//! integrated with semi-implicit Euler on a fixed time step, and the velocity damped by
//! `ℓ < 1` every step so every spring comes back to rest.

use bevy::math::Vec3;
use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;

/// Gusts: bursts of extra wind at random moments, rising and falling linearly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GustDesc {
    /// Mean gusts per second (0 for none).
    pub frequency: f32,
    /// Strength of a gust, drawn between these (force units).
    pub strength: (f32, f32),
    /// Duration of a gust's plateau, drawn between these (seconds).
    pub duration: (f32, f32),
    /// Seconds to rise to full strength.
    pub rise: f32,
    /// Seconds to fall back to nothing.
    pub fall: f32,
}

impl Default for GustDesc {
    fn default() -> Self {
        Self {
            frequency: 0.0,
            strength: (0.0, 0.0),
            duration: (0.5, 1.5),
            rise: 0.3,
            fall: 0.6,
        }
    }
}

/// The wind acting on one spring.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WindDesc {
    /// Direction the wind blows towards (normalised; zero for calm).
    pub direction: Vec3,
    /// Steady strength (force units).
    pub strength: f32,
    /// Gusts on top of it.
    pub gusts: GustDesc,
}

impl Default for WindDesc {
    fn default() -> Self {
        Self {
            direction: Vec3::X,
            strength: 0.0,
            gusts: GustDesc::default(),
        }
    }
}

/// One spring's parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringDesc {
    /// Stiffness `k`.
    pub stiffness: f32,
    /// Mass `M`.
    pub mass: f32,
    /// Velocity kept per step, `ℓ` in (0, 1]: 1 never loses energy.
    pub damping: f32,
    /// The wind on it.
    pub wind: WindDesc,
    /// Seed of its gusts.
    pub seed: u64,
}

impl Default for SpringDesc {
    fn default() -> Self {
        Self {
            stiffness: 20.0,
            mass: 1.0,
            damping: 0.995,
            wind: WindDesc::default(),
            seed: 0,
        }
    }
}

/// A spring in motion.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Spring {
    desc: SpringDesc,
    /// Displacement from rest.
    pub displacement: Vec3,
    /// Velocity.
    pub velocity: Vec3,
    time: f32,
    gust_start: f32,
    gust_strength: f32,
    gust_length: f32,
    rng: SplitMix64,
}

impl Spring {
    /// A spring at rest.
    pub(crate) fn new(desc: SpringDesc) -> Self {
        let rng = SplitMix64::new(desc.seed ^ 0x0057_1DE0);
        let mut spring = Self {
            desc,
            displacement: Vec3::ZERO,
            velocity: Vec3::ZERO,
            time: 0.0,
            gust_start: f32::INFINITY,
            gust_strength: 0.0,
            gust_length: 0.0,
            rng,
        };
        spring.schedule_gust(0.0);
        spring
    }

    fn schedule_gust(&mut self, after: f32) {
        let g = &self.desc.wind.gusts;
        if !(g.frequency > 0.0 && g.frequency.is_finite()) {
            self.gust_start = f32::INFINITY;
            return;
        }
        // Exponential waiting time: gusts arrive as a Poisson process.
        let wait = -(1.0 - self.rng.unit()).max(1e-6).ln() / g.frequency;
        self.gust_start = after + wait;
        let lerp = |(a, b): (f32, f32), t: f32| a + (b - a) * t;
        self.gust_strength = lerp(g.strength, self.rng.unit());
        self.gust_length = lerp(g.duration, self.rng.unit()).max(0.0);
    }

    /// The wind's force at the spring's current time.
    pub(crate) fn wind_force(&self) -> Vec3 {
        let w = &self.desc.wind;
        let g = &w.gusts;
        let t = self.time - self.gust_start;
        let envelope = if t < 0.0 {
            0.0
        } else if t < g.rise {
            t / g.rise.max(1e-6)
        } else if t < g.rise + self.gust_length {
            1.0
        } else {
            (1.0 - (t - g.rise - self.gust_length) / g.fall.max(1e-6)).max(0.0)
        };
        w.direction.normalize_or_zero() * (w.strength + envelope * self.gust_strength)
    }

    /// One semi-implicit Euler step of `dt` seconds.
    pub(crate) fn step(&mut self, dt: f32) {
        let d = &self.desc;
        let force = -d.stiffness * self.displacement + self.wind_force();
        let mass = if d.mass > 0.0 { d.mass } else { 1.0 };
        self.velocity += force / mass * dt;
        self.displacement += self.velocity * dt;
        self.velocity *= d.damping.clamp(0.0, 1.0);
        self.time += dt;
        let g = &self.desc.wind.gusts;
        if self.time > self.gust_start + g.rise + self.gust_length + g.fall {
            self.schedule_gust(self.time);
        }
        if !self.displacement.is_finite() || !self.velocity.is_finite() {
            // An unstable configuration (time step too large for the stiffness): reset
            // rather than spread NaN into every tree.
            self.displacement = Vec3::ZERO;
            self.velocity = Vec3::ZERO;
        }
    }
}

/// Runs springs on a fixed time step, independent of the frame rate.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FixedStepper {
    /// The step, seconds.
    pub step: f32,
    accumulated: f32,
}

impl FixedStepper {
    /// A stepper of `step` seconds (at least 0.1 ms).
    pub(crate) fn new(step: f32) -> Self {
        Self {
            step: if step.is_finite() {
                step.max(1e-4)
            } else {
                1.0 / 120.0
            },
            accumulated: 0.0,
        }
    }

    /// Advances `springs` by `elapsed` seconds of frame time, in whole steps (at most a
    /// quarter of a second per call, so a stalled frame does not freeze the app).
    pub(crate) fn advance(&mut self, springs: &mut [Spring], elapsed: f32) -> u32 {
        if !(elapsed.is_finite() && elapsed > 0.0) {
            return 0;
        }
        self.accumulated = (self.accumulated + elapsed).min(0.25);
        let mut steps = 0;
        while self.accumulated >= self.step {
            for spring in springs.iter_mut() {
                spring.step(self.step);
            }
            self.accumulated -= self.step;
            steps += 1;
        }
        steps
    }

    /// Advances `springs` by the whole steps in `elapsed` seconds (at most
    /// [`CATCH_UP_SECONDS`]): for springs that start after the clock did, so that they
    /// stand where they would had they run from the start. The fraction of a step left
    /// over is dropped, as a stepper that ran all along would carry it.
    pub(crate) fn catch_up(&mut self, springs: &mut [Spring], elapsed: f32) -> u32 {
        if !(elapsed.is_finite() && elapsed > 0.0) {
            return 0;
        }
        let steps = (elapsed.min(CATCH_UP_SECONDS) / self.step).round() as u32;
        for _ in 0..steps {
            for spring in springs.iter_mut() {
                spring.step(self.step);
            }
        }
        steps
    }
}

/// The most a spring set that loads late is advanced to catch up with the clock,
/// seconds: well past its springs' memory (a damping of 0.995 per 1/120 s step forgets
/// in about 2 s), so a later one stands where it would have anyway, in a steady gusty
/// state.
pub(crate) const CATCH_UP_SECONDS: f32 = 10.0;

#[cfg(test)]
mod tests {
    use super::*;

    fn calm(stiffness: f32, mass: f32, damping: f32) -> Spring {
        Spring::new(SpringDesc {
            stiffness,
            mass,
            damping,
            ..Default::default()
        })
    }

    #[test]
    fn undamped_spring_oscillates_with_the_textbook_period() {
        for (k, m) in [(20.0_f32, 1.0_f32), (5.0, 2.0), (80.0, 0.5)] {
            let period = core::f32::consts::TAU * (m / k).sqrt();
            let dt = period / 2000.0;
            let mut s = calm(k, m, 1.0);
            s.displacement = Vec3::X;
            // Time between the first and the fifth upward zero crossing = 4 periods.
            let mut crossings = Vec::new();
            let mut t = 0.0;
            let mut last = s.displacement.x;
            while crossings.len() < 5 {
                s.step(dt);
                t += dt;
                if last < 0.0 && s.displacement.x >= 0.0 {
                    crossings.push(t);
                }
                last = s.displacement.x;
            }
            let measured = (crossings[4] - crossings[0]) / 4.0;
            assert!(
                (measured - period).abs() / period < 0.01,
                "k {k} m {m}: {measured} vs {period}"
            );
        }
    }

    #[test]
    fn damped_spring_returns_to_rest() {
        let mut s = calm(20.0, 1.0, 0.99);
        s.displacement = Vec3::new(1.0, 0.0, 0.5);
        let mut peak = 0.0_f32;
        for i in 0..5000 {
            s.step(1.0 / 120.0);
            if i > 4000 {
                peak = peak.max(s.displacement.length());
            }
        }
        assert!(peak < 1e-3, "{peak}");
    }

    #[test]
    fn steady_wind_settles_at_force_over_stiffness() {
        let mut s = Spring::new(SpringDesc {
            stiffness: 10.0,
            damping: 0.98,
            wind: WindDesc {
                direction: Vec3::Z,
                strength: 2.0,
                ..Default::default()
            },
            ..Default::default()
        });
        for _ in 0..5000 {
            s.step(1.0 / 120.0);
        }
        assert!(
            (s.displacement - Vec3::new(0.0, 0.0, 0.2)).length() < 1e-3,
            "{}",
            s.displacement
        );
    }

    #[test]
    fn gusts_come_and_go() {
        let mut s = Spring::new(SpringDesc {
            wind: WindDesc {
                direction: Vec3::X,
                strength: 0.0,
                gusts: GustDesc {
                    frequency: 0.5,
                    strength: (3.0, 5.0),
                    ..Default::default()
                },
            },
            seed: 9,
            ..Default::default()
        });
        let (mut calm_steps, mut gusty_steps) = (0, 0);
        for _ in 0..120 * 60 {
            s.step(1.0 / 120.0);
            if s.wind_force().length() > 1.0 {
                gusty_steps += 1;
            } else {
                calm_steps += 1;
            }
        }
        assert!(
            gusty_steps > 0 && calm_steps > 0,
            "{gusty_steps} {calm_steps}"
        );
        assert!(s.wind_force().length() <= 5.0 + 1e-4);
    }

    #[test]
    fn fixed_steps_do_not_depend_on_the_frame_rate() {
        let mut fast = vec![calm(20.0, 1.0, 0.995)];
        let mut slow = fast.clone();
        fast[0].displacement = Vec3::X;
        slow[0].displacement = Vec3::X;
        let (mut a, mut b) = (
            FixedStepper::new(1.0 / 120.0),
            FixedStepper::new(1.0 / 120.0),
        );
        for _ in 0..240 {
            a.advance(&mut fast, 1.0 / 240.0);
        }
        for _ in 0..30 {
            b.advance(&mut slow, 1.0 / 30.0);
        }
        assert!((fast[0].displacement - slow[0].displacement).length() < 1e-5);
        assert_eq!(a.advance(&mut fast, f32::NAN), 0);
    }

    #[test]
    fn springs_that_start_late_catch_up_with_the_ones_that_ran_all_along() {
        let gusty = || {
            vec![Spring::new(SpringDesc {
                seed: 4,
                ..Default::default()
            })]
        };
        let frame = 1.0 / 60.0;
        let mut all_along = gusty();
        let mut clock = FixedStepper::new(1.0 / 120.0);
        for _ in 0..200 {
            clock.advance(&mut all_along, frame);
        }
        for late in [1_u32, 3, 17] {
            let mut springs = gusty();
            let mut stepper = FixedStepper::new(1.0 / 120.0);
            stepper.catch_up(&mut springs, late as f32 * frame);
            for _ in late..200 {
                stepper.advance(&mut springs, frame);
            }
            assert_eq!(springs, all_along, "started {late} frames late");
        }
        // Long after the start: only the last CATCH_UP_SECONDS are simulated.
        let mut springs = gusty();
        let steps = FixedStepper::new(0.01).catch_up(&mut springs, 1.0e6);
        assert_eq!(steps, (CATCH_UP_SECONDS / 0.01).round() as u32);
    }

    #[test]
    fn an_unstable_spring_resets_instead_of_spreading_nan() {
        let mut s = calm(1e30, 1e-30, 1.0);
        s.displacement = Vec3::X;
        for _ in 0..100 {
            s.step(0.1);
        }
        assert!(s.displacement.is_finite() && s.velocity.is_finite());
    }
}
