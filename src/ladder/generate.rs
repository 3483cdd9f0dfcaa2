//! A ladder of levels from one mesh, by simplification with meshoptimizer.

use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};

/// One level [`generate_ladder`] built.
#[derive(Clone, Debug)]
pub struct GeneratedLevel {
    /// The level: the input mesh's vertices and attributes, fewer triangles.
    pub mesh: Mesh,
    /// Its triangle count.
    pub triangles: u32,
    /// meshoptimizer's error estimate: the largest deviation of the simplified surface
    /// from the original, relative to the mesh's extent (0 for the full level).
    pub error: f32,
}

/// Why a mesh cannot be made into a ladder.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LadderError {
    /// Only triangle lists simplify.
    #[error("the mesh is a {0:?}; a ladder needs a triangle list")]
    NotTriangles(PrimitiveTopology),
    /// No positions, or not three 32-bit floats per vertex.
    #[error("the mesh has no Float32x3 positions")]
    NoPositions,
    /// A position is NaN or infinite.
    #[error("vertex {vertex} has a non-finite position")]
    NonFinitePosition {
        /// The vertex.
        vertex: usize,
    },
    /// An index past the vertices, or a count that is not a multiple of 3.
    #[error("the mesh's indices are not a triangle list over its {vertices} vertices")]
    BadIndices {
        /// The vertex count.
        vertices: usize,
    },
    /// The mesh has no triangles.
    #[error("the mesh has no triangles")]
    NoTriangles,
    /// A ratio is not in (0, 1), or the ratios do not decrease.
    #[error("ratio {index} is {ratio}: ratios must lie in (0, 1) and decrease")]
    BadRatio {
        /// Its position in the list.
        index: usize,
        /// The ratio.
        ratio: f32,
    },
}

/// Builds a ladder from `mesh`: the mesh itself first, then one level per ratio (each
/// the fraction of the full triangle count it aims at, decreasing, in (0, 1)).
///
/// Each level keeps every vertex and attribute of the input (normals, UVs, tangents,
/// colours: the material sees the same vertices) with a simplified index list, so the
/// bounds are the input's; meshoptimizer's attribute-preserving simplification first,
/// its "sloppy" one where topology stops it well short of the aim. A level that would
/// not have fewer triangles than the one before is left out, so the counts strictly
/// decrease; the levels' triangle counts and errors tell what each ratio gave.
pub fn generate_ladder(mesh: &Mesh, ratios: &[f32]) -> Result<Vec<GeneratedLevel>, LadderError> {
    let topology = mesh.primitive_topology();
    if topology != PrimitiveTopology::TriangleList {
        return Err(LadderError::NotTriangles(topology));
    }
    let Some(VertexAttributeValues::Float32x3(positions)) =
        mesh.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        return Err(LadderError::NoPositions);
    };
    if let Some(vertex) = positions
        .iter()
        .position(|p| !p.iter().all(|c| c.is_finite()))
    {
        return Err(LadderError::NonFinitePosition { vertex });
    }
    let indices: Vec<u32> = match mesh.indices() {
        Some(Indices::U16(i)) => i.iter().map(|&i| u32::from(i)).collect(),
        Some(Indices::U32(i)) => i.clone(),
        None => (0..positions.len() as u32).collect(),
    };
    let vertices = positions.len();
    if !indices.len().is_multiple_of(3) || indices.iter().any(|&i| i as usize >= vertices) {
        return Err(LadderError::BadIndices { vertices });
    }
    if indices.is_empty() {
        return Err(LadderError::NoTriangles);
    }
    let mut previous = 1.0_f32;
    for (index, &ratio) in ratios.iter().enumerate() {
        if !(ratio > 0.0 && ratio < previous) {
            return Err(LadderError::BadRatio { index, ratio });
        }
        previous = ratio;
    }

    let full = (indices.len() / 3) as u32;
    let mut levels = vec![GeneratedLevel {
        mesh: mesh.clone(),
        triangles: full,
        error: 0.0,
    }];
    for &ratio in ratios {
        let aim = ((full as f32 * ratio).round() as usize).max(1) * 3;
        let mut error = 0.0;
        let mut simplified = meshopt::simplify_decoder(
            &indices,
            positions,
            aim,
            f32::MAX,
            meshopt::SimplifyOptions::None,
            Some(&mut error),
        );
        if simplified.len() > 2 * aim {
            let mut sloppy_error = 0.0;
            let sloppy = meshopt::simplify_sloppy_decoder(
                &indices,
                positions,
                aim,
                f32::MAX,
                Some(&mut sloppy_error),
            );
            if !sloppy.is_empty() && sloppy.len() < simplified.len() {
                simplified = sloppy;
                error = sloppy_error;
            }
        }
        let triangles = (simplified.len() / 3) as u32;
        let fewer = levels.last().is_some_and(|l| triangles < l.triangles);
        if triangles == 0 || !fewer {
            continue;
        }
        let mut level = mesh.clone();
        level.insert_indices(Indices::U32(simplified));
        levels.push(GeneratedLevel {
            mesh: level,
            triangles,
            error: if error.is_finite() { error } else { 0.0 },
        });
    }
    Ok(levels)
}
