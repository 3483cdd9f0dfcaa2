//! The instance table: every [`TreeInstance`] in the world — every ecosystem's trees and
//! trees spawned by hand — in one dense, indexed list that culling, the level of detail,
//! the wind and the render pass all index the same way.
//!
//! [`ForestInstances`] is kept by one system at the head of the frame
//! ([`SherwoodSystems::Instances`](crate::schedule::SherwoodSystems::Instances)): a tree
//! spawned or despawned changes the layout (and [`ForestInstances::layout_version`]); a
//! tree whose `GlobalTransform` changed keeps its index and is listed in
//! [`ForestInstances::moved`] for that frame. A tree with [`FixedDrawList`] stays out: it
//! draws the list it was given.

use bevy::ecs::entity::EntityHashMap;
use bevy::math::Affine3A;
use bevy::prelude::*;

use crate::tree::TreeModel;

/// One tree in the world. Spawn it with a `Transform` (uniform scale); the Sherwood stages
/// cull it, give it time and draw it, whether an ecosystem spawned it or you did
/// ([`TreeInstance::new`]).
#[derive(Component, Clone, Debug)]
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
#[derive(Component, Clone, Copy, Debug, Default)]
pub struct FixedDrawList;

/// Every [`TreeInstance`] without [`FixedDrawList`], densely indexed: instance `i` is
/// `entities[i]`, placed by `transforms[i]`, of model `model_ids[models[i]]`. Every
/// per-instance array of the later stages (culling's result, the wind's offsets, the
/// level of detail's placement) is indexed the same way.
#[derive(Resource, Debug, Default)]
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
    index: EntityHashMap<u32>,
    moved: Vec<u32>,
    layout_version: u64,
    transforms_version: u64,
}

impl ForestInstances {
    /// Changes whenever an instance was added or removed (or its model changed): every
    /// index may have changed.
    pub fn layout_version(&self) -> u64 {
        self.layout_version
    }

    /// Changes whenever an instance moved (or the layout changed).
    pub fn transforms_version(&self) -> u64 {
        self.transforms_version
    }

    /// The instances whose transform changed this frame, layout unchanged (ascending).
    pub fn moved(&self) -> &[u32] {
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
    pub fn index_of(&self, entity: Entity) -> Option<u32> {
        self.index.get(&entity).copied()
    }

    /// The model of instance `i`.
    pub fn model_id(&self, i: usize) -> Option<AssetId<TreeModel>> {
        self.model_ids.get(*self.models.get(i)? as usize).copied()
    }

    /// Lays the table out anew from `trees` in `order`.
    fn lay_out<'a>(&mut self, trees: impl Iterator<Item = (Entity, &'a TreeInstance, Affine3A)>) {
        self.entities.clear();
        self.transforms.clear();
        self.models.clear();
        self.model_ids.clear();
        self.scales.clear();
        self.motions.clear();
        self.index.clear();
        self.moved.clear();
        let mut model_index: bevy::platform::collections::HashMap<AssetId<TreeModel>, u32> =
            Default::default();
        for (entity, tree, transform) in trees {
            let id = tree.model.id();
            let next = model_index.len() as u32;
            let model = *model_index.entry(id).or_insert_with(|| {
                self.model_ids.push(id);
                next
            });
            self.index.insert(entity, self.entities.len() as u32);
            self.entities.push(entity);
            self.transforms.push(transform);
            self.models.push(model);
            self.scales.push(tree.scale);
            self.motions.push(tree.motion);
        }
        self.layout_version += 1;
        self.transforms_version += 1;
    }
}

type Tracked = (With<TreeInstance>, Without<FixedDrawList>);

/// The farthest a tree may stand from the origin on any axis, metres: past it an `f32`
/// position is coarser than a few centimetres, and one tree that far would stretch the
/// culling hierarchy over every other.
pub const MAX_TREE_COORDINATE: f32 = 1.0e6;

/// Whether a tree at `transform` with `scale` can be culled and drawn: a finite
/// transform within [`MAX_TREE_COORDINATE`] of the origin and a positive, finite scale.
/// Others (a NaN from a physics step, a tree sent to infinity) stay out of the instance
/// table, with a warning, until they are placeable again.
pub fn placeable(transform: &Affine3A, scale: f32) -> bool {
    transform.is_finite()
        && transform.translation.abs().max_element() <= MAX_TREE_COORDINATE
        && scale.is_finite()
        && scale > 0.0
}

/// Keeps [`ForestInstances`] up to date: a new layout when instances were added, removed,
/// given another tree or moved in or out of [`placeable`] places; otherwise the moved
/// ones' transforms.
pub(crate) fn track_instances(
    mut table: ResMut<ForestInstances>,
    changed: Query<(), (Tracked, Changed<TreeInstance>)>,
    mut removed: RemovedComponents<TreeInstance>,
    mut fixed: RemovedComponents<FixedDrawList>,
    trees: Query<(Entity, &TreeInstance, &GlobalTransform), Without<FixedDrawList>>,
    moved: Query<(Entity, &TreeInstance, &GlobalTransform), (Tracked, Changed<GlobalTransform>)>,
    mut left_out: Local<bevy::ecs::entity::EntityHashSet>,
) {
    let table = &mut *table;
    // (`Changed` includes added. Both readers are drained every frame; trees that were
    // never in the table, such as a calibration's benchmark trees, change nothing.)
    let left = removed
        .read()
        .filter(|e| table.index.contains_key(e) || left_out.remove(e))
        .count();
    let joined = fixed.read().filter(|&e| trees.contains(e)).count();
    let crossed = || {
        moved.iter().any(|(entity, tree, transform)| {
            table.index.contains_key(&entity) != placeable(&transform.affine(), tree.scale)
        })
    };
    if left + joined > 0 || !changed.is_empty() || crossed() {
        // Survivors keep their order; the new ones follow forest by forest in each
        // forest's own instance order (hand-placed trees last), so a respawned forest is
        // laid out the same way every time, whatever entities it was given.
        let mut order: Vec<(Entity, &TreeInstance, Affine3A)> = trees
            .iter()
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
        order.sort_by_key(|(entity, tree, _)| {
            (
                table.index.get(entity).copied().unwrap_or(u32::MAX),
                tree.forest.index_u32(),
                tree.index,
                entity.index_u32(),
            )
        });
        table.lay_out(order.into_iter());
        return;
    }
    table.moved.clear();
    for (entity, _, transform) in &moved {
        if let Some(&i) = table.index.get(&entity) {
            table.transforms[i as usize] = transform.affine();
            table.moved.push(i);
        }
    }
    if !table.moved.is_empty() {
        table.moved.sort_unstable();
        table.transforms_version += 1;
    }
}
