//! Ladders given by the modeller: sibling nodes named `X_LOD0`, `X_LOD1`, … (the
//! convention of Unity, Unreal and Blender's exporters) under an entity marked
//! [`LadderFromLodNames`], as a glTF scene spawns them.

use std::collections::BTreeMap;

use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;

use super::{LadderLevel, LodLadder};

/// Put on a scene's root (beside the `WorldAssetRoot` a glTF scene spawns from, in Bevy
/// 0.19; see the `gltf_props` example): once its descendants
/// are spawned and their meshes loaded, every group of siblings named `X_LOD0`,
/// `X_LOD1`, … (case-insensitive `_LOD` followed by the level, best first) becomes a
/// [`LodLadder`] on the `X_LOD0` node's mesh entity, and the other levels' nodes are
/// hidden. The marker is removed once LOD-named nodes have been found and their meshes
/// have loaded.
///
/// A node's mesh entities are the node itself when it has a `Mesh3d`, or else its
/// children that have one (a glTF mesh of several primitives spawns one child per
/// primitive, in order); with several, primitive `i` of every level makes one ladder.
///
/// A group that cannot be a ladder — no `X_LOD0`, a level number twice, levels with
/// different primitive counts, a mesh that is not triangles, or a level with more
/// triangles than the one before — is left as spawned, with a warning naming it.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component)]
pub struct LadderFromLodNames;

/// The base name and level of a node named `X_LOD<n>` (`_lod` in any case), or `None`:
/// `Rock_LOD2` is `("Rock", 2)`, `rock_lod0` is `("rock", 0)`, `Rock` is none.
pub(crate) fn lod_name_level(name: &str) -> Option<(&str, u32)> {
    const TAG: &str = "_lod";
    let digits = name.len() - name.bytes().rev().take_while(u8::is_ascii_digit).count();
    if digits == name.len() || digits < TAG.len() {
        return None;
    }
    let (front, number) = name.split_at(digits);
    let split = front.len() - TAG.len();
    let tag = front.get(split..)?;
    if split == 0 || !tag.eq_ignore_ascii_case(TAG) {
        return None;
    }
    Some((&front[..split], number.parse().ok()?))
}

/// The triangles a mesh draws, `None` for points and lines.
pub(crate) fn mesh_triangles(mesh: &Mesh) -> Option<u32> {
    let corners = match mesh.indices() {
        Some(Indices::U16(i)) => i.len(),
        Some(Indices::U32(i)) => i.len(),
        None => mesh.count_vertices(),
    };
    let triangles = match mesh.primitive_topology() {
        PrimitiveTopology::TriangleList => corners / 3,
        PrimitiveTopology::TriangleStrip => corners.saturating_sub(2),
        _ => return None,
    };
    u32::try_from(triangles).ok()
}

/// What became of a named group: made into ladders, waiting for its meshes, or refused
/// (and left as spawned).
enum GroupOutcome {
    Made,
    /// A mesh is still loading: try again later.
    Waiting,
    Refused(String),
}

/// Makes ladders of the LOD-named groups under every [`LadderFromLodNames`] entity,
/// looking again whenever names are spawned or while meshes load.
pub(super) fn ladders_from_lod_names(
    roots: Query<Entity, With<LadderFromLodNames>>,
    spawned_names: Query<(), Added<Name>>,
    mut waiting: Local<bool>,
    children: Query<&Children>,
    names: Query<&Name>,
    parents: Query<&ChildOf>,
    mesh_entities: Query<&Mesh3d>,
    // Absent in an app without Bevy's mesh assets (a headless app): then there is
    // nothing to make ladders of.
    meshes: Option<Res<Assets<Mesh>>>,
    mut commands: Commands,
) {
    let Some(meshes) = meshes else {
        return;
    };
    if roots.is_empty() || (spawned_names.is_empty() && !*waiting) {
        return;
    }
    *waiting = false;
    for root in &roots {
        let mut groups: BTreeMap<(Entity, String), Vec<(u32, Entity)>> = BTreeMap::new();
        for node in children.iter_descendants(root) {
            let Some((base, level)) = names.get(node).ok().and_then(|n| lod_name_level(n)) else {
                continue;
            };
            let parent = parents.get(node).map_or(root, ChildOf::parent);
            groups
                .entry((parent, base.to_owned()))
                .or_default()
                .push((level, node));
        }
        let found = !groups.is_empty();
        let mut root_waits = false;
        for ((_, base), mut levels) in groups {
            levels.sort_unstable();
            match make_ladders(&levels, &children, &mesh_entities, &meshes, &mut commands) {
                GroupOutcome::Made => {}
                GroupOutcome::Waiting => root_waits = true,
                GroupOutcome::Refused(why) => {
                    warn!("`{base}_LOD*` under {root}: {why}; left as spawned");
                }
            }
        }
        *waiting |= root_waits;
        // Done once found and decided: a scene spawned later under the same root would
        // otherwise be looked at again, and a refused group warned about again.
        if found && !root_waits {
            commands.entity(root).try_remove::<LadderFromLodNames>();
        }
    }
}

