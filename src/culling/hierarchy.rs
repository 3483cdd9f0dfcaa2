//! The thesis' box hierarchy (§4.3): a quadtree of boxes over the populated terrain, of
//! user-chosen depth. Boxes fully inside the view mark every instance below them fully
//! visible without further tests; only instances in partially visible leaves get
//! per-part tests (whole tree box, trunk box, each leaf-group sphere).

use core::ops::Range;

use bevy::ecs::resource::Resource;
use bevy::math::{Affine3A, Mat4, Vec3, Vec3A, Vec4};

use crate::instance::LayoutEdits;
use crate::tree::{BoundingSphere, Bounds, TreeModel};

/// Where a volume lies against the view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Containment {
    /// Entirely outside one of the planes.
    Outside,
    /// Crosses at least one plane.
    Intersecting,
    /// Inside every plane.
    Inside,
}

/// The six planes of a view frustum, each `(normal, d)` with `normal · p + d ≥ 0` inside.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct FrustumPlanes(pub [Vec4; 6]);

impl FrustumPlanes {
    /// The planes of a clip-from-world (view-projection) matrix with wgpu's clip space
    /// (x, y in [-w, w], z in [0, w]); works with Bevy's reverse-Z and infinite far plane.
    pub(crate) fn from_clip_from_world(m: Mat4) -> Self {
        let rows = [m.row(0), m.row(1), m.row(2), m.row(3)];
        let planes = [
            rows[3] + rows[0],
            rows[3] - rows[0],
            rows[3] + rows[1],
            rows[3] - rows[1],
            rows[2],
            rows[3] - rows[2],
        ];
        Self(planes.map(|p| {
            let length = p.truncate().length();
            if length > 0.0 { p / length } else { p }
        }))
    }

    /// Where an axis-aligned box lies. An empty box is outside.
    pub(crate) fn classify_box(&self, bounds: &Bounds) -> Containment {
        if bounds.is_empty() {
            return Containment::Outside;
        }
        let center = Vec3A::from(bounds.center());
        let half = Vec3A::from(bounds.half_extents());
        let mut result = Containment::Inside;
        for plane in &self.0 {
            let normal = Vec3A::from(plane.truncate());
            let distance = normal.dot(center) + plane.w;
            let reach = normal.abs().dot(half);
            if distance < -reach {
                return Containment::Outside;
            }
            if distance < reach {
                result = Containment::Intersecting;
            }
        }
        result
    }

    /// Whether a sphere is at least partly inside.
    pub(crate) fn intersects_sphere(&self, sphere: &BoundingSphere) -> bool {
        let center = Vec3A::from(sphere.center);
        self.0
            .iter()
            .all(|p| Vec3A::from(p.truncate()).dot(center) + p.w >= -sphere.radius)
    }
}

/// The parts of a tree type that culling tests, in the tree's own space.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct CullShape {
    /// Box around the whole tree.
    pub bounds: Bounds,
    /// Box around the trunk.
    pub trunk: Bounds,
    /// A sphere per leaf group.
    pub groups: Vec<BoundingSphere>,
}

impl From<&TreeModel> for CullShape {
    fn from(model: &TreeModel) -> Self {
        Self {
            bounds: model.bounds,
            trunk: model.trunk_bounds,
            groups: model.leaf_groups.iter().map(|g| g.bounds).collect(),
        }
    }
}

/// The shapes of the instances the wind has moved, in their own space: they replace
/// their species' [`CullShape`] in the per-instance tests of partially visible leaves, so
/// a bent tree is culled where it is drawn. An instance keeps its shape until it is
/// rewritten or removed; storage is reused.
///
/// Instances may also share a shape ([`share`](Self::share)): far trees that sway with
/// one block of offsets between them have one moved shape between them too.
///
/// As a resource it belongs to the wind stage, which writes it for the instances it moved
/// this frame (indexed like [`ForestInstances`](crate::instance::ForestInstances));
/// culling, which runs after it, reads it.
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub(crate) struct MovedShapes {
    /// Per instance: index into `shapes`, `SHARED` | index into `shared`, or `NOT_MOVED`.
    slot: Vec<u32>,
    shapes: Vec<CullShape>,
    /// Per used shape: the instance it belongs to.
    owner: Vec<u32>,
    used: usize,
    shared: Vec<CullShape>,
}

const NOT_MOVED: u32 = u32::MAX;

/// The bit of a slot that points into the shared shapes.
const SHARED: u32 = 1 << 31;

impl MovedShapes {
    /// Forgets every moved shape, shared ones too (keeps the storage).
    pub(crate) fn clear(&mut self) {
        self.slot.clear();
        self.owner.clear();
        self.used = 0;
        self.shared.clear();
    }

