//! Cost models: what primitives and logic cost on this machine (paper §4, thesis §6.2).
//!
//! A [`Calibration`] measured once per adapter (`CalibrationRunPlugin` in an app, or in
//! this repository `cargo run --release -p sherwood-lab -- forest --calibrate`) is the prior; while the app runs, [`CostPlugin`] measures every frame
//! ([`FrameSample`]: the main world's logic, the render world's rendering and the frame
//! time) and the [`CostModel`] learns from them what this machine costs now: the fixed
//! part and each primitive family's cost over seconds, how fast the machine runs within
//! a second, and how logic and rendering overlap in a frame.

mod calibration;
mod calibration_assets;
mod fit;
#[cfg(feature = "render")]
mod gpu_frame;
mod measure;
mod model;
pub(crate) mod online;
mod pacing;
mod primitive;

#[cfg(feature = "render")]
pub(crate) use calibration::MeshPathCost;
#[cfg(test)]
pub(crate) use calibration::logic_time;
pub use calibration::{AdapterIdentity, Calibration, CalibrationError};
#[cfg(any(test, feature = "render"))]
pub(crate) use calibration::{LogicTable, calibration_file_name};
pub(crate) use calibration_assets::APP_INDEX;
#[cfg(any(test, feature = "render"))]
pub(crate) use calibration_assets::add_to_index;
#[cfg(test)]
pub(crate) use calibration_assets::choose_calibration;
use calibration_assets::{CalibrationIndex, CalibrationLookup, LookupStep};
pub(crate) use fit::LinearCost;
#[cfg(feature = "render")]
pub(crate) use fit::fit_nonnegative_cost;
#[cfg(any(test, feature = "render"))]
pub(crate) use fit::{CostSample, fit_sized_costs};
#[cfg(test)]
pub(crate) use fit::{FitError, fit_linear_cost};
#[cfg(feature = "render")]
pub(crate) use measure::DrawIncomplete;
pub(crate) use measure::WAIT_THRESHOLD;
pub use measure::{FrameBound, FrameClock, FrameSample, FrameSamples};
pub use model::{
    CostModel, FrameOverlap, FramePrediction, LearnedCosts, LearnedFrame, LearningRates,
};
pub(crate) use pacing::MeasuredPacing;
pub(crate) use primitive::PrimitiveCosts;
pub use primitive::{FamilyScales, FamilyTimes};

use bevy::prelude::*;
use serde::{Deserialize, Serialize};

/// The cost model's systems, in `PreUpdate`.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CostSystems {
    /// The calibration [`CostSettings::calibration`] chooses is installed when the choice
    /// or the adapter changes.
    LoadCalibration,
    /// Measured frames arrive ([`FrameSamples::arrived`]).
    Measure,
    /// The [`CostModel`] learns from them.
    Learn,
}

/// How the cost model is set up. Changing it takes effect on the next frame.
#[derive(Resource, Clone, Debug, PartialEq, Serialize, Deserialize, Reflect)]
#[reflect(Resource)]
#[serde(default)]
pub struct CostSettings {
    /// Where the calibration comes from. Default: [`CalibrationChoice::Adapter`].
    pub calibration: CalibrationChoice,
    /// Learn from measured frames; without it the budget predicts with the calibration
    /// alone. Default: `true`.
    pub online: bool,
    /// How fast the model learns. Changing them forgets what was learned. Default:
    /// [`LearningRates::default`]. A rate that is not finite is taken as its default and
    /// the others kept within bounds (`LearningRates::usable`), with a warning.
    pub rates: LearningRates,
}

impl Default for CostSettings {
    fn default() -> Self {
        Self {
            calibration: CalibrationChoice::Adapter,
            online: true,
            rates: LearningRates::default(),
        }
    }
}

/// Where the cost model's [`Calibration`] comes from. Changing it reloads. Calibrations
/// are assets (`*.calibration.ron`), loaded by Bevy's asset server from any asset source;
/// a file that does not load is reported with its path, line, column and field.
#[derive(Clone, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, Reflect)]
pub enum CalibrationChoice {
    /// The calibration measured on the adapter the app renders with (and its driver,
    /// preferred), among those listed in the app's `calibration/index.calibrations.ron`
    /// (a RON list of file names next to it; optional) and then those this crate ships,
    /// embedded in it. With none, [`Calibration::default`] and one warning. Without the
    /// `render` feature there is no adapter: the default.
    #[default]
    Adapter,
    /// The calibration at this asset path (`calibration/mine.calibration.ron`, or with a
    /// source: `embedded://…`); when it does not load, an error is logged once and the
    /// default is used.
    File(String),
    /// Whatever [`CostModel::calibration`] holds: set by code, never loaded.
    Keep,
}

