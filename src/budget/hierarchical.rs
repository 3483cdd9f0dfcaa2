//! Mason & Blake (1997): incremental level-of-detail optimisation over a hierarchy of
//! objects in which groups may have impostors of their own, so a whole group can be
//! replaced by one cheap representation instead of dropping its members.
//!
//! Each node of a [`LodHierarchy`] is represented *explicitly* (one of its impostors),
//! *implicitly* (by its children), or not at all (beneath an explicit ancestor). The
//! explicit nodes are the leaves of the *representation tree*. Every iteration
//! increments the root — which ends in a terminal node stepping up one impostor, or an
//! explicit group opening into its children at their lowest representations — choosing
//! the terminal whose subsequent representation's highest-valued leaf has the greatest
//! `Value`; then, while the cost exceeds the budget, decrements — a terminal stepping
//! down, or a group whose children are all at their lowest collapsing into its best
//! impostor — choosing the one whose current highest-valued leaf has the lowest `Value`.
//! It stops when the cost fits and nothing can be incremented, when the cost exceeds the
//! budget and nothing can be decremented, or when the node just incremented is
//! decremented. Each node stores the deciding values of its subtree, updated post-order
//! along the changed path, so a step costs O(depth × fan-out).
//!
//! The scene starts represented by an imaginary item of no cost and no benefit at the
//! (virtual) root; later frames start from the previous frame's representation.

use super::problem::{
    Allocation, BudgetProblem, BudgetStats, BudgetStrategy, Level, PreviousSelection, sanitize_time,
};

/// Index of a node in a [`LodHierarchy`].
pub(crate) type NodeId = u32;

const NONE: u32 = u32::MAX;

/// Why a node was refused by [`LodHierarchy`].
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub(crate) enum HierarchyError {
    /// A leaf object without impostors cannot be represented.
    #[error("node {node}: a leaf object needs at least one impostor")]
    LeafWithoutImpostor {
        /// The node it would have been.
        node: NodeId,
    },
    /// An impostor with a NaN, infinite or negative cost or benefit.
    #[error("node {node}, impostor {impostor}: cost and benefit must be finite and non-negative")]
    InvalidImpostor {
        /// The node it would have been.
        node: NodeId,
        /// Index of the impostor.
        impostor: usize,
    },
    /// Impostors must run best → cheapest, like every ladder.
    #[error(
        "node {node}, impostor {impostor}: costs must not increase (impostors run best → cheapest)"
    )]
    CostsIncreasing {
        /// The node it would have been.
        node: NodeId,
        /// Index of the impostor.
        impostor: usize,
    },
    /// A child that does not exist (yet) or already has a parent.
    #[error("node {node}: child {child} does not exist or already belongs to a group")]
    BadChild {
        /// The group it would have been.
        node: NodeId,
        /// The offending child.
        child: NodeId,
    },
}

/// A hierarchy of objects and groups with impostors, best → cheapest per node.
///
/// Build it bottom-up: [`add_object`](Self::add_object) for leaves, then
/// [`add_group`](Self::add_group) over existing parentless nodes. Parentless nodes hang
/// from a virtual root.
#[derive(Clone, Debug, Default)]
pub(crate) struct LodHierarchy {
    parent: Vec<u32>,
    child_start: Vec<u32>,
    child_end: Vec<u32>,
    children: Vec<u32>,
    impostor_start: Vec<u32>,
    impostors: Vec<Level>,
}

impl LodHierarchy {
    /// An empty hierarchy.
    pub(crate) fn new() -> Self {
        Self {
            impostor_start: vec![0],
            ..Self::default()
        }
    }

    /// Number of nodes.
    pub(crate) fn len(&self) -> usize {
        self.parent.len()
    }

    /// Adds a leaf object with its impostors (best → cheapest, at least one).
    pub(crate) fn add_object(&mut self, impostors: &[Level]) -> Result<NodeId, HierarchyError> {
        let node = self.len() as NodeId;
        if impostors.is_empty() {
            return Err(HierarchyError::LeafWithoutImpostor { node });
        }
        self.add_node(&[], impostors)
    }

