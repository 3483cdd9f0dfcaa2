//! Moving a tree's ring hierarchy with springs (thesis §5.3.2): which ring follows which
//! spring, and the per-ring offsets of one instance for the renderer's ring-offset table.

use bevy::math::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::culling::CullShape;
use crate::tree::{BoundingSphere, Bounds, NO_RING, TreeModel};

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
pub struct RingMotion {
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
pub fn associate(
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
            None => RingMotion {
                spring: None,
                influence: 0.0,
                max_angle: 0.0,
                start_of_motion: false,
            },
        });
    }
    motions
}

fn has_moving_ancestor(motions: &[RingMotion], model: &TreeModel, mut ring: u32) -> bool {
    while ring != NO_RING {
        if motions[ring as usize].spring.is_some() {
            return true;
        }
        ring = model.rings[ring as usize].parent;
    }
    false
}

/// Computes every ring's offset from rest, in the model's space, for one instance.
///
/// `springs` are the spring displacements in world space; `rotation` and `scale` are the
/// instance's, so every tree bends the same world direction and a larger tree responds
/// less. A ring's own movement smaller than `threshold` (model units) is not applied but
/// accumulated along its path until it is — the thesis' fix for jerky tips; 0 applies
/// everything. Root rings never move.
pub fn ring_offsets(
    model: &TreeModel,
    motions: &[RingMotion],
    springs: &[Vec3],
    rotation: Quat,
    scale: f32,
    threshold: f32,
    offsets: &mut Vec<Vec3>,
) {
    let inverse = rotation.inverse();
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    offsets.clear();
    offsets.resize(model.rings.len(), Vec3::ZERO);
    let mut pending = vec![Vec3::ZERO; model.rings.len()];
    for (r, ring) in model.rings.iter().enumerate() {
        if ring.is_root() {
            continue;
        }
        let p = ring.parent as usize;
        let carried = offsets[p];
        let motion = motions[r];
        let own = match motion.spring.and_then(|s| springs.get(s as usize)) {
            Some(&displacement) if displacement.is_finite() => {
                let rest = ring.center - model.rings[p].center;
                let length = rest.length();
                let push = inverse * displacement / scale * motion.influence;
                match (rest.try_normalize(), (rest + push).try_normalize()) {
                    (Some(from), Some(to)) => {
                        let angle = from.angle_between(to).min(motion.max_angle);
                        let axis = from.cross(to).try_normalize();
                        let bent = axis.map_or(from, |a| Quat::from_axis_angle(a, angle) * from);
                        bent * length - rest
                    }
                    _ => Vec3::ZERO,
                }
            }
            _ => Vec3::ZERO,
        };
        let accumulated = pending[p] + own;
        if accumulated.length() >= threshold.max(0.0) {
            offsets[r] = carried + accumulated;
        } else {
            offsets[r] = carried;
            pending[r] = accumulated;
        }
    }
}

/// The culling shape of a moved instance (model space), written into `out`: a sphere per
/// ring around its moved centre makes the trunk box, leaf groups are translated with their
/// terminal ring, and the whole box holds both.
pub fn moved_bounds(model: &TreeModel, offsets: &[Vec3], out: &mut CullShape) {
    let mut trunk = Bounds::EMPTY;
    for (ring, offset) in model.rings.iter().zip(offsets) {
        let c = ring.center + *offset;
        let r = Vec3::splat(ring.diameter * 0.5);
        trunk = trunk.union(Bounds {
            min: c - r,
            max: c + r,
        });
    }
    out.groups.clear();
    out.groups
        .extend(model.leaf_groups.iter().map(|g| BoundingSphere {
            center: g.bounds.center + offsets.get(g.ring as usize).copied().unwrap_or(Vec3::ZERO),
            radius: g.bounds.radius,
        }));
    out.bounds = out.groups.iter().fold(trunk, |b, s| {
        b.union(Bounds {
            min: s.center - Vec3::splat(s.radius),
            max: s.center + Vec3::splat(s.radius),
        })
    });
    out.trunk = trunk;
}
