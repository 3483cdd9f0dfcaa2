//! Culling in the ECS (`SherwoodSystems::Cull`): the box hierarchy over a forest's
//! instances, culled every frame against the view, and a debug view of its boxes.

use bevy::prelude::*;

use super::hierarchy::{
    BoxHierarchy, CullInstance, CullResult, CullShape, FrustumPlanes, MovedShapes,
};
use crate::ecosystem::{ForestState, ForestTerrain, TreeInstance};
use crate::schedule::SherwoodSystems;
use crate::tree::{Bounds, TreeModel};

/// The view culling tests against. Cameras get one automatically from their Bevy
/// `Frustum` (with the `render` feature); headless apps insert it themselves.
/// With several, the first one found is used.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct CullView(pub FrustumPlanes);

/// The culling state of the forest being shown: instance `i` of `entities` has
/// visibility `result.visibility[i]`.
#[derive(Resource, Default)]
pub struct ForestCulling {
    /// The instance entities, in the order of [`CullResult::visibility`].
    pub entities: Vec<Entity>,
    /// Their transforms and shapes.
    pub instances: Vec<CullInstance>,
    /// The culling shape of every species.
    pub shapes: Vec<CullShape>,
    /// The hierarchy, once every species' model has loaded.
    pub hierarchy: Option<BoxHierarchy>,
    /// This frame's answer.
    pub result: CullResult,
    /// Shapes of the instances the wind moved this frame (filled by the wind stage,
    /// which runs first), indexed like `entities`.
    pub moved: MovedShapes,
    generation: u32,
    failed_logged: u32,
    rebuilds: u64,
}

impl ForestCulling {
    /// Changes whenever `entities` (and with it every per-instance index) is rebuilt.
    pub fn layout_version(&self) -> u64 {
        self.rebuilds
    }
}

/// Draws the culling boxes with gizmos: dashed for fully visible, solid for partially
/// visible (thesis figure 4.7). Default: off.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub struct CullingDebug {
    /// Draw the boxes. Default: `false`.
    pub enabled: bool,
}

/// Builds and runs the box hierarchy in [`SherwoodSystems::Cull`].
#[derive(Default)]
pub struct CullingPlugin;

impl Plugin for CullingPlugin {
    fn build(&self, app: &mut App) {
        app.init_resource::<ForestCulling>()
            .init_resource::<CullingDebug>()
            .register_type::<CullingDebug>()
            .add_systems(
                PostUpdate,
                (rebuild_hierarchy, cull_forest)
                    .chain()
                    .in_set(SherwoodSystems::Cull),
            );
        #[cfg(feature = "render")]
        app.add_systems(PostUpdate, update_cull_views.before(SherwoodSystems::Cull));
    }

    fn finish(&self, app: &mut App) {
        crate::schedule::require_plugin::<crate::tree::TreePlugin>(
            app,
            "CullingPlugin",
            "TreePlugin",
        );
        // The debug view needs Bevy's gizmos, which headless apps do not have.
        #[cfg(feature = "render")]
        if app.is_plugin_added::<bevy::gizmos::GizmoPlugin>() {
            app.init_gizmo_group::<FullyVisibleBoxes>()
                .add_systems(Startup, configure_debug_gizmos)
                .add_systems(
                    PostUpdate,
                    draw_culling_boxes
                        .after(SherwoodSystems::Cull)
                        .run_if(|debug: Res<CullingDebug>| debug.enabled),
                );
        }
        #[cfg(not(feature = "render"))]
        let _ = app;
    }
}

