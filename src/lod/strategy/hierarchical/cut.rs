//! The hierarchical strategy's frame: the visible part of the culling box hierarchy as a
//! Mason–Blake [`LodHierarchy`] — boxes with group impostors over trees over their trunk
//! and leaves — solved from last frame's cut, and the cut read back as what to draw.

use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use crate::budget::{HierarchicalLod, HierarchyOutcome, LodHierarchy, NodeId, NodeSelection};
use crate::culling::{BoxHierarchy, NodeVisibility};
use crate::lod::group_impostors::ImpostorStatus;
use crate::lod::search::Rungs;
use crate::lod::value::{Object, Part, VisibleTree};
use crate::lod::{LadderEntry, RUNG_FRACTIONS};

/// An object's or a group impostor's rungs, and the time each rung's search is given
/// (for a group impostor: the fraction of its full detail).
pub(super) type SearchedRungs = (Rungs, [f32; RUNG_FRACTIONS.len()]);

/// Who a node of this frame's hierarchy is, across frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Key {
    /// A box of the culling hierarchy.
    Box(u32),
    /// A tree, as the parent of its trunk and leaves.
    Tree(Entity),
    /// One object of the hand-out.
    Object(Entity, Part),
}

/// What a node of this frame's hierarchy stands for.
#[derive(Clone, Copy, Debug)]
enum What {
    /// Object `i` of the hand-out.
    Object(u32),
    /// A tree's two objects.
    Tree,
    /// A culling box (with or without a group impostor).
    Box(u32),
}

/// One representation the cut draws.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Drawn {
    /// Object `object` at rung `level`, its search given `time`.
    Object {
        /// Index into the frame's objects.
        object: u32,
        /// Its rung.
        level: u32,
        /// Time its search is given.
        time: f32,
    },
    /// The group impostor of box `node`, at `fraction` of its full detail.
    Impostor {
        /// The box.
        node: u32,
        /// Its rung.
        level: u32,
        /// Fraction of its full detail.
        fraction: f32,
    },
}

/// The last frame's cut of the [`StrategyKind::Hierarchical`](crate::lod::StrategyKind::Hierarchical)
/// strategy, as the solver saw it: for inspection and tests (for example re-solving
/// `hierarchy` from `seed` with a fresh [`HierarchicalLod`] gives `selection`).
#[derive(Resource, Default, Debug)]
pub(crate) struct HierarchicalCut {
    /// The frame's hierarchy: visible boxes (with their group impostors' rungs) over
    /// visible trees over their trunk and leaves objects (each with its rungs).
    pub hierarchy: LodHierarchy,
    /// Where the solve started: last frame's selection carried over by node identity.
    pub seed: Vec<NodeSelection>,
    /// The rendering time it was solved for, seconds.
    pub rendering: f32,
    /// How each node ended up represented.
    pub selection: Vec<NodeSelection>,
    /// Per node, the culling box it stands for (`None` for a tree or one of its parts).
    /// A box without children here was added alone, below last frame's cut.
    pub boxes: Vec<Option<u32>>,
    /// Not even the coarsest cut fitted the rendering time: the solver left the scene to
    /// its imaginary empty item, and the coarsest cut (every top-level box's cheapest
    /// group impostor, or its children's) was drawn instead, overrunning.
    pub coarsest_forced: bool,
    /// The culling hierarchy's version `boxes` index
    /// ([`ForestCulling::hierarchy_version`](crate::culling::ForestCulling::hierarchy_version)).
    pub layout: Option<u64>,
}

/// The hierarchical strategy's state, kept between frames.
#[derive(Default)]
pub(super) struct HierarchicalFrame {
    lod: HierarchicalLod,
    hierarchy: LodHierarchy,
    keys: Vec<Key>,
    what: Vec<What>,
    times: Vec<[f32; RUNG_FRACTIONS.len()]>,
    /// Last frame's selection by node identity.
    previous: HashMap<Key, NodeSelection>,
    /// Per box, its visible trees' summed value and full-detail cost when it was last
    /// added with its trees.
    box_totals: HashMap<u32, (f32, f32)>,
    /// The culling hierarchy `previous` and `box_totals` are for
    /// ([`ForestCulling::hierarchy_version`](crate::culling::ForestCulling::hierarchy_version)).
    layout: Option<u64>,
    seed: Vec<NodeSelection>,
    /// Per instance of the table, its visible tree (or `u32::MAX`).
    tree_of_instance: Vec<u32>,
    /// Per visible tree, its trunk and leaves objects (or `u32::MAX`).
    tree_objects: Vec<[u32; 2]>,
    /// This frame's cut.
    pub(super) drawn: Vec<Drawn>,
    /// A box stayed alone this frame waiting for a child's group impostor.
    waiting: bool,
}

