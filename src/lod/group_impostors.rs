//! The group impostors of the hierarchical strategy: one [`TreeModel`] per box of the
//! culling hierarchy that holds enough trees, spawned as a tree entity the LOD stages
//! write a draw list into (empty while its trees are drawn on their own).
//!
//! They are built lazily, for the boxes last frame's cut reached (and the children of
//! those it drew as group impostors, where it refines next), coarsest first within
//! [`GroupImpostorSettings::build_ms_per_frame`], and released once the cut has not
//! reached them for [`GroupImpostorSettings::idle_secs`]: memory follows the boxes in
//! view, not the forest, and no frame stops to build them all. The cut waits for them:
//! a box drawn as its group impostor opens only once its children in view have theirs
//! ([`ImpostorStatus::Coming`]); a box that cannot have one is opened to its trees.

use std::time::Instant;

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::{FrameBudget, GroupImpostorSettings, HierarchicalCut, StrategyKind};
use crate::budget::NodeSelection;
use crate::culling::{BoxHierarchy, ForestCulling};
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
    /// When (`Time<Real>` seconds) the cut last reached its box.
    wanted_at: f32,
    /// Its box's trees changed since it was built: rebuilt when next wanted.
    stale: bool,
}

/// After trees are planted or felled, the group impostors of the boxes that hold them are
/// rebuilt at most this often, in seconds of real time; until then they show the trees
/// they were built with.
pub(crate) const GROUP_REBUILD_SECS: f32 = 1.0;

/// What group impostors are built for: the hierarchy's version and depth, and the
/// settings that shape a group's model.
type BuiltFor = (u64, u32, (u32, u32, u32, u32));

/// The group impostors of the culling hierarchy's boxes, built by the LOD plugin while
/// the strategy is [`StrategyKind::Hierarchical`].
#[derive(Resource, Default)]
pub struct GroupImpostors {
    /// Per box of the hierarchy, its impostor.
    pub(crate) nodes: Vec<Option<GroupImpostor>>,
    /// Per box, whether it cannot have one (too few trees, no bounds, or its model could
    /// not be built) until its trees change.
    unbuildable: Vec<bool>,
    /// The vertices of the smallest model built that found no room in the vertex budget
    /// since one last fitted: no box is built while less room than that could be made.
    unfit: Option<usize>,
    /// What they were built for.
    built: Option<BuiltFor>,
    /// The hierarchy's edits they follow, and when (`Time<Real>` seconds) they were last
    /// brought up to them.
    edits_seen: u64,
    edits_checked_at: f32,
    /// Vertices of all the built groups' models.
    vertices: usize,
    /// Boxes wanted this frame, sorted, and the order they are built in (scratch).
    wanted: Vec<u32>,
    build_order: Vec<u32>,
    /// Group models built and not yet spawned, and when the last were.
    pending: Vec<Built>,
    published_at: Option<f32>,
    /// Boxes whose impostors make room for this frame's builds (scratch).
    releasing: Vec<usize>,
    /// Last frame's building time, milliseconds.
    build_ms: f32,
    /// Models built so far.
    builds: u64,
    /// Whether the vertex budget stopped a build since the hierarchy was built (logged once).
    full_logged: bool,
    /// Whether the vertex budget stopped a build, and no group impostor was released
    /// since (to make room or idle): boxes without one will not get it soon.
    stopped_at_budget: bool,
    /// Whether boxes the cut wants are still without their group impostor, or what it
    /// wants is not known yet.
    building: bool,
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

    /// Vertices of the group impostors' models together.
    pub fn vertices(&self) -> usize {
        self.vertices
    }

    /// Group models built so far (rebuilds included).
    pub fn builds(&self) -> u64 {
        self.builds
    }

    /// The main-world time the last frame spent building and publishing group models, ms
    /// (at most about [`GroupImpostorSettings::build_ms_per_frame`] while boxes wait).
    pub fn build_ms(&self) -> f32 {
        self.build_ms
    }

    /// Whether boxes the cut reached are still waiting for their group impostor (built a
    /// few a frame, [`GroupImpostorSettings::build_ms_per_frame`]; their trees are drawn
    /// on their own meanwhile).
    pub fn building(&self) -> bool {
        self.building
    }

