//! The app's own meshes in the frame's prediction: every visible `Mesh3d` that is not a
//! ladder entity is counted (a draw, its triangles, the pixels its bounds cover in the
//! budget's view), so that a mesh spawned this frame moves this frame's prediction and
//! the trees get the time the meshes leave. The cost model learns their cost with the
//! ladders' ("meshes" and "mesh pixels" families).

use bevy::camera::primitives::Aabb;
use bevy::camera::visibility::RenderLayers;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

use super::{LadderGhost, LodLadder, mesh_triangles};
use crate::culling::{CullView, transform_bounds};
use crate::lod::{AppMeshLoad, LadderObjects};
use crate::tree::{BoundingSphere, Bounds};
use crate::view::LodView;

/// Counts the app's visible meshes in the budget's view ([`LadderObjects::app_meshes`]).
/// Visible: not hidden (`InheritedVisibility`), on layer 0 (the layer the budget's camera
/// draws, as the forest's), and with bounds in the view's frustum.
pub(super) fn count_app_meshes(
    mut objects: ResMut<LadderObjects>,
    views: Query<(&LodView, Option<&CullView>)>,
    meshes: Query<
        (
            &Mesh3d,
            &GlobalTransform,
            &Aabb,
            &InheritedVisibility,
            Option<&RenderLayers>,
        ),
        (Without<LodLadder>, Without<LadderGhost>),
    >,
    assets: Res<Assets<Mesh>>,
    mut events: MessageReader<AssetEvent<Mesh>>,
    mut triangles_of: Local<HashMap<AssetId<Mesh>, u32>>,
) {
    // A mesh asset changed or removed is counted anew.
    for event in events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            triangles_of.remove(id);
        }
    }
    let mut load = AppMeshLoad::default();
    if let Some((view, cull)) = views.iter().next() {
        let layers = RenderLayers::default();
        for (mesh, transform, aabb, visible, mesh_layers) in &meshes {
            if !visible.get() || mesh_layers.is_some_and(|l| !l.intersects(&layers)) {
                continue;
            }
            let local = Bounds {
                min: (aabb.center - aabb.half_extents).into(),
                max: (aabb.center + aabb.half_extents).into(),
            };
            let world = transform_bounds(&transform.affine(), &local);
            let (center, radius) = (world.center(), world.half_extents().length());
            let sphere = BoundingSphere { center, radius };
            if cull.is_some_and(|c| !c.0.intersects_sphere(&sphere)) {
                continue;
            }
            let id = mesh.0.id();
            let triangles = match triangles_of.get(&id) {
                Some(&t) => t,
                None => {
                    let Some(t) = assets.get(id).and_then(mesh_triangles) else {
                        continue;
                    };
                    triangles_of.insert(id, t);
                    t
                }
            };
            load.draws += 1;
            load.triangles += u64::from(triangles);
            load.pixels += view.sphere_pixels(center, radius);
        }
    }
    objects.app_meshes = load;
}