    /// Adds a group over `children` (existing nodes without a parent) with its own
    /// impostors, best → cheapest; a group may have none, and is then always represented
    /// by its children.
    pub(crate) fn add_group(
        &mut self,
        children: &[NodeId],
        impostors: &[Level],
    ) -> Result<NodeId, HierarchyError> {
        let node = self.len() as NodeId;
        if children.is_empty() && impostors.is_empty() {
            return Err(HierarchyError::LeafWithoutImpostor { node });
        }
        for (i, &child) in children.iter().enumerate() {
            let exists = (child as usize) < self.len();
            if !exists || self.parent[child as usize] != NONE || children[..i].contains(&child) {
                return Err(HierarchyError::BadChild { node, child });
            }
        }
        let node = self.add_node(children, impostors)?;
        for &child in children {
            self.parent[child as usize] = node;
        }
        Ok(node)
    }

    fn add_node(
        &mut self,
        children: &[NodeId],
        impostors: &[Level],
    ) -> Result<NodeId, HierarchyError> {
        let node = self.len() as NodeId;
        for (impostor, l) in impostors.iter().enumerate() {
            let ok =
                l.cost.is_finite() && l.benefit.is_finite() && l.cost >= 0.0 && l.benefit >= 0.0;
            if !ok {
                return Err(HierarchyError::InvalidImpostor { node, impostor });
            }
            if impostor > 0 && l.cost > impostors[impostor - 1].cost {
                return Err(HierarchyError::CostsIncreasing { node, impostor });
            }
        }
        if self.impostor_start.is_empty() {
            self.impostor_start.push(0);
        }
        self.parent.push(NONE);
        self.child_start.push(self.children.len() as u32);
        self.children.extend_from_slice(children);
        self.child_end.push(self.children.len() as u32);
        self.impostors.extend_from_slice(impostors);
        self.impostor_start.push(self.impostors.len() as u32);
        Ok(node)
    }

    /// The node's parent, `None` for a top-level node.
    pub(crate) fn parent(&self, node: NodeId) -> Option<NodeId> {
        let p = self.parent[node as usize];
        (p != NONE).then_some(p)
    }

    /// The node's children.
    pub(crate) fn children(&self, node: NodeId) -> &[NodeId] {
        let (s, e) = (
            self.child_start[node as usize],
            self.child_end[node as usize],
        );
        &self.children[s as usize..e as usize]
    }

    /// The node's impostors, best → cheapest.
    pub(crate) fn impostors(&self, node: NodeId) -> &[Level] {
        let (s, e) = (
            self.impostor_start[node as usize],
            self.impostor_start[node as usize + 1],
        );
        &self.impostors[s as usize..e as usize]
    }

    /// Nodes without a parent.
    pub(crate) fn top_level(&self) -> impl Iterator<Item = NodeId> + '_ {
        (0..self.len() as NodeId).filter(|&n| self.parent[n as usize] == NONE)
    }
}

/// How a node is represented after [`HierarchicalLod::solve`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NodeSelection {
    /// Drawn as this impostor (index into its impostors, best → cheapest).
    Impostor(u32),
    /// Represented by its children.
    Children,
    /// Beneath an explicit ancestor, or the whole scene is the imaginary empty item.
    Hidden,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Hidden,
    Explicit(u32),
    Implicit,
}

/// Per-node aggregates over its subtree.
#[derive(Clone, Copy, Debug)]
struct Aggregate {
    inc_value: f32,
    inc_node: u32,
    dec_value: f32,
    dec_node: u32,
    leaf_max: f32,
    at_lowest: bool,
}

const EMPTY: Aggregate = Aggregate {
    inc_value: f32::NEG_INFINITY,
    inc_node: NONE,
    dec_value: f32::INFINITY,
    dec_node: NONE,
    leaf_max: f32::NEG_INFINITY,
    at_lowest: true,
};

