//! Moving a tree's ring hierarchy with springs (thesis §5.3.2): which ring follows which
//! spring, and the per-ring offsets of one instance for the renderer's ring-offset table.

use bevy::math::{Quat, Vec3, Vec3A, Vec4};
use serde::{Deserialize, Serialize};

use crate::culling::CullShape;
use crate::tree::{BoundingSphere, Bounds, TreeModel};

/// A rule associating rings with a spring: the first rule a ring satisfies applies.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AssociationRule {
    /// Index of the spring in the set.
    pub spring: u32,
    /// Rings at least this thick (model units).
    pub min_diameter: f32,
    /// Rings at most this thick.
    pub max_diameter: f32,
    /// Only terminal rings (branch ends).
    pub terminal_only: bool,
    /// Rings at least this high above the model's origin.
    pub min_height: f32,
    /// Rings at least this deep in the hierarchy (the root is level 0).
    pub min_level: u32,
    /// Fraction of the spring's displacement the ring follows (e.g. 0.5 thick, 0.9 thin).
    pub influence: f32,
    /// Largest rotation of the ring's segment away from rest, degrees.
    pub max_angle: f32,
}

impl Default for AssociationRule {
    fn default() -> Self {
        Self {
            spring: 0,
            min_diameter: 0.0,
            max_diameter: f32::INFINITY,
            terminal_only: false,
            min_height: f32::NEG_INFINITY,
            min_level: 1,
            influence: 0.7,
            max_angle: 20.0,
        }
    }
}

/// How one ring moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct RingMotion {
    /// The spring it follows, if any.
    pub spring: Option<u32>,
    /// Fraction of the spring's displacement it follows.
    pub influence: f32,
    /// Largest rotation away from rest, radians.
    pub max_angle: f32,
    /// The first associated ring on its path from the root: motion starts here.
    pub start_of_motion: bool,
}

/// Associates every ring of `model` with the first matching rule (the root rings never
/// move). Springs outside `spring_count` are ignored.
pub(crate) fn associate(
    model: &TreeModel,
    rules: &[AssociationRule],
    spring_count: usize,
) -> Vec<RingMotion> {
    let mut motions: Vec<RingMotion> = Vec::with_capacity(model.rings.len());
    for ring in &model.rings {
        let rule = (!ring.is_root())
            .then(|| {
                rules.iter().find(|r| {
                    (r.spring as usize) < spring_count
                        && ring.diameter >= r.min_diameter
                        && ring.diameter <= r.max_diameter
                        && (!r.terminal_only || ring.is_terminal())
                        && ring.center.y >= r.min_height
                        && ring.level >= r.min_level
                })
            })
            .flatten();
        // Parents come before children, so every ancestor's entry already exists.
        let start_of_motion = rule.is_some() && !has_moving_ancestor(&motions, model, ring.parent);
        motions.push(match rule {
            Some(r) => RingMotion {
                spring: Some(r.spring),
                influence: r.influence.clamp(0.0, 1.0),
                max_angle: r.max_angle.clamp(0.0, 180.0).to_radians(),
                start_of_motion,
            },
            None => RingMotion::default(),
        });
    }
    motions
}

fn has_moving_ancestor(motions: &[RingMotion], model: &TreeModel, mut ring: u32) -> bool {
    // In a valid model parents come first ([`TreeModel::validate`]); a model built by
    // hand that breaks this ends the walk instead of reading past the rings or looping.
    for _ in 0..model.rings.len() {
        let Some(motion) = motions.get(ring as usize) else {
            return false;
        };
        if motion.spring.is_some() {
            return true;
        }
        ring = model.rings[ring as usize].parent;
    }
    false
}

/// What the motion of one tree type under one spring set needs per ring, in ring order:
/// built once from [`associate`]'s result, then used for every instance of the type.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct WindRig {
    rings: Vec<RigRing>,
    /// Each ring's sphere at rest: centre (`xyz`) and half its diameter (`w`), packed for
    /// [`moved_bounds`].
    ring_spheres: Vec<Vec4>,
    /// Each leaf group's sphere at rest and the ring that carries it.
    leaf_groups: Vec<(BoundingSphere, u32)>,
    reach: f32,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct RigRing {
    /// Unit direction from the parent's centre to this ring's, at rest.
    from: Vec3A,
    /// [`NO_RING`](crate::tree::NO_RING) for a root ring.
    parent: u32,
    /// [`NO_SPRING`] for a ring that only carries its parent's offset.
    spring: u32,
    /// Distance from the parent's centre, at rest.
    length: f32,
    influence: f32,
    cos_max_angle: f32,
    sin_max_angle: f32,
    /// Pushes shorter than this (squared) bend the segment by its first-order rotation.
    linear_below_squared: f32,
}

const NO_SPRING: u32 = u32::MAX;

/// Pushes up to this fraction of a segment's length bend it by the first-order rotation
/// (the push's component across the segment) instead of the exact rigid turn: within
/// 5% of the exact offset and the segment's length within 0.5%, at a fraction of the cost.
const LINEAR_PUSH: f32 = 0.1;