    /// Shared shape `index`, to fill (its previous contents are unspecified; set every
    /// field). Instances point at it with [`share`](Self::share).
    pub(crate) fn shared_mut(&mut self, index: usize) -> &mut CullShape {
        if self.shared.len() <= index {
            self.shared.resize_with(index + 1, || CullShape {
                bounds: Bounds::EMPTY,
                trunk: Bounds::EMPTY,
                groups: Vec::new(),
            });
        }
        &mut self.shared[index]
    }

    /// Gives `instance` shared shape `index` (see [`shared_mut`](Self::shared_mut)) in
    /// place of a shape of its own.
    pub(crate) fn share(&mut self, instance: usize, index: usize) {
        if self.slot.get(instance) == Some(&(SHARED | index as u32)) {
            return;
        }
        self.remove(instance);
        if self.slot.len() <= instance {
            self.slot.resize(instance + 1, NOT_MOVED);
        }
        self.slot[instance] = SHARED | index as u32;
    }

    /// Forgets `instance`'s moved shape (it is back at rest), if it has one.
    pub(crate) fn remove(&mut self, instance: usize) {
        let Some(&s) = self.slot.get(instance) else {
            return;
        };
        if s == NOT_MOVED {
            return;
        }
        if s & SHARED != 0 {
            self.slot[instance] = NOT_MOVED;
            return;
        }
        // The last used shape fills the hole.
        let last = self.used - 1;
        self.shapes.swap(s as usize, last);
        self.owner.swap(s as usize, last);
        self.owner.pop();
        if let Some(&moved_in) = self.owner.get(s as usize) {
            self.slot[moved_in as usize] = s;
        }
        self.slot[instance] = NOT_MOVED;
        self.used = last;
    }

    /// Takes `instance` out as `Vec::swap_remove` does from `instances` instances: the
    /// last instance (and its moved shape) takes its index.
    pub(crate) fn swap_remove(&mut self, instance: usize, instances: usize) {
        self.remove(instance);
        let Some(last) = instances.checked_sub(1) else {
            return;
        };
        let last_slot = self.slot.get(last).copied().unwrap_or(NOT_MOVED);
        if let Some(slot) = self.slot.get_mut(instance) {
            *slot = last_slot;
        }
        if last_slot != NOT_MOVED && last_slot & SHARED == 0 {
            self.owner[last_slot as usize] = instance as u32;
        }
        self.slot.truncate(last);
    }

    /// Instances with a moved shape of their own (not counting those sharing one).
    #[cfg(test)]
    pub(crate) fn len(&self) -> usize {
        self.used
    }

    /// Whether no instance has a moved shape, of its own or shared.
    #[cfg(test)]
    pub(crate) fn is_empty(&self) -> bool {
        self.slot.iter().all(|&s| s == NOT_MOVED)
    }

    /// The moved shape of `instance`, if it has one.
    pub(crate) fn get(&self, instance: usize) -> Option<&CullShape> {
        match self.slot.get(instance) {
            Some(&s) if s == NOT_MOVED => None,
            Some(&s) if s & SHARED != 0 => self.shared.get((s & !SHARED) as usize),
            Some(&s) => Some(&self.shapes[s as usize]),
            None => None,
        }
    }

    /// The shape to fill for `instance` (its previous contents are unspecified; set every
    /// field).
    pub(crate) fn shape_mut(&mut self, instance: usize) -> &mut CullShape {
        if self.slot.len() <= instance {
            self.slot.resize(instance + 1, NOT_MOVED);
        }
        if self.slot[instance] & SHARED != 0 && self.slot[instance] != NOT_MOVED {
            self.slot[instance] = NOT_MOVED;
        }
        if self.slot[instance] == NOT_MOVED {
            if self.used == self.shapes.len() {
                self.shapes.push(CullShape {
                    bounds: Bounds::EMPTY,
                    trunk: Bounds::EMPTY,
                    groups: Vec::new(),
                });
            }
            self.slot[instance] = self.used as u32;
            self.owner.push(instance as u32);
            self.used += 1;
        }
        &mut self.shapes[self.slot[instance] as usize]
    }
}

/// The box around `bounds` transformed by `transform`.
pub(crate) fn transform_bounds(transform: &Affine3A, bounds: &Bounds) -> Bounds {
    if bounds.is_empty() {
        return Bounds::EMPTY;
    }
    let center = transform.transform_point3(bounds.center());
    let half = Vec3A::from(bounds.half_extents());
    let m = transform.matrix3;
    let extent = Vec3::new(
        m.row(0).abs().dot(half),
        m.row(1).abs().dot(half),
        m.row(2).abs().dot(half),
    );
    Bounds {
        min: center - extent,
        max: center + extent,
    }
}

