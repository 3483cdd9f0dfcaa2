//! The viewpoint the level-of-detail stages work from.

use bevy::prelude::*;

use crate::tree::Projection;

/// Where the camera is, where it looks and how it projects: what the value function, the
/// LOD searches and the wind's motion LOD measure depths and pixels against.
///
/// With the `render` feature the camera the budget follows gets one automatically, kept up
/// to date before the Sherwood stages (see [`BudgetView`] for which camera that is);
/// headless apps insert it themselves on an entity of their own.
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
    pub(crate) fn depth(&self, point: Vec3) -> f32 {
        (point - self.position).dot(self.forward)
    }

    /// The pixels a sphere covers on screen: its projected disc, at most the viewport (a
    /// sphere around the eye covers what a sphere touching it would).
    pub(crate) fn sphere_pixels(&self, center: Vec3, radius: f32) -> f32 {
        if !(radius > 0.0 && radius.is_finite()) {
            return 0.0;
        }
        let depth = self.depth(center).max(radius);
        let r = radius * self.focal_pixels / depth;
        let disc = core::f32::consts::PI * r * r;
        if disc.is_finite() {
            disc.min(self.viewport_pixels)
        } else {
            0.0
        }
    }

    /// The view's projection, for the pixel-driven searches.
    pub(crate) fn projection(&self) -> Projection {
        Projection {
            focal_pixels: self.focal_pixels,
        }
    }
}

/// Marks the camera the frame budget follows: its view is culled, valued and budgeted,
/// and every camera that draws the forest draws that selection.
///
/// Without a marked camera the budget follows the active 3D camera that renders to the
/// primary window (the largest on screen, when several do), else the largest active 3D
/// camera. Inactive cameras (`Camera::is_active == false`), cameras with no viewport (a
/// minimised window) and cameras whose `RenderLayers` leave out layer 0, the forest's
/// (a minimap that should not draw the forest), are never followed; a warning names the
/// choice when several cameras remain equally likely. Orthographic cameras are followed
/// as well as perspective ones.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq, Reflect)]
#[reflect(Component, Default)]
pub struct BudgetView;

/// A camera the budget may follow, as [`choose_view`] sees it.
#[cfg(any(feature = "render", test))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Candidate<K> {
    pub(crate) key: K,
    /// Active, with a viewport, drawing layer 0.
    pub(crate) eligible: bool,
    pub(crate) marked: bool,
    pub(crate) on_primary_window: bool,
    /// Viewport pixels.
    pub(crate) pixels: u32,
    /// `Camera::order`: with equal viewports, the first drawn wins.
    pub(crate) order: isize,
}

/// The camera the budget follows, and how many others were as likely (a reason to warn).
#[cfg(any(feature = "render", test))]
pub(crate) fn choose_view<K: Copy>(candidates: &[Candidate<K>]) -> Option<(K, usize)> {
    let eligible = || candidates.iter().filter(|c| c.eligible);
    let pool: Vec<&Candidate<K>> = if eligible().any(|c| c.marked) {
        eligible().filter(|c| c.marked).collect()
    } else if eligible().any(|c| c.on_primary_window) {
        eligible().filter(|c| c.on_primary_window).collect()
    } else {
        eligible().collect()
    };
    let best = pool
        .iter()
        .max_by(|a, b| a.pixels.cmp(&b.pixels).then(b.order.cmp(&a.order)))?;
    let rivals = if pool.iter().any(|c| c.marked) {
        pool.len() - 1
    } else {
        pool.iter().filter(|c| c.pixels == best.pixels).count() - 1
    };
    Some((best.key, rivals))
}

