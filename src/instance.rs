//! The instance table: every [`TreeInstance`] in the world — every ecosystem's trees and
//! trees spawned by hand — in one dense, indexed list that culling, the level of detail,
//! the wind and the render pass all index the same way.
//!
//! [`ForestInstances`] is kept by one system at the head of the frame
//! ([`SherwoodSystems::Instances`](crate::schedule::SherwoodSystems::Instances)): a tree
//! spawned or despawned changes the layout (and `ForestInstances::layout_version`) by
//! an edit the later stages replay on their own per-instance state
//! (`ForestInstances::edits_since`), so that planting one tree costs them one tree, not
//! the forest; a tree whose `GlobalTransform` changed keeps its index and is listed in
//! `ForestInstances::moved` for that frame. A tree with [`FixedDrawList`] stays out: it
//! draws the list it was given.

use std::ops::Range;

use bevy::ecs::entity::EntityHashMap;
use bevy::math::Affine3A;
use bevy::prelude::*;

use crate::tree::TreeModel;

/// One tree in the world. Spawn it with a `Transform` (uniform scale); the Sherwood stages
/// cull it, give it time and draw it, whether an ecosystem spawned it or you did
/// ([`TreeInstance::new`]). It requires a `Transform` (and, with the `render` feature, a
/// `Visibility`), inserted at their defaults when missing.
#[derive(Component, Clone, Debug, Reflect)]
#[reflect(Component, Debug)]
#[cfg_attr(feature = "render", require(Transform, Visibility))]
#[cfg_attr(not(feature = "render"), require(Transform))]
pub struct TreeInstance {
    /// The forest entity of the ecosystem that spawned it; `Entity::PLACEHOLDER` for a
    /// tree placed by hand.
    pub forest: Entity,
    /// Index of its species in its ecosystem (0 for a tree placed by hand).
    pub species: usize,
    /// Its tree type.
    pub model: Handle<TreeModel>,
    /// Its index among its forest's instances (0 for a tree placed by hand).
    pub index: u32,
    /// Uniform scale (also in its `Transform`).
    pub scale: f32,
    /// Trunk material, an index into the ecosystem's materials (in name order).
    pub trunk_material: usize,
    /// Leaf material, an index into the ecosystem's materials (in name order).
    pub leaf_material: usize,
    /// Which wind setup moves it (an index into
    /// [`WindSettings::sets`](crate::wind::WindSettings::sets)).
    pub motion: u32,
}

impl TreeInstance {
    /// A tree of `model` placed by hand, in no ecosystem: culled, valued, budgeted, moved
    /// by the first wind setup and drawn like any forest's tree. Give its `Transform` the
    /// same uniform scale as [`TreeInstance::scale`] (1 here; set both to change it).
    pub fn new(model: Handle<TreeModel>) -> Self {
        Self {
            forest: Entity::PLACEHOLDER,
            species: 0,
            model,
            index: 0,
            scale: 1.0,
            trunk_material: 0,
            leaf_material: 0,
            motion: 0,
        }
    }

    /// The same as [`TreeInstance::new`]; spawn it with [`FixedDrawList`] and a
    /// [`TreeDrawList`](crate::draw::TreeDrawList) to draw that list whatever the view
    /// (benchmarks, previews, tests).
    pub fn standalone(model: Handle<TreeModel>) -> Self {
        Self::new(model)
    }
}

/// Keeps a [`TreeInstance`] out of the instance table: culling, the level of detail and
/// the wind leave it alone, and the render pass draws the
/// [`TreeDrawList`](crate::draw::TreeDrawList) spawned with it (the full tree without
/// one). Insert it when the tree is spawned.
#[derive(Component, Clone, Copy, Debug, Default, Reflect)]
#[reflect(Component, Default)]
pub struct FixedDrawList;

/// Every [`TreeInstance`] without [`FixedDrawList`], densely indexed: instance `i` is
/// `entities[i]`, placed by `transforms[i]`, of model `model_ids[models[i]]`. Every
/// per-instance array of the later stages (culling's result, the wind's offsets, the
/// level of detail's placement) is indexed the same way.
#[derive(Resource, Debug, Default, Reflect)]
#[reflect(Resource, Debug)]
pub struct ForestInstances {
    /// The instance entities.
    pub entities: Vec<Entity>,
    /// Their world transforms (from `GlobalTransform`).
    pub transforms: Vec<Affine3A>,
    /// Their model, an index into `model_ids`.
    pub models: Vec<u32>,
    /// The distinct models of the instances, in order of first appearance.
    pub model_ids: Vec<AssetId<TreeModel>>,
    /// Their uniform scale ([`TreeInstance::scale`]).
    pub scales: Vec<f32>,
    /// Their wind setup ([`TreeInstance::motion`]).
    pub motions: Vec<u32>,
    #[reflect(ignore)]
    index: EntityHashMap<u32>,
    #[reflect(ignore)]
    moved: Vec<u32>,
    #[reflect(ignore)]
    edits: LayoutEdits,
    #[reflect(ignore)]
    layout_version: u64,
    #[reflect(ignore)]
    transforms_version: u64,
    #[reflect(ignore)]
    models_version: u64,
}