fn transform_sphere(transform: &Affine3A, sphere: &BoundingSphere) -> BoundingSphere {
    let m = transform.matrix3;
    let scale = m
        .x_axis
        .length()
        .max(m.y_axis.length())
        .max(m.z_axis.length());
    BoundingSphere {
        center: transform.transform_point3(sphere.center),
        radius: sphere.radius * scale,
    }
}

/// One instance to cull: its transform and which [`CullShape`] it has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct CullInstance {
    /// Local → world.
    pub transform: Affine3A,
    /// Index into the shapes slice.
    pub shape: u32,
}

/// Visibility of one instance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub(crate) enum InstanceVisibility {
    /// Not drawn.
    #[default]
    Invisible,
    /// Entirely inside the view: every part is drawn without further tests.
    Full,
    /// Partly inside: draw the trunk if `trunk`, and the leaf groups whose bits are set in
    /// [`CullResult::group_bits`] from word `first_word` on.
    Partial {
        /// Whether the trunk box is (partly) visible.
        trunk: bool,
        /// First 64-bit word of this instance's group bits.
        first_word: u32,
    },
}

/// One frame's culling answer.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct CullResult {
    /// Per instance, in instance order.
    pub visibility: Vec<InstanceVisibility>,
    /// Group visibility bits of partially visible instances (bit `g` of the words
    /// starting at `first_word`).
    pub group_bits: Vec<u64>,
}

impl CullResult {
    /// Whether leaf group `group` of instance `instance` is visible.
    pub(crate) fn group_visible(&self, instance: usize, group: usize) -> bool {
        match self.visibility[instance] {
            InstanceVisibility::Invisible => false,
            InstanceVisibility::Full => true,
            InstanceVisibility::Partial { first_word, .. } => {
                self.group_bits[first_word as usize + group / 64] & (1 << (group % 64)) != 0
            }
        }
    }

    /// Whether the trunk of `instance` is visible.
    #[cfg(test)]
    pub(crate) fn trunk_visible(&self, instance: usize) -> bool {
        match self.visibility[instance] {
            InstanceVisibility::Invisible => false,
            InstanceVisibility::Full => true,
            InstanceVisibility::Partial { trunk, .. } => trunk,
        }
    }

    pub(crate) fn clear(&mut self, instances: usize) {
        self.visibility.clear();
        self.visibility
            .resize(instances, InstanceVisibility::Invisible);
        self.group_bits.clear();
    }
}

/// Per-part test of one instance (what brute force does for every instance, and the
/// hierarchy only in partially visible leaves).
fn test_instance(
    planes: &FrustumPlanes,
    instance: &CullInstance,
    world_bounds: &Bounds,
    shape: &CullShape,
    result: &mut CullResult,
) -> InstanceVisibility {
    match planes.classify_box(world_bounds) {
        Containment::Outside => InstanceVisibility::Invisible,
        Containment::Inside => InstanceVisibility::Full,
        Containment::Intersecting => {
            let trunk_box = transform_bounds(&instance.transform, &shape.trunk);
            let trunk = planes.classify_box(&trunk_box) != Containment::Outside;
            let first_word = result.group_bits.len();
            result
                .group_bits
                .resize(first_word + shape.groups.len().div_ceil(64), 0);
            let mut any = trunk;
            for (g, sphere) in shape.groups.iter().enumerate() {
                if planes.intersects_sphere(&transform_sphere(&instance.transform, sphere)) {
                    result.group_bits[first_word + g / 64] |= 1 << (g % 64);
                    any = true;
                }
            }
            if any {
                InstanceVisibility::Partial {
                    trunk,
                    first_word: first_word as u32,
                }
            } else {
                result.group_bits.truncate(first_word);
                InstanceVisibility::Invisible
            }
        }
    }
}

