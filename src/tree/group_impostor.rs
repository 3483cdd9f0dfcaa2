//! Group impostors: one cheap [`TreeModel`] standing for many trees (Mason & Blake's
//! group representations), so that a far region of a forest can be drawn as one object.
//!
//! The group is built as a tree like any other and analysed by [`analyze`]: a few of its
//! trees (spread evenly over the members, which the box hierarchy lists in space-filling
//! order) keep their main stem as a tube, and the same trees keep their far-first leaves
//! (the leaves a far tree draws first) as one triangle each, enlarged so that the group's
//! leaves cover the area of every member's leaves. The points-and-lines LOD then gives the
//! group its own ladder: triangles when there is time, points of several sizes and lines
//! when there is little.

use bevy::math::{Affine3A, Vec3};

use super::analyze::{AnalysisOptions, MeshData, TreeAnalysisError, TreePart, analyze};
use super::model::{NO_RING, TreeModel};
use super::species::{GeneratedTree, tube};

/// One tree of a group: its model, where it stands relative to the group's origin, and
/// its model's [`TreeModel::far_first_leaves`] (computed once per model by the caller).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GroupImpostorMember<'a> {
    /// The tree's model.
    pub model: &'a TreeModel,
    /// Model space → group space (uniform scale).
    pub transform: Affine3A,
    /// The model's leaves in far-first order.
    pub far_first: &'a [u32],
}

/// How much of its members a group model keeps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct GroupImpostorOptions {
    /// Leaves kept in all (one triangle each), at least one per kept tree.
    pub leaves: u32,
    /// Trees whose stem and leaves are kept, at most.
    pub trunks: u32,
}

impl Default for GroupImpostorOptions {
    fn default() -> Self {
        Self {
            leaves: 256,
            trunks: 32,
        }
    }
}

/// Largest factor a kept leaf is enlarged by (in length): beyond it the group covers less
/// than its members' leaf area rather than drawing leaves the size of trees.
const MAX_LEAF_ENLARGEMENT: f32 = 32.0;

/// Sides of a stem tube.
const STEM_SIDES: usize = 5;

