//! What the forest tool puts in the scene: the forest, light and camera, the boulders of
//! `--meshes`, the flat ID colours of `--id-colors`, a calibration read from a file.

use bevy::camera::RenderTarget;
use bevy::camera_controller::free_camera::FreeCamera;
use bevy::mesh::VertexAttributeValues;
use bevy::prelude::*;
use bevy::render::render_resource::{TextureFormat, TextureUsages};
use bevy_sherwood::cost::{CalibrationChoice, CostModel, CostSettings};
use bevy_sherwood::draw::Shading;
use bevy_sherwood::ecosystem::{EcosystemDesc, ForestState, ForestTerrain};
use bevy_sherwood::prelude::*;

use super::Run;
use super::args::{Args, CameraPath};
use super::camera::{MAX_CAMERA_BACK, path_pose};
use crate::{assets, id_colors};

pub fn setup(
    mut commands: Commands,
    options: Res<Args>,
    mut ecosystems: ResMut<Assets<Ecosystem>>,
    mut images: ResMut<Assets<Image>>,
    mut run: ResMut<Run>,
    mut hud: ResMut<ForestHud>,
    mut exit: MessageWriter<AppExit>,
) {
    // The file is read here rather than by the asset server, so that it may be anywhere.
    let path = match assets::resolve(&options.ecosystem) {
        Ok(path) => path,
        Err(e) => {
            eprintln!("forest: --ecosystem {e}");
            exit.write(AppExit::error());
            return;
        }
    };
    let desc = std::fs::read_to_string(&path)
        .map_err(|e| e.to_string())
        .and_then(|text| EcosystemDesc::from_ron_str(&text).map_err(|e| e.to_string()));
    let path = path.display();
    let mut desc = match desc {
        Ok(desc) => desc,
        Err(e) => {
            eprintln!("forest: {path}: {e}");
            exit.write(AppExit::error());
            return;
        }
    };
    if let Some(total) = options.trees
        && let Err(e) = desc.set_total_trees(total)
    {
        eprintln!("forest: {path}: --trees {total}: {e}");
        exit.write(AppExit::error());
        return;
    }
    if let Some(seed) = options.seed {
        desc.seed = seed;
    }
    // Refused now, rather than by the forest's layout later with nothing drawn.
    if let Err(e) = desc.validate() {
        eprintln!("forest: {path}: {e}");
        exit.write(AppExit::error());
        return;
    }
    if desc.instance_count() == 0 {
        eprintln!("forest: {path}: every species has 0 trees: nothing to draw");
        exit.write(AppExit::error());
        return;
    }
    let size = desc.terrain.size;
    let start_back = (0.1 * size).min(MAX_CAMERA_BACK);
    commands.spawn(Forest(ecosystems.add(Ecosystem(desc))));
    commands.spawn((
        DirectionalLight {
            illuminance: 9_000.0,
            ..default()
        },
        Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        // Multisampling quadruples the rasteriser's work on a software renderer.
        Msaa::Off,
        // Outside the forest's corner, but near enough that Bevy's 1 km far plane
        // reaches into a large one (`--trees 1000000` is 8 km wide).
        Transform::from_xyz(-start_back, 25.0, -start_back)
            .looking_at(Vec3::new(size * 0.5, 0.0, size * 0.5), Vec3::Y),
    ));
    if options.path.is_none() {
        camera.insert(FreeCamera::default());
    }
    if options.headless {
        let mut image = Image::new_target_texture(
            options.width,
            options.height,
            TextureFormat::Rgba8UnormSrgb,
            None,
        );
        image.texture_descriptor.usage |= TextureUsages::COPY_SRC;
        let image = images.add(image);
        camera.insert(RenderTarget::Image(image.clone().into()));
        run.image = Some(image);
    }
    hud.footer = "WASD/QE move, right drag look".into();
    hud.visible = !(options.no_hud || options.id_colors);
}

/// With every species failed there is nothing to draw, and the frame counter (which starts
/// at the first drawn frame) would wait forever: say why and stop.
pub fn stop_when_no_species_loads(
    forests: Query<&ForestState>,
    server: Res<AssetServer>,
    mut exit: MessageWriter<AppExit>,
    mut reported: Local<bool>,
) {
    if *reported {
        return;
    }
    for state in &forests {
        let failures: Vec<String> = state
            .species
            .iter()
            .filter_map(|species| match server.load_state(species) {
                bevy::asset::LoadState::Failed(e) => Some(e.to_string()),
                _ => None,
            })
            .collect();
        if !state.species.is_empty() && failures.len() == state.species.len() {
            for failure in failures {
                eprintln!("forest: {failure}");
            }
            eprintln!("forest: no species of the ecosystem loaded; nothing to draw");
            *reported = true;
            exit.write(AppExit::error());
        }
    }
}

