//! Ecosystems in the ECS: the `*.ecosystem.ron` asset, and forests spawned (and
//! respawned when the file changes) from it.

use bevy::asset::io::Reader;
use bevy::asset::{AssetLoader, LoadContext};
use bevy::prelude::*;

use crate::draw::{Shading, TreeShading};

use super::desc::{EcosystemDesc, EcosystemError};
use super::terrain::Terrain;
use crate::culling::CullingSettings;
use crate::instance::TreeInstance;
use crate::tree::TreeModel;

/// A loaded, validated ecosystem description.
#[derive(Asset, TypePath, Clone, Debug, Deref)]
pub struct Ecosystem(pub EcosystemDesc);

/// Why an ecosystem file could not be loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum EcosystemFileError {
    /// Reading failed.
    #[error("could not read the file: {0}")]
    Io(#[from] std::io::Error),
    /// Not UTF-8.
    #[error("the file is not UTF-8 text: {0}")]
    Utf8(#[from] core::str::Utf8Error),
    /// Malformed or out of range (the message names line, column and field).
    #[error("{0}")]
    Ecosystem(#[from] EcosystemError),
}

/// Loads `*.ecosystem.ron` files.
#[derive(Default, TypePath)]
pub(crate) struct EcosystemLoader;

impl AssetLoader for EcosystemLoader {
    type Asset = Ecosystem;
    type Settings = ();
    type Error = EcosystemFileError;

    async fn load(
        &self,
        reader: &mut dyn Reader,
        _settings: &(),
        _load_context: &mut LoadContext<'_>,
    ) -> Result<Ecosystem, EcosystemFileError> {
        let text = crate::ron_file::read_text::<EcosystemFileError>(reader).await?;
        Ok(Ecosystem(EcosystemDesc::from_ron_str(&text)?))
    }

    fn extensions(&self) -> &[&str] {
        &["ecosystem.ron"]
    }
}

/// Spawns a forest from an ecosystem file, and respawns it when the file changes:
/// `commands.spawn(Forest(asset_server.load("forests/default.ecosystem.ron")))`.
///
/// A malformed edit fails to load, is logged with its line, column and field, and leaves
/// the previous forest standing. Despawning it despawns its trees and terrain
/// ([`ForestMembers`]).
#[derive(Component, Clone, Debug, Reflect)]
#[reflect(Component, Debug)]
#[require(ForestState)]
pub struct Forest(pub Handle<Ecosystem>);

/// The [`Forest`] a tree or a terrain was spawned by: despawning the forest despawns
/// them ([`ForestMembers`]). A relationship of its own, not `ChildOf`: the trees keep
/// their own transforms and do not move with the forest entity.
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
#[relationship(relationship_target = ForestMembers)]
pub struct InForest(pub Entity);

/// The trees and the terrain a [`Forest`] spawned (kept by Bevy from their
/// [`InForest`]); they are despawned with it.
#[derive(Component, Debug, Default, PartialEq, Eq)]
#[relationship_target(relationship = InForest, linked_spawn)]
pub struct ForestMembers(Vec<Entity>);

/// What a [`Forest`] has spawned.
#[derive(Component, Clone, Debug, Default, Reflect)]
#[reflect(Component, Default)]
pub struct ForestState {
    /// The tree model of every species, in the ecosystem's species order.
    pub species: Vec<Handle<TreeModel>>,
    /// The instance entities, in instance order.
    pub instances: Vec<Entity>,
    /// The terrain entity.
    pub terrain: Option<Entity>,
    /// Incremented at every (re)spawn.
    pub generation: u32,
    spawned: bool,
}

/// The terrain of a forest: query heights and normals with [`Terrain::height_at`] and
/// [`Terrain::normal_at`].
#[derive(Component, Clone, Debug)]
pub struct ForestTerrain {
    /// The [`Forest`] entity it belongs to.
    pub forest: Entity,
    /// The sampled terrain.
    pub terrain: Terrain,
}

/// Registers ecosystem assets and spawns [`Forest`]s.
#[derive(Default)]
pub struct EcosystemPlugin;

impl Plugin for EcosystemPlugin {
    fn finish(&self, app: &mut App) {
        crate::schedule::require_plugin::<crate::tree::TreePlugin>(
            app,
            "EcosystemPlugin",
            "TreePlugin",
        );
    }

    fn build(&self, app: &mut App) {
        crate::schedule::require_plugin::<AssetPlugin>(
            app,
            "EcosystemPlugin",
            "Bevy's AssetPlugin",
        );
        app.init_asset::<Ecosystem>()
            .register_type::<Forest>()
            .register_type::<ForestState>()
            .register_asset_loader(EcosystemLoader)
            .add_systems(Update, spawn_forests);
        #[cfg(feature = "render")]
        super::terrain_material::add_terrain_material(app);
    }
}

fn spawn_forests(
    mut commands: Commands,
    mut events: MessageReader<AssetEvent<Ecosystem>>,
    mut forests: Query<(Entity, &Forest, &mut ForestState)>,
    ecosystems: Res<Assets<Ecosystem>>,
    server: Res<AssetServer>,
    mut culling: Option<ResMut<CullingSettings>>,
    // Absent in headless apps: the terrain then gets no mesh.
    #[cfg(feature = "render")] mut meshes: Option<ResMut<Assets<Mesh>>>,
    #[cfg(feature = "render")] mut materials: Option<ResMut<Assets<super::TerrainMaterial>>>,
    // Only when SherwoodPlugins came before Bevy's PbrPlugin (see `TerrainMaterial`).
    #[cfg(feature = "render")] mut standard_materials: Option<ResMut<Assets<StandardMaterial>>>,
) {
    let changed: Vec<AssetId<Ecosystem>> = events
        .read()
        .filter_map(|e| match e {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    for (entity, forest, mut state) in &mut forests {
        let id = forest.0.id();
        if state.spawned && !changed.contains(&id) {
            continue;
        }
        let Some(ecosystem) = ecosystems.get(id) else {
            continue;
        };
        let layout = match ecosystem.layout() {
            Ok(layout) => layout,
            Err(e) => {
                error!(
                    "ecosystem {:?}: {e}; the previous forest stays",
                    forest.0.path()
                );
                state.spawned = true;
                continue;
            }
        };
        let terrain = state.terrain.take();
        for old in state.instances.drain(..).chain(terrain) {
            commands.entity(old).try_despawn();
        }
        state.species = ecosystem
            .species
            .iter()
            .map(|s| server.load::<TreeModel>(&s.tree))
            .collect();
        if let Some(culling) = culling.as_deref_mut() {
            culling.depth = ecosystem.culling_depth;
        }
        state.generation += 1;
        state.spawned = true;
        let shadings: Vec<Shading> = ecosystem
            .materials
            .values()
            .map(|m| Shading {
                ambient: Vec3::from(m.ambient),
                diffuse: Vec3::from(m.diffuse),
                specular: Vec3::from(m.specular),
                shininess: m.shininess,
            })
            .collect();
        for (index, instance) in layout.instances.iter().enumerate() {
            let (scale, rotation, translation) = instance.transform.to_scale_rotation_translation();
            let id = commands
                .spawn((
                    TreeInstance {
                        forest: entity,
                        species: instance.species,
                        model: state.species[instance.species].clone(),
                        index: index as u32,
                        scale: instance.scale,
                        trunk_material: instance.trunk_material,
                        leaf_material: instance.leaf_material,
                        motion: instance.motion,
                    },
                    InForest(entity),
                    Transform {
                        translation,
                        rotation,
                        scale,
                    },
                ))
                .id();
            if let (Some(&trunk), Some(&leaves)) = (
                shadings.get(instance.trunk_material),
                shadings.get(instance.leaf_material),
            ) {
                commands
                    .entity(id)
                    .try_insert(TreeShading { trunk, leaves });
            }
            state.instances.push(id);
        }
        let terrain = commands
            .spawn((
                ForestTerrain {
                    forest: entity,
                    terrain: layout.terrain.clone(),
                },
                InForest(entity),
                Transform::default(),
            ))
            .id();
        #[cfg(feature = "render")]
        if let Some(meshes) = meshes
            .as_mut()
            .filter(|_| materials.is_some() || standard_materials.is_some())
        {
            let t = &layout.terrain;
            let mesh = meshes.add(crate::tree::triangle_mesh(
                &t.mesh_positions(),
                &t.mesh_normals(),
                &t.mesh_indices(),
            ));
            let material = ecosystem
                .materials
                .get(&ecosystem.terrain_material)
                .map_or_else(
                    super::TerrainMaterial::default,
                    super::TerrainMaterial::from_desc,
                );
            if let Some(materials) = materials.as_mut() {
                commands
                    .entity(terrain)
                    .try_insert((Mesh3d(mesh), MeshMaterial3d(materials.add(material))));
            } else if let Some(materials) = standard_materials.as_mut() {
                commands.entity(terrain).try_insert((
                    Mesh3d(mesh),
                    MeshMaterial3d(materials.add(StandardMaterial {
                        base_color: material.diffuse.into(),
                        perceptual_roughness: 0.95,
                        ..default()
                    })),
                ));
            }
        }
        state.terrain = Some(terrain);
    }
}
