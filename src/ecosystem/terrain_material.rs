//! The terrain's material (with the `render` feature).

use bevy::asset::{embedded_asset, embedded_path};
use bevy::pbr::{Material, MaterialPlugin};
use bevy::prelude::*;
use bevy::render::render_resource::AsBindGroup;
use bevy::shader::ShaderRef;

use super::MaterialDesc;

/// The material spawned forests give their terrain: ambient plus Lambert diffuse under
/// the scene's first directional light, the lighting model of the forest pass.
///
/// Not Bevy's `StandardMaterial`: its physically based fragment costs about 0.8 µs per
/// pixel on a software rasteriser (Mesa lavapipe), so a terrain filling half a 960×540
/// view took ~200 ms a frame — more than the forest, and a cost the time-critical budget
/// does not control. This one costs a few nanoseconds per pixel.
#[derive(Asset, TypePath, AsBindGroup, Debug, Clone, PartialEq)]
pub(crate) struct TerrainMaterial {
    /// Colour where the light does not reach (linear RGB, alpha unused).
    #[uniform(0)]
    pub ambient: LinearRgba,
    /// Colour under full light (linear RGB, alpha unused).
    #[uniform(0)]
    pub diffuse: LinearRgba,
}

impl TerrainMaterial {
    /// The ecosystem material's ambient and diffuse colours.
    pub(crate) fn from_desc(desc: &MaterialDesc) -> Self {
        let [ar, ag, ab] = desc.ambient;
        let [dr, dg, db] = desc.diffuse;
        Self {
            ambient: LinearRgba::rgb(ar, ag, ab),
            diffuse: LinearRgba::rgb(dr, dg, db),
        }
    }
}

impl Default for TerrainMaterial {
    /// A mid green.
    fn default() -> Self {
        Self {
            ambient: LinearRgba::rgb(0.06, 0.08, 0.04),
            diffuse: LinearRgba::rgb(0.3, 0.4, 0.2),
        }
    }
}

impl Material for TerrainMaterial {
    fn fragment_shader() -> ShaderRef {
        ShaderRef::Path(
            bevy::asset::AssetPath::from_path_buf(embedded_path!("terrain.wgsl"))
                .with_source("embedded"),
        )
    }
}

/// Registers [`TerrainMaterial`] when Bevy's PBR plugin (and so the mesh pipeline) is
/// present; headless apps have neither and their terrain gets no mesh.
pub(super) fn add_terrain_material(app: &mut App) {
    embedded_asset!(app, "terrain.wgsl");
    if app.is_plugin_added::<bevy::pbr::PbrPlugin>() {
        app.add_plugins(MaterialPlugin::<TerrainMaterial>::default());
    }
}
