//! The group impostors of the hierarchical strategy: one [`TreeModel`] per box of the
//! culling hierarchy that holds enough trees, spawned as a tree entity the LOD stages
//! write a draw list into (empty while its trees are drawn on their own).

use std::time::Instant;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::{FrameBudget, GroupImpostorSettings, StrategyKind};
use crate::culling::ForestCulling;
use crate::draw::{ModelSlot, TreeDrawList, TreeShading};
use crate::instance::{FixedDrawList, ForestInstances, TreeInstance};
use crate::tree::{GroupImpostorMember, TreeModel, group_impostor_model};

/// Marks the entity of a group impostor: it stands for the trees under box `node` of the
/// culling hierarchy. It is a [`TreeInstance`] with [`FixedDrawList`], outside the
/// instance table; the Budget stage writes its [`TreeDrawList`].
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct GroupImpostorOf {
    /// The box, an index into the hierarchy's nodes.
    pub node: u32,
}

/// One box's group impostor.
#[derive(Clone, Debug)]
pub(crate) struct GroupImpostor {
    pub(crate) entity: Entity,
    pub(crate) model: Handle<TreeModel>,
    /// Where the model's origin stands (world space).
    pub(crate) origin: Vec3,
    /// What counting its draw list needs.
    pub(crate) slot: ModelSlot,
    /// Its model's vertices (counted against [`GroupImpostorSettings::max_vertices`]).
    vertices: usize,
}

/// After trees are planted or felled, the group impostors of the boxes that hold them are
/// rebuilt at most this often, in seconds of real time; until then they show the trees
/// they were built with.
pub(crate) const GROUP_REBUILD_SECS: f32 = 1.0;

/// The group impostors of the culling hierarchy's boxes, built by the LOD plugin while
/// the strategy is [`StrategyKind::Hierarchical`].
#[derive(Resource, Default)]
pub struct GroupImpostors {
    /// Per box of the hierarchy, its impostor.
    pub(crate) nodes: Vec<Option<GroupImpostor>>,
    /// `(hierarchy version, depth, settings)` they were built for.
    built: Option<(u64, u32, GroupImpostorSettings)>,
    /// The hierarchy's edits they follow, and when (`Time<Real>` seconds) they were last
    /// brought up to them.
    edits_seen: u64,
    built_at: f32,
    build_ms: f32,
    failed: u32,
    builds: u64,
}

impl GroupImpostors {
    /// How many boxes have a group impostor.
    pub fn len(&self) -> usize {
        self.nodes.iter().flatten().count()
    }

    /// Whether none has.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Whether box `node` of the culling's hierarchy has a group impostor built for the
    /// hierarchy it holds now (impostors of an older hierarchy are not used).
    pub(crate) fn has_impostor(&self, culling: Option<&ForestCulling>, node: usize) -> bool {
        let current = culling.is_some_and(|c| {
            let depth = c.hierarchy.as_ref().map_or(0, crate::culling::BoxHierarchy::depth);
            matches!((self.built, c.hierarchy_version()), (Some((v, d, _)), Some(now)) if v == now && d == depth)
        });
        current && self.nodes.get(node).is_some_and(Option::is_some)
    }
}