/// The group model of `members`, in the members' common space.
///
/// Fails like [`analyze`] does; in particular with
/// [`TreeAnalysisError::NoTriangles`] when no member has a trunk.
pub(crate) fn group_impostor_model(
    members: &[GroupImpostorMember],
    options: &GroupImpostorOptions,
) -> Result<TreeModel, TreeAnalysisError> {
    let kept = members.len().min(options.trunks.max(1) as usize);
    let leaves_each = (options.leaves as usize / kept.max(1)).max(1);
    let mut out = GeneratedTree {
        trunk_positions: Vec::new(),
        trunk_normals: Vec::new(),
        trunk_indices: Vec::new(),
        leaf_positions: Vec::new(),
        leaf_normals: Vec::new(),
        leaf_indices: Vec::new(),
    };
    // Every stem reaches down to below the lowest stem's foot, so one ground plane under
    // them all cuts each stem's own root, however far apart in height the trees stand (a
    // slope, a hill); the reach lies under its tree's own ground.
    let kept_members: Vec<&GroupImpostorMember> = (0..kept)
        .map(|k| &members[k * members.len() / kept])
        .collect();
    let stems: Vec<Option<(Vec<Vec3>, Vec<f32>)>> = kept_members
        .iter()
        .map(|member| {
            let scale = member.transform.matrix3.x_axis.length();
            main_stem(member.model).map(|(points, radii)| {
                let points = points
                    .iter()
                    .map(|&p| member.transform.transform_point3(p))
                    .collect::<Vec<_>>();
                (points, radii.iter().map(|r| r * scale).collect::<Vec<_>>())
            })
        })
        .collect();
    let floor = stems
        .iter()
        .flatten()
        .map(|(points, radii)| points[0].y - 2.0 * radii[0])
        .fold(f32::INFINITY, f32::min);
    let mut bark = Vec3::ZERO;
    let mut leaf_color = Vec3::ZERO;
    // The centre of every kept leaf triangle, to enlarge them all at the end.
    let mut kept_leaves: Vec<Vec3> = Vec::new();
    let mut kept_area = 0.0f32;
    for (member, stem) in kept_members.iter().zip(stems) {
        let model = member.model;
        if let Some((mut points, mut radii)) = stem {
            points.insert(0, Vec3::new(points[0].x, floor, points[0].z));
            radii.insert(0, radii[0]);
            tube(&mut out, &points, &radii, STEM_SIDES, 0.0);
        }
        bark += Vec3::from(model.bark_color);
        leaf_color += Vec3::from(model.leaf_color);
        for &leaf in member.far_first.iter().take(leaves_each) {
            let Some(leaf) = model.leaves.get(leaf as usize) else {
                continue;
            };
            let first = leaf.triangles.start as usize * 3;
            let Some(triangle) = model.leaf_indices.get(first..first + 3) else {
                continue;
            };
            let at = |i: usize| -> Option<(Vec3, Vec3)> {
                let v = *triangle.get(i)? as usize;
                Some((
                    member
                        .transform
                        .transform_point3(*model.leaf_positions.get(v)?),
                    member
                        .transform
                        .transform_vector3(*model.leaf_normals.get(v)?)
                        .normalize_or(Vec3::Y),
                ))
            };
            let (Some(a), Some(b), Some(c)) = (at(0), at(1), at(2)) else {
                continue;
            };
            kept_area += (b.0 - a.0).cross(c.0 - a.0).length() * 0.5;
            let base = out.leaf_positions.len() as u32;
            for (p, n) in [a, b, c] {
                out.leaf_positions.push(p);
                out.leaf_normals.push(n);
            }
            out.leaf_indices.extend([base, base + 1, base + 2]);
            kept_leaves.push((a.0 + b.0 + c.0) / 3.0);
        }
    }
    // Every member's leaf area, not only the kept ones'.
    let total_area: f32 = members
        .iter()
        .map(|m| {
            let scale = m.transform.matrix3.x_axis.length();
            m.model.mean_leaf_triangle_area * m.model.leaf_triangle_count() as f32 * scale * scale
        })
        .sum();
    if kept_area > 0.0 && total_area > kept_area {
        let enlarge = (total_area / kept_area).sqrt().min(MAX_LEAF_ENLARGEMENT);
        for (t, centre) in kept_leaves.iter().enumerate() {
            for p in &mut out.leaf_positions[3 * t..3 * t + 3] {
                *p = *centre + (*p - *centre) * enlarge;
            }
        }
    }
    let n = kept.max(1) as f32;
    let options = AnalysisOptions {
        // Every stem's open base is a root, wherever its tree stands.
        ground: if floor.is_finite() {
            floor + 1e-3 * (1.0 + floor.abs())
        } else {
            0.0
        },
        ..AnalysisOptions::default()
    };
    let trunk = MeshData {
        positions: &out.trunk_positions,
        normals: Some(&out.trunk_normals),
        indices: &out.trunk_indices,
        color: Some((bark / n).to_array()),
    };
    let leaves = MeshData {
        positions: &out.leaf_positions,
        normals: Some(&out.leaf_normals),
        indices: &out.leaf_indices,
        color: Some((leaf_color / n).to_array()),
    };
    if trunk.indices.is_empty() {
        return Err(TreeAnalysisError::NoTriangles {
            part: TreePart::Trunk,
        });
    }
    // A group stands for many crowns: one disc over them all would cover the gaps
    // between its trees.
    analyze(&trunk, &leaves, &options).map(|analysis| TreeModel {
        crown: None,
        ..analysis.model
    })
}

