//! Value functions: how much of the frame's rendering time an object deserves
//! (paper equations 8–11).

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

/// Depths and distances below this (in world units) are raised to it, so a camera
/// standing inside a tree gives that tree a large but finite value instead of an
/// infinite or NaN one.
pub(crate) const MIN_DEPTH: f32 = 1.0e-3;

/// What a value function knows about one visible object.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct ValueInputs {
    /// Un-projected area of the instance (world units², already scaled).
    pub area: f32,
    /// Depth of the object along the camera's view direction.
    pub depth: f32,
    /// Euclidean distance from the camera to the object.
    pub distance: f32,
    /// Importance factor `I` of the object's type (the paper uses 1 for trunks and
    /// 1/16 for leaves).
    pub importance: f32,
}

impl ValueInputs {
    /// The inputs with NaN or negative area and importance replaced by 0, and depth and
    /// distance raised to [`MIN_DEPTH`] (NaN depth counts as [`MIN_DEPTH`] too).
    pub(crate) fn sanitized(&self) -> Self {
        let non_negative = |x: f32| if x.is_nan() { 0.0 } else { x.max(0.0) };
        let depth = |x: f32| {
            if x.is_nan() {
                MIN_DEPTH
            } else {
                x.max(MIN_DEPTH)
            }
        };
        Self {
            area: non_negative(self.area),
            depth: depth(self.depth),
            distance: depth(self.distance),
            importance: non_negative(self.importance),
        }
    }
}

/// Anything that turns [`ValueInputs`] into a value: the built-in [`ValueFunction`]s, or
/// a user's own function (any `Fn(&ValueInputs) -> f32`).
///
/// Callers pass the result through [`finite_value`], so a user function that returns
/// NaN, a negative or an infinite number cannot poison the budget.
pub(crate) trait ValueModel: Send + Sync {
    /// The value of one object. Should be finite and non-negative.
    fn value(&self, inputs: &ValueInputs) -> f32;
}

impl<F> ValueModel for F
where
    F: Fn(&ValueInputs) -> f32 + Send + Sync,
{
    fn value(&self, inputs: &ValueInputs) -> f32 {
        self(inputs)
    }
}

/// The value functions of the Robin Hood paper (`a` area, `z` depth, `d` distance,
/// `I` importance).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default, Serialize, Deserialize, Reflect)]
pub enum ValueFunction {
    /// P-8, `a/√z · I`: spreads time evenly over near and far objects, leaving the
    /// smallest remainders; suits scenes where distant objects matter.
    P8,
    /// P-9, `a/z · I`.
    P9,
    /// P-10, `a/z² · I`: favours near objects; can leave large remainders when few
    /// objects are visible and one is close.
    P10,
    /// P-11, `√(a/d²) · I`: distance instead of depth favours the centre of the screen,
    /// and the square root curbs remainders. The paper's choice for its LOD results.
    #[default]
    P11,
}

impl ValueFunction {
    /// Every built-in value function, in paper order.
    #[cfg(test)]
    pub(crate) const ALL: [Self; 4] = [Self::P8, Self::P9, Self::P10, Self::P11];

    /// The power of the area in the function: the value of `k` times the area is `k^e`
    /// times the value (1 for P-8, P-9 and P-10, ½ for P-11). The LOD uses it to value a
    /// far tree's leaf groups, all at one depth, with one evaluation.
    pub(crate) fn area_exponent(self) -> f32 {
        match self {
            Self::P8 | Self::P9 | Self::P10 => 1.0,
            Self::P11 => 0.5,
        }
    }
}

impl ValueModel for ValueFunction {
    fn value(&self, inputs: &ValueInputs) -> f32 {
        let ValueInputs {
            area,
            depth,
            distance,
            importance,
        } = inputs.sanitized();
        let raw = match self {
            Self::P8 => area / depth.sqrt() * importance,
            Self::P9 => area / depth * importance,
            Self::P10 => area / (depth * depth) * importance,
            Self::P11 => area.sqrt() / distance * importance,
        };
        finite_value(raw)
    }
}