const NONE: u32 = u32::MAX;

/// Whether box `node` is in view, and then whether it is entirely inside (its children
/// too: culling does not test below a box entirely inside, so `inside` carries it down).
/// `None` for a box out of view or without trees.
fn in_view(boxes: &BoxHierarchy, node: usize, inside: bool) -> Option<bool> {
    if boxes.node_bounds(node).is_empty() {
        return None;
    }
    match boxes.node_visibility(node) {
        _ if inside => Some(true),
        NodeVisibility::Full => Some(true),
        NodeVisibility::Partial => Some(false),
        NodeVisibility::Outside | NodeVisibility::Untested => None,
    }
}

/// What one frame's solve did.
#[derive(Clone, Copy, Debug)]
pub(super) struct CutOutcome {
    /// The solver's totals (for the coarsest cut when nothing fitted).
    pub(super) solved: HierarchyOutcome,
    /// Group impostors in the cut.
    pub(super) impostors_drawn: u32,
    /// Not even the coarsest cut fitted: the solver left the scene empty and the coarsest
    /// cut is drawn instead.
    pub(super) scene_dropped: bool,
    /// A box stayed its group impostor waiting for a child's ([`ImpostorStatus::Coming`]):
    /// the cut may refine once it is built.
    pub(super) waiting: bool,
}

/// How a box enters a frame's hierarchy ([`HierarchicalFrame::entry`]).
enum Entry {
    /// With what is under it in view; whether it was drawn as its group impostor last
    /// frame (its children are then under one).
    Opened { was_impostor: bool },
    /// Alone, as a leaf with its group impostor's rungs; `waiting` for a child's group
    /// impostor to open.
    Alone { waiting: bool },
}

/// What one frame of the strategy needs from the stage.
pub(super) struct HierarchyInputs<'a> {
    pub(super) boxes: Option<&'a BoxHierarchy>,
    pub(super) instances: usize,
    pub(super) trees: &'a [VisibleTree],
    pub(super) objects: &'a [Object],
    pub(super) values: &'a [f32],
    pub(super) ladders: &'a [LadderEntry],
    pub(super) rendering: f32,
    /// The version of the boxes (a new hierarchy forgets last frame's cut; trees planted
    /// or felled do not).
    pub(super) layout: Option<u64>,
    /// Where box `node`'s group impostor stands.
    pub(super) status: &'a dyn Fn(usize) -> ImpostorStatus,
}

