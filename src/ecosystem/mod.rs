//! Ecosystems (thesis chapter 3): RON descriptions of materials, species, terrain and
//! placement rules ([`EcosystemDesc`]), the NURBS-and-faults [`Terrain`], and the
//! jittered-grid placement.

mod desc;
pub(crate) mod placement;
mod plugin;
mod terrain;
#[cfg(feature = "render")]
mod terrain_material;

pub use desc::{EcosystemDesc, EcosystemError, InstanceDesc, MaterialDesc, SpeciesEntry};

pub use placement::{Angles, Tilt};

pub use plugin::ForestMembers;
pub use plugin::{
    Ecosystem, EcosystemFileError, EcosystemPlugin, Forest, ForestState, ForestTerrain, InForest,
};
pub use terrain::Terrain;
pub use terrain::{FaultsDesc, TerrainDesc, TerrainError};
#[cfg(feature = "render")]
pub(crate) use terrain_material::TerrainMaterial;
