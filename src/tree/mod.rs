//! Trees: the ring-hierarchy model ([`TreeModel`]), its analysis from meshes
//! ([`analyze`]), a procedural generator of species ([`SpeciesDesc`]), and the assets
//! that load them ([`TreePlugin`]).

mod analyze;
mod asset;
mod crown;
#[cfg(feature = "gltf")]
mod gltf;
mod group_impostor;
mod lod;
#[cfg(feature = "render")]
mod mesh;
mod model;
mod species;

pub use analyze::{
    AnalysisOptions, AnalysisWarning, MeshData, TreeAnalysis, TreeAnalysisError, TreePart, analyze,
};
pub(crate) use asset::{FollowedModels, TreeModelsVersion};

pub use asset::{TreeFileError, TreePlugin};
pub use crown::Crown;
#[cfg(feature = "gltf")]
pub(crate) use gltf::GltfTreeLoader;
#[cfg(feature = "gltf")]
pub use gltf::{BufferFile, GltfTreeError, GltfTreeSettings, external_buffers, import_gltf};
pub(crate) use group_impostor::{GroupImpostorMember, GroupImpostorOptions, group_impostor_model};
pub use lod::PixelRange;
pub(crate) use lod::Projection;
pub(crate) use lod::trunk_line_runs;
#[cfg(test)]
pub(crate) use lod::trunk_lod;
#[cfg(feature = "render")]
pub(crate) use mesh::triangle_mesh;
#[cfg(feature = "render")]
pub use mesh::{MeshConversionError, OwnedMeshData};
pub use model::{
    BoundingSphere, Bounds, Leaf, LeafGroup, LinearRgb, NO_RING, Ring, Segments, TreeModel,
};
#[cfg(test)]
pub(crate) use species::tube;
pub use species::{BranchLevel, GeneratedTree, LeafDesc, LeafShape, SpeciesDesc, SpeciesError};

/// The shipped `grand` species, generated and analysed: a full tree for unit tests.
#[cfg(test)]
pub(crate) fn grand_model() -> TreeModel {
    let text = include_str!("../../assets/species/grand.species.ron");
    SpeciesDesc::from_ron_str(text)
        .unwrap()
        .generate_and_analyze()
        .unwrap()
        .model
}
