//! Spring sets as assets (`*.wind.ron`): the springs a group of trees shares, the rules
//! that associate their rings with the springs, and the motion level of detail.

use crate::ron_file::invalid;
use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::prelude::*;
use serde::{Deserialize, Serialize};

use super::motion::AssociationRule;
use super::spring::SpringDesc;

/// A spring set, as stored in `*.wind.ron`.
#[derive(Asset, TypePath, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpringSet {
    /// Fixed simulation step, seconds.
    pub time_step: f32,
    /// An instance whose farthest-moving ring would move less than this many pixels on
    /// screen (its largest spring displacement × its rig's `reach`,
    /// projected at its distance) is not moved at all (motion level of detail); also the
    /// per-ring threshold below which movement accumulates along a path instead of being
    /// applied.
    pub pixel_threshold: f32,
    /// The springs; several with slightly different parameters give variety.
    pub springs: Vec<SpringDesc>,
    /// Which rings follow which spring (first match wins).
    pub rules: Vec<AssociationRule>,
}

impl Default for SpringSet {
    fn default() -> Self {
        Self {
            time_step: 1.0 / 120.0,
            pixel_threshold: 0.5,
            springs: vec![SpringDesc::default()],
            rules: vec![AssociationRule::default()],
        }
    }
}

/// Why a spring set was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SpringSetError {
    /// Reading failed.
    #[error("could not read the file: {0}")]
    Io(#[from] std::io::Error),
    /// Not UTF-8.
    #[error("the file is not UTF-8 text: {0}")]
    Utf8(#[from] core::str::Utf8Error),
    /// The RON does not parse (the message names line, column and field).
    #[error("{0}")]
    Ron(#[from] ron::error::SpannedError),
    /// A value is out of range.
    #[error("{0}")]
    Invalid(#[from] crate::ron_file::FieldError),
}

/// The most a spring may be displaced at rest under its strongest wind, in world units:
/// a push a thousand units long bends any tree flat.
pub(crate) const MAX_WIND_DISPLACEMENT: f32 = 1000.0;

impl SpringSet {
    /// Parses and validates a spring set (optional fields may be written bare).
    pub fn from_ron_str(text: &str) -> Result<Self, SpringSetError> {
        let set: Self = crate::ron_file::ron_options().from_str(text)?;
        set.validate()?;
        Ok(set)
    }

    /// Checks ranges, and that the time step is small enough for every spring to stay
    /// stable (semi-implicit Euler needs `ω·dt < 2`; this asks for `ω·dt ≤ 1`).
    pub(crate) fn validate(&self) -> Result<(), SpringSetError> {
        if !(self.time_step.is_finite() && self.time_step > 0.0 && self.time_step <= 0.1) {
            return Err(invalid("time_step".into(), "must be in (0, 0.1] seconds"));
        }
        if !(self.pixel_threshold.is_finite() && self.pixel_threshold >= 0.0) {
            return Err(invalid(
                "pixel_threshold".into(),
                "must be a non-negative number",
            ));
        }
        if self.springs.is_empty() {
            return Err(invalid("springs".into(), "needs at least one spring"));
        }
        for (i, s) in self.springs.iter().enumerate() {
            let f = |name: &str| format!("springs[{i}].{name}");
            if !(s.stiffness.is_finite() && s.stiffness > 0.0) {
                return Err(invalid(f("stiffness"), "must be positive"));
            }
            if !(s.mass.is_finite() && s.mass > 0.0) {
                return Err(invalid(f("mass"), "must be positive"));
            }
            if !(s.damping > 0.0 && s.damping <= 1.0) {
                return Err(invalid(
                    f("damping"),
                    "must be in (0, 1]: the velocity kept per step",
                ));
            }
            let omega = (s.stiffness / s.mass).sqrt();
            if omega * self.time_step > 1.0 {
                return Err(invalid(
                    f("stiffness"),
                    format!(
                        "too stiff for time_step {}: ω·dt = {:.2} > 1 would be unstable; use a smaller step or a softer spring",
                        self.time_step,
                        omega * self.time_step
                    ),
                ));
            }
            let w = &s.wind;
            let g = &w.gusts;
            let time = |t: f32| t.is_finite() && t >= 0.0;
            let ok = w.direction.is_finite()
                && w.strength.is_finite()
                && g.frequency.is_finite()
                && g.frequency >= 0.0
                && g.strength.0.is_finite()
                && g.strength.1.is_finite()
                && g.strength.1 >= g.strength.0
                && time(g.duration.0)
                && time(g.duration.1)
                && g.duration.1 >= g.duration.0
                && time(g.rise)
                && time(g.fall);
            if !ok {
                return Err(invalid(
                    f("wind"),
                    "direction and strengths must be finite, ranges (min, max) ordered, times finite and non-negative",
                ));
            }
            // The spring's rest under the strongest wind: beyond this it would swing past
            // any tree (and at 1e38 the step overflows and nothing moves at all).
            let strongest = w.strength.abs() + g.strength.0.abs().max(g.strength.1.abs());
            let reach = strongest / s.stiffness;
            if reach > MAX_WIND_DISPLACEMENT {
                return Err(invalid(
                    f("wind.strength"),
                    format!(
                        "the strongest wind over the stiffness moves the spring {reach} units; at most {MAX_WIND_DISPLACEMENT}"
                    ),
                ));
            }
        }
        for (i, r) in self.rules.iter().enumerate() {
            let f = |name: &str| format!("rules[{i}].{name}");
            if r.spring as usize >= self.springs.len() {
                return Err(invalid(
                    f("spring"),
                    format!("there are only {} springs", self.springs.len()),
                ));
            }
            for (name, x) in [
                ("min_diameter", r.min_diameter),
                ("max_diameter", r.max_diameter),
                ("min_height", r.min_height),
            ] {
                if x.is_nan() {
                    return Err(invalid(f(name), "must be a number"));
                }
            }
            if !(r.influence.is_finite() && (0.0..=1.0).contains(&r.influence)) {
                return Err(invalid(f("influence"), "must be within 0–1"));
            }
            if !(r.max_angle.is_finite() && (0.0..=180.0).contains(&r.max_angle)) {
                return Err(invalid(f("max_angle"), "must be within 0–180 degrees"));
            }
        }
        Ok(())
    }
}

/// Loads `*.wind.ron` spring sets.
#[derive(Default, TypePath)]
pub(crate) struct SpringSetLoader;

impl AssetLoader for SpringSetLoader {
    type Asset = SpringSet;
    type Settings = ();
    type Error = SpringSetError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _load_context: &mut LoadContext<'_>,
    ) -> Result<SpringSet, SpringSetError> {
        let text = crate::ron_file::read_text::<SpringSetError>(reader).await?;
        SpringSet::from_ron_str(&text)
    }

    fn extensions(&self) -> &[&str] {
        &["wind.ron"]
    }
}
