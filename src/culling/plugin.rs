//! Culling in the ECS (`SherwoodSystems::Cull`): the box hierarchy over a forest's
//! instances, culled every frame against the view, and a debug view of its boxes.

use bevy::prelude::*;

use super::hierarchy::{
    BoxHierarchy, CullInstance, CullResult, CullShape, FrustumPlanes, InstanceVisibility,
    MovedShapes,
};
use crate::instance::{ForestInstances, LayoutEdits};
use crate::schedule::SherwoodSystems;
use crate::tree::{Bounds, TreeModel};

/// The view culling tests against. The camera the budget follows gets one automatically
/// from its Bevy `Frustum` (with the `render` feature; see
/// [`BudgetView`](crate::view::BudgetView)); headless apps insert it themselves, next to
/// a [`LodView`](crate::view::LodView):
///
/// ```
/// # use bevy::prelude::*;
/// # use bevy_sherwood::culling::CullView;
/// let eye = Vec3::new(0.0, 2.0, 10.0);
/// let clip_from_world = Mat4::perspective_infinite_reverse_rh(1.2, 16.0 / 9.0, 0.1)
///     * Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
/// let view = CullView::from_clip_from_world(clip_from_world);
/// ```
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct CullView(pub(crate) FrustumPlanes);

impl CullView {
    /// The view of a camera whose `clip_from_world` (projection times view) matrix this
    /// is: the six planes of its frustum.
    pub fn from_clip_from_world(clip_from_world: Mat4) -> Self {
        Self(FrustumPlanes::from_clip_from_world(clip_from_world))
    }
}

/// The culling state of the instances in
/// [`ForestInstances`](crate::instance::ForestInstances): instance `i` has visibility
/// `result.visibility[i]`.
#[derive(Resource, Default)]
pub struct ForestCulling {
    /// Every instance's transform and shape (its model's index in
    /// [`ForestInstances::model_ids`]).
    pub(crate) instances: Vec<CullInstance>,
    /// The culling shape of every model (empty while it loads, or when it failed).
    pub(crate) shapes: Vec<CullShape>,
    /// The hierarchy, once there are instances.
    pub(crate) hierarchy: Option<BoxHierarchy>,
    /// This frame's answer.
    pub(crate) result: CullResult,
    /// `(instance layout, the instances' models version, depth)` the hierarchy was built
    /// for.
    built: Option<(u64, u64, u32)>,
    loading: u32,
    /// Since when (`Time<Real>` seconds) some model has been loading, and how many have
    /// been loading for over [`LOADING_WARNING_SECS`].
    loading_since: Option<f32>,
    stuck: u32,
    failed_logged: Vec<AssetId<TreeModel>>,
    rebuilds: u64,
    refits: u64,
    edits: u64,
    boxes_version: u64,
}

impl ForestCulling {
    /// The [`ForestInstances::layout_version`] that `result` is indexed by (`None` before
    /// the first hierarchy).
    pub(crate) fn layout_version(&self) -> Option<u64> {
        self.built.map(|(layout, ..)| layout)
    }

    /// Changes whenever the hierarchy is built anew for another layout or depth (not when
    /// it follows an edit of the layout or a move, nor when only the models changed): box
    /// indices of an older version mean other boxes. `None` before the first hierarchy.
    pub(crate) fn hierarchy_version(&self) -> Option<u64> {
        self.built.map(|_| self.boxes_version)
    }

    /// Whether the hierarchy is built: there are instances, and culling runs.
    pub fn is_built(&self) -> bool {
        self.hierarchy.is_some()
    }

    /// How many of the instances' models are still loading (their instances are not
    /// visible until they have).
    pub fn models_loading(&self) -> u32 {
        self.loading
    }

    /// How many models have been loading for over [`LOADING_WARNING_SECS`] (a handle
    /// that never loads: a typo'd path the asset server still waits on, an asset added by
    /// hand under a reserved handle that never came): their trees are not drawn, and a
    /// warning names them once.
    pub(crate) fn models_stuck_loading(&self) -> u32 {
        self.stuck
    }

    /// How many times the hierarchy was built, and how many times refitted for moved
    /// instances.
    #[cfg(test)]
    pub(crate) fn rebuilds_and_refits(&self) -> (u64, u64) {
        (self.rebuilds, self.refits)
    }
}

/// A tree model still loading after this many seconds is warned about, once.
pub(crate) const LOADING_WARNING_SECS: f32 = 10.0;