/// How [`ForestInstances`] went from one layout to the next without being laid out anew:
/// the instances at [`removed`](Self::removed) were taken out one after another, each as
/// by `Vec::swap_remove` (the last instance fills its place), then
/// [`added`](Self::added) were pushed at the end. Replaying this on a per-instance `Vec`
/// ([`apply`](Self::apply)) indexes it like the new table; every other instance keeps its
/// index.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct LayoutEdits {
    /// The layout version the edits start from.
    from: u64,
    removed: Vec<u32>,
    added: Range<u32>,
    /// Models new to `model_ids` (appended at its end).
    new_models: Range<u32>,
}

impl LayoutEdits {
    /// Edits from layout `from` removing `removed` (in order) and adding `added`.
    #[cfg(test)]
    pub(crate) fn new(from: u64, removed: Vec<u32>, added: Range<u32>) -> Self {
        Self {
            from,
            removed,
            added,
            new_models: 0..0,
        }
    }

    /// The indices removed, in the order they were (each by swap-remove).
    pub(crate) fn removed(&self) -> &[u32] {
        &self.removed
    }

    /// The indices of the instances added (at the end of the new table).
    pub(crate) fn added(&self) -> Range<usize> {
        self.added.start as usize..self.added.end as usize
    }

    /// The models that joined [`ForestInstances::model_ids`] (at its end; none leave it by
    /// an edit).
    pub(crate) fn new_models(&self) -> Range<usize> {
        self.new_models.start as usize..self.new_models.end as usize
    }

    /// How many instances were removed and added.
    pub(crate) fn len(&self) -> usize {
        self.removed.len() + self.added().len()
    }

    /// Replays the edits on `items`, indexed like the old table: swap-removes the removed
    /// and pushes `new(i)` for each added index `i`.
    pub(crate) fn apply<T>(&self, items: &mut Vec<T>, mut new: impl FnMut(usize) -> T) {
        swap_remove_each(items, &self.removed);
        for i in self.added() {
            items.push(new(i));
        }
    }
}

/// Swap-removes `removed` from `items`, one after another (indices past the end are
/// skipped).
fn swap_remove_each<T>(items: &mut Vec<T>, removed: &[u32]) {
    for &i in removed {
        if (i as usize) < items.len() {
            items.swap_remove(i as usize);
        }
    }
}

impl ForestInstances {
    /// Changes whenever an instance was added or removed (or its model changed): a
    /// per-instance array kept for an older version is indexed otherwise.
    pub(crate) fn layout_version(&self) -> u64 {
        self.layout_version
    }

    /// How to bring per-instance state kept for layout `version` to this one, when it is
    /// the previous layout (otherwise, or after a new layout, `None`: rebuild from the
    /// table).
    pub(crate) fn edits_since(&self, version: u64) -> Option<&LayoutEdits> {
        (version.wrapping_add(1) == self.layout_version && self.edits.from == version)
            .then_some(&self.edits)
    }

    /// Changes whenever one of [`model_ids`](Self::model_ids) was loaded, changed or
    /// removed (not when a model no instance uses did, such as a group impostor's).
    pub(crate) fn models_version(&self) -> u64 {
        self.models_version
    }

    /// Changes whenever an instance moved (or the layout changed).
    pub(crate) fn transforms_version(&self) -> u64 {
        self.transforms_version
    }

    /// The instances whose transform changed this frame, in this frame's layout
    /// (ascending; an instance added this frame is not listed).
    pub(crate) fn moved(&self) -> &[u32] {
        &self.moved
    }

    /// How many instances there are.
    pub fn len(&self) -> usize {
        self.entities.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.entities.is_empty()
    }

    /// The index of `entity`, if it is in the table.
    pub(crate) fn index_of(&self, entity: Entity) -> Option<u32> {
        self.index.get(&entity).copied()
    }

    /// The model of instance `i`.
    pub(crate) fn model_id(&self, i: usize) -> Option<AssetId<TreeModel>> {
        self.model_ids.get(*self.models.get(i)? as usize).copied()
    }

