//! Far trees sway alike: a tree whose motion is a few pixels on screen may borrow the
//! offsets of a representative tree of its type — one heading and size standing for a bin
//! of them — when the difference cannot show (less than a tolerance in pixels). The wind
//! then computes one block per bin instead of one per tree.
//!
//! Why the difference is bounded: an instance's offsets are `scale · R · f(R⁻¹ d / scale)`
//! for spring displacements `d`, its rotation `R` and scale `scale`, where `f` (the rig's
//! bend, [`ring_offsets`](super::motion::ring_offsets)) moves each ring by at most the sum
//! of influences on its path per unit of push: the rig's reach. The representative's
//! rotation `R_b` and scale `s_b` change the push by at most `|d| / scale · (φ + δ)`, with
//! `φ` the angle between `R` and `R_b` and `δ = |scale / s_b − 1|`, so every ring lands
//! within `reach · |d| · (φ + δ)` of where the tree's own offsets put it: the motion level
//! of detail's measure (`largest |d| · reach`, in pixels) times `φ + δ`.

use bevy::math::{Quat, Vec3};

/// Bin levels: level `l` has `BASE_HEADINGS << l` headings and size bins
/// `BASE_SIZE_STEP / 2^l` wide (natural log of the scale).
pub(crate) const LEVELS: usize = 3;
const BASE_HEADINGS: u32 = 16;
const BASE_SIZE_STEP: f32 = 0.1;

/// Which bin of representatives a tree borrows its offsets from (per tree type).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct SwayBin {
    level: u8,
    heading: u16,
    size: i16,
}

/// A bin and the representative tree whose offsets its members borrow.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Representative {
    pub bin: SwayBin,
    /// The representative's rotation (a heading about +Y) and scale.
    pub rotation: Quat,
    pub scale: f32,
    /// How far a member's rings may land from its own, per pixel of its motion: the
    /// angle between its rotation and the representative's plus their scales' ratio's
    /// difference from 1 (the bound above).
    pub error_per_pixel: f32,
}

/// A tree's representative at every level, coarsest first; empty for a rotation or scale
/// that is not finite (or a scale of 0 or less): such a tree computes its own.
pub(crate) fn representatives(rotation: Quat, scale: f32) -> Vec<Representative> {
    if !(scale.is_finite() && scale > 0.0 && rotation.is_finite() && rotation.length() > 0.0) {
        return Vec::new();
    }
    let rotation = rotation.normalize();
    // The heading: where the model's +X points, seen from above.
    let x = rotation * Vec3::X;
    let heading = (-x.z).atan2(x.x);
    let log_scale = scale.ln();
    (0..LEVELS)
        .map(|level| {
            let headings = BASE_HEADINGS << level;
            let step = std::f32::consts::TAU / headings as f32;
            let heading_bin =
                (heading / step).round().rem_euclid(headings as f32) as u32 % headings;
            let representative = Quat::from_rotation_y(heading_bin as f32 * step);
            let size_step = BASE_SIZE_STEP / (1 << level) as f32;
            let size_bin = (log_scale / size_step).round();
            let representative_scale = (size_bin * size_step).exp();
            Representative {
                bin: SwayBin {
                    level: level as u8,
                    heading: heading_bin as u16,
                    size: size_bin.clamp(i16::MIN as f32, i16::MAX as f32) as i16,
                },
                rotation: representative,
                scale: representative_scale,
                error_per_pixel: rotation.angle_between(representative)
                    + (scale / representative_scale - 1.0).abs(),
            }
        })
        .collect()
}

/// The coarsest of a tree's levels (`error_per_pixel` of each, from
/// [`representatives`]) whose representative moves it within `tolerance_pixels` of its
/// own motion when its farthest ring moves `motion_pixels`; `None` when none is fine
/// enough, or for a tolerance of 0 or less.
pub(crate) fn borrowing_level(
    error_per_pixel: &[f32],
    motion_pixels: f32,
    tolerance_pixels: f32,
) -> Option<usize> {
    if tolerance_pixels.is_nan() || tolerance_pixels <= 0.0 {
        return None;
    }
    error_per_pixel
        .iter()
        .position(|e| motion_pixels * e <= tolerance_pixels)
}

/// [`representatives`] and [`borrowing_level`] together: the representative a tree
/// borrows from, and the most its rings land off its own, pixels.
#[cfg(test)]
pub(crate) fn shared_sway(
    rotation: Quat,
    scale: f32,
    motion_pixels: f32,
    tolerance_pixels: f32,
) -> Option<(Representative, f32)> {
    let all = representatives(rotation, scale);
    let errors: Vec<f32> = all.iter().map(|r| r.error_per_pixel).collect();
    let level = borrowing_level(&errors, motion_pixels, tolerance_pixels)?;
    Some((all[level], motion_pixels * all[level].error_per_pixel))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tree_too_near_or_a_zero_tolerance_computes_its_own() {
        let r = Quat::from_rotation_y(0.2);
        assert!(shared_sway(r, 1.0, 0.5, 0.0).is_none());
        assert!(shared_sway(r, 1.0, 400.0, 0.5).is_none());
        assert!(shared_sway(r, f32::NAN, 1.0, 0.5).is_none());
        assert!(shared_sway(r, 0.0, 1.0, 0.5).is_none());
        let (far, _) = shared_sway(r, 1.0, 1.0, 0.5).expect("shares");
        assert_eq!(far.bin.level, 0);
        // Nearer trees need finer bins, and trees of one bin share one representative.
        let (nearer, _) = shared_sway(r, 1.0, 3.0, 0.5).expect("shares");
        assert!(nearer.bin.level > 0);
        let (neighbour, _) = shared_sway(Quat::from_rotation_y(0.21), 1.01, 1.0, 0.5).unwrap();
        assert_eq!((neighbour.bin, neighbour.rotation), (far.bin, far.rotation));
    }
}