    /// Where box `node`'s group impostor stands for the hierarchy the culling holds now
    /// (impostors built for an older one are not used).
    pub(crate) fn status(&self, culling: Option<&ForestCulling>, node: usize) -> ImpostorStatus {
        let current = culling.is_some_and(|c| {
            let depth = c.hierarchy.as_ref().map_or(0, BoxHierarchy::depth);
            matches!((self.built, c.hierarchy_version()), (Some((v, d, _)), Some(now)) if v == now && d == depth)
        });
        if current && self.nodes.get(node).is_some_and(Option::is_some) {
            ImpostorStatus::Built
        } else if self.stopped_at_budget || (current && self.unbuildable.get(node) == Some(&true)) {
            ImpostorStatus::Unavailable
        } else {
            ImpostorStatus::Coming
        }
    }
}

/// Where a box's group impostor stands ([`GroupImpostors::status`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ImpostorStatus {
    /// Built for the boxes the culling holds now.
    Built,
    /// Not built yet, and it will be once the cut wants it: the box may have one, and
    /// the vertex budget has room (no build stopped at it since an impostor was last
    /// released).
    Coming,
    /// It cannot have one (too few trees, no bounds, its model could not be built), or
    /// [`GroupImpostorSettings::max_vertices`] stopped the building.
    Unavailable,
}

/// Built group models are handed to the renderer together, at most this often (seconds
/// of real time) while more are being built: one change of the set of tree models for
/// them all, which what is derived from the models (packed geometry, per-model infos)
/// follows by appending.
const GROUP_PUBLISH_SECS: f32 = 0.5;

/// An impostor is released to make room for another only once the cut has not wanted it
/// for this long (seconds of real time).
const EVICT_IDLE_SECS: f32 = 1.0;

/// A group model built and not yet spawned.
struct Built {
    node: usize,
    origin: Vec3,
    model: TreeModel,
    first_tree: u32,
}

/// Builds, once the hierarchical strategy is chosen, the culling hierarchy is built for
/// the current layout and every tree model has loaded, the group impostors of the boxes
/// last frame's cut wanted (see the module's documentation); after trees were planted or
/// felled, rebuilds the ones of the boxes that hold them (at most every
/// [`GROUP_REBUILD_SECS`]). Releases them all when another strategy is chosen.
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
    cut: Res<HierarchicalCut>,
    time: Res<Time<Real>>,
) {
    let groups = &mut *groups;
    if budget.strategy != StrategyKind::Hierarchical {
        if groups.built.is_some() {
            groups.release_all(&mut commands, &mut models);
        }
        return;
    }
    // Until the cut has reached the boxes of the current hierarchy, what it wants is not
    // known yet.
    groups.building = true;
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
    let now = time.elapsed_secs();
    let key = (version, hierarchy.depth(), settings.shape());
    if groups.built != Some(key) {
        groups.release_all(&mut commands, &mut models);
        groups.nodes.resize(hierarchy.node_count(), None);
        groups.unbuildable.resize(hierarchy.node_count(), false);
        groups.built = Some(key);
        groups.edits_seen = hierarchy.edits();
        groups.edits_checked_at = now;
    } else if groups.edits_seen != hierarchy.edits()
        && now - groups.edits_checked_at >= GROUP_REBUILD_SECS
    {
        groups.follow_edits(hierarchy, now);
    }

    let start = Instant::now();
    let mut wanted = core::mem::take(&mut groups.wanted);
    let mut order = core::mem::take(&mut groups.build_order);
    let cut_known = cut.layout == Some(version);
    if cut_known {
        wanted_boxes(&cut, hierarchy, &mut wanted);
    } else {
        wanted.clear();
    }
    build_order(&cut, hierarchy, &wanted, &mut order);
    for &node in &wanted {
        if let Some(g) = groups.nodes[node as usize].as_mut() {
            g.wanted_at = now;
        }
    }
    groups.release_idle(
        &mut commands,
        &mut models,
        now - settings.idle_secs.max(0.0),
    );
    let (built, exhausted) = groups.build_wanted(
        &order,
        &wanted,
        GroupInputs {
            hierarchy,
            table: &table,
            models: &models,
            settings: &settings,
            now,
        },
        start,
    );
    groups.wanted = wanted;
    groups.build_order = order;
    for node in core::mem::take(&mut groups.releasing) {
        groups.release(node, &mut commands, &mut models);
    }
    let due = groups
        .published_at
        .is_none_or(|at| now - at >= GROUP_PUBLISH_SECS);
    if !groups.pending.is_empty() && (exhausted || due) {
        groups.published_at = Some(now);
        for b in core::mem::take(&mut groups.pending) {
            // Shaded like its first tree.
            let shading = table
                .entities
                .get(b.first_tree as usize)
                .and_then(|&e| shadings.get(e).ok())
                .copied()
                .unwrap_or_else(|| TreeShading::of_model(&b.model));
            if let Some(old) = groups.nodes[b.node].take() {
                groups.vertices -= old.vertices;
                commands.entity(old.entity).try_despawn();
                models.remove(&old.model);
            }
            let impostor = spawn_impostor(
                &mut commands,
                &mut models,
                b.node,
                b.origin,
                b.model,
                shading,
            );
            groups.vertices += impostor.vertices;
            groups.nodes[b.node] = Some(GroupImpostor {
                wanted_at: now,
                ..impostor
            });
        }
    }
    groups.building = !cut_known || !exhausted || !groups.pending.is_empty();
    groups.build_ms = start.elapsed().as_secs_f32() * 1000.0;
    if built > 0 {
        debug!(
            "built {built} group impostors in {:.1} ms ({} in all, {} vertices)",
            groups.build_ms,
            groups.len(),
            groups.vertices
        );
    }
}