    /// Takes out `removed` (entities in the table) and appends `added` (in order), every
    /// other instance keeping its index but the ones that fill the holes.
    fn edit<'a>(
        &mut self,
        removed: &[Entity],
        added: impl Iterator<Item = (Entity, &'a TreeInstance, Affine3A)>,
    ) {
        let mut holes: Vec<u32> = removed
            .iter()
            .filter_map(|e| self.index.remove(e))
            .collect();
        // Highest first: each swap-remove then moves an instance that stays.
        holes.sort_unstable_by(|a, b| b.cmp(a));
        swap_remove_each(&mut self.entities, &holes);
        swap_remove_each(&mut self.transforms, &holes);
        swap_remove_each(&mut self.models, &holes);
        swap_remove_each(&mut self.scales, &holes);
        swap_remove_each(&mut self.motions, &holes);
        // Highest first, each hole was filled by an instance that stays.
        for &i in &holes {
            if let Some(&moved_in) = self.entities.get(i as usize) {
                self.index.insert(moved_in, i);
            }
        }
        let first_added = self.entities.len() as u32;
        let first_model = self.model_ids.len() as u32;
        for (entity, tree, transform) in added {
            let id = tree.model.id();
            let model = match self.model_ids.iter().position(|&m| m == id) {
                Some(m) => m as u32,
                None => {
                    self.model_ids.push(id);
                    self.model_ids.len() as u32 - 1
                }
            };
            self.index.insert(entity, self.entities.len() as u32);
            self.entities.push(entity);
            self.transforms.push(transform);
            self.models.push(model);
            self.scales.push(tree.scale);
            self.motions.push(tree.motion);
        }
        self.edits = LayoutEdits {
            from: self.layout_version,
            removed: holes,
            added: first_added..self.entities.len() as u32,
            new_models: first_model..self.model_ids.len() as u32,
        };
        self.layout_version += 1;
        self.transforms_version += 1;
    }
}

type Tracked = (With<TreeInstance>, Without<FixedDrawList>);

/// The farthest a tree may stand from the origin on any axis, metres: past it an `f32`
/// position is coarser than a few centimetres, and one tree that far would stretch the
/// culling hierarchy over every other.
pub(crate) const MAX_TREE_COORDINATE: f32 = 1.0e6;

/// Whether a tree at `transform` with `scale` can be culled and drawn: a finite
/// transform within [`MAX_TREE_COORDINATE`] of the origin and a positive, finite scale.
/// Others (a NaN from a physics step, a tree sent to infinity) stay out of the instance
/// table, with a warning, until they are placeable again.
pub(crate) fn placeable(transform: &Affine3A, scale: f32) -> bool {
    transform.is_finite()
        && transform.translation.abs().max_element() <= MAX_TREE_COORDINATE
        && scale.is_finite()
        && scale > 0.0
}