/// One group's ladders (one per primitive), `levels` sorted by level.
fn make_ladders(
    levels: &[(u32, Entity)],
    children: &Query<&Children>,
    mesh_entities: &Query<&Mesh3d>,
    meshes: &Assets<Mesh>,
    commands: &mut Commands,
) -> GroupOutcome {
    if levels.first().is_none_or(|&(level, _)| level != 0) {
        return GroupOutcome::Refused("there is no level 0".into());
    }
    if levels.len() < 2 {
        return GroupOutcome::Refused("there is only level 0".into());
    }
    if let Some(pair) = levels.windows(2).find(|w| w[0].0 == w[1].0) {
        return GroupOutcome::Refused(format!("level {} is named twice", pair[0].0));
    }
    let primitives: Vec<Vec<Entity>> = levels
        .iter()
        .map(|&(_, node)| {
            if mesh_entities.contains(node) {
                vec![node]
            } else {
                children
                    .get(node)
                    .map(|c| c.iter().filter(|&e| mesh_entities.contains(e)).collect())
                    .unwrap_or_default()
            }
        })
        .collect();
    let count = primitives[0].len();
    if let Some((i, other)) = primitives
        .iter()
        .enumerate()
        .find(|(_, p)| p.len() != count)
    {
        return GroupOutcome::Refused(format!(
            "level 0 has {count} meshes, level {} has {}",
            levels[i].0,
            other.len()
        ));
    }
    if count == 0 {
        return GroupOutcome::Refused("level 0 has no mesh".into());
    }
    let mut ladders = Vec::with_capacity(count);
    for primitive in 0..count {
        let mut steps = Vec::with_capacity(levels.len());
        for (&(level, _), entities) in levels.iter().zip(&primitives) {
            let Ok(handle) = mesh_entities.get(entities[primitive]) else {
                return GroupOutcome::Refused(format!("level {level} lost its mesh"));
            };
            let Some(mesh) = meshes.get(&handle.0) else {
                return GroupOutcome::Waiting;
            };
            let Some(triangles) = mesh_triangles(mesh) else {
                return GroupOutcome::Refused(format!(
                    "level {level}'s mesh is a {:?}, not triangles",
                    mesh.primitive_topology()
                ));
            };
            steps.push(LadderLevel {
                mesh: handle.0.clone(),
                triangles,
            });
        }
        let counts: Vec<u32> = steps.iter().map(|s| s.triangles).collect();
        let Some(ladder) = LodLadder::new(steps) else {
            return GroupOutcome::Refused(format!(
                "triangle counts {counts:?} do not decrease from level to level"
            ));
        };
        ladders.push((primitives[0][primitive], ladder));
    }
    for (entity, ladder) in ladders {
        commands.entity(entity).try_insert(ladder);
    }
    for &(_, node) in &levels[1..] {
        commands.entity(node).try_insert(Visibility::Hidden);
    }
    GroupOutcome::Made
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lod_names_parse_only_base_tag_and_number() {
        assert_eq!(lod_name_level("Rock_LOD0"), Some(("Rock", 0)));
        assert_eq!(lod_name_level("Big_Rock_Lod12"), Some(("Big_Rock", 12)));
        assert_eq!(lod_name_level("Rock_LOD01"), Some(("Rock", 1)));
        for name in [
            "",
            "Rock",
            "Rock_LOD",
            "_LOD1",
            "LOD1",
            "Rock_LOD1a",
            "RockLOD1",
            "é_lo1",
            "Rock_LOD99999999999",
        ] {
            assert_eq!(lod_name_level(name), None, "{name}");
        }
        assert_eq!(lod_name_level("é_LOD1"), Some(("é", 1)));
    }

    #[test]
    fn triangles_are_counted_by_topology() {
        use bevy::asset::RenderAssetUsages;
        let mut mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        );
        mesh.insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0_f32; 3]; 6]);
        assert_eq!(mesh_triangles(&mesh), Some(2));
        mesh.insert_indices(Indices::U16(vec![0, 1, 2]));
        assert_eq!(mesh_triangles(&mesh), Some(1));
        let mut strip = Mesh::new(
            PrimitiveTopology::TriangleStrip,
            RenderAssetUsages::default(),
        );
        strip.insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0_f32; 3]; 5]);
        assert_eq!(mesh_triangles(&strip), Some(3));
        let mut lines = Mesh::new(PrimitiveTopology::LineList, RenderAssetUsages::default());
        lines.insert_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0_f32; 3]; 2]);
        assert_eq!(mesh_triangles(&lines), None);
    }
}