impl HierarchicalFrame {
    /// Builds this frame's hierarchy, solves it from last frame's cut and leaves the cut
    /// in [`drawn`](Self::drawn). `object_rungs(i)` are object `i`'s rungs; `impostor_rungs(node,
    /// value, full)` the group impostor's of box `node` (`None` without one), given its
    /// visible trees' summed value and full-detail cost.
    pub(super) fn solve(
        &mut self,
        inputs: &HierarchyInputs,
        object_rungs: &mut dyn FnMut(usize) -> SearchedRungs,
        impostor_rungs: &mut dyn FnMut(usize, f32, f32) -> Option<SearchedRungs>,
        cut: &mut HierarchicalCut,
    ) -> CutOutcome {
        self.hierarchy = LodHierarchy::new();
        self.keys.clear();
        self.what.clear();
        self.times.clear();
        if self.layout != inputs.layout {
            self.layout = inputs.layout;
            self.previous.clear();
            self.box_totals.clear();
        }
        self.tree_of_instance.clear();
        self.tree_of_instance.resize(inputs.instances, NONE);
        for (t, tree) in inputs.trees.iter().enumerate() {
            if let Some(slot) = self.tree_of_instance.get_mut(tree.instance as usize) {
                *slot = t as u32;
            }
        }
        self.tree_objects.clear();
        self.tree_objects.resize(inputs.trees.len(), [NONE; 2]);
        self.waiting = false;
        let mut loose = Vec::new();
        for (i, object) in inputs.objects.iter().enumerate() {
            match object.part {
                Part::Trunk => self.tree_objects[object.index as usize][0] = i as u32,
                Part::Leaves => self.tree_objects[object.index as usize][1] = i as u32,
                Part::Mesh => loose.push(i),
            }
        }
        let mut built = Builder {
            frame: self,
            inputs,
            object_rungs,
            impostor_rungs,
        };
        if let Some(boxes) = inputs.boxes {
            built.add_box(boxes, 0, false, false);
        } else {
            for t in 0..inputs.trees.len() {
                built.add_tree(t);
            }
        }
        for i in loose {
            built.add_object(i);
        }

        // (Taken out and put back to keep its allocation.)
        let mut seed = core::mem::take(&mut self.seed);
        seed.clear();
        seed.extend(self.remembered());
        self.seed = seed;
        let mut outcome = self
            .lod
            .solve_from(&self.hierarchy, inputs.rendering, &self.seed);

        // The cut, and the selection to start from next frame.
        self.previous.clear();
        self.drawn.clear();
        let scene_dropped = self
            .hierarchy
            .top_level()
            .any(|n| self.lod.selection(n) == NodeSelection::Hidden);
        if scene_dropped {
            // Nothing fitted, not even the coarsest cut: the scene was left to Mason &
            // Blake's imaginary empty item. Nothing visible is dropped here: last frame's
            // cut is drawn a box level coarser and at its cheapest, overrunning. Falling
            // to the coarsest cut at once would show the forest as its root box's one
            // group impostor after a single starved frame, and the cut would then refine
            // again a box level a frame; a lasting starvation still gets there.
            let top: Vec<NodeId> = self.hierarchy.top_level().collect();
            outcome.cost = 0.0;
            outcome.benefit = 0.0;
            for node in top {
                self.coarser_than_last_cut(node, &mut outcome);
            }
        } else {
            for node in 0..self.hierarchy.len() as NodeId {
                let selection = self.lod.selection(node);
                self.previous.insert(self.keys[node as usize], selection);
                if let NodeSelection::Impostor(level) = selection {
                    self.draw(node, level);
                }
            }
        }
        // What was drawn: the solver's selection, or the coarsest cut forced over it.
        cut.selection.clear();
        cut.selection.extend(self.remembered());
        cut.boxes.clear();
        cut.boxes.extend(self.what.iter().map(|what| match *what {
            What::Box(node) => Some(node),
            What::Object(_) | What::Tree => None,
        }));
        cut.rendering = inputs.rendering;
        cut.coarsest_forced = scene_dropped;
        cut.layout = inputs.layout;
        core::mem::swap(&mut cut.hierarchy, &mut self.hierarchy);
        core::mem::swap(&mut cut.seed, &mut self.seed);
        CutOutcome {
            impostors_drawn: self
                .drawn
                .iter()
                .filter(|d| matches!(d, Drawn::Impostor { .. }))
                .count() as u32,
            solved: outcome,
            scene_dropped,
            waiting: self.waiting,
        }
    }