/// Makes any computed value usable by the budget: NaN and negatives become 0,
/// +∞ becomes `f32::MAX`.
pub(crate) fn finite_value(value: f32) -> f32 {
    if value.is_nan() {
        0.0
    } else {
        value.clamp(0.0, f32::MAX)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn inputs(area: f32, depth: f32, distance: f32, importance: f32) -> ValueInputs {
        ValueInputs {
            area,
            depth,
            distance,
            importance,
        }
    }

    #[test]
    fn scaling_the_area_scales_the_value_by_the_area_exponent() {
        for f in ValueFunction::ALL {
            let one = f.value(&inputs(3.0, 40.0, 50.0, 0.5));
            for k in [0.25_f32, 2.0, 7.0, 1000.0] {
                let scaled = f.value(&inputs(3.0 * k, 40.0, 50.0, 0.5));
                assert_relative_eq!(scaled, one * k.powf(f.area_exponent()), max_relative = 1e-5);
            }
        }
    }

    #[test]
    fn paper_formulas() {
        let i = inputs(8.0, 4.0, 5.0, 0.5);
        assert_relative_eq!(ValueFunction::P8.value(&i), 8.0 / 2.0 * 0.5);
        assert_relative_eq!(ValueFunction::P9.value(&i), 8.0 / 4.0 * 0.5);
        assert_relative_eq!(ValueFunction::P10.value(&i), 8.0 / 16.0 * 0.5);
        assert_relative_eq!(ValueFunction::P11.value(&i), (8.0_f32 / 25.0).sqrt() * 0.5);
    }

    #[test]
    fn nearer_is_worth_more_and_p10_favours_near_most() {
        for f in ValueFunction::ALL {
            let near = f.value(&inputs(1.0, 2.0, 2.0, 1.0));
            let far = f.value(&inputs(1.0, 20.0, 20.0, 1.0));
            assert!(near > far, "{f:?}");
        }
        let ratio = |f: ValueFunction| {
            f.value(&inputs(1.0, 2.0, 2.0, 1.0)) / f.value(&inputs(1.0, 20.0, 20.0, 1.0))
        };
        assert!(ratio(ValueFunction::P10) > ratio(ValueFunction::P9));
        assert!(ratio(ValueFunction::P9) > ratio(ValueFunction::P8));
    }

    #[test]
    fn camera_inside_or_behind_an_object_gives_a_finite_value() {
        for f in ValueFunction::ALL {
            for (depth, distance) in [(0.0, 0.0), (-3.0, 0.5), (f32::NAN, f32::NAN)] {
                let v = f.value(&inputs(2.0, depth, distance, 1.0));
                assert!(v.is_finite() && v > 0.0, "{f:?} {depth} → {v}");
            }
        }
    }

    #[test]
    fn bad_area_or_importance_gives_zero_and_overflow_saturates() {
        for f in ValueFunction::ALL {
            assert_eq!(f.value(&inputs(f32::NAN, 1.0, 1.0, 1.0)), 0.0);
            assert_eq!(f.value(&inputs(-1.0, 1.0, 1.0, 1.0)), 0.0);
            assert_eq!(f.value(&inputs(1.0, 1.0, 1.0, -2.0)), 0.0);
            assert_eq!(f.value(&inputs(f32::MAX, 0.0, 0.0, f32::MAX)), f32::MAX);
        }
    }

    #[test]
    fn user_functions_are_value_models() {
        let custom = |i: &ValueInputs| i.area * 3.0;
        let model: &dyn ValueModel = &custom;
        assert_eq!(model.value(&inputs(2.0, 1.0, 1.0, 1.0)), 6.0);
    }

    #[test]
    fn round_trips_through_ron() {
        for f in ValueFunction::ALL {
            let text = ron::to_string(&f).unwrap();
            assert_eq!(ron::from_str::<ValueFunction>(&text).unwrap(), f);
        }
    }
}