/// Keeps a [`LodView`] on the camera the budget follows ([`BudgetView`]) and on no other
/// camera (scheduled by the core plugin before the Sherwood stages).
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
            Option<&bevy::camera::RenderTarget>,
            Option<&bevy::camera::visibility::RenderLayers>,
            Has<BudgetView>,
        ),
        With<Camera3d>,
    >,
    primary: Query<Entity, With<bevy::window::PrimaryWindow>>,
    mut warned: Local<Option<(Entity, usize)>>,
) {
    use bevy::camera::{NormalizedRenderTarget, visibility::RenderLayers};
    let primary = primary.iter().next();
    let forest_layers = RenderLayers::default();
    let candidates: Vec<Candidate<Entity>> = cameras
        .iter()
        .map(|(entity, camera, _, _, _, target, layers, marked)| {
            let size = camera.physical_viewport_size().unwrap_or(UVec2::ZERO);
            let on_primary_window = target.and_then(|t| t.normalize(primary)).is_some_and(
                |t| matches!(t, NormalizedRenderTarget::Window(w) if Some(w.entity()) == primary),
            );
            Candidate {
                key: entity,
                eligible: camera.is_active
                    && size.x > 0
                    && size.y > 0
                    && layers.is_none_or(|l| l.intersects(&forest_layers)),
                marked,
                on_primary_window,
                pixels: size.x.saturating_mul(size.y),
                order: camera.order,
            }
        })
        .collect();
    let chosen = choose_view(&candidates);
    if let Some((entity, rivals)) = chosen
        && rivals > 0
        && *warned != Some((entity, rivals))
    {
        warn!(
            "bevy_sherwood: {} cameras could be the one the frame budget follows; it follows \
             {entity} (mark the one you mean with `BudgetView`)",
            rivals + 1
        );
        *warned = Some((entity, rivals));
    }
    for (entity, camera, projection, transform, current, ..) in &cameras {
        let view = chosen
            .filter(|(chosen, _)| *chosen == entity)
            .and_then(|_| lod_view(camera, projection, transform));
        match (view, current) {
            (Some(view), current) if current != Some(&view) => {
                commands.entity(entity).try_insert(view);
            }
            (None, Some(_)) => {
                commands.entity(entity).try_remove::<LodView>();
            }
            _ => {}
        }
    }
}

/// The view of a camera with a viewport. An orthographic camera is seen as a perspective
/// one from far behind it with the same pixels per world unit at its near end: projected
/// sizes then hardly depend on depth, as they do not in an orthographic view, and the
/// depth order is kept.
#[cfg(feature = "render")]
fn lod_view(
    camera: &Camera,
    projection: &Projection_,
    transform: &GlobalTransform,
) -> Option<LodView> {
    let size = camera.physical_viewport_size()?;
    let forward = transform.forward().as_vec3();
    let viewport_pixels = size.x as f32 * size.y as f32;
    match projection {
        Projection_::Perspective(perspective) => Some(LodView {
            position: transform.translation(),
            forward,
            focal_pixels: size.y as f32 / (2.0 * (perspective.fov * 0.5).tan()).max(1e-6),
            viewport_pixels,
        }),
        Projection_::Orthographic(ortho) => {
            let height = ortho.area.height().abs();
            if !(height > 0.0 && height.is_finite()) {
                return None;
            }
            let pixels_per_unit = size.y as f32 / height;
            // Far enough that a depth across the view changes sizes by a thousandth.
            let behind = ORTHOGRAPHIC_DISTANCE * height.max(ortho.far.abs().min(1e6));
            Some(LodView {
                position: transform.translation() - forward * behind,
                forward,
                focal_pixels: pixels_per_unit * behind,
                viewport_pixels,
            })
        }
        Projection_::Custom(_) => None,
    }
}

/// How far behind an orthographic camera its stand-in perspective eye sits, in view
/// heights (or far distances).
#[cfg(feature = "render")]
const ORTHOGRAPHIC_DISTANCE: f32 = 1000.0;

#[cfg(feature = "render")]
use bevy::camera::Projection as Projection_;

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(key: u32) -> Candidate<u32> {
        Candidate {
            key,
            eligible: true,
            marked: false,
            on_primary_window: false,
            pixels: 100,
            order: 0,
        }
    }

    #[test]
    fn the_budget_follows_the_marked_then_the_primary_window_s_then_the_largest_camera() {
        // An inactive camera found first is passed over.
        let inactive = Candidate {
            eligible: false,
            on_primary_window: true,
            pixels: 1000,
            ..camera(0)
        };
        let texture = Candidate {
            pixels: 50,
            ..camera(1)
        };
        let main = Candidate {
            on_primary_window: true,
            ..camera(2)
        };
        assert_eq!(choose_view(&[inactive, texture, main]), Some((2, 0)));
        // Without a window, the largest.
        assert_eq!(choose_view(&[inactive, texture, camera(3)]), Some((3, 0)));
        // A marked camera wins over everything.
        let marked = Candidate {
            marked: true,
            ..texture
        };
        assert_eq!(choose_view(&[inactive, marked, main]), Some((1, 0)));
        // Two cameras equally likely: one is chosen (the first drawn), and it is said.
        let other = Candidate { order: 1, ..main };
        assert_eq!(choose_view(&[other, main]), Some((2, 1)));
        // Two marked: the largest, and it is said.
        let big_marked = Candidate {
            marked: true,
            pixels: 500,
            ..camera(4)
        };
        assert_eq!(choose_view(&[marked, big_marked]), Some((4, 1)));
        // Nothing eligible: no view.
        assert_eq!(choose_view(&[inactive]), None);
        assert_eq!(choose_view::<u32>(&[]), None);
    }
}