    /// Per node of this frame's hierarchy, the selection `previous` holds for it
    /// (hidden when none).
    fn remembered(&self) -> impl Iterator<Item = NodeSelection> + '_ {
        self.keys.iter().map(|key| {
            self.previous
                .get(key)
                .copied()
                .unwrap_or(NodeSelection::Hidden)
        })
    }

    /// How box `node` (in view; `inside`: entirely) enters this frame's hierarchy.
    ///
    /// Alone where last frame's cut makes opening it this frame impossible: below a box
    /// drawn as its group impostor (`under_impostor`), or drawn as its group impostor at
    /// a rung it can still refine within. Its trees' value and cost are then last known
    /// ones. So the work of a frame follows the cut, not every tree in view; the cut
    /// refines by at most one box level a frame (coarsening is not limited).
    ///
    /// Alone too, waiting, where it was drawn as its best group impostor and a child in
    /// view has no group impostor yet but will have one: opened, it would be opened
    /// through that child down to every tree beneath it — thousands of trees priced at
    /// once near the top of the hierarchy, drawn at their cheapest, and collapsed again
    /// when their cost arrives.
    fn entry(
        &self,
        boxes: &BoxHierarchy,
        node: usize,
        inside: bool,
        under_impostor: bool,
        status: &dyn Fn(usize) -> ImpostorStatus,
    ) -> Entry {
        let previous = self.previous.get(&Key::Box(node as u32)).copied();
        let was_impostor = matches!(previous, Some(NodeSelection::Impostor(_)));
        let known =
            status(node) == ImpostorStatus::Built && self.box_totals.contains_key(&(node as u32));
        if !known {
            return Entry::Opened { was_impostor };
        }
        if under_impostor || matches!(previous, Some(NodeSelection::Impostor(k)) if k > 0) {
            return Entry::Alone { waiting: false };
        }
        let child_coming = was_impostor
            && boxes.children(node).is_some_and(|mut children| {
                children.any(|c| {
                    in_view(boxes, c, inside).is_some() && status(c) == ImpostorStatus::Coming
                })
            });
        if child_coming {
            Entry::Alone { waiting: true }
        } else {
            Entry::Opened { was_impostor }
        }
    }

    /// Marks in `needed` (one per instance) the instances this frame's hierarchy will
    /// add as trees: those under the boxes in view that [`entry`](Self::entry) opens
    /// down to their trees. The Value stage values only these.
    pub(super) fn needed_instances(
        &self,
        boxes: &BoxHierarchy,
        layout: Option<u64>,
        instances: usize,
        status: &dyn Fn(usize) -> ImpostorStatus,
        needed: &mut Vec<bool>,
    ) {
        needed.clear();
        needed.resize(instances, false);
        if self.layout != layout {
            needed.fill(true);
            return;
        }
        let mut stack = vec![(0usize, false, false)];
        while let Some((node, inside, under_impostor)) = stack.pop() {
            let Some(inside) = in_view(boxes, node, inside) else {
                continue;
            };
            let Entry::Opened {
                was_impostor: drawn_as_impostor,
            } = self.entry(boxes, node, inside, under_impostor, status)
            else {
                continue;
            };
            match boxes.children(node) {
                Some(range) => stack.extend(range.map(|c| (c, inside, drawn_as_impostor))),
                None => {
                    for &i in boxes.node_instances(node) {
                        if let Some(slot) = needed.get_mut(i as usize) {
                            *slot = true;
                        }
                    }
                }
            }
        }
    }

    /// Draws `node`'s subtree as last frame's cut had it (the seed), one group coarser: a
    /// box with a group impostor, opened last frame, none of whose children with a group
    /// impostor was opened, is drawn as its group (a box without one yet is passed
    /// over); the rest of the cut, at its cheapest. What the cut did not reach, at its
    /// coarsest.
    fn coarser_than_last_cut(&mut self, node: NodeId, outcome: &mut HierarchyOutcome) {
        let opened =
            |frame: &Self, n: NodeId| frame.seed.get(n as usize) == Some(&NodeSelection::Children);
        let children = self.hierarchy.children(node).to_vec();
        let is_group = |frame: &Self, n: NodeId| {
            !frame.hierarchy.impostors(n).is_empty() && !frame.hierarchy.children(n).is_empty()
        };
        let deepest = children
            .iter()
            .all(|&c| !(opened(self, c) && is_group(self, c)));
        if !opened(self, node) || children.is_empty() || (deepest && is_group(self, node)) {
            self.coarsest(node, outcome);
            return;
        }
        self.previous
            .insert(self.keys[node as usize], NodeSelection::Children);
        for child in children {
            self.coarser_than_last_cut(child, outcome);
        }
    }

    /// Draws `node`'s subtree at its coarsest: its cheapest impostor, or its children's.
    fn coarsest(&mut self, node: NodeId, outcome: &mut HierarchyOutcome) {
        let impostors = self.hierarchy.impostors(node);
        if let Some(cheapest) = impostors.last() {
            outcome.cost += f64::from(cheapest.cost);
            outcome.benefit += f64::from(cheapest.benefit);
            let level = impostors.len() as u32 - 1;
            self.previous
                .insert(self.keys[node as usize], NodeSelection::Impostor(level));
            self.draw(node, level);
        } else {
            self.previous
                .insert(self.keys[node as usize], NodeSelection::Children);
            let children = self.hierarchy.children(node).to_vec();
            for child in children {
                self.coarsest(child, outcome);
            }
        }
    }

    fn draw(&mut self, node: NodeId, level: u32) {
        let time = self.times[node as usize][level as usize];
        match self.what[node as usize] {
            What::Object(object) => self.drawn.push(Drawn::Object {
                object,
                level,
                time,
            }),
            What::Box(b) => {
                self.drawn.push(Drawn::Impostor {
                    node: b,
                    level,
                    fraction: time,
                });
            }
            What::Tree => {}
        }
    }
}

struct Builder<'f, 'i, 'a, 'l> {
    frame: &'f mut HierarchicalFrame,
    inputs: &'i HierarchyInputs<'a>,
    object_rungs: &'l mut dyn FnMut(usize) -> SearchedRungs,
    impostor_rungs: &'l mut dyn FnMut(usize, f32, f32) -> Option<SearchedRungs>,
}