/// Keeps [`ForestInstances`] up to date: an edit of the layout when instances were added,
/// removed, given another tree or moved in or out of [`placeable`] places (a tree whose
/// [`TreeInstance`] changed is taken out and added again); otherwise the moved ones'
/// transforms.
#[expect(
    clippy::too_many_arguments,
    reason = "one system reading each way a tree can join or leave the table"
)]
pub(crate) fn track_instances(
    mut table: ResMut<ForestInstances>,
    changed: Query<Entity, (Tracked, Changed<TreeInstance>)>,
    mut removed: RemovedComponents<TreeInstance>,
    mut unfixed: RemovedComponents<FixedDrawList>,
    fixed: Query<Entity, (With<TreeInstance>, Added<FixedDrawList>)>,
    trees: Query<(Entity, &TreeInstance, &GlobalTransform), Without<FixedDrawList>>,
    moved: Query<(Entity, &TreeInstance, &GlobalTransform), (Tracked, Changed<GlobalTransform>)>,
    mut model_events: MessageReader<AssetEvent<TreeModel>>,
    mut left_out: Local<bevy::ecs::entity::EntityHashSet>,
) {
    let table = &mut *table;
    let models_changed = model_events.read().any(|event| match event {
        AssetEvent::Added { id }
        | AssetEvent::Modified { id }
        | AssetEvent::Removed { id }
        | AssetEvent::LoadedWithDependencies { id } => table.model_ids.contains(id),
        AssetEvent::Unused { .. } => false,
    });
    if models_changed {
        table.models_version += 1;
    }
    // (`Changed` includes added. Both readers are drained every frame; trees that were
    // never in the table, such as a calibration's benchmark trees, change nothing.)
    let mut leaving = Vec::new();
    for entity in removed.read() {
        left_out.remove(&entity);
        if table.index.contains_key(&entity) {
            leaving.push(entity);
        }
    }
    leaving.extend(fixed.iter().filter(|e| table.index.contains_key(e)));
    let mut joining: Vec<Entity> = unfixed.read().filter(|&e| trees.contains(e)).collect();
    for entity in &changed {
        if table.index.contains_key(&entity) {
            leaving.push(entity);
        }
        joining.push(entity);
    }
    for (entity, tree, transform) in &moved {
        let placed = placeable(&transform.affine(), tree.scale);
        match (table.index.contains_key(&entity), placed) {
            (true, false) => leaving.push(entity),
            (false, true) => joining.push(entity),
            _ => {}
        }
    }
    leaving.sort_unstable();
    leaving.dedup();
    joining.sort_unstable();
    joining.dedup();
    // Survivors keep their index; the new ones follow forest by forest in each forest's
    // own instance order (hand-placed trees last), so a respawned forest is laid out the
    // same way every time, whatever entities it was given.
    let mut added: Vec<(Entity, &TreeInstance, Affine3A)> = joining
        .iter()
        .filter(|&&e| !table.index.contains_key(&e) || leaving.binary_search(&e).is_ok())
        .filter_map(|&e| trees.get(e).ok())
        .map(|(entity, tree, transform)| (entity, tree, transform.affine()))
        .filter(|&(entity, tree, affine)| {
            let placed = placeable(&affine, tree.scale);
            if placed {
                left_out.remove(&entity);
            } else if left_out.insert(entity) {
                warn!(
                    "bevy_sherwood: tree {entity} is not drawn: its transform ({}) or \
                     scale ({}) is not finite, or it stands over {MAX_TREE_COORDINATE} m \
                     from the origin; it is drawn again once it is placed",
                    affine.translation, tree.scale
                );
            }
            placed
        })
        .collect();
    added
        .sort_by_key(|(entity, tree, _)| (tree.forest.index_u32(), tree.index, entity.index_u32()));
    let edited = !leaving.is_empty() || !added.is_empty();
    if edited {
        table.edit(&leaving, added.into_iter());
    }
    table.moved.clear();
    for (entity, _, transform) in &moved {
        if let Some(&i) = table.index.get(&entity)
            && table.transforms[i as usize] != transform.affine()
        {
            table.transforms[i as usize] = transform.affine();
            table.moved.push(i);
        }
    }
    if !table.moved.is_empty() {
        table.moved.sort_unstable();
        if !edited {
            table.transforms_version += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn tree(model: u128) -> TreeInstance {
        TreeInstance::new(Handle::Uuid(
            bevy::asset::uuid::Uuid::from_u128(model),
            Default::default(),
        ))
    }

    /// Rounds of felling and planting: state kept per instance and replayed with the
    /// table's edits stays indexed like the table, and every instance that did not fill a
    /// hole keeps its index.
    #[test]
    fn state_replayed_with_the_edits_stays_indexed_like_the_table() {
        let mut rng = SplitMix64::new(7);
        let mut table = ForestInstances::default();
        let mut follower: Vec<Entity> = Vec::new();
        let mut next = 1_u32;
        for round in 0..200 {
            let before = table.layout_version();
            let old: Vec<Entity> = table.entities.clone();
            let felled: Vec<Entity> = old.iter().copied().filter(|_| rng.unit() < 0.1).collect();
            let planted: Vec<(Entity, TreeInstance)> = (0..rng.next_u64() % 6)
                .map(|_| {
                    next += 1;
                    (
                        Entity::from_raw_u32(next).unwrap(),
                        tree(u128::from(rng.next_u64() % 3)),
                    )
                })
                .collect();
            table.edit(
                &felled,
                planted
                    .iter()
                    .map(|(e, t)| (*e, t, Affine3A::from_translation(Vec3::splat(next as f32)))),
            );
            let edits = table.edits_since(before).expect("one edit after the last");
            assert!(table.edits_since(before.wrapping_sub(1)).is_none());
            edits.apply(&mut follower, |i| table.entities[i]);
            assert_eq!(follower, table.entities, "round {round}");
            // Only the last ones fill holes.
            let kept = old.len() - felled.len();
            for (i, e) in old.iter().enumerate().take(kept) {
                if !felled.contains(e) {
                    assert_eq!(table.index_of(*e), Some(i as u32), "round {round}");
                }
            }
            for (i, &e) in table.entities.iter().enumerate() {
                assert_eq!(table.index_of(e), Some(i as u32));
                let id = table.model_id(i).unwrap();
                assert!(table.model_ids.iter().filter(|&&m| m == id).count() == 1);
            }
            assert_eq!(
                table.entities.len(),
                old.len() - felled.len() + planted.len()
            );
        }
    }

    #[test]
    fn a_tree_instance_brings_its_transform_and_is_reflected() {
        let mut app = App::new();
        app.add_plugins(crate::SherwoodCorePlugin);
        let tree = app.world_mut().spawn(tree(1)).id();
        assert!(app.world().get::<Transform>(tree).is_some());
        #[cfg(feature = "render")]
        assert!(app.world().get::<Visibility>(tree).is_some());
        let registry = app.world().resource::<AppTypeRegistry>().read();
        for name in ["TreeInstance", "ForestInstances", "FixedDrawList"] {
            assert!(
                registry.get_with_short_type_path(name).is_some(),
                "{name} is not registered"
            );
        }
    }
}