/// Where a calibration run writes by default, adding what it wrote to the index there
/// (`index.calibrations.ron`, which [`CalibrationChoice::Adapter`] reads): `calibration/`
/// in the app's asset folder — Bevy's `AssetPlugin::file_path`, resolved as Bevy resolves
/// it. [`CostPlugin`] inserts it unless one is already there.
#[derive(Resource, Clone, Debug, PartialEq, Eq, Reflect)]
#[reflect(Resource)]
pub struct CalibrationDir(pub std::path::PathBuf);

impl CalibrationDir {
    /// `calibration/` in the asset folder `file_path` (absolute, or relative to Bevy's
    /// base path, as `AssetPlugin::file_path` is).
    pub fn in_asset_folder(file_path: &str) -> Self {
        Self(
            bevy::asset::io::file::FileAssetReader::get_base_path()
                .join(file_path)
                .join("calibration"),
        )
    }
}

impl Default for CalibrationDir {
    /// In the default asset folder.
    fn default() -> Self {
        Self::in_asset_folder(&AssetPlugin::default().file_path)
    }
}

/// Measures frames, loads the calibration and keeps the [`CostModel`] learning. Part of
/// [`SherwoodPlugins`](crate::SherwoodPlugins).
///
/// Frames are measured when Bevy's render app is present (the `render` feature and
/// `RenderPlugin`); without it nothing is measured and the model predicts with its
/// calibration, unless something else pushes samples.
#[derive(Default)]
pub struct CostPlugin;

impl Plugin for CostPlugin {
    fn build(&self, app: &mut App) {
        if !app.world().contains_resource::<CalibrationDir>() {
            let dir = app
                .get_added_plugins::<AssetPlugin>()
                .first()
                .map_or_else(CalibrationDir::default, |assets| {
                    CalibrationDir::in_asset_folder(&assets.file_path)
                });
            app.insert_resource(dir);
        }
        if app.world().contains_resource::<AssetServer>() {
            calibration_assets::register(app);
        }
        app.register_type::<CostSettings>()
            .register_type::<AdapterIdentity>()
            .register_type::<CalibrationDir>()
            .init_resource::<CostSettings>()
            .init_resource::<CostModel>()
            .init_resource::<MeasuredPacing>()
            .configure_sets(
                PreUpdate,
                (
                    CostSystems::LoadCalibration,
                    CostSystems::Measure,
                    CostSystems::Learn,
                )
                    .chain(),
            )
            .add_systems(
                PreUpdate,
                (
                    load_calibration.in_set(CostSystems::LoadCalibration),
                    learn_costs.in_set(CostSystems::Learn),
                    pacing::observe_pacing.in_set(CostSystems::Learn),
                ),
            );
        measure::build(app);
    }

    fn finish(&self, app: &mut App) {
        // Without pipelined rendering the render world runs after the main world.
        #[cfg(feature = "render")]
        let pipelined = app
            .get_sub_app(bevy::render::pipelined_rendering::RenderExtractApp)
            .is_some();
        #[cfg(not(feature = "render"))]
        let pipelined = false;
        let overlap = if pipelined {
            FrameOverlap::PIPELINED
        } else {
            FrameOverlap::SERIAL
        };
        app.world_mut()
            .resource_mut::<CostModel>()
            .set_prior_overlap(overlap);
        app.world_mut()
            .resource_mut::<FrameClock>()
            .set_pipelined(pipelined);
    }
}

fn learn_costs(
    settings: Res<CostSettings>,
    samples: Res<FrameSamples>,
    mut model: ResMut<CostModel>,
    mut rates: Local<Option<LearningRates>>,
) {
    // Compared as used: a NaN set from an inspector is never equal to itself, and would
    // otherwise forget everything every frame.
    let wanted = settings.rates.usable();
    if *rates != Some(wanted) {
        if wanted != settings.rates {
            warn!(
                "bevy_sherwood: CostSettings::rates {:?} are not usable; learning with {wanted:?}",
                settings.rates
            );
        }
        if rates.is_some() {
            model.set_rates(wanted);
        }
        *rates = Some(wanted);
    }
    if !settings.online {
        return;
    }
    for sample in samples.arrived() {
        model.learn(sample);
    }
    for &pass in samples.arrived_passes() {
        model.learn_pass(pass);
    }
}