/// How the box hierarchy is built.
#[derive(Resource, Clone, Copy, Debug, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub struct CullingSettings {
    /// Levels of the box hierarchy below its root (4^depth leaf boxes over the
    /// instances' area), at most 10. An ecosystem sets it to its `culling_depth` when it
    /// spawns. Default: `4`.
    pub depth: u32,
}

impl Default for CullingSettings {
    fn default() -> Self {
        Self { depth: 4 }
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
        crate::core_plugin::use_instance_table(app);
        app.init_resource::<ForestCulling>()
            .init_resource::<CullingDebug>()
            .init_resource::<CullingSettings>()
            .register_type::<CullingDebug>()
            .register_type::<CullingSettings>()
            // The hierarchy follows the layout before the wind reads last frame's answer.
            .add_systems(
                PostUpdate,
                (rebuild_hierarchy, warn_models_stuck_loading)
                    .chain()
                    .after(SherwoodSystems::Instances)
                    .before(SherwoodSystems::Animate),
            )
            .add_systems(PostUpdate, cull_forest.in_set(SherwoodSystems::Cull));
        #[cfg(feature = "render")]
        app.add_systems(
            PostUpdate,
            update_cull_views
                .after(SherwoodSystems::Instances)
                .before(SherwoodSystems::Cull),
        );
    }