impl WindRig {
    /// The rig of `model` with its rings associated as `motions` says (one entry per
    /// ring, as [`associate`] returns). A ring at its parent's centre has no direction to
    /// bend and does not move on its own.
    pub(crate) fn new(model: &TreeModel, motions: &[RingMotion]) -> Self {
        let rings = model
            .rings
            .iter()
            .enumerate()
            .map(|(r, ring)| {
                let motion = motions.get(r).copied().unwrap_or_default();
                let rest = model
                    .rings
                    .get(ring.parent as usize)
                    .map_or(Vec3::ZERO, |p| ring.center - p.center);
                let length = rest.length();
                let from = rest.try_normalize();
                let (sin_max_angle, cos_max_angle) = motion.max_angle.sin_cos();
                RigRing {
                    parent: ring.parent,
                    spring: match (motion.spring, from) {
                        (Some(s), Some(_)) if !ring.is_root() => s,
                        _ => NO_SPRING,
                    },
                    from: from.map_or(Vec3A::ZERO, Vec3A::from),
                    length,
                    influence: motion.influence,
                    cos_max_angle,
                    sin_max_angle,
                    linear_below_squared: if motion.max_angle >= LINEAR_PUSH.atan() {
                        (LINEAR_PUSH * length).powi(2)
                    } else {
                        0.0
                    },
                }
            })
            .collect::<Vec<RigRing>>();
        // Each moving ring adds up to its influence × the push to what it carries, so a
        // ring moves at most the sum of the influences on its path × the largest push.
        let mut path_influence = vec![0.0_f32; rings.len()];
        for (r, ring) in rings.iter().enumerate() {
            let carried = path_influence
                .get(ring.parent as usize)
                .copied()
                .unwrap_or(0.0);
            let own = if ring.spring == NO_SPRING {
                0.0
            } else {
                ring.influence
            };
            path_influence[r] = carried + own;
        }
        let reach = path_influence.iter().copied().fold(0.0, f32::max);
        Self {
            rings,
            ring_spheres: model
                .rings
                .iter()
                .map(|ring| ring.center.extend(ring.diameter * 0.5))
                .collect(),
            leaf_groups: model
                .leaf_groups
                .iter()
                .map(|g| (g.bounds, g.ring))
                .collect(),
            reach,
        }
    }

    /// How far the farthest-moving ring moves per unit of spring displacement (small
    /// displacements, before the angle limits): the sum of influences along the longest
    /// moving path. Motion LOD multiplies the largest spring displacement by it — a tip
    /// twenty rings up moves about twenty times as far as one spring's displacement.
    pub(crate) fn reach(&self) -> f32 {
        self.reach
    }
}

impl Default for RingMotion {
    fn default() -> Self {
        Self {
            spring: None,
            influence: 0.0,
            max_angle: 0.0,
            start_of_motion: false,
        }
    }
}

/// Computes every ring's offset from rest, in the model's space, for one instance of the
/// tree type `rig` was built for.
///
/// `springs` are the spring displacements in world space; `rotation` and `scale` are the
/// instance's, so every tree bends the same world direction and a larger tree responds
/// less. A ring pivots rigidly on its parent towards its spring's push (scaled by its
/// influence) by at most its maximum angle; a ring's own movement smaller than
/// `threshold` (model units) is not applied but accumulated along its path until it is
/// — the thesis' fix for jerky tips; 0 applies everything. Root rings never move, and
/// neither do rings whose spring is missing or not finite.
///
/// `offsets` gets one entry per ring (SIMD-width vectors: the renderer pads each offset
/// to four floats anyway).
pub(crate) fn ring_offsets(
    rig: &WindRig,
    springs: &[Vec3],
    rotation: Quat,
    scale: f32,
    threshold: f32,
    offsets: &mut Vec<Vec3A>,
) {
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    // Springs are few and rings many: bring each spring into model space once.
    let to_model = rotation.inverse();
    let mut local = [Vec3A::ZERO; LOCAL_SPRINGS];
    let local_springs: Vec<Vec3A>;
    let local: &[Vec3A] = if springs.len() <= LOCAL_SPRINGS {
        for (l, s) in local.iter_mut().zip(springs) {
            *l = to_model_space(to_model, scale, *s);
        }
        &local[..springs.len()]
    } else {
        local_springs = springs
            .iter()
            .map(|s| to_model_space(to_model, scale, *s))
            .collect();
        &local_springs
    };
    let threshold_squared = threshold.max(0.0).powi(2);
    let n = rig.rings.len();
    // The second half holds each ring's movement not yet applied (below the threshold),
    // so that no allocation is made per instance; it is cut off at the end.
    offsets.clear();
    offsets.resize(2 * n, Vec3A::ZERO);
    let (applied, pending) = offsets.split_at_mut(n);
    // Two passes: each ring's own bend does not depend on any other ring's, so the first
    // pass runs at the processor's throughput; the second carries offsets down the paths,
    // a chain from ring to ring kept as short as it can be.
    for (own, ring) in pending.iter_mut().zip(&rig.rings) {
        if let Some(&push) = local.get(ring.spring as usize) {
            *own = bend(ring, push * ring.influence);
        }
    }
    for (r, ring) in rig.rings.iter().enumerate() {
        let p = ring.parent as usize;
        if p >= n {
            continue;
        }
        // `pending[r]` still holds the ring's own bend; `pending[p]`, what its parent
        // left unapplied.
        let accumulated = pending[p] + pending[r];
        if accumulated.length_squared() >= threshold_squared {
            applied[r] = applied[p] + accumulated;
            pending[r] = Vec3A::ZERO;
        } else {
            applied[r] = applied[p];
            pending[r] = accumulated;
        }
    }
    offsets.truncate(n);
}