/// What building a box's group model reads.
#[derive(Clone, Copy)]
struct GroupInputs<'a> {
    hierarchy: &'a BoxHierarchy,
    table: &'a ForestInstances,
    models: &'a Assets<TreeModel>,
    settings: &'a GroupImpostorSettings,
    /// This frame's `Time<Real>` seconds.
    now: f32,
}

impl GroupImpostors {
    /// Despawns every group impostor and forgets what they were built for.
    fn release_all(&mut self, commands: &mut Commands, models: &mut Assets<TreeModel>) {
        for old in self.nodes.drain(..).flatten() {
            commands.entity(old.entity).try_despawn();
            models.remove(&old.model);
        }
        self.unbuildable.clear();
        self.unfit = None;
        self.pending.clear();
        self.vertices = 0;
        self.built = None;
        self.building = false;
        self.full_logged = false;
        self.stopped_at_budget = false;
    }

    /// Releases box `node`'s group impostor, if it has one.
    fn release(&mut self, node: usize, commands: &mut Commands, models: &mut Assets<TreeModel>) {
        if let Some(old) = self.nodes.get_mut(node).and_then(Option::take) {
            self.stopped_at_budget = false;
            self.vertices -= old.vertices;
            commands.entity(old.entity).try_despawn();
            models.remove(&old.model);
        }
    }

    /// Releases the group impostors last wanted before `before` (`Time<Real>` seconds).
    fn release_idle(
        &mut self,
        commands: &mut Commands,
        models: &mut Assets<TreeModel>,
        before: f32,
    ) {
        for node in 0..self.nodes.len() {
            if self.nodes[node]
                .as_ref()
                .is_some_and(|g| g.wanted_at < before)
            {
                self.release(node, commands, models);
            }
        }
    }

    /// Marks the group impostors of the boxes whose trees changed since last time stale
    /// (rebuilt when next wanted, shown until then), and lets those boxes be tried again.
    fn follow_edits(&mut self, hierarchy: &BoxHierarchy, now: f32) {
        for node in 0..self.nodes.len() {
            if hierarchy.node_edit(node) > self.edits_seen {
                self.unbuildable[node] = false;
                if let Some(g) = self.nodes[node].as_mut() {
                    g.stale = true;
                }
            }
        }
        let seen = self.edits_seen;
        self.pending.retain(|b| hierarchy.node_edit(b.node) <= seen);
        self.edits_seen = hierarchy.edits();
        self.edits_checked_at = now;
    }