    fn finish(&self, app: &mut App) {
        crate::core_plugin::warn_without_core(app, "CullingPlugin");
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

/// Counts, and names once, the models that have been loading for over
/// [`LOADING_WARNING_SECS`].
fn warn_models_stuck_loading(
    mut culling: ResMut<ForestCulling>,
    table: Res<ForestInstances>,
    models: Res<Assets<TreeModel>>,
    server: Res<AssetServer>,
    time: Res<Time<Real>>,
) {
    if culling.loading == 0 {
        culling.loading_since = None;
        culling.stuck = 0;
        return;
    }
    let now = time.elapsed_secs();
    let since = *culling.loading_since.get_or_insert(now);
    if culling.stuck > 0 || now - since < LOADING_WARNING_SECS {
        return;
    }
    for (m, &id) in table.model_ids.iter().enumerate() {
        if models.contains(id) || server.load_state(id).is_failed() {
            continue;
        }
        let trees = table.models.iter().filter(|&&i| i as usize == m).count();
        let name = server
            .get_path(id)
            .map_or_else(|| format!("{id:?}"), |path| format!("`{path}`"));
        warn!(
            "bevy_sherwood: tree {name} has not loaded in {LOADING_WARNING_SECS} s \
             ({:?}); its {trees} trees are not drawn until it does",
            server.load_state(id)
        );
        culling.stuck += 1;
    }
}

/// Builds the hierarchy when the models or the depth changed, or the instance layout
/// changed by more than [`BoxHierarchy::edit`] follows; edits it when trees were planted
/// or felled; refits it when instances only moved.
fn rebuild_hierarchy(
    mut culling: ResMut<ForestCulling>,
    table: Res<ForestInstances>,
    settings: Res<CullingSettings>,
    models: Res<Assets<TreeModel>>,
    server: Res<AssetServer>,
) {
    let culling = &mut *culling;
    let key = (
        table.layout_version(),
        table.models_version(),
        settings.depth,
    );
    let followed = match culling.built {
        Some(built) if built == key => true,
        Some((layout, models_version, depth)) if (models_version, depth) == (key.1, key.2) => table
            .edits_since(layout)
            .is_some_and(|edits| culling.follow_edits(edits, &table, &models, &server)),
        _ => false,
    };
    if followed {
        culling.built = Some(key);
        if table.moved().is_empty() {
            return;
        }
        for &i in table.moved() {
            culling.instances[i as usize].transform = table.transforms[i as usize];
        }
        if let Some(hierarchy) = &mut culling.hierarchy
            && hierarchy.refit(table.moved(), &culling.instances, &culling.shapes)
        {
            culling.refits += 1;
            return;
        }
    }
    culling.shapes.clear();
    culling.loading = 0;
    for &id in &table.model_ids {
        let shape = culling.shape_of(id, &models, &server);
        culling.shapes.push(shape);
    }
    culling.instances.clear();
    culling
        .instances
        .extend((0..table.len()).map(|i| cull_instance(&table, i)));
    let area = Bounds::from_points(
        culling
            .instances
            .iter()
            .map(|i| Vec3::from(i.transform.translation)),
    );
    let hierarchy = (!culling.instances.is_empty())
        .then(|| BoxHierarchy::build(settings.depth, &area, &culling.instances, &culling.shapes));
    // Group impostors and the hierarchical cut are kept per box: only a build over other
    // trees or other cells makes them stale (a model's new shape does not).
    let same_boxes = culling.built.map(|(layout, ..)| layout) == Some(key.0)
        && match (&culling.hierarchy, &hierarchy) {
            (Some(old), Some(new)) => old.same_cells(new),
            (old, new) => old.is_none() && new.is_none(),
        };
    if !same_boxes {
        culling.boxes_version += 1;
    }
    culling.hierarchy = hierarchy;
    culling.result.clear(culling.instances.len());
    culling.built = Some(key);
    culling.rebuilds += 1;
}

fn cull_instance(table: &ForestInstances, i: usize) -> CullInstance {
    CullInstance {
        transform: table.transforms[i],
        shape: table.models[i],
    }
}

impl ForestCulling {
    /// The culling shape of model `id`. A model still loading, or whose tree failed to
    /// load, gets an empty shape: its instances are not visible (until it loads), and the
    /// rest is not held back.
    fn shape_of(
        &mut self,
        id: AssetId<TreeModel>,
        models: &Assets<TreeModel>,
        server: &AssetServer,
    ) -> CullShape {
        if let Some(model) = models.get(id) {
            return CullShape::from(model);
        }
        if !server.load_state(id).is_failed() {
            self.loading += 1;
        } else if !self.failed_logged.contains(&id) {
            error!(
                "tree {:?} failed to load; its instances are not drawn",
                server.get_path(id)
            );
            self.failed_logged.push(id);
        }
        CullShape {
            bounds: Bounds::EMPTY,
            trunk: Bounds::EMPTY,
            groups: Vec::new(),
        }
    }

    /// Replays the table's `edits` on the instances, the hierarchy and last frame's
    /// answer (so the wind, which reads it before this frame's culling, finds every tree
    /// where it now is). `false` when the hierarchy must be built anew.
    fn follow_edits(
        &mut self,
        edits: &LayoutEdits,
        table: &ForestInstances,
        models: &Assets<TreeModel>,
        server: &AssetServer,
    ) -> bool {
        if self.hierarchy.is_none() {
            return false;
        }
        edits.apply(&mut self.instances, |i| cull_instance(table, i));
        for m in edits.new_models() {
            let shape = self.shape_of(table.model_ids[m], models, server);
            self.shapes.push(shape);
        }
        let edited = self
            .hierarchy
            .as_mut()
            .is_some_and(|h| h.edit(edits, &self.instances, &self.shapes));
        if edited {
            edits.apply(&mut self.result.visibility, |_| {
                InstanceVisibility::Invisible
            });
            self.edits += 1;
        }
        edited
    }
}

fn cull_forest(
    mut culling: ResMut<ForestCulling>,
    views: Query<&CullView>,
    moved: Option<Res<MovedShapes>>,
) {
    let Some(view) = views.iter().next() else {
        return;
    };
    let ForestCulling {
        instances,
        shapes,
        hierarchy,
        result,
        ..
    } = &mut *culling;
    let still = MovedShapes::default();
    let moved = moved.as_deref().unwrap_or(&still);
    if let Some(hierarchy) = hierarchy {
        hierarchy.cull(&view.0, instances, shapes, moved, result);
    }
}

/// Keeps a [`CullView`] on the camera the budget follows (the one with a
/// [`LodView`](crate::view::LodView), see [`BudgetView`](crate::view::BudgetView)) and on
/// no other camera.
#[cfg(feature = "render")]
fn update_cull_views(
    mut commands: Commands,
    cameras: Query<
        (
            Entity,
            &bevy::camera::primitives::Frustum,
            Option<&CullView>,
            Has<crate::view::LodView>,
        ),
        With<Camera3d>,
    >,
) {
    for (entity, frustum, view, followed) in &cameras {
        if !followed {
            if view.is_some() {
                commands.entity(entity).try_remove::<CullView>();
            }
            continue;
        }
        let planes = FrustumPlanes(frustum.0.half_spaces.map(|h| h.normal_d()));
        if view.is_none_or(|v| v.0 != planes) {
            commands.entity(entity).try_insert(CullView(planes));
        }
    }
}

/// Gizmo group for fully visible boxes, drawn dashed.
#[cfg(feature = "render")]
#[derive(Default, Reflect, GizmoConfigGroup)]
pub(crate) struct FullyVisibleBoxes;

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