/// The reference: every instance tested on its own, moved instances with their
/// [`MovedShapes`].
#[cfg(any(test, feature = "testing"))]
pub(crate) fn cull_brute_force(
    planes: &FrustumPlanes,
    instances: &[CullInstance],
    shapes: &[CullShape],
    moved: &MovedShapes,
    result: &mut CullResult,
) {
    result.clear(instances.len());
    for (i, instance) in instances.iter().enumerate() {
        let shape = moved.get(i).unwrap_or(&shapes[instance.shape as usize]);
        let bounds = transform_bounds(&instance.transform, &shape.bounds);
        result.visibility[i] = test_instance(planes, instance, &bounds, shape, result);
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Node {
    bounds: Bounds,
    /// Instances below this node: a range of `order`.
    instances: (u32, u32),
}

/// How one node of the hierarchy was seen last frame, for the debug view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum NodeVisibility {
    /// Not tested (empty, or below a node already decided).
    Untested,
    /// Outside the view.
    Outside,
    /// Partly inside.
    Partial,
    /// Entirely inside.
    Full,
}

/// An instance's world box: its shape's box, transformed.
fn instance_bounds(instance: &CullInstance, shapes: &[CullShape]) -> Bounds {
    transform_bounds(&instance.transform, &shapes[instance.shape as usize].bounds)
}

/// A quadtree of boxes over the populated area.
#[derive(Clone, Debug)]
pub(crate) struct BoxHierarchy {
    depth: u32,
    grid: Grid,
    /// Level-order complete quadtree: level `l` starts at `(4^l − 1) / 3`.
    nodes: Vec<Node>,
    /// Instance indices grouped by leaf.
    order: Vec<u32>,
    /// World box of every instance.
    instance_bounds: Vec<Bounds>,
    /// Leaf (Morton index) of every instance.
    leaf_of: Vec<u32>,
    node_visibility: Vec<NodeVisibility>,
    /// Edits followed since the build.
    edits: u64,
    /// Per node, the edit (1, 2, …) that last changed its instances; 0: none since the
    /// build.
    node_edits: Vec<u64>,
}

fn level_start(level: u32) -> usize {
    ((1_usize << (2 * level)) - 1) / 3
}

/// The leaf cells over the area's XZ rectangle.
#[derive(Clone, Copy, Debug)]
struct Grid {
    depth: u32,
    min: Vec3,
    size: Vec3,
}

impl Grid {
    /// The leaf (in Morton order, so every subtree's leaves are contiguous) holding `p`;
    /// points outside the area go to the nearest border cell.
    fn leaf(&self, p: Vec3) -> usize {
        let side = 1_usize << self.depth;
        let f = ((p - self.min) / self.size * side as f32).floor();
        let x = (f.x.max(0.0) as usize).min(side - 1);
        let z = (f.z.max(0.0) as usize).min(side - 1);
        let mut code = 0;
        for bit in 0..self.depth {
            code |= ((x >> bit) & 1) << (2 * bit);
            code |= ((z >> bit) & 1) << (2 * bit + 1);
        }
        code
    }
}

impl BoxHierarchy {
    /// Builds a hierarchy of `depth` levels below the root (4^depth leaves, each owning an
    /// equal cell of `area`'s XZ rectangle) over `instances`. Instances outside the area
    /// go to the nearest border cell. A depth above 10 is treated as 10.
    pub(crate) fn build(
        depth: u32,
        area: &Bounds,
        instances: &[CullInstance],
        shapes: &[CullShape],
    ) -> Self {
        let depth = depth.min(10);
        let side = 1_usize << depth;
        let instance_bounds: Vec<Bounds> = instances
            .iter()
            .map(|i| instance_bounds(i, shapes))
            .collect();
        let grid = Grid {
            depth,
            min: area.min,
            size: (area.max - area.min).max(Vec3::splat(f32::EPSILON)),
        };
        let leaves = side * side;
        let leaf_of: Vec<u32> = instances
            .iter()
            .map(|i| grid.leaf(i.transform.translation.into()) as u32)
            .collect();
        // An instance with an empty box (a tree that failed to load) can never be visible:
        // it stays out of the hierarchy, so a fully visible box cannot mark it visible.
        let mut order: Vec<u32> = (0..instances.len() as u32)
            .filter(|&i| !instance_bounds[i as usize].is_empty())
            .collect();
        order.sort_by_key(|&i| leaf_of[i as usize]);
        let mut nodes = vec![
            Node {
                bounds: Bounds::EMPTY,
                instances: (0, 0),
            };
            level_start(depth + 1)
        ];
        let first_leaf = level_start(depth);
        let mut cursor = 0;
        for leaf in 0..leaves {
            let start = cursor;
            while cursor < order.len() && leaf_of[order[cursor] as usize] as usize == leaf {
                let b = instance_bounds[order[cursor] as usize];
                nodes[first_leaf + leaf].bounds = nodes[first_leaf + leaf].bounds.union(b);
                cursor += 1;
            }
            nodes[first_leaf + leaf].instances = (start as u32, cursor as u32);
        }
        for level in (0..depth).rev() {
            let start = level_start(level);
            let child_start = level_start(level + 1);
            for i in 0..(1 << (2 * level)) {
                let children = &nodes[child_start + 4 * i..child_start + 4 * i + 4];
                let bounds = children
                    .iter()
                    .fold(Bounds::EMPTY, |b, c| b.union(c.bounds));
                let instances = (children[0].instances.0, children[3].instances.1);
                nodes[start + i] = Node { bounds, instances };
            }
        }
        let node_visibility = vec![NodeVisibility::Untested; nodes.len()];
        let node_edits = vec![0; nodes.len()];
        Self {
            depth,
            grid,
            nodes,
            order,
            instance_bounds,
            leaf_of,
            node_visibility,
            edits: 0,
            node_edits,
        }
    }

    /// Refits the boxes after the instances in `moved` changed their transforms in
    /// `instances` (the same slice as at build time, otherwise unchanged): their boxes and
    /// every box above them, O(moved × depth). Returns `false`, changing nothing, when a
    /// moved instance left its leaf cell (or its box appeared or vanished): build anew.
    pub(crate) fn refit(
        &mut self,
        moved: &[u32],
        instances: &[CullInstance],
        shapes: &[CullShape],
    ) -> bool {
        let first_leaf = level_start(self.depth);
        let mut dirty = Vec::with_capacity(moved.len());
        for &i in moved {
            let i = i as usize;
            let Some(instance) = instances.get(i) else {
                return false;
            };
            if i >= self.leaf_of.len()
                || self.grid.leaf(instance.transform.translation.into()) != self.leaf_of[i] as usize
                || instance_bounds(instance, shapes).is_empty()
                    != self.instance_bounds[i].is_empty()
            {
                return false;
            }
            dirty.push(first_leaf + self.leaf_of[i] as usize);
        }
        for &i in moved {
            self.instance_bounds[i as usize] = instance_bounds(&instances[i as usize], shapes);
        }
        self.refit_boxes(dirty);
        true
    }

    /// Replays `edits` (see [`LayoutEdits`]): `instances` is the edited slice, indexed like
    /// the new table. Each removal and addition costs O(boxes + instances) moves of
    /// indices, no sort; the boxes they touched are refitted. Returns `false`, changing
    /// nothing, when an added instance stands farther outside the hierarchy's area than a
    /// quarter of its width, or the edits touch over an eighth of the instances: build
    /// anew.
    pub(crate) fn edit(
        &mut self,
        edits: &LayoutEdits,
        instances: &[CullInstance],
        shapes: &[CullShape],
    ) -> bool {
        // A tree planted past the area joins its nearest border box, which grows to hold
        // it; one far past it would stretch that box over the rest.
        let reach = self.grid.size * 0.25;
        let (min, max) = (
            self.grid.min - reach,
            self.grid.min + self.grid.size + reach,
        );
        let outside = edits.added().any(|i| {
            instances.get(i).is_none_or(|instance| {
                let p = Vec3::from(instance.transform.translation);
                p.x < min.x || p.z < min.z || p.x > max.x || p.z > max.z
            })
        });
        if outside || edits.len() * 8 > self.leaf_of.len().max(8) {
            return false;
        }
        let first_leaf = level_start(self.depth);
        let mut dirty = Vec::with_capacity(edits.len());
        for &i in edits.removed() {
            let i = i as usize;
            let leaf = self.leaf_of[i] as usize;
            dirty.push(first_leaf + leaf);
            self.take_from_leaf(i, leaf);
            let last = self.leaf_of.len() - 1;
            if i != last
                && let Some(at) = self.place_in_leaf(last, self.leaf_of[last] as usize)
            {
                self.order[at] = i as u32;
            }
            self.leaf_of.swap_remove(i);
            self.instance_bounds.swap_remove(i);
        }
        for i in edits.added() {
            let instance = &instances[i];
            let bounds = instance_bounds(instance, shapes);
            let leaf = self.grid.leaf(instance.transform.translation.into());
            self.leaf_of.push(leaf as u32);
            self.instance_bounds.push(bounds);
            if !bounds.is_empty() {
                self.put_in_leaf(i as u32, leaf);
                dirty.push(first_leaf + leaf);
            }
        }
        self.edits += 1;
        for &leaf in &dirty {
            let mut node = leaf;
            for level in (0..=self.depth).rev() {
                self.node_edits[node] = self.edits;
                if level > 0 {
                    node = level_start(level - 1) + (node - level_start(level)) / 4;
                }
            }
        }
        self.refit_boxes(dirty);
        true
    }

    /// Whether `other` has the same boxes over the same cells, holding the same instances
    /// (as a build over the same instances of other shapes does).
    pub(crate) fn same_cells(&self, other: &Self) -> bool {
        self.depth == other.depth
            && self.grid.min == other.grid.min
            && self.grid.size == other.grid.size
            && self.order == other.order
    }

    /// How many edits ([`edit`](Self::edit)) the hierarchy followed since it was built.
    pub(crate) fn edits(&self) -> u64 {
        self.edits
    }

    /// The edit that last changed which instances are under `node` (counting from 1; 0
    /// when none did since the build).
    pub(crate) fn node_edit(&self, node: usize) -> u64 {
        self.node_edits[node]
    }

    /// Takes instance `i` out of `leaf`'s part of `order` (if it is there: an instance
    /// without a box is not).
    fn take_from_leaf(&mut self, i: usize, leaf: usize) {
        if let Some(at) = self.place_in_leaf(i, leaf) {
            self.order.remove(at);
            self.shift_ranges(leaf, -1);
        }
    }

    /// Where instance `i` is in `order`, looked for in `leaf`'s part of it.
    fn place_in_leaf(&self, i: usize, leaf: usize) -> Option<usize> {
        let (start, end) = self.nodes[level_start(self.depth) + leaf].instances;
        let range = start as usize..end as usize;
        let at = self.order[range.clone()]
            .iter()
            .position(|&o| o as usize == i)?;
        Some(range.start + at)
    }

    /// Puts instance `i` at the end of `leaf`'s part of `order`.
    fn put_in_leaf(&mut self, i: u32, leaf: usize) {
        let first_leaf = level_start(self.depth);
        let end = self.nodes[first_leaf + leaf].instances.1;
        self.order.insert(end as usize, i);
        self.shift_ranges(leaf, 1);
    }

    /// After one instance joined (`by` 1) or left (−1) the end of `leaf`'s range of
    /// `order`: the boxes holding the leaf end `by` later, the boxes after it start and end
    /// `by` later.
    fn shift_ranges(&mut self, leaf: usize, by: i32) {
        let shift = |v: u32| v.wrapping_add_signed(by);
        for level in 0..=self.depth {
            let start = level_start(level);
            let leaves_per_box = 1_usize << (2 * (self.depth - level));
            let holder = leaf / leaves_per_box;
            for (b, node) in self.nodes[start..start + (1 << (2 * level))]
                .iter_mut()
                .enumerate()
            {
                if b == holder {
                    node.instances.1 = shift(node.instances.1);
                } else if b > holder {
                    node.instances = (shift(node.instances.0), shift(node.instances.1));
                }
            }
        }
    }

    /// Refits the leaf boxes `dirty` (node indices) from their instances' boxes, and
    /// every box above them.
    fn refit_boxes(&mut self, mut dirty: Vec<usize>) {
        dirty.sort_unstable();
        dirty.dedup();
        for &node in &dirty {
            let (start, end) = self.nodes[node].instances;
            self.nodes[node].bounds = self.order[start as usize..end as usize]
                .iter()
                .fold(Bounds::EMPTY, |b, &i| {
                    b.union(self.instance_bounds[i as usize])
                });
        }
        for level in (0..self.depth).rev() {
            let (start, child_start) = (level_start(level), level_start(level + 1));
            for node in &mut dirty {
                *node = start + (*node - child_start) / 4;
            }
            dirty.dedup();
            for &node in &dirty {
                let first_child = child_start + 4 * (node - start);
                self.nodes[node].bounds = self.nodes[first_child..first_child + 4]
                    .iter()
                    .fold(Bounds::EMPTY, |b, c| b.union(c.bounds));
            }
        }
    }

    /// Levels below the root.
    pub(crate) fn depth(&self) -> u32 {
        self.depth
    }

    /// Every node's box and how it was seen by the last [`cull`](Self::cull), skipping
    /// empty (invalid) nodes — for the debug view.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn nodes(&self) -> impl Iterator<Item = (Bounds, NodeVisibility)> + '_ {
        self.nodes
            .iter()
            .zip(&self.node_visibility)
            .filter(|(n, _)| !n.bounds.is_empty())
            .map(|(n, v)| (n.bounds, *v))
    }

    /// Culls `instances` (the same slice, in the same order, as at build time). Instances
    /// in `moved` are tested with their moved shape where their leaf is partially
    /// visible; the hierarchy's boxes stay those of the trees at rest, so a tree swaying
    /// across the edge of a box that is entirely outside the view is missed until it
    /// comes back (a sway is a fraction of a tree, boxes hold many).
    pub(crate) fn cull(
        &mut self,
        planes: &FrustumPlanes,
        instances: &[CullInstance],
        shapes: &[CullShape],
        moved: &MovedShapes,
        result: &mut CullResult,
    ) {
        result.clear(instances.len());
        self.node_visibility.fill(NodeVisibility::Untested);
        let mut stack = vec![(0_usize, 0_u32)];
        while let Some((node, level)) = stack.pop() {
            let n = self.nodes[node];
            if n.bounds.is_empty() {
                continue; // invalid: no instance below
            }
            match planes.classify_box(&n.bounds) {
                Containment::Outside => self.node_visibility[node] = NodeVisibility::Outside,
                Containment::Inside => {
                    self.node_visibility[node] = NodeVisibility::Full;
                    for &i in &self.order[n.instances.0 as usize..n.instances.1 as usize] {
                        result.visibility[i as usize] = InstanceVisibility::Full;
                    }
                }
                Containment::Intersecting => {
                    self.node_visibility[node] = NodeVisibility::Partial;
                    if level == self.depth {
                        for &i in &self.order[n.instances.0 as usize..n.instances.1 as usize] {
                            let i = i as usize;
                            let instance = &instances[i];
                            let (shape, bounds) = match moved.get(i) {
                                Some(shape) => {
                                    (shape, transform_bounds(&instance.transform, &shape.bounds))
                                }
                                None => (&shapes[instance.shape as usize], self.instance_bounds[i]),
                            };
                            result.visibility[i] =
                                test_instance(planes, instance, &bounds, shape, result);
                        }
                    } else {
                        let first_child = level_start(level + 1) + 4 * (node - level_start(level));
                        stack.extend((first_child..first_child + 4).map(|c| (c, level + 1)));
                    }
                }
            }
        }
    }

    /// Number of nodes (level order: node 0 is the root, a node's children follow its
    /// level's nodes; see [`children`](Self::children)).
    pub(crate) fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// The box of `node` around its instances at rest ([`Bounds::EMPTY`] when it holds
    /// none).
    pub(crate) fn node_bounds(&self, node: usize) -> Bounds {
        self.nodes[node].bounds
    }

    /// The instances below `node` (indices into the culled instances).
    pub(crate) fn node_instances(&self, node: usize) -> &[u32] {
        let (start, end) = self.nodes[node].instances;
        &self.order[start as usize..end as usize]
    }

    /// How `node` was seen by the last [`cull`](Self::cull): the children of a node seen
    /// entirely inside are [`NodeVisibility::Untested`] (and inside too).
    pub(crate) fn node_visibility(&self, node: usize) -> NodeVisibility {
        self.node_visibility[node]
    }

    /// The four children of `node`, or `None` for a leaf box.
    pub(crate) fn children(&self, node: usize) -> Option<Range<usize>> {
        let level = self.level_of(node);
        (level < self.depth).then(|| {
            let first = level_start(level + 1) + 4 * (node - level_start(level));
            first..first + 4
        })
    }

    /// The level of `node` (0 for the root, [`depth`](Self::depth) for leaf boxes).
    pub(crate) fn level_of(&self, node: usize) -> u32 {
        let mut level = 0;
        while level < self.depth && node >= level_start(level + 1) {
            level += 1;
        }
        level
    }

    /// Instances grouped by leaf, as a range of instance indices per leaf (for reports).
    #[cfg(test)]
    pub(crate) fn leaf_ranges(&self) -> impl Iterator<Item = Range<u32>> + '_ {
        let first_leaf = level_start(self.depth);
        self.nodes[first_leaf..]
            .iter()
            .map(|n| n.instances.0..n.instances.1)
    }
}