/// The Mason–Blake incremental hierarchical optimiser. Keeps the representation between
/// frames: call [`solve`](Self::solve) every frame with the same hierarchy shape, or
/// [`reset`](Self::reset) when the hierarchy changes.
#[derive(Clone, Debug)]
pub(crate) struct HierarchicalLod {
    /// Compare the result with the best single impostor shown with everything else at its
    /// cheapest representation, and keep the better (Mason & Blake's fix of the greedy's
    /// half-optimality guarantee). Default: `true`.
    pub half_optimality_fix: bool,
    state: Vec<State>,
    aggregate: Vec<Aggregate>,
    open_value: Vec<f32>,
    cost: f64,
    benefit: f64,
    iterations: u32,
    /// The virtual root's children (the hierarchy's parentless nodes), cached per solve.
    top: Vec<NodeId>,
    flat: LodHierarchy,
}

impl Default for HierarchicalLod {
    fn default() -> Self {
        Self {
            half_optimality_fix: true,
            state: Vec::new(),
            aggregate: Vec::new(),
            open_value: Vec::new(),
            cost: 0.0,
            benefit: 0.0,
            iterations: 0,
            top: Vec::new(),
            flat: LodHierarchy::new(),
        }
    }
}

/// Totals of one [`HierarchicalLod::solve`].
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct HierarchyOutcome {
    /// Predicted cost of the representation.
    pub cost: f64,
    /// Its benefit.
    pub benefit: f64,
    /// Increment/decrement iterations taken.
    pub iterations: u32,
}

impl HierarchicalLod {
    /// An optimiser that starts from the imaginary empty item.
    #[cfg(any(test, feature = "testing"))]
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// How `node` is represented.
    pub(crate) fn selection(&self, node: NodeId) -> NodeSelection {
        match self.state.get(node as usize) {
            Some(State::Explicit(k)) => NodeSelection::Impostor(*k),
            Some(State::Implicit) => NodeSelection::Children,
            _ => NodeSelection::Hidden,
        }
    }

    /// Chooses a representation of `hierarchy` costing at most `budget` where possible.
    pub(crate) fn solve(&mut self, hierarchy: &LodHierarchy, budget: f32) -> HierarchyOutcome {
        let budget = f64::from(sanitize_time(budget));
        let root = hierarchy.len();
        let fresh = self.state.len() != root + 1;
        if fresh {
            self.state.clear();
            self.state.resize(root + 1, State::Hidden);
            self.state[root] = State::Explicit(0);
        }
        self.prepare(hierarchy);
        self.run(hierarchy, budget);
        if self.half_optimality_fix {
            self.apply_single_best(hierarchy, budget);
        }
        HierarchyOutcome {
            cost: self.cost,
            benefit: self.benefit,
            iterations: self.iterations,
        }
    }

    /// Like [`solve`](Self::solve), but starting from `seed` (one entry per node of
    /// `hierarchy`, e.g. last frame's selection carried over to this frame's hierarchy by
    /// the caller's own node identities) instead of the previous solve's state: a
    /// hierarchy whose shape changes from frame to frame (nodes coming into and out of
    /// view) stays incremental.
    ///
    /// The seed is repaired into a complete representation, parents first: beneath an
    /// explicit node everything is hidden; under an open node a child keeps its seeded
    /// impostor (clamped to its ladder) or stays open when it has children, and a child
    /// seeded [`NodeSelection::Hidden`] (new this frame) starts at its cheapest impostor,
    /// or open when it has none. So every node starts represented; missing entries count
    /// as hidden.
    pub(crate) fn solve_from(
        &mut self,
        hierarchy: &LodHierarchy,
        budget: f32,
        seed: &[NodeSelection],
    ) -> HierarchyOutcome {
        let root = hierarchy.len();
        self.state.clear();
        self.state.resize(root + 1, State::Hidden);
        self.state[root] = State::Implicit;
        // Parents have higher indices than their children: walk downwards.
        for node in (0..root).rev() {
            let parent = hierarchy
                .parent(node as NodeId)
                .map_or(root, |p| p as usize);
            if self.state[parent] != State::Implicit {
                continue;
            }
            let impostors = hierarchy.impostors(node as NodeId).len() as u32;
            let has_children = !hierarchy.children(node as NodeId).is_empty();
            let cheapest = || {
                if impostors > 0 {
                    State::Explicit(impostors - 1)
                } else {
                    State::Implicit
                }
            };
            self.state[node] = match seed.get(node).copied().unwrap_or(NodeSelection::Hidden) {
                NodeSelection::Impostor(k) if impostors > 0 => {
                    State::Explicit(k.min(impostors - 1))
                }
                NodeSelection::Children if has_children => State::Implicit,
                _ => cheapest(),
            };
        }
        self.solve(hierarchy, budget)
    }

