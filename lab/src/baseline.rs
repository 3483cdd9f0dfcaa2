//! The baseline of the memory figures: the forest tool's headless Bevy app (Bevy's
//! default plugins, no window, a camera drawing into a target of the same size, a light)
//! without any Sherwood plugin or tree. Its peak resident set is what Bevy and the
//! renderer take before a forest (on lavapipe the GPU's memory is the process's too).
//!
//! ```sh
//! /usr/bin/time -v cargo run --release -p sherwood-lab -- baseline --frames 60
//! ```

use bevy::camera::RenderTarget;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;

/// The baseline's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Frames to draw before exiting.
    #[arg(long, default_value_t = 60)]
    frames: u32,
    /// Render target width, pixels (the forest tool's default).
    #[arg(long, default_value_t = 960)]
    width: u32,
    /// Render target height, pixels.
    #[arg(long, default_value_t = 540)]
    height: u32,
}

#[derive(Resource)]
struct FramesLeft(u32);

/// Runs the empty app for `--frames` frames.
pub fn run(args: Args) -> AppExit {
    let mut app = App::new();
    crate::forest::add_headless_bevy(&mut app);
    let (width, height) = (args.width, args.height);
    app.insert_resource(FramesLeft(args.frames))
        .add_systems(
            Startup,
            move |mut commands: Commands, mut images: ResMut<Assets<Image>>| {
                let image =
                    Image::new_target_texture(width, height, TextureFormat::Rgba8UnormSrgb, None);
                commands.spawn((
                    Camera3d::default(),
                    Msaa::Off,
                    RenderTarget::Image(images.add(image).into()),
                    Transform::from_xyz(0.0, 25.0, 0.0).looking_at(Vec3::X, Vec3::Y),
                ));
                commands.spawn((
                    DirectionalLight::default(),
                    Transform::from_xyz(4.0, 10.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
            },
        )
        .add_systems(
            Update,
            |mut left: ResMut<FramesLeft>, mut exit: MessageWriter<AppExit>| {
                left.0 = left.0.saturating_sub(1);
                if left.0 == 0 {
                    exit.write(AppExit::Success);
                }
            },
        );
    let exit = app.run();
    println!("baseline done frames={}", args.frames);
    exit
}
