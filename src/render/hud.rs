//! On-screen counters like the thesis figures: primitives drawn, frame time, FPS and
//! target frame time.

use bevy::prelude::*;

use super::ForestRenderStats;

/// Adds a text overlay in the top-left corner of every window with the forest pass's
/// counts and the frame time. Leave it out for a clean picture; toggle it at run time
/// with [`ForestHud::visible`].
#[derive(Default)]
pub struct ForestHudPlugin;

/// HUD settings and the numbers it shows besides [`ForestRenderStats`].
#[derive(Resource, Clone, Debug, Reflect)]
#[reflect(Resource)]
pub struct ForestHud {
    /// Whether the overlay is shown. Default: `true`.
    pub visible: bool,
    /// Target frame time in milliseconds to show; when `None`, the
    /// [`FrameBudget`](crate::lod::FrameBudget)'s. Default: `None`.
    pub target_ms: Option<f32>,
    /// Extra lines shown under the counters (an example's key help, for instance).
    /// Default: empty.
    pub footer: String,
    /// Frame time smoothed over about half a second, in milliseconds; written by the HUD.
    /// Default: `0.0`.
    pub smoothed_frame_ms: f32,
}

impl Default for ForestHud {
    fn default() -> Self {
        Self {
            visible: true,
            target_ms: None,
            footer: String::new(),
            smoothed_frame_ms: 0.0,
        }
    }
}

/// Marks the HUD's text.
#[derive(Component)]
struct HudText;

impl Plugin for ForestHudPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<ForestHud>()
            .init_resource::<ForestHud>()
            .add_systems(Startup, spawn_hud)
            .add_systems(Update, update_hud);
    }
}

fn spawn_hud(mut commands: Commands) {
    commands.spawn((
        HudText,
        Text::new(""),
        TextFont {
            font_size: FontSize::Px(16.0),
            ..default()
        },
        TextColor(Color::WHITE),
        Node {
            position_type: PositionType::Absolute,
            top: Val::Px(8.0),
            left: Val::Px(8.0),
            padding: UiRect::all(Val::Px(6.0)),
            ..default()
        },
        BackgroundColor(Color::srgba(0.0, 0.0, 0.0, 0.55)),
    ));
}

fn update_hud(
    time: Res<Time<Real>>,
    stats: Res<ForestRenderStats>,
    mut hud: ResMut<ForestHud>,
    budget: Option<Res<crate::lod::FrameBudget>>,
    lod: Option<Res<crate::lod::LodDiagnostics>>,
    mut text: Query<(&mut Text, &mut Visibility), With<HudText>>,
) {
    let frame_ms = time.delta_secs() * 1000.0;
    if frame_ms > 0.0 {
        // An exponential average with a time constant of about half a second.
        let blend = (time.delta_secs() / 0.5).min(1.0);
        hud.smoothed_frame_ms = if hud.smoothed_frame_ms > 0.0 {
            hud.smoothed_frame_ms + (frame_ms - hud.smoothed_frame_ms) * blend
        } else {
            frame_ms
        };
    }
    for (mut text, mut visibility) in &mut text {
        *visibility = if hud.visible {
            Visibility::Inherited
        } else {
            Visibility::Hidden
        };
        if !hud.visible {
            continue;
        }
        text.0 = hud_text(&hud, &stats, budget.as_deref(), lod.as_deref());
    }
}

fn hud_text(
    hud: &ForestHud,
    stats: &ForestRenderStats,
    budget: Option<&crate::lod::FrameBudget>,
    lod: Option<&crate::lod::LodDiagnostics>,
) -> String {
    use core::fmt::Write;
    let mut s = String::new();
    let fps = if hud.smoothed_frame_ms > 0.0 {
        1000.0 / hud.smoothed_frame_ms
    } else {
        0.0
    };
    let _ = writeln!(s, "triangles {}", stats.counts.triangles);
    let _ = writeln!(s, "lines     {}", stats.counts.lines);
    let _ = writeln!(s, "points    {}", stats.counts.points);
    let _ = writeln!(
        s,
        "frame     {:.1} ms ({fps:.1} fps)",
        hud.smoothed_frame_ms
    );
    match hud.target_ms.or(budget.map(|b| b.target_ms)) {
        Some(target) => {
            let mode = budget.map_or(String::new(), |b| {
                format!(" ({:?}, {:?})", b.mode, b.strategy)
            });
            let _ = writeln!(s, "target    {target:.1} ms{mode}");
        }
        None => {
            let _ = writeln!(s, "target    none");
        }
    }
    if let Some(d) = lod.filter(|d| d.measured_frame > 0) {
        // The latest measured frame against what was predicted for it, and what the
        // cost model has learned (see `crate::cost`).
        let _ = writeln!(
            s,
            "measured  {:.1} ms (logic {:.1}, render {:.1}) predicted {:.1} ms",
            d.measured_frame_ms,
            d.measured_logic_ms,
            d.measured_render_ms,
            d.measured_frame_predicted_ms
        );
        let l = &d.learned;
        let _ = writeln!(
            s,
            "learned   fixed {:.1} ms, triangle {:.2} us, line {:.2} us, point {:.2} us",
            l.render_fixed_ms, l.triangle_us, l.line_us, l.point_us
        );
        let _ = writeln!(
            s,
            "          logic {:.1} ms + {:.1} us/tree, speed x{:.2}, {} frames",
            l.logic_fixed_ms, l.logic_per_instance_us, l.render_speed, l.frames_learned
        );
        if let Some(b) = budget {
            let _ = writeln!(
                s,
                "goal      work aimed at {:.1} ms (scatter {:.1}%, calibrated {:+.1}% / {:+.1}%), {:.0}% of the last second over {:.1} ms",
                d.work_target_ms,
                d.frame_spread * 100.0,
                d.tail_offsets[0] * 100.0,
                d.tail_offsets[1] * 100.0,
                d.frames_over_share * 100.0,
                b.goal.over_limit(b.target_ms)
            );
        }
        if d.floor_excess_ms > 0.0 {
            let _ = writeln!(
                s,
                "floors    {:.1} ms over the rendering time ({} objects)",
                d.floor_excess_ms, d.visible_objects
            );
        }
    }
    if let Some(d) = lod.filter(|d| d.impostors_drawn > 0) {
        let _ = writeln!(
            s,
            "cut       {} groups, {} trees on their own",
            d.impostors_drawn, d.trees_drawn
        );
    }
    if let Some(gpu) = stats.gpu_time_ms {
        let _ = writeln!(s, "pass GPU  {gpu:.2} ms");
    }
    let _ = write!(
        s,
        "trees {}  draws {}/view",
        stats.instances, stats.draw_calls_per_view
    );
    if !hud.footer.is_empty() {
        let _ = write!(s, "\n{}", hud.footer);
    }
    s
}