    /// Sets a starting representation from per-leaf impostor indices, opening every group
    /// above them (used to seed from last frame's flat selection).
    fn seed_leaves(&mut self, hierarchy: &LodHierarchy, leaf_levels: &[u32]) {
        let root = hierarchy.len();
        self.state.clear();
        self.state.resize(root + 1, State::Implicit);
        for (leaf, &level) in leaf_levels.iter().enumerate() {
            self.state[leaf] = State::Explicit(level);
        }
    }

    // --- structure helpers (the virtual root is node `hierarchy.len()`) ---

    fn children<'a>(&'a self, h: &'a LodHierarchy, node: usize) -> ChildIter<'a> {
        if node == h.len() {
            ChildIter(self.top.iter())
        } else {
            ChildIter(h.children(node as NodeId).iter())
        }
    }

    fn impostors<'a>(h: &'a LodHierarchy, node: usize) -> &'a [Level] {
        const IMAGINARY: &[Level] = &[Level::new(0.0, 0.0)];
        if node == h.len() {
            IMAGINARY
        } else {
            h.impostors(node as NodeId)
        }
    }

    fn parent(h: &LodHierarchy, node: usize) -> Option<usize> {
        if node == h.len() {
            None
        } else {
            Some(h.parent(node as NodeId).map_or(h.len(), |p| p as usize))
        }
    }

    fn value(h: &LodHierarchy, node: usize, impostor: u32) -> f32 {
        Self::impostors(h, node)[impostor as usize].value()
    }

    /// Recomputes `open_value`, every aggregate, and the totals from the current state.
    fn prepare(&mut self, h: &LodHierarchy) {
        self.top.clear();
        self.top.extend(h.top_level());
        let n = h.len() + 1;
        self.open_value.clear();
        self.open_value.resize(n, f32::NEG_INFINITY);
        // Children always have lower indices than their group, so index order is post-order
        // for real nodes; the virtual root comes last.
        for node in 0..n {
            let mut best = f32::NEG_INFINITY;
            for child in self.children(h, node) {
                let lowest = Self::impostors(h, child);
                let v = if lowest.is_empty() {
                    self.open_value[child]
                } else {
                    Self::value(h, child, lowest.len() as u32 - 1)
                };
                best = best.max(v);
            }
            self.open_value[node] = best;
        }
        self.aggregate.clear();
        self.aggregate.resize(n, EMPTY);
        for node in 0..n {
            self.recompute(h, node);
        }
        let (cost, benefit) = self.represented(h, n - 1);
        self.cost = cost;
        self.benefit = benefit;
    }

    /// Cost and benefit of how `node`'s subtree is represented now.
    fn represented(&self, h: &LodHierarchy, node: usize) -> (f64, f64) {
        match self.state[node] {
            State::Hidden => (0.0, 0.0),
            State::Explicit(k) => {
                let l = Self::impostors(h, node)[k as usize];
                (f64::from(l.cost), f64::from(l.benefit))
            }
            State::Implicit => self.children(h, node).fold((0.0, 0.0), |(c, b), child| {
                let (cc, cb) = self.represented(h, child);
                (c + cc, b + cb)
            }),
        }
    }

    fn recompute(&mut self, h: &LodHierarchy, node: usize) {
        let impostors = Self::impostors(h, node);
        let has_children = self.children(h, node).next().is_some();
        let mut agg = EMPTY;
        match self.state[node] {
            State::Hidden => {}
            State::Explicit(k) => {
                let last = impostors.len() as u32 - 1;
                agg.leaf_max = Self::value(h, node, k);
                agg.at_lowest = k == last;
                if k > 0 {
                    agg.inc_value = Self::value(h, node, k - 1);
                    agg.inc_node = node as u32;
                } else if has_children {
                    agg.inc_value = self.open_value[node];
                    agg.inc_node = node as u32;
                }
                if k < last {
                    agg.dec_value = agg.leaf_max;
                    agg.dec_node = node as u32;
                }
            }
            State::Implicit => {
                let mut all_lowest = true;
                for child in self.children(h, node) {
                    let c = self.aggregate[child];
                    if c.inc_value > agg.inc_value {
                        agg.inc_value = c.inc_value;
                        agg.inc_node = c.inc_node;
                    }
                    if c.dec_value < agg.dec_value {
                        agg.dec_value = c.dec_value;
                        agg.dec_node = c.dec_node;
                    }
                    agg.leaf_max = agg.leaf_max.max(c.leaf_max);
                    all_lowest &= c.at_lowest;
                }
                // A group without impostors is at its lowest when its children are; one
                // with impostors can still collapse, so it is not.
                agg.at_lowest = all_lowest && impostors.is_empty();
                if all_lowest && !impostors.is_empty() && agg.leaf_max < agg.dec_value {
                    agg.dec_value = agg.leaf_max;
                    agg.dec_node = node as u32;
                }
            }
        }
        self.aggregate[node] = agg;
    }

    fn update_upwards(&mut self, h: &LodHierarchy, mut node: usize) {
        loop {
            self.recompute(h, node);
            match Self::parent(h, node) {
                Some(p) => node = p,
                None => break,
            }
        }
    }

    /// Puts `node` at its lowest representation (recursively through impostor-less groups).
    fn set_lowest(&mut self, h: &LodHierarchy, node: usize) {
        let impostors = Self::impostors(h, node);
        if impostors.is_empty() {
            self.state[node] = State::Implicit;
            let children: Vec<usize> = self.children(h, node).collect();
            for child in children {
                self.set_lowest(h, child);
            }
        } else {
            self.state[node] = State::Explicit(impostors.len() as u32 - 1);
        }
        self.recompute(h, node);
    }

    fn hide(&mut self, h: &LodHierarchy, node: usize) {
        self.state[node] = State::Hidden;
        let children: Vec<usize> = self.children(h, node).collect();
        for child in children {
            self.hide(h, child);
        }
        self.recompute(h, node);
    }

    fn increment(&mut self, h: &LodHierarchy, node: usize) {
        let (old_cost, old_benefit) = self.represented(h, node);
        match self.state[node] {
            State::Explicit(k) if k > 0 => self.state[node] = State::Explicit(k - 1),
            State::Explicit(_) => {
                self.state[node] = State::Implicit;
                let children: Vec<usize> = self.children(h, node).collect();
                for child in children {
                    self.set_lowest(h, child);
                }
            }
            _ => return,
        }
        self.account(h, node, old_cost, old_benefit);
        self.update_upwards(h, node);
    }

    fn decrement(&mut self, h: &LodHierarchy, node: usize) {
        let (old_cost, old_benefit) = self.represented(h, node);
        match self.state[node] {
            State::Explicit(k) => self.state[node] = State::Explicit(k + 1),
            State::Implicit => {
                let children: Vec<usize> = self.children(h, node).collect();
                for child in children {
                    self.hide(h, child);
                }
                self.state[node] = State::Explicit(0);
            }
            State::Hidden => return,
        }
        self.account(h, node, old_cost, old_benefit);
        self.update_upwards(h, node);
    }

    fn account(&mut self, h: &LodHierarchy, node: usize, old_cost: f64, old_benefit: f64) {
        let (cost, benefit) = self.represented(h, node);
        self.cost += cost - old_cost;
        self.benefit += benefit - old_benefit;
    }

    fn run(&mut self, h: &LodHierarchy, budget: f64) {
        let root = h.len();
        let limit = 4 * (h.impostors.len() + h.len()) + 16;
        self.iterations = 0;
        loop {
            self.iterations += 1;
            let mut incremented = None;
            if self.cost <= budget {
                let agg = self.aggregate[root];
                if agg.inc_node == NONE {
                    break; // fits, and the root cannot increment
                }
                incremented = Some(agg.inc_node as usize);
                self.increment(h, agg.inc_node as usize);
            }
            let mut undone = false;
            while self.cost > budget {
                let agg = self.aggregate[root];
                if agg.dec_node == NONE {
                    return; // exceeds, and the root cannot decrement
                }
                undone |= incremented == Some(agg.dec_node as usize);
                self.decrement(h, agg.dec_node as usize);
            }
            if undone || self.iterations as usize >= limit {
                break;
            }
        }
    }

    /// Mason & Blake's fix: the best single impostor, with the rest of the scene at its
    /// cheapest complete representation, if that fits and beats the incremental result.
    fn apply_single_best(&mut self, h: &LodHierarchy, budget: f64) {
        let root = h.len();
        let n = root + 1;
        // Cost and benefit of each node's lowest representation.
        let mut lowest = vec![(0.0_f64, 0.0_f64); n];
        for node in 0..n {
            let imp = Self::impostors(h, node);
            lowest[node] = match imp.last() {
                Some(l) if node != root || self.children(h, node).next().is_none() => {
                    (f64::from(l.cost), f64::from(l.benefit))
                }
                _ => self.children(h, node).fold((0.0, 0.0), |(c, b), child| {
                    (c + lowest[child].0, b + lowest[child].1)
                }),
            };
        }
        let mut children_lowest = vec![(0.0_f64, 0.0_f64); n];
        for (node, &(cost, benefit)) in lowest.iter().enumerate().take(root) {
            let parent = Self::parent(h, node).unwrap_or(root);
            children_lowest[parent].0 += cost;
            children_lowest[parent].1 += benefit;
        }
        // "Everything else" when `node` is shown: its parent's everything-else plus its
        // siblings at their lowest. Parents have higher indices, so walk downwards.
        let mut others = vec![(0.0_f64, 0.0_f64); n];
        let mut best: Option<(usize, u32, f64)> = None;
        for node in (0..root).rev() {
            let parent = Self::parent(h, node).unwrap_or(root);
            let base = if parent == root {
                (0.0, 0.0)
            } else {
                others[parent]
            };
            let c = base.0 + children_lowest[parent].0 - lowest[node].0;
            let b = base.1 + children_lowest[parent].1 - lowest[node].1;
            others[node] = (c, b);
            for (k, l) in h.impostors(node as NodeId).iter().enumerate() {
                let cost = c + f64::from(l.cost);
                let benefit = b + f64::from(l.benefit);
                if cost <= budget && benefit > best.map_or(self.benefit, |(_, _, bb)| bb) {
                    best = Some((node, k as u32, benefit));
                }
            }
        }
        let Some((node, impostor, _)) = best else {
            return;
        };
        // Open the path from the root to `node`, everything beside it at its lowest.
        self.state.fill(State::Hidden);
        let mut path = vec![node];
        while let Some(p) = Self::parent(h, *path.last().unwrap()) {
            path.push(p);
        }
        for window in path.windows(2).rev() {
            let (child, parent) = (window[0], window[1]);
            self.state[parent] = State::Implicit;
            let siblings: Vec<usize> = self.children(h, parent).filter(|&s| s != child).collect();
            for s in siblings {
                self.set_lowest(h, s);
            }
        }
        self.state[node] = State::Explicit(impostor);
        self.prepare(h);
    }

    fn flat_hierarchy(&mut self, problem: &BudgetProblem) {
        const FAN_OUT: usize = 8;
        let mut h = core::mem::take(&mut self.flat);
        h.parent.clear();
        h.child_start.clear();
        h.child_end.clear();
        h.children.clear();
        h.impostors.clear();
        h.impostor_start.clear();
        h.impostor_start.push(0);
        let mut ladder = Vec::new();
        for object in 0..problem.len() {
            ladder.clear();
            ladder.extend_from_slice(problem.ladder(object));
            ladder.push(Level::new(0.0, 0.0)); // not drawn
            // Validated by `BudgetProblem::push_object`, so this cannot fail.
            let _ = h.add_node(&[], &ladder);
        }
        let mut level: Vec<NodeId> = (0..problem.len() as NodeId).collect();
        while level.len() > FAN_OUT {
            let next: Vec<NodeId> = level
                .chunks(FAN_OUT)
                .map(|chunk| h.add_group(chunk, &[]).unwrap_or(NONE))
                .collect();
            level = next;
        }
        self.flat = h;
    }
}