/// A tree's main stem in model space: from its thickest root ring up through the thickest
/// child at every fork, as (base, middle, top) ring centres and radii; `None` without
/// rings.
fn main_stem(model: &TreeModel) -> Option<([Vec3; 3], [f32; 3])> {
    let diameter = |r: u32| model.rings[r as usize].diameter;
    let root = model
        .roots()
        .max_by(|&a, &b| diameter(a).total_cmp(&diameter(b)))?;
    let mut path = vec![root];
    let mut ring = root;
    while let Some(&next) = model.rings[ring as usize]
        .children
        .iter()
        .filter(|&&c| (c as usize) < model.rings.len() && c != NO_RING)
        .max_by(|&&a, &&b| diameter(a).total_cmp(&diameter(b)))
    {
        if path.len() > model.rings.len() {
            break; // a cycle in a corrupt model
        }
        path.push(next);
        ring = next;
    }
    let base = &model.rings[root as usize];
    let radius = (base.diameter * 0.5).max(1e-3);
    let top = if path.len() > 1 {
        model.rings[*path.last()? as usize].center
    } else {
        // A root that is its own tip: a stub as tall as it is wide.
        base.center + Vec3::Y * base.diameter.max(2e-3)
    };
    let middle = if path.len() > 2 {
        model.rings[path[path.len() / 2] as usize].center
    } else {
        (base.center + top) * 0.5
    };
    if base.center.distance(top) <= f32::EPSILON {
        return None;
    }
    Some((
        [base.center, middle, top],
        [radius, radius * 0.7, radius * 0.4],
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::SpeciesDesc;

    /// A culling box's kept members as an app's forest gave them (three species on a
    /// hilly terrain, 11 m between the lowest and the highest foot, one tilted 34°;
    /// `tests/data`: ring count, then the transform's columns): the group is built, every
    /// stem a root. (With one ground plane at the highest foot, the highest tree's stem
    /// had no segment above it.)
    #[test]
    fn a_group_of_trees_on_a_hill_roots_every_stem() {
        let models: Vec<TreeModel> = ["slender", "broad", "grand"]
            .iter()
            .map(|name| {
                let path = format!(
                    "{}/assets/species/{name}.species.ron",
                    env!("CARGO_MANIFEST_DIR")
                );
                let text = std::fs::read_to_string(path).unwrap();
                SpeciesDesc::from_ron_str(&text)
                    .unwrap()
                    .generate_and_analyze()
                    .unwrap()
                    .model
            })
            .collect();
        let far: Vec<Vec<u32>> = models.iter().map(TreeModel::far_first_leaves).collect();
        let text = include_str!("../../tests/data/group_members_on_a_slope.txt");
        let members: Vec<GroupImpostorMember> = text
            .lines()
            .map(|line| {
                let numbers: Vec<f32> = line
                    .split_whitespace()
                    .map(|n| n.parse().unwrap())
                    .collect();
                let s = models
                    .iter()
                    .position(|m| m.rings.len() == numbers[0] as usize)
                    .unwrap();
                GroupImpostorMember {
                    model: &models[s],
                    transform: Affine3A::from_cols_array(&numbers[1..13].try_into().unwrap()),
                    far_first: &far[s],
                }
            })
            .collect();
        let group = group_impostor_model(&members, &GroupImpostorOptions::default()).unwrap();
        group.validate().unwrap();
        assert_eq!(group.roots().count(), members.len());
    }

    #[test]
    fn a_group_is_a_valid_tree_with_its_members_leaf_area() {
        let text = include_str!("../../assets/species/slender.species.ron");
        let model = SpeciesDesc::from_ron_str(text)
            .unwrap()
            .generate_and_analyze()
            .unwrap()
            .model;
        let far_first = model.far_first_leaves();
        let members: Vec<GroupImpostorMember> = (0..40)
            .map(|i| GroupImpostorMember {
                model: &model,
                transform: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(1.0 + 0.01 * i as f32),
                    Default::default(),
                    Vec3::new((i % 8) as f32 * 6.0, 0.1 * i as f32, (i / 8) as f32 * 6.0),
                ),
                far_first: &far_first,
            })
            .collect();
        let options = GroupImpostorOptions {
            leaves: 128,
            trunks: 16,
        };
        let group = group_impostor_model(&members, &options).unwrap();
        group.validate().unwrap();
        // One stem per kept tree, each its own root.
        let roots: Vec<Vec3> = group
            .roots()
            .map(|r| group.rings[r as usize].center)
            .collect();
        assert_eq!(roots.len(), 16, "{roots:?} rings {}", group.rings.len());
        assert!(group.leaf_triangle_count() <= 128);
        assert!(group.leaf_triangle_count() >= 16);
        // The kept leaves cover (up to the enlargement cap) every member's leaf area.
        let members_area: f32 = members
            .iter()
            .map(|m| {
                let s = m.transform.matrix3.x_axis.length();
                model.mean_leaf_triangle_area * model.leaf_triangle_count() as f32 * s * s
            })
            .sum();
        let group_area = group.mean_leaf_triangle_area * group.leaf_triangle_count() as f32;
        let capped = members_area.min(
            group.leaf_triangle_count() as f32
                * model.mean_leaf_triangle_area
                * MAX_LEAF_ENLARGEMENT.powi(2),
        );
        assert!(
            (group_area / capped - 1.0).abs() < 0.5,
            "group leaf area {group_area}, members' {members_area}"
        );
        // The group spans its members.
        let span = group.bounds.max - group.bounds.min;
        assert!(span.x > 40.0 && span.z > 24.0, "{span}");
    }

    #[test]
    fn members_without_a_trunk_make_no_group() {
        assert!(matches!(
            group_impostor_model(&[], &GroupImpostorOptions::default()),
            Err(TreeAnalysisError::NoTriangles { .. })
        ));
    }
}