/// `--calibration FILE` and `--scale-calibration`: once the calibration asked for is
/// installed (the adapter's is, in `PreUpdate`, once the adapter is known), the file's
/// instead, then scaled.
pub fn install_calibration(
    options: Res<Args>,
    mut settings: ResMut<CostSettings>,
    mut model: ResMut<CostModel>,
    adapter: Option<Res<bevy_sherwood::cost::AdapterIdentity>>,
    mut exit: MessageWriter<AppExit>,
    mut done: Local<bool>,
) {
    let file = options.calibration_file();
    if *done || (file.is_none() && options.scale_calibration.is_none()) {
        return;
    }
    if settings.calibration == CalibrationChoice::Adapter && adapter.is_none() {
        return;
    }
    *done = true;
    if let Some(file) = file {
        match assets::read_calibration(file) {
            Ok(calibration) => {
                info!("cost model: calibration {}", file.display());
                model.set_calibration(calibration);
            }
            Err(e) => {
                eprintln!("forest: --calibration {e}");
                exit.write(AppExit::error());
                return;
            }
        }
    }
    if let Some(factor) = options.scale_calibration {
        let scaled = model.calibration().scaled(factor);
        info!("cost model: calibration scaled by {factor}");
        model.set_calibration(scaled);
    }
    settings.calibration = CalibrationChoice::Keep;
}

/// `--id-colors`: every tree in its own flat colour (ambient only, no light), the colour
/// of [`id_colors::id_color`] of its index in the instance table.
/// A tree painted by [`paint_trees_by_id`].
#[derive(Component)]
pub struct PaintedById;

pub fn paint_trees_by_id(
    mut commands: Commands,
    table: Res<ForestInstances>,
    painted: Query<(), With<PaintedById>>,
) {
    for (i, &entity) in table.entities.iter().enumerate() {
        if painted.contains(entity) {
            continue;
        }
        let color = id_colors::id_color(i as u32);
        let flat = Shading {
            ambient: Vec3::from(id_colors::linear(color)),
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            shininess: 1.0,
        };
        commands.entity(entity).insert((
            TreeShading {
                trunk: flat,
                leaves: flat,
            },
            PaintedById,
        ));
    }
}

pub fn hide_terrain(mut terrain: Query<&mut Visibility, With<ForestTerrain>>) {
    for mut visibility in &mut terrain {
        *visibility = Visibility::Hidden;
    }
}

/// A boulder placed by [`place_boulders`].
#[derive(Component)]
pub struct Boulder;

/// `--meshes N`: once the terrain is there, N boulders (three shapes of 20 480 triangles,
/// each with a ladder generated at 35, 12, 4 and 1.2% of its triangles) scattered ahead of
/// the camera along its path, in the same budget as the trees.
pub fn place_boulders(
    mut commands: Commands,
    options: Res<Args>,
    terrain: Query<&ForestTerrain>,
    placed: Query<(), With<Boulder>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let Ok(terrain) = terrain.single() else {
        return;
    };
    if options.meshes == 0 || !placed.is_empty() {
        return;
    }
    let ladders: Vec<LodLadder> = (0..3)
        .map(|shape| {
            let levels = generate_ladder(&boulder(shape), &[0.35, 0.12, 0.04, 0.012])
                .expect("a boulder is a valid triangle mesh");
            LodLadder::from_generated(&mut meshes, levels).expect("levels get cheaper")
        })
        .collect();
    let material = materials.add(StandardMaterial {
        base_color: Color::srgb(0.62, 0.58, 0.54),
        perceptual_roughness: 0.9,
        ..default()
    });
    let size = terrain.terrain.size();
    let path = options.path.unwrap_or(CameraPath::Linear);
    // A fixed stream of pseudo-random numbers: the same boulders every run.
    let mut state = 0x9E37_79B9_7F4A_7C15_u64 ^ u64::from(options.meshes);
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    for k in 0..options.meshes {
        // Ahead of the camera at a point of its path, on the terrain (a few tries: the
        // linear path runs outside the forest's edge, looking in).
        let mut spot = None;
        for _ in 0..16 {
            let t = (k as f32 + unit()) / options.meshes as f32;
            let (at, heading) = path_pose(path, t, size);
            let side = Vec2::new(-heading.y, heading.x);
            let p = at + heading * (20.0 + 60.0 * unit()) + side * (unit() - 0.5) * 60.0;
            if p.cmpge(Vec2::ZERO).all() && p.cmple(Vec2::splat(size)).all() {
                spot = Some(p);
                break;
            }
        }
        let Some(Vec2 { x, y: z }) = spot else {
            continue;
        };
        let scale = 0.8 + 1.7 * unit();
        let ladder = ladders[k as usize % ladders.len()].clone();
        let mesh = ladder.levels()[0].mesh.clone();
        commands.spawn((
            Boulder,
            ladder,
            Mesh3d(mesh),
            MeshMaterial3d(material.clone()),
            Transform::from_xyz(x, terrain.terrain.height_at(x, z) + 0.3 * scale, z)
                .with_rotation(Quat::from_rotation_y(unit() * core::f32::consts::TAU))
                .with_scale(Vec3::new(1.3, 0.8, 1.0) * scale),
        ));
    }
}

/// A boulder: an icosphere (20 480 triangles) pushed in and out by a few waves.
fn boulder(shape: u32) -> Mesh {
    let mut mesh = Sphere::new(1.0)
        .mesh()
        .ico(5)
        .expect("ico 5 is small enough");
    let phase = shape as f32 * 1.7;
    if let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute_mut(Mesh::ATTRIBUTE_POSITION)
    {
        for p in positions.iter_mut() {
            let v = Vec3::from(*p);
            let bump = 0.12 * (3.0 * v.x + phase).sin() * (2.0 * v.z - phase).cos()
                + 0.06 * (7.0 * v.y + 2.0 * phase).sin()
                + 0.03 * (13.0 * (v.x + v.z) + phase).cos();
            *p = (v * (1.0 + bump)).to_array();
        }
    }
    mesh.compute_smooth_normals();
    mesh
}