struct ChildIter<'a>(core::slice::Iter<'a, NodeId>);

impl Iterator for ChildIter<'_> {
    type Item = usize;
    fn next(&mut self) -> Option<usize> {
        self.0.next().map(|&c| c as usize)
    }
}

/// On a flat [`BudgetProblem`], every object becomes a leaf whose ladder ends in a
/// zero-cost "not drawn" impostor, under impostor-less groups of eight. The start is last
/// frame's selection (newly visible objects at their cheapest level), so on a flat
/// problem this behaves like Funkhouser–Séquin's incremental algorithm.
impl BudgetStrategy for HierarchicalLod {
    #[cfg(test)]
    fn name(&self) -> &'static str {
        "Mason–Blake hierarchical"
    }

    fn distribute(
        &mut self,
        problem: &BudgetProblem,
        rendering_time: f32,
        allocations: &mut Vec<Allocation>,
    ) -> BudgetStats {
        let rendering_time = sanitize_time(rendering_time);
        self.flat_hierarchy(problem);
        let h = core::mem::take(&mut self.flat);
        let seed: Vec<u32> = (0..problem.len())
            .map(|object| {
                let len = problem.ladder(object).len() as u32;
                match problem.previous(object) {
                    PreviousSelection::Level(level) => level,
                    PreviousSelection::New => len - 1,
                    PreviousSelection::Dropped => len,
                }
            })
            .collect();
        self.seed_leaves(&h, &seed);
        self.solve(&h, rendering_time);
        allocations.clear();
        allocations.extend((0..problem.len()).map(|object| {
            let ladder = problem.ladder(object);
            match self.state[object] {
                State::Explicit(k) if (k as usize) < ladder.len() => {
                    Allocation::drawn(ladder[k as usize].cost, k)
                }
                _ => Allocation::DROPPED,
            }
        }));
        self.flat = h;
        BudgetStats::from_allocations(rendering_time, allocations)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Two objects with a shared group impostor; the group impostor is cheap.
    fn scene() -> (LodHierarchy, NodeId, NodeId, NodeId) {
        let mut h = LodHierarchy::new();
        let a = h
            .add_object(&[Level::new(4.0, 8.0), Level::new(1.0, 3.0)])
            .unwrap();
        let b = h
            .add_object(&[Level::new(4.0, 8.0), Level::new(1.0, 3.0)])
            .unwrap();
        let g = h.add_group(&[a, b], &[Level::new(1.0, 4.0)]).unwrap();
        (h, a, b, g)
    }

    #[test]
    fn tight_budget_uses_the_group_impostor_instead_of_dropping() {
        let (h, a, b, g) = scene();
        let mut lod = HierarchicalLod::new();
        let out = lod.solve(&h, 1.5);
        assert_eq!(lod.selection(g), NodeSelection::Impostor(0));
        assert_eq!(lod.selection(a), NodeSelection::Hidden);
        assert_eq!(lod.selection(b), NodeSelection::Hidden);
        assert_relative_eq!(out.cost, 1.0);
        assert_relative_eq!(out.benefit, 4.0);
    }

    #[test]
    fn generous_budget_opens_the_group() {
        let (h, a, b, g) = scene();
        let mut lod = HierarchicalLod::new();
        let out = lod.solve(&h, 8.0);
        assert_eq!(lod.selection(g), NodeSelection::Children);
        assert_eq!(lod.selection(a), NodeSelection::Impostor(0));
        assert_eq!(lod.selection(b), NodeSelection::Impostor(0));
        assert_relative_eq!(out.cost, 8.0);
    }

    #[test]
    fn middle_budget_refines_one_member() {
        let (h, a, b, _) = scene();
        let mut lod = HierarchicalLod::new();
        let out = lod.solve(&h, 5.0);
        // Both at their cheapest (2), then one steps up (5): the other would make 8.
        let sel = [lod.selection(a), lod.selection(b)];
        assert!(sel.contains(&NodeSelection::Impostor(0)));
        assert!(sel.contains(&NodeSelection::Impostor(1)));
        assert_relative_eq!(out.cost, 5.0);
    }

    #[test]
    fn incremental_from_last_frame_follows_a_shrinking_budget() {
        let (h, _, _, g) = scene();
        let mut lod = HierarchicalLod::new();
        lod.solve(&h, 8.0);
        let out = lod.solve(&h, 1.0);
        assert_eq!(lod.selection(g), NodeSelection::Impostor(0));
        assert!(out.cost <= 1.0);
    }

    #[test]
    fn nothing_fits_leaves_the_imaginary_item() {
        let (h, _, _, g) = scene();
        let mut lod = HierarchicalLod::new();
        let out = lod.solve(&h, 0.5);
        assert_eq!(lod.selection(g), NodeSelection::Hidden);
        assert_eq!(out.cost, 0.0);
    }

    #[test]
    fn seeded_with_its_own_selection_it_picks_up_where_it_left() {
        let (h, a, b, g) = scene();
        let mut lod = HierarchicalLod::new();
        lod.solve(&h, 5.0);
        let seed: Vec<NodeSelection> = (0..h.len() as NodeId).map(|n| lod.selection(n)).collect();
        let mut fresh = HierarchicalLod::new();
        let out = fresh.solve_from(&h, 5.0, &seed);
        for n in [a, b, g] {
            assert_eq!(fresh.selection(n), lod.selection(n));
        }
        assert_relative_eq!(out.cost, 5.0);
    }

    #[test]
    fn a_seed_is_repaired_into_a_complete_representation() {
        let (h, a, b, g) = scene();
        // Nothing known (every node new): the group starts at its impostor, and a budget
        // that fits it keeps the region represented.
        let mut lod = HierarchicalLod::new();
        let out = lod.solve_from(&h, 1.0, &[]);
        assert_eq!(lod.selection(g), NodeSelection::Impostor(0));
        assert_relative_eq!(out.cost, 1.0);
        // An inconsistent seed (the group open, one member out of its ladder, the other
        // unknown) starts from the members' nearest valid levels.
        let seed = [
            NodeSelection::Impostor(9),
            NodeSelection::Hidden,
            NodeSelection::Children,
        ];
        let out = lod.solve_from(&h, 2.0, &seed);
        assert_eq!(lod.selection(g), NodeSelection::Children);
        assert_eq!(lod.selection(a), NodeSelection::Impostor(1));
        assert_eq!(lod.selection(b), NodeSelection::Impostor(1));
        assert_relative_eq!(out.cost, 2.0);
    }

    #[test]
    fn refuses_malformed_hierarchies() {
        let mut h = LodHierarchy::new();
        assert!(matches!(
            h.add_object(&[]),
            Err(HierarchyError::LeafWithoutImpostor { .. })
        ));
        let a = h.add_object(&[Level::new(1.0, 1.0)]).unwrap();
        assert!(matches!(
            h.add_group(&[a, 7], &[]),
            Err(HierarchyError::BadChild { child: 7, .. })
        ));
        h.add_group(&[a], &[]).unwrap();
        assert!(matches!(
            h.add_group(&[a], &[]),
            Err(HierarchyError::BadChild { .. })
        ));
        assert!(matches!(
            h.add_object(&[Level::new(1.0, 1.0), Level::new(2.0, 2.0)]),
            Err(HierarchyError::CostsIncreasing { .. })
        ));
        assert!(matches!(
            h.add_object(&[Level::new(f32::NAN, 1.0)]),
            Err(HierarchyError::InvalidImpostor { .. })
        ));
    }
}