#[cfg(test)]
mod tests {
    use bevy::math::Quat;

    use super::*;
    use crate::rng::SplitMix64;

    fn shapes() -> Vec<CullShape> {
        (1..4)
            .map(|h| CullShape {
                bounds: Bounds {
                    min: Vec3::new(-2.0, 0.0, -2.0),
                    max: Vec3::new(2.0, 3.0 * h as f32, 2.0),
                },
                trunk: Bounds {
                    min: Vec3::new(-0.3, 0.0, -0.3),
                    max: Vec3::new(0.3, 2.0 * h as f32, 0.3),
                },
                groups: vec![BoundingSphere {
                    center: Vec3::new(0.0, 2.0 * h as f32, 0.0),
                    radius: 1.5,
                }],
            })
            .collect()
    }

    fn tree(rng: &mut SplitMix64, size: f32) -> CullInstance {
        CullInstance {
            transform: Affine3A::from_rotation_translation(
                Quat::from_rotation_y(rng.unit() * 6.0),
                Vec3::new(rng.unit() * size, rng.unit(), rng.unit() * size),
            ),
            shape: (rng.next_u64() % 3) as u32,
        }
    }

    /// Trees felled and planted round after round: the edited hierarchy holds each
    /// tree once, in the box where it stands, with boxes as tight as a new build's, and
    /// culls like brute force.
    #[test]
    fn an_edited_hierarchy_holds_and_culls_every_tree_where_it_stands() {
        let mut rng = SplitMix64::new(3);
        let shapes = shapes();
        let size = 300.0;
        let mut instances: Vec<CullInstance> = (0..800).map(|_| tree(&mut rng, size)).collect();
        let area = Bounds::from_points(
            instances
                .iter()
                .map(|i| Vec3::from(i.transform.translation)),
        );
        let mut hierarchy = BoxHierarchy::build(4, &area, &instances, &shapes);
        let mut edits_followed = 0;
        for round in 0..40 {
            let removed: Vec<u32> = (0..rng.next_u64() % 20)
                .map(|k| ((rng.next_u64() as usize) % (instances.len() - k as usize)) as u32)
                .collect();
            let kept = instances.len() - removed.len();
            let added = rng.next_u64() as u32 % 20;
            let edits = LayoutEdits::new(0, removed, kept as u32..kept as u32 + added);
            // Planted over the square, some just past the first trees' area.
            edits.apply(&mut instances, |_| tree(&mut rng, size * 1.1));
            assert!(hierarchy.edit(&edits, &instances, &shapes), "round {round}");
            edits_followed += 1;
            let mut held: Vec<u32> = hierarchy.node_instances(0).to_vec();
            held.sort_unstable();
            assert_eq!(
                held,
                (0..instances.len() as u32).collect::<Vec<_>>(),
                "round {round}"
            );
            for node in 0..hierarchy.node_count() {
                let tight = hierarchy
                    .node_instances(node)
                    .iter()
                    .fold(Bounds::EMPTY, |b, &i| {
                        b.union(instance_bounds(&instances[i as usize], &shapes))
                    });
                assert_eq!(
                    hierarchy.node_bounds(node),
                    tight,
                    "round {round}, box {node}"
                );
            }
            let first_leaf = level_start(hierarchy.depth());
            for (leaf, range) in hierarchy.leaf_ranges().enumerate() {
                for &i in &hierarchy.order[range.start as usize..range.end as usize] {
                    let at = instances[i as usize].transform.translation.into();
                    assert_eq!(
                        hierarchy.grid.leaf(at),
                        leaf,
                        "tree {i} in leaf box {}",
                        first_leaf + leaf
                    );
                }
            }
            let eye = Vec3::new(rng.unit() * size, 30.0, rng.unit() * size);
            let planes = FrustumPlanes::from_clip_from_world(
                Mat4::perspective_infinite_reverse_rh(1.0, 1.5, 0.1)
                    * Mat4::look_at_rh(eye, Vec3::new(size / 2.0, 0.0, size / 2.0), Vec3::Y),
            );
            let still = MovedShapes::default();
            let (mut fast, mut slow) = (CullResult::default(), CullResult::default());
            hierarchy.cull(&planes, &instances, &shapes, &still, &mut fast);
            cull_brute_force(&planes, &instances, &shapes, &still, &mut slow);
            for i in 0..instances.len() {
                assert_eq!(
                    fast.trunk_visible(i),
                    slow.trunk_visible(i),
                    "round {round}, tree {i}"
                );
                assert_eq!(fast.group_visible(i, 0), slow.group_visible(i, 0));
            }
        }
        assert_eq!(hierarchy.edits(), edits_followed);
        assert!(hierarchy.node_edit(0) == edits_followed);
    }

    /// A tree planted outside the area, or edits touching most of the forest: refused,
    /// for a new build.
    #[test]
    fn edits_outside_the_area_or_of_most_trees_are_refused() {
        let mut rng = SplitMix64::new(5);
        let shapes = shapes();
        let mut instances: Vec<CullInstance> = (0..100).map(|_| tree(&mut rng, 50.0)).collect();
        let area = Bounds::from_points(
            instances
                .iter()
                .map(|i| Vec3::from(i.transform.translation)),
        );
        let mut hierarchy = BoxHierarchy::build(3, &area, &instances, &shapes);
        let mut far = tree(&mut rng, 50.0);
        far.transform.translation.x += 500.0;
        instances.push(far);
        assert!(!hierarchy.edit(&LayoutEdits::new(0, vec![], 100..101), &instances, &shapes));
        instances.pop();
        let many = LayoutEdits::new(0, (0..20).rev().collect(), 80..80);
        many.apply(&mut instances, |_| unreachable!());
        assert!(!hierarchy.edit(&many, &instances, &shapes));
    }
}