/// Spring sets with at most this many springs are moved to model space on the stack.
const LOCAL_SPRINGS: usize = 16;

/// A world-space displacement in an instance's model space: `to_model` is the inverse of
/// its rotation, `scale` its scale; zero for a displacement that is not finite. (Dividing
/// the quaternion by the scale instead would divide the result by the scale's square:
/// rotating by a quaternion is quadratic in it.)
fn to_model_space(to_model: Quat, scale: f32, displacement: Vec3) -> Vec3A {
    if displacement.is_finite() {
        to_model * Vec3A::from(displacement) / scale
    } else {
        Vec3A::ZERO
    }
}

/// How far a ring moves when `push` bends its segment on the parent, rigidly (its length
/// kept) and by at most its limit angle. Within the limit the segment simply points along
/// `rest + push`; past it, it turns by the limit towards that direction — no
/// trigonometry per ring. No push (also on a ring with no small-push range) moves nothing.
fn bend(ring: &RigRing, push: Vec3A) -> Vec3A {
    if push.length_squared() <= ring.linear_below_squared {
        // Small push: the first-order rotation (the push across the segment).
        return push - ring.from * ring.from.dot(push);
    }
    let rest = ring.from * ring.length;
    let Some(to) = (rest + push).try_normalize() else {
        return Vec3A::ZERO;
    };
    let cos = ring.from.dot(to);
    let direction = if cos >= ring.cos_max_angle {
        to
    } else {
        // Turned past the limit: the limit's angle within the plane of `from` and `to`
        // (when they are opposite there is no such plane and the segment stays).
        match (to - ring.from * cos).try_normalize() {
            Some(across) => ring.from * ring.cos_max_angle + across * ring.sin_max_angle,
            None => ring.from,
        }
    };
    direction * ring.length - rest
}

/// The culling shape of a moved instance of the tree `rig` was built for (model space),
/// written into `out`: a sphere per ring around its moved centre makes the trunk box, leaf
/// groups are translated with their terminal ring, and the whole box holds both.
pub(crate) fn moved_bounds(rig: &WindRig, offsets: &[Vec3A], out: &mut CullShape) {
    let (mut min, mut max) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for (sphere, offset) in rig.ring_spheres.iter().zip(offsets) {
        let center = Vec3A::from_vec4(*sphere) + *offset;
        let radius = Vec3A::splat(sphere.w);
        min = min.min(center - radius);
        max = max.max(center + radius);
    }
    // No rings leave it empty (infinite corners the wrong way round), as Bounds::EMPTY.
    let trunk = Bounds {
        min: min.into(),
        max: max.into(),
    };
    out.groups.clear();
    out.groups
        .extend(rig.leaf_groups.iter().map(|(sphere, ring)| {
            BoundingSphere {
                center: sphere.center
                    + offsets
                        .get(*ring as usize)
                        .map_or(Vec3::ZERO, |o| Vec3::from(*o)),
                radius: sphere.radius,
            }
        }));
    out.bounds = out.groups.iter().fold(trunk, |b, s| {
        b.union(Bounds {
            min: s.center - Vec3::splat(s.radius),
            max: s.center + Vec3::splat(s.radius),
        })
    });
    out.trunk = trunk;
}

/// The wind's update-rate level of detail: how many frames apart an instance whose
/// farthest ring moves `motion_pixels` from rest is updated, a power of two from 1 to
/// `max_interval` (rounded down to one).
///
/// A tree moving at least `full_rate_pixels` is updated every frame; one moving half as
/// far every second frame, a quarter as far every fourth, and so on. Springs swing a tree
/// by a roughly fixed fraction of its amplitude per frame, so the jump a held tree makes
/// when it is next updated stays about the same size on screen whatever its interval.
/// `full_rate_pixels` of 0 (or less, or not a number) updates every instance every frame.
pub(crate) fn update_interval(motion_pixels: f32, full_rate_pixels: f32, max_interval: u32) -> u32 {
    let ratio = full_rate_pixels / motion_pixels;
    // Also for a zero, negative or NaN `full_rate_pixels`.
    if ratio.is_nan() || ratio < 2.0 {
        return 1;
    }
    let most = floor_power_of_two(max_interval.max(1));
    let wanted = floor_power_of_two(ratio.min(most as f32) as u32);
    wanted.clamp(1, most)
}

fn floor_power_of_two(n: u32) -> u32 {
    if n == 0 {
        0
    } else {
        1 << (31 - n.leading_zeros())
    }
}