/// Builds the group impostors once the hierarchical strategy is chosen, the culling
/// hierarchy is built for the current layout and every tree model has loaded; after
/// trees were planted or felled, rebuilds the boxes that hold them (at most every
/// [`GROUP_REBUILD_SECS`]).
#[expect(
    clippy::too_many_arguments,
    reason = "a system names every resource it reads"
)]
pub(super) fn build_group_impostors(
    mut commands: Commands,
    budget: Res<FrameBudget>,
    settings: Res<GroupImpostorSettings>,
    culling: Option<Res<ForestCulling>>,
    table: Res<ForestInstances>,
    mut models: ResMut<Assets<TreeModel>>,
    shadings: Query<&TreeShading>,
    mut groups: ResMut<GroupImpostors>,
    time: Res<Time<Real>>,
) {
    if budget.strategy != StrategyKind::Hierarchical {
        return;
    }
    let Some(culling) = culling else {
        return;
    };
    let (Some(hierarchy), Some(version)) =
        (culling.hierarchy.as_ref(), culling.hierarchy_version())
    else {
        return;
    };
    // Every tree's model is waited for, but one stuck loading (warned about) does not
    // hold back the forest's groups.
    let waiting = culling.models_loading() > culling.models_stuck_loading();
    if culling.layout_version() != Some(table.layout_version()) || waiting {
        return;
    }
    let key = (version, hierarchy.depth(), *settings);
    let now = time.elapsed_secs();
    let every_box = groups.built != Some(key);
    if !every_box
        && (groups.edits_seen == hierarchy.edits() || now - groups.built_at < GROUP_REBUILD_SECS)
    {
        return;
    }
    let start = Instant::now();
    let boxes: Vec<usize> = if every_box {
        (0..hierarchy.node_count()).collect()
    } else {
        (0..hierarchy.node_count())
            .filter(|&node| hierarchy.node_edit(node) > groups.edits_seen)
            .collect()
    };
    let stale: Vec<GroupImpostor> = if every_box {
        groups.nodes.drain(..).flatten().collect()
    } else {
        boxes
            .iter()
            .filter_map(|&node| groups.nodes.get_mut(node).and_then(Option::take))
            .collect()
    };
    for old in stale {
        commands.entity(old.entity).try_despawn();
        models.remove(&old.model);
    }
    groups.nodes.resize(hierarchy.node_count(), None);
    let mut far_first: HashMap<AssetId<TreeModel>, Vec<u32>> = HashMap::default();
    for id in &table.model_ids {
        if let Some(model) = models.get(*id) {
            far_first.insert(*id, model.far_first_leaves());
        }
    }
    let options = settings.model_options();
    let mut built = Vec::with_capacity(boxes.len());
    let mut failed = 0;
    let mut vertices: usize = groups.nodes.iter().flatten().map(|g| g.vertices).sum();
    let mut full = false;
    // Boxes are numbered level by level from the root: coarsest first.
    for &node in &boxes {
        let trees = hierarchy.node_instances(node);
        let bounds = hierarchy.node_bounds(node);
        if full || trees.len() < settings.min_trees.max(1) as usize || bounds.is_empty() {
            continue;
        }
        let origin = Vec3::new(bounds.center().x, bounds.min.y, bounds.center().z);
        let members = members_around(&table, &models, &far_first, trees, origin);
        match group_impostor_model(&members, &options) {
            Ok(model) => {
                vertices += model.trunk_positions.len() + model.leaf_positions.len();
                if vertices > settings.max_vertices as usize {
                    full = true;
                    info!(
                        "group impostors stop at culling box {node} (level {}): GroupImpostorSettings::max_vertices ({}) reached",
                        hierarchy.level_of(node),
                        settings.max_vertices
                    );
                } else {
                    built.push((node, origin, model, trees[0]));
                }
            }
            Err(error) => {
                // Warned once, when every box is built: a box rebuilt after planting
                // may fail again every time.
                let trees = trees.len();
                if every_box {
                    warn!("group impostor of culling box {node} ({trees} trees): {error}");
                } else {
                    debug!("group impostor of culling box {node} ({trees} trees): {error}");
                }
                failed += 1;
            }
        }
    }
    let rebuilt = built.len();
    for (node, origin, model, first_tree) in built {
        // Shaded like its first tree.
        let shading = table
            .entities
            .get(first_tree as usize)
            .and_then(|&e| shadings.get(e).ok())
            .copied()
            .unwrap_or_else(|| TreeShading::of_model(&model));
        let impostor = spawn_impostor(&mut commands, &mut models, node, origin, model, shading);
        groups.nodes[node] = Some(impostor);
    }
    groups.built = Some(key);
    groups.edits_seen = hierarchy.edits();
    groups.built_at = now;
    groups.builds += 1;
    groups.build_ms = start.elapsed().as_secs_f32() * 1000.0;
    groups.failed = failed;
    if every_box {
        info!(
            "built {} group impostors in {:.0} ms",
            groups.len(),
            groups.build_ms
        );
    } else {
        debug!(
            "rebuilt {rebuilt} group impostors of {} boxes whose trees changed in {:.0} ms",
            boxes.len(),
            groups.build_ms
        );
    }
}

/// The trees `trees` of the table as members of a group placed at `origin` (their
/// transforms relative to it); trees whose model is not loaded are left out.
fn members_around<'a>(
    table: &ForestInstances,
    models: &'a Assets<TreeModel>,
    far_first: &'a HashMap<AssetId<TreeModel>, Vec<u32>>,
    trees: &[u32],
    origin: Vec3,
) -> Vec<GroupImpostorMember<'a>> {
    trees
        .iter()
        .filter_map(|&i| {
            let id = table.model_id(i as usize)?;
            let mut transform = *table.transforms.get(i as usize)?;
            transform.translation -= Vec3A::from(origin);
            Some(GroupImpostorMember {
                model: models.get(id)?,
                transform,
                far_first: far_first.get(&id)?,
            })
        })
        .collect()
}

/// Spawns box `node`'s group impostor: `model` at `origin`, drawn with a fixed list the
/// Budget stage writes.
fn spawn_impostor(
    commands: &mut Commands,
    models: &mut Assets<TreeModel>,
    node: usize,
    origin: Vec3,
    model: TreeModel,
    shading: TreeShading,
) -> GroupImpostor {
    let slot = ModelSlot::of(&model);
    let vertices = model.trunk_positions.len() + model.leaf_positions.len();
    let handle = models.add(model);
    let entity = commands
        .spawn((
            Name::new(format!("group impostor {node}")),
            TreeInstance::new(handle.clone()),
            FixedDrawList,
            TreeDrawList::default(),
            shading,
            GroupImpostorOf { node: node as u32 },
            Transform::from_translation(origin),
            // Drawn from this frame on, before transforms propagate again.
            GlobalTransform::from_translation(origin),
        ))
        .id();
    GroupImpostor {
        entity,
        model: handle,
        origin,
        slot,
        vertices,
    }
}