/// Rebuilds the hierarchy when the forest was (re)spawned or its models finished loading.
fn rebuild_hierarchy(
    mut culling: ResMut<ForestCulling>,
    forests: Query<&ForestState>,
    instances: Query<(&TreeInstance, &GlobalTransform)>,
    terrains: Query<&ForestTerrain>,
    models: Res<Assets<TreeModel>>,
    server: Res<AssetServer>,
) {
    let Some(state) = forests.iter().find(|s| !s.instances.is_empty()) else {
        return;
    };
    if culling.hierarchy.is_some() && culling.generation == state.generation {
        return;
    }
    // A species whose tree failed to load gets an empty shape: its instances are never
    // visible, and the rest of the forest is not held back waiting for it.
    let mut shapes = Vec::with_capacity(state.species.len());
    for handle in &state.species {
        if let Some(model) = models.get(handle) {
            shapes.push(CullShape::from(model));
        } else if server.load_state(handle).is_failed() {
            if culling.failed_logged != state.generation {
                error!(
                    "tree {:?} failed to load; its instances are not drawn",
                    handle.path()
                );
            }
            shapes.push(CullShape {
                bounds: Bounds::EMPTY,
                trunk: Bounds::EMPTY,
                groups: Vec::new(),
            });
        } else {
            return; // still loading
        }
    }
    culling.failed_logged = state.generation;
    let mut entities = Vec::with_capacity(state.instances.len());
    let mut list = Vec::with_capacity(state.instances.len());
    for &entity in &state.instances {
        let Ok((instance, transform)) = instances.get(entity) else {
            return; // spawned this frame: transforms not propagated yet
        };
        entities.push(entity);
        list.push(CullInstance {
            transform: transform.affine(),
            shape: instance.species as u32,
        });
    }
    let area = state
        .terrain
        .and_then(|t| terrains.get(t).ok())
        .map_or_else(
            || Bounds::from_points(list.iter().map(|i| Vec3::from(i.transform.translation))),
            |t| Bounds {
                min: Vec3::ZERO,
                max: Vec3::new(t.terrain.size(), 0.0, t.terrain.size()),
            },
        );
    culling.hierarchy = Some(BoxHierarchy::build(
        state.culling_depth,
        &area,
        &list,
        &shapes,
    ));
    culling.entities = entities;
    // Indexed by the old order.
    culling.moved.clear();
    culling.instances = list;
    culling.shapes = shapes;
    culling.generation = state.generation;
    culling.rebuilds += 1;
}

fn cull_forest(mut culling: ResMut<ForestCulling>, views: Query<&CullView>) {
    let Some(view) = views.iter().next() else {
        return;
    };
    let ForestCulling {
        instances,
        shapes,
        hierarchy,
        result,
        moved,
        ..
    } = &mut *culling;
    if let Some(hierarchy) = hierarchy {
        hierarchy.cull(&view.0, instances, shapes, moved, result);
    }
}

#[cfg(feature = "render")]
fn update_cull_views(
    mut commands: Commands,
    cameras: Query<
        (
            Entity,
            &bevy::camera::primitives::Frustum,
            Option<&CullView>,
        ),
        With<Camera3d>,
    >,
) {
    for (entity, frustum, view) in &cameras {
        let planes = FrustumPlanes(frustum.0.half_spaces.map(|h| h.normal_d()));
        if view.is_none_or(|v| v.0 != planes) {
            commands.entity(entity).insert(CullView(planes));
        }
    }
}

/// Gizmo group for fully visible boxes, drawn dashed.
#[cfg(feature = "render")]
#[derive(Default, Reflect, GizmoConfigGroup)]
pub struct FullyVisibleBoxes;

#[cfg(feature = "render")]
fn configure_debug_gizmos(mut store: ResMut<GizmoConfigStore>) {
    let (config, _) = store.config_mut::<FullyVisibleBoxes>();
    config.line.style = GizmoLineStyle::Dashed {
        gap_scale: 3.0,
        line_scale: 6.0,
    };
}

#[cfg(feature = "render")]
fn draw_culling_boxes(
    culling: Res<ForestCulling>,
    mut solid: Gizmos,
    mut dashed: Gizmos<FullyVisibleBoxes>,
) {
    use super::hierarchy::NodeVisibility;
    use bevy::math::bounding::Aabb3d;
    let Some(hierarchy) = &culling.hierarchy else {
        return;
    };
    for (bounds, visibility) in hierarchy.nodes() {
        let aabb = Aabb3d::new(bounds.center(), bounds.half_extents());
        match visibility {
            NodeVisibility::Full => {
                dashed.aabb_3d(aabb, Transform::IDENTITY, Color::srgb(0.2, 0.9, 0.3));
            }
            NodeVisibility::Partial => {
                solid.aabb_3d(aabb, Transform::IDENTITY, Color::srgb(0.95, 0.8, 0.2));
            }
            _ => {}
        }
    }
}