    /// Builds the group models of the `wanted` boxes (sorted) that have none or a stale
    /// one, in the order `order` lists them, into `pending`, until the frame's building
    /// time is spent (at least one a frame) or the vertex budget is reached (releasing the
    /// impostors wanted longest ago, not this frame, to make room). Returns how many it
    /// built and whether every wanted box is now built or cannot be.
    fn build_wanted(
        &mut self,
        order: &[u32],
        wanted: &[u32],
        inputs: GroupInputs,
        start: Instant,
    ) -> (usize, bool) {
        let GroupInputs {
            hierarchy,
            table,
            models,
            settings,
            now,
        } = inputs;
        let spend = settings.build_ms_per_frame.max(0.0) / 1000.0;
        let evict_before = now - EVICT_IDLE_SECS;
        let mut far_first: HashMap<AssetId<TreeModel>, Vec<u32>> = HashMap::default();
        let mut built = 0;
        let mut pending_vertices: usize =
            self.pending.iter().map(|b| model_vertices(&b.model)).sum();
        let mut freed = 0;
        for &node in order {
            let node = node as usize;
            let needs = self.nodes[node].as_ref().is_none_or(|g| g.stale)
                && !self.unbuildable[node]
                && !self.pending.iter().any(|b| b.node == node);
            if !needs {
                continue;
            }
            // Once a model found no room, none is built until that much room could be
            // made: building models (1–3 ms each) to throw them away every frame was the
            // largest part of a frame at the vertex budget.
            if let Some(unfit) = self.unfit
                && self.room(
                    settings.max_vertices as usize,
                    pending_vertices,
                    wanted,
                    evict_before,
                ) < unfit
            {
                return (built, true);
            }
            if built > 0 && start.elapsed().as_secs_f32() >= spend {
                return (built, false);
            }
            let trees = hierarchy.node_instances(node);
            let bounds = hierarchy.node_bounds(node);
            if trees.len() < settings.min_trees.max(1) as usize || bounds.is_empty() {
                self.unbuildable[node] = true;
                continue;
            }
            if far_first.is_empty() {
                for id in &table.model_ids {
                    if let Some(model) = models.get(*id) {
                        far_first.insert(*id, model.far_first_leaves());
                    }
                }
            }
            let origin = Vec3::new(bounds.center().x, bounds.min.y, bounds.center().z);
            let members = members_around(table, models, &far_first, trees, origin);
            let model = match group_impostor_model(&members, &settings.model_options()) {
                Ok(model) => model,
                Err(error) => {
                    warn!(
                        "group impostor of culling box {node} ({} trees): {error}",
                        trees.len()
                    );
                    self.unbuildable[node] = true;
                    continue;
                }
            };
            built += 1;
            self.builds += 1;
            let replaced = self.nodes[node].as_ref().map_or(0, |g| g.vertices);
            let needed = (self.vertices + pending_vertices + model_vertices(&model))
                .saturating_sub(replaced + freed);
            let over = needed.saturating_sub(settings.max_vertices as usize);
            let made = if over > 0 {
                self.make_room(over, wanted, evict_before)
            } else {
                Some(0)
            };
            let Some(made) = made else {
                let vertices = model_vertices(&model);
                self.unfit = Some(self.unfit.map_or(vertices, |v| v.min(vertices)));
                self.stopped_at_budget = true;
                if !self.full_logged {
                    self.full_logged = true;
                    info!(
                        "group impostors stop at culling box {node} (level {}): GroupImpostorSettings::max_vertices ({}) reached by the boxes in view",
                        hierarchy.level_of(node),
                        settings.max_vertices
                    );
                }
                return (built, true);
            };
            freed += made;
            self.unfit = None;
            pending_vertices += model_vertices(&model);
            self.pending.push(Built {
                node,
                origin,
                model,
                first_tree: trees[0],
            });
        }
        (built, true)
    }

    /// The vertices a model could have within `max_vertices`: what the built and `pending`
    /// ones leave, and what releasing the impostors [evictable](Self::evictable) would free.
    fn room(&self, max_vertices: usize, pending: usize, wanted: &[u32], before: f32) -> usize {
        let releasable: usize = self.evictable(wanted, before).map(|(.., v)| v).sum();
        max_vertices.saturating_sub(self.vertices + pending) + releasable
    }