/// A node added: its id, its visible trees' summed value and full-detail cost.
type Added = (NodeId, f32, f32);

impl Builder<'_, '_, '_, '_> {
    fn push(&mut self, key: Key, what: What, times: [f32; RUNG_FRACTIONS.len()]) {
        self.frame.keys.push(key);
        self.frame.what.push(what);
        self.frame.times.push(times);
    }

    fn add_object(&mut self, i: usize) -> Option<Added> {
        let (levels, times) = (self.object_rungs)(i);
        let node = self.frame.hierarchy.add_object(&levels).ok()?;
        let object = self.inputs.objects[i];
        let entity = match object.part {
            Part::Mesh => self.inputs.ladders[object.index as usize].entity,
            _ => self.inputs.trees[object.index as usize].entity,
        };
        self.push(
            Key::Object(entity, object.part),
            What::Object(i as u32),
            times,
        );
        Some((node, self.inputs.values[i], levels[0].cost))
    }

    fn add_tree(&mut self, t: usize) -> Option<Added> {
        let [trunk, leaves] = self.frame.tree_objects[t];
        let parts: Vec<Added> = [trunk, leaves]
            .into_iter()
            .filter(|&o| o != NONE)
            .filter_map(|o| self.add_object(o as usize))
            .collect();
        self.add_parent(
            Key::Tree(self.inputs.trees[t].entity),
            What::Tree,
            &parts,
            None,
        )
    }

    /// A parent over `children`; one child without impostors of its own is that child.
    fn add_parent(
        &mut self,
        key: Key,
        what: What,
        children: &[Added],
        impostors: Option<SearchedRungs>,
    ) -> Option<Added> {
        let value = children.iter().map(|c| c.1).sum();
        let full = children.iter().map(|c| c.2).sum();
        if impostors.is_none() && children.len() <= 1 {
            return children.first().copied();
        }
        let ids: Vec<NodeId> = children.iter().map(|c| c.0).collect();
        let (levels, times) = impostors.map_or(
            (
                [crate::budget::Level::new(0.0, 0.0); RUNG_FRACTIONS.len()],
                [0.0; RUNG_FRACTIONS.len()],
            ),
            |l| l,
        );
        let levels = if impostors.is_some() {
            &levels[..]
        } else {
            &[]
        };
        let node = self.frame.hierarchy.add_group(&ids, levels).ok()?;
        self.push(key, what, times);
        Some((node, value, full))
    }

    /// Adds box `node` in view and what is in view under it — or, where
    /// [`HierarchicalFrame::entry`] says so, the box alone.
    fn add_box(
        &mut self,
        boxes: &BoxHierarchy,
        node: usize,
        inside: bool,
        under_impostor: bool,
    ) -> Option<Added> {
        let inside = in_view(boxes, node, inside)?;
        let key = Key::Box(node as u32);
        let drawn_as_impostor =
            match self
                .frame
                .entry(boxes, node, inside, under_impostor, self.inputs.status)
            {
                Entry::Opened { was_impostor } => was_impostor,
                Entry::Alone { waiting } => {
                    self.frame.waiting |= waiting;
                    let &(value, full) = self.frame.box_totals.get(&(node as u32))?;
                    let (levels, times) = (self.impostor_rungs)(node, value, full)?;
                    let id = self.frame.hierarchy.add_object(&levels).ok()?;
                    self.push(key, What::Box(node as u32), times);
                    return Some((id, value, full));
                }
            };
        let children: Vec<Added> = match boxes.children(node) {
            Some(range) => range
                .filter_map(|child| self.add_box(boxes, child, inside, drawn_as_impostor))
                .collect(),
            None => boxes
                .node_instances(node)
                .iter()
                .filter_map(|&i| {
                    let t = *self.frame.tree_of_instance.get(i as usize)?;
                    (t != NONE).then_some(t as usize)
                })
                .collect::<Vec<_>>()
                .into_iter()
                .filter_map(|t| self.add_tree(t))
                .collect(),
        };
        if children.is_empty() {
            return None;
        }
        let value = children.iter().map(|c| c.1).sum();
        let full = children.iter().map(|c| c.2).sum();
        self.frame.box_totals.insert(node as u32, (value, full));
        let impostors = (self.impostor_rungs)(node, value, full);
        self.add_parent(key, What::Box(node as u32), &children, impostors)
    }
}
