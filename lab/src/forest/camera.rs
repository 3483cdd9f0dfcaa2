//! Where the camera goes: the paper's camera paths.

use bevy::prelude::*;
use bevy_sherwood::ecosystem::ForestTerrain;

use super::Run;
use super::args::{Args, CameraPath};

/// How far outside the forest's edge the camera may stand, metres: a tenth of a large
/// forest's width would put its trees past the far plane. (Forests of up to 100 000 trees
/// at the default density keep their views.)
pub const MAX_CAMERA_BACK: f32 = 320.0;

/// Where the path puts the camera at `t` in [0, 1] over a terrain of `size`: position
/// (x, z) and viewing direction (x, z).
pub fn path_pose(path: CameraPath, t: f32, size: f32) -> (Vec2, Vec2) {
    let t = t.clamp(0.0, 1.0);
    match path {
        // Along the forest's edge, looking in: the view takes in a growing, then a
        // shrinking part of the forest (peak just before half way, as in the paper).
        CameraPath::Linear => {
            let x = size * (-0.55 + 2.0 * t);
            let back = (0.12 * size).min(MAX_CAMERA_BACK);
            (Vec2::new(x, -back), Vec2::new(0.35, 1.0).normalize())
        }
        // Back and forth through the forest in three legs, turning at the edges (at a
        // third and two thirds of the path): complexity jumps at each turn.
        CameraPath::Zigzag => {
            let leg = (t * 3.0).min(2.999_9);
            let i = leg.floor();
            let s = leg - i;
            let z = size * (0.2 + 0.3 * i);
            let (from, to) = if (i as u32).is_multiple_of(2) {
                (0.08, 0.92)
            } else {
                (0.92, 0.08)
            };
            let x = size * (from + (to - from) * s);
            let heading = Vec2::new((to - from).signum(), 0.25).normalize();
            (Vec2::new(x, z), heading)
        }
    }
}

pub fn follow_path(
    options: Res<Args>,
    run: Res<Run>,
    terrain: Query<&ForestTerrain>,
    mut camera: Query<&mut Transform, With<Camera3d>>,
) {
    let (Some(path), Ok(mut transform), Ok(terrain)) =
        (options.path, camera.single_mut(), terrain.single())
    else {
        return;
    };
    let size = terrain.terrain.size();
    let frames = options.path_length().unwrap_or(path.frames()).max(2);
    let measured = options
        .hold_frame
        .unwrap_or(run.frame.saturating_sub(options.warmup));
    let t = measured as f32 / (frames - 1) as f32;
    let (at, heading) = path_pose(path, t, size);
    let ground = terrain
        .terrain
        .height_at(at.x.clamp(0.0, size), at.y.clamp(0.0, size));
    let eye = Vec3::new(at.x, ground + 12.0, at.y);
    let target = eye + Vec3::new(heading.x, -0.12, heading.y);
    *transform = Transform::from_translation(eye).looking_at(target, Vec3::Y);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_linear_path_crosses_the_forest_edge_looking_in() {
        let size = 200.0;
        let (start, heading) = path_pose(CameraPath::Linear, 0.0, size);
        let (end, _) = path_pose(CameraPath::Linear, 1.0, size);
        assert!(start.x < 0.0 && end.x > size, "{start} {end}");
        assert!(
            start.y < 0.0 && heading.y > 0.0,
            "outside the edge, looking in"
        );
        assert_eq!(
            path_pose(CameraPath::Linear, 2.0, size),
            (end, heading),
            "t is clamped"
        );
    }

    #[test]
    fn the_zigzag_path_stays_in_the_forest_and_turns_at_each_third() {
        let size = 200.0;
        for k in 0..=30 {
            let (at, _) = path_pose(CameraPath::Zigzag, k as f32 / 30.0, size);
            assert!(
                at.cmpge(Vec2::ZERO).all() && at.cmple(Vec2::splat(size)).all(),
                "{at}"
            );
        }
        let (_, first) = path_pose(CameraPath::Zigzag, 0.1, size);
        let (_, second) = path_pose(CameraPath::Zigzag, 0.5, size);
        assert!(first.x > 0.0 && second.x < 0.0, "{first} {second}");
    }
}