/// No calibration was measured on the adapter the app renders with (none in the app's
/// index nor among the shipped ones): the cost model starts from
/// [`Calibration::default`] and learns this machine's costs as it runs (a warning is
/// logged as well). Raised once per adapter and choice; observe it with
/// `app.add_observer(|missing: On<CalibrationNotFound>| …)`.
#[derive(Event, Clone, Debug, PartialEq, Eq)]
pub struct CalibrationNotFound {
    /// The adapter nobody measured.
    pub adapter: AdapterIdentity,
}

/// The calibration lookup under way, and what it was started for.
#[derive(Default)]
struct CalibrationState {
    started_for: Option<(CalibrationChoice, Option<AdapterIdentity>)>,
    lookup: CalibrationLookup,
}

/// Installs the calibration [`CostSettings::calibration`] chooses, when the choice or the
/// adapter changes (loading takes a few frames; the model predicts with what it had
/// meanwhile); a new calibration restarts the learning.
fn load_calibration(
    settings: Res<CostSettings>,
    adapter: Option<Res<AdapterIdentity>>,
    assets: Option<(
        Res<AssetServer>,
        Res<Assets<Calibration>>,
        Res<Assets<CalibrationIndex>>,
    )>,
    mut model: ResMut<CostModel>,
    mut state: Local<CalibrationState>,
    mut commands: Commands,
) {
    // Compared in place: this runs every frame, and cloning the key would allocate.
    let started = state.started_for.as_ref().is_some_and(|(choice, seen)| {
        *choice == settings.calibration && seen.as_ref() == adapter.as_deref()
    });
    if !started {
        state.started_for = Some((settings.calibration.clone(), adapter.as_deref().cloned()));
        state.lookup = match (&settings.calibration, adapter.as_deref(), &assets) {
            (CalibrationChoice::Keep, ..) | (CalibrationChoice::Adapter, None, _) => {
                CalibrationLookup::Idle
            }
            (_, _, None) => {
                warn!(
                    "cost model: no AssetPlugin, so no calibration can load; using the default costs"
                );
                model.set_calibration(Calibration::default());
                CalibrationLookup::Idle
            }
            (CalibrationChoice::File(path), _, Some((server, ..))) => {
                CalibrationLookup::file(server, path)
            }
            (CalibrationChoice::Adapter, Some(_), Some((server, ..))) => {
                CalibrationLookup::adapter(server)
            }
        };
    }
    if matches!(state.lookup, CalibrationLookup::Idle) {
        return;
    }
    let Some((server, calibrations, indexes)) = &assets else {
        return;
    };
    let unknown = AdapterIdentity::default();
    let adapter = adapter.as_deref().unwrap_or(&unknown);
    let LookupStep::Done(found) = state.lookup.step(server, calibrations, indexes, adapter) else {
        return;
    };
    state.lookup = CalibrationLookup::Idle;
    let chosen = match (&settings.calibration, found) {
        (CalibrationChoice::File(path), Some(c)) => {
            info!("cost model: calibration {path} ({})", c.adapter);
            c
        }
        (CalibrationChoice::File(path), None) => {
            error!(
                "cost model: calibration {path} did not load (the asset error above says why); using the default costs"
            );
            Calibration::default()
        }
        (_, Some(c)) => {
            info!(
                "cost model: calibration for {} ({})",
                adapter.name, c.driver
            );
            c
        }
        (_, None) => {
            warn!(
                "cost model: no calibration for adapter `{}` in {} or the shipped ones; using the \
                 default costs (measure one with `CalibrationRunPlugin`, or in bevy_sherwood's \
                 repository `cargo run --release -p sherwood-lab -- forest --calibrate`)",
                adapter.name, APP_INDEX,
            );
            commands.trigger(CalibrationNotFound {
                adapter: adapter.clone(),
            });
            Calibration::default()
        }
    };
    model.set_calibration(chosen);
}
