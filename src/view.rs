//! The viewpoint the level-of-detail stages work from.

use bevy::prelude::*;

use crate::tree::Projection;

/// Where the camera is, where it looks and how it projects: what the value function, the
/// LOD searches and the wind's motion LOD measure depths and pixels against.
///
/// Perspective 3D cameras get one automatically, kept up to date before the Sherwood
/// stages (with the `render` feature); headless apps insert it themselves. With several,
/// the first one found is used.
#[derive(Component, Clone, Copy, Debug, PartialEq, Reflect)]
#[reflect(Component)]
pub struct LodView {
    /// Camera position, world space.
    pub position: Vec3,
    /// Unit viewing direction, world space.
    pub forward: Vec3,
    /// Pixels per world unit at unit distance (`viewport height / (2·tan(fov / 2))`).
    pub focal_pixels: f32,
    /// Pixels in the viewport (width × height): the most any one primitive can cover, so
    /// the cost of something at the camera stays finite. `f32::INFINITY` when unknown.
    pub viewport_pixels: f32,
}

impl LodView {
    /// Depth of `point` along the viewing direction.
    pub fn depth(&self, point: Vec3) -> f32 {
        (point - self.position).dot(self.forward)
    }

    /// The view's projection, for the pixel-driven searches.
    pub fn projection(&self) -> Projection {
        Projection {
            focal_pixels: self.focal_pixels,
        }
    }
}

/// Keeps a [`LodView`] on every perspective 3D camera (scheduled by the core plugin
/// before the Sherwood stages).
#[cfg(feature = "render")]
pub(crate) fn update_lod_views(
    mut commands: Commands,
    cameras: Query<
        (
            Entity,
            &Camera,
            &Projection_,
            &GlobalTransform,
            Option<&LodView>,
        ),
        With<Camera3d>,
    >,
) {
    for (entity, camera, projection, transform, current) in &cameras {
        let (Projection_::Perspective(perspective), Some(size)) =
            (projection, camera.physical_viewport_size())
        else {
            continue;
        };
        let view = LodView {
            position: transform.translation(),
            forward: transform.forward().as_vec3(),
            focal_pixels: size.y as f32 / (2.0 * (perspective.fov * 0.5).tan()).max(1e-6),
            viewport_pixels: size.x as f32 * size.y as f32,
        };
        if current != Some(&view) {
            commands.entity(entity).insert(view);
        }
    }
}

#[cfg(feature = "render")]
use bevy::camera::Projection as Projection_;