    /// `(wanted_at, node, vertices)` of the impostors that may be released to make room:
    /// not `wanted` this frame, not already releasing, and last wanted before `before`
    /// (`Time<Real>` seconds). An impostor wanted a moment ago is kept: a swaying view
    /// wants it again, and releasing it to build another would rebuild the two in turn
    /// every frame.
    fn evictable<'a>(
        &'a self,
        wanted: &'a [u32],
        before: f32,
    ) -> impl Iterator<Item = (f32, usize, usize)> + 'a {
        self.nodes
            .iter()
            .enumerate()
            .filter_map(|(node, g)| g.as_ref().map(|g| (g.wanted_at, node, g.vertices)))
            .filter(move |&(at, node, _)| {
                at < before
                    && wanted.binary_search(&(node as u32)).is_err()
                    && !self.releasing.contains(&node)
            })
    }

    /// Picks for release (into `releasing`), wanted longest ago first, impostors
    /// [evictable](Self::evictable) until `over` vertices are freed; how many it frees, or
    /// `None` (and picks none) when those impostors do not free enough.
    fn make_room(&mut self, over: usize, wanted: &[u32], before: f32) -> Option<usize> {
        let mut idle: Vec<(f32, usize, usize)> = self.evictable(wanted, before).collect();
        if idle.iter().map(|i| i.2).sum::<usize>() < over {
            return None;
        }
        idle.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut freed = 0;
        for (_, node, vertices) in idle {
            if freed >= over {
                break;
            }
            self.releasing.push(node);
            freed += vertices;
        }
        Some(freed)
    }
}

fn model_vertices(model: &TreeModel) -> usize {
    model.trunk_positions.len() + model.leaf_positions.len()
}

/// Into `wanted` (sorted, without repeats): the boxes of the culling hierarchy last
/// frame's cut reached, and the children in view of those it drew as group impostors
/// (where it refines next).
fn wanted_boxes(cut: &HierarchicalCut, boxes: &BoxHierarchy, wanted: &mut Vec<u32>) {
    wanted.clear();
    for (node, selection) in cut.boxes.iter().zip(&cut.selection) {
        let Some(node) = *node else {
            continue;
        };
        wanted.push(node);
        if matches!(selection, NodeSelection::Impostor(_))
            && let Some(children) = boxes.children(node as usize)
        {
            wanted.extend(
                children
                    .filter(|&c| {
                        boxes.node_visibility(c) != crate::culling::NodeVisibility::Outside
                    })
                    .map(|c| c as u32),
            );
        }
    }
    wanted.retain(|&node| (node as usize) < boxes.node_count());
    wanted.sort_unstable();
    wanted.dedup();
}

/// Into `order`: the `wanted` boxes (sorted) in the order their group impostors are
/// built. First the children of the boxes last frame's cut drew as their best group
/// impostor, the most valuable box's first: the cut opens those boxes once their children
/// have their group impostors ([`ImpostorStatus::Coming`]), so these builds are what
/// lets it refine where the forest is near. Then the rest, coarsest first.
fn build_order(cut: &HierarchicalCut, boxes: &BoxHierarchy, wanted: &[u32], order: &mut Vec<u32>) {
    order.clear();
    let mut opening: Vec<(f32, u32)> = cut
        .boxes
        .iter()
        .zip(&cut.selection)
        .enumerate()
        .filter_map(|(i, (node, selection))| match (*node, selection) {
            (Some(node), NodeSelection::Impostor(0)) if i < cut.hierarchy.len() => {
                let best = cut.hierarchy.impostors(i as u32).first();
                Some((best.map_or(0.0, |level| level.benefit), node))
            }
            _ => None,
        })
        .collect();
    opening.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (_, node) in opening {
        if let Some(children) = boxes.children(node as usize) {
            order.extend(
                children
                    .map(|c| c as u32)
                    .filter(|c| wanted.binary_search(c).is_ok()),
            );
        }
    }
    let mut first: Vec<u32> = order.clone();
    first.sort_unstable();
    first.dedup();
    order.extend(
        wanted
            .iter()
            .copied()
            .filter(|node| first.binary_search(node).is_err()),
    );
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
        wanted_at: 0.0,
        stale: false,
    }
}
