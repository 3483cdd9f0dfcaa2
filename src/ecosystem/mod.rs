//! Ecosystems (thesis chapter 3): RON descriptions of materials, species, terrain and
//! placement rules ([`EcosystemDesc`]), the NURBS-and-faults [`Terrain`], and the
//! jittered-grid placement.

mod desc;
mod placement;
mod plugin;
mod terrain;
#[cfg(feature = "render")]
mod terrain_material;

pub use desc::{
    EcosystemDesc, EcosystemError, EcosystemLayout, InstanceDesc, InstanceLayout, MAX_SCALE,
    MIN_HAND_PLACED_SPACING, MaterialDesc, SpeciesEntry,
};
pub use placement::{Angles, Placement, Tilt, tilt_from_normal};
pub use plugin::{
    Ecosystem, EcosystemFileError, EcosystemLoader, EcosystemPlugin, Forest, ForestMembers,
    ForestState, ForestTerrain, InForest,
};
pub use terrain::{FaultsDesc, Terrain, TerrainDesc, TerrainError};
#[cfg(feature = "render")]
pub use terrain_material::TerrainMaterial;
