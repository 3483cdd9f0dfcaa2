//! Inspects a tree file: what the analysis made of it.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- tree-info FILE [--rings OUT.csv] [OPTIONS]
//! ```
//!
//! FILE is a glTF tree (`.glb`, `.gltf`), a model (`.tree.ron`, `.tree.bin`) or a species
//! (`.species.ron`, generated and analysed). Prints the rings, segments, leaves, leaf
//! groups, the depth of the hierarchy and the analysis' warnings; exits non-zero with
//! the error when the file is not a tree. See `--help` for the options.

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use bevy_sherwood::tree::{
    AnalysisWarning, GltfTreeSettings, NO_RING, SpeciesDesc, TreeModel, external_buffers,
    import_gltf,
};

/// The tree-info tool's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A glTF tree (.glb or .gltf, buffers embedded or beside it), a model (.tree.ron,
    /// .tree.bin), or a species (.species.ron: generated, then analysed): a path, or one
    /// under `assets/`.
    file: PathBuf,
    /// Write every ring as CSV with the header `ring,parent,x,y,z,radius,vertices`
    /// (ring: its index; parent: its parent's index, empty for a root; x,y,z: its centre
    /// and radius: its mean distance from the centre, in the file's own space and units,
    /// node transforms applied; vertices: the ring's distinct vertices, seam duplicates
    /// welded, so an EZ-Tree ring of S segments has S and a pointed tip has 1).
    #[arg(long, value_name = "OUT.csv")]
    rings: Option<PathBuf>,
    /// glTF and species: the ground height; open ends at or below it are root rings
    /// (default 0).
    #[arg(long, value_parser = finite, allow_negative_numbers = true)]
    ground: Option<f32>,
    /// glTF and species: vertices closer than T × the model's diagonal are one vertex
    /// (default 1e-6).
    #[arg(long, value_parser = non_negative)]
    weld_tolerance: Option<f32>,
    /// glTF: a primitive whose node, mesh or material name contains one of these is
    /// leaves (comma-separated; default leaf,leaves,foliage,needle).
    #[arg(long, value_delimiter = ',')]
    leaf_keywords: Option<Vec<String>>,
}

impl Args {
    fn settings(&self) -> GltfTreeSettings {
        let mut settings = GltfTreeSettings::default();
        if let Some(ground) = self.ground {
            settings.analysis.ground = ground;
        }
        if let Some(tolerance) = self.weld_tolerance {
            settings.analysis.weld_tolerance = tolerance;
        }
        if let Some(keywords) = &self.leaf_keywords {
            settings.leaf_keywords = keywords
                .iter()
                .map(|k| k.trim().to_owned())
                .filter(|k| !k.is_empty())
                .collect();
        }
        settings
    }
}

fn finite(text: &str) -> Result<f32, String> {
    match text.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{text:?} is not a finite number")),
    }
}

fn non_negative(text: &str) -> Result<f32, String> {
    finite(text).and_then(|v| {
        if v >= 0.0 {
            Ok(v)
        } else {
            Err("must not be negative".into())
        }
    })
}

/// The model and the analysis' warnings (none for a saved model).
fn load(
    path: &Path,
    settings: &GltfTreeSettings,
) -> Result<(TreeModel, Vec<AnalysisWarning>), String> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read: {e}"))?;
    if name.ends_with(".glb") || name.ends_with(".gltf") {
        let folder = path.parent().unwrap_or(Path::new("."));
        let mut external = HashMap::new();
        for file in external_buffers(&bytes).map_err(|e| e.to_string())? {
            let data = std::fs::read(folder.join(&file.path))
                .map_err(|e| format!("buffer {:?} beside the file: {e}", file.uri))?;
            external.insert(file.uri, data);
        }
        let analysis = import_gltf(&bytes, settings, &external).map_err(|e| e.to_string())?;
        Ok((analysis.model, analysis.warnings))
    } else if name.ends_with(".tree.bin") {
        Ok((
            TreeModel::from_binary(&bytes).map_err(|e| e.to_string())?,
            Vec::new(),
        ))
    } else if name.ends_with(".tree.ron") {
        let text = String::from_utf8(bytes).map_err(|e| format!("not UTF-8: {e}"))?;
        Ok((
            TreeModel::from_ron_str(&text).map_err(|e| e.to_string())?,
            Vec::new(),
        ))
    } else if name.ends_with(".species.ron") {
        let text = String::from_utf8(bytes).map_err(|e| format!("not UTF-8: {e}"))?;
        let species = SpeciesDesc::from_ron_str(&text).map_err(|e| e.to_string())?;
        let analysis = species
            .generate_and_analyze_with(&settings.analysis)
            .map_err(|e| e.to_string())?;
        Ok((analysis.model, analysis.warnings))
    } else {
        Err(
            "unknown kind of file: expected .glb, .gltf, .tree.ron, .tree.bin or .species.ron"
                .into(),
        )
    }
}

/// Each ring's branch order: a root's chain is order 0, and a ring that is not its
/// parent's thickest child starts a branch one order deeper.
fn branch_orders(model: &TreeModel) -> Vec<u32> {
    let mut order = vec![0_u32; model.rings.len()];
    // Parents come before children in the analysis' ring order.
    for (r, ring) in model.rings.iter().enumerate() {
        if ring.parent == NO_RING {
            continue;
        }
        let parent = &model.rings[ring.parent as usize];
        let thickest = parent
            .children
            .iter()
            .copied()
            .max_by(|&a, &b| {
                model.rings[a as usize]
                    .diameter
                    .total_cmp(&model.rings[b as usize].diameter)
                    .then(b.cmp(&a))
            })
            .unwrap_or(r as u32);
        order[r] = order[ring.parent as usize] + u32::from(thickest != r as u32);
    }
    order
}

fn report(path: &Path, model: &TreeModel, warnings: &[AnalysisWarning]) -> String {
    let mut out = String::new();
    let roots = model.roots().count();
    let terminal = model.rings.iter().filter(|r| r.is_terminal()).count();
    let ring_depth = model.rings.iter().map(|r| r.level).max().unwrap_or(0);
    let orders = branch_orders(model);
    let mut branches_per_order = vec![0_usize; orders.iter().max().map_or(1, |&o| o as usize + 1)];
    for (r, ring) in model.rings.iter().enumerate() {
        let starts_branch = ring.parent == NO_RING || orders[r] != orders[ring.parent as usize];
        if starts_branch {
            branches_per_order[orders[r] as usize] += 1;
        }
    }
    let b = model.bounds;
    let _ = writeln!(out, "{}", path.display());
    let _ = writeln!(
        out,
        "rings        {} ({roots} root, {terminal} terminal), ring levels up to {ring_depth}",
        model.rings.len()
    );
    let _ = writeln!(
        out,
        "segments     {} ({} trunk triangles, {:.2} total length)",
        model.segments.len(),
        model.trunk_triangle_count(),
        model
            .segments
            .cumulative_length
            .last()
            .copied()
            .unwrap_or(0.0)
    );
    let _ = writeln!(
        out,
        "branches     {} in {} orders (per order: {})",
        branches_per_order.iter().sum::<usize>(),
        branches_per_order.len(),
        branches_per_order
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join("/")
    );
    let _ = writeln!(
        out,
        "leaves       {} ({} triangles) in {} groups",
        model.leaves.len(),
        model.leaf_triangle_count(),
        model.leaf_groups.len()
    );
    let _ = writeln!(
        out,
        "bounds       ({:.3}, {:.3}, {:.3}) .. ({:.3}, {:.3}, {:.3})",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    if warnings.is_empty() {
        let _ = writeln!(out, "warnings     none");
    }
    for w in warnings {
        let _ = writeln!(out, "warning      {w:?}");
    }
    out
}

fn rings_csv(model: &TreeModel) -> String {
    let mut out = String::from("ring,parent,x,y,z,radius,vertices\n");
    for (r, ring) in model.rings.iter().enumerate() {
        let parent = if ring.parent == NO_RING {
            String::new()
        } else {
            ring.parent.to_string()
        };
        let c = ring.center;
        let _ = writeln!(
            out,
            "{r},{parent},{},{},{},{},{}",
            c.x,
            c.y,
            c.z,
            0.5 * ring.diameter,
            ring.vertices.len()
        );
    }
    out
}

/// Runs the tree-info tool.
pub fn run(args: Args) -> ExitCode {
    // A path that names no file may be one under `assets/`, as the shipped trees are.
    let file = crate::assets::resolve(&args.file).unwrap_or_else(|_| args.file.clone());
    let (model, warnings) = match load(&file, &args.settings()) {
        Ok(loaded) => loaded,
        Err(e) => {
            eprintln!("{}: {e}", file.display());
            return ExitCode::FAILURE;
        }
    };
    // Printed with `write!`: a closed pipe (`| head`) ends the output, not the program.
    let mut stdout = std::io::stdout().lock();
    let _ = write!(stdout, "{}", report(&args.file, &model, &warnings));
    if let Some(out) = &args.rings {
        if let Err(e) = std::fs::write(out, rings_csv(&model)) {
            eprintln!("{}: cannot write: {e}", out.display());
            return ExitCode::FAILURE;
        }
        let _ = writeln!(stdout, "rings written to {}", out.display());
    }
    ExitCode::SUCCESS
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> TreeModel {
        let path = crate::assets::root().join("trees/eztree/aspen_small.tree.glb");
        load(&path, &GltfTreeSettings::default()).unwrap().0
    }

    #[test]
    fn rings_csv_has_the_documented_header_and_one_row_per_ring() {
        let model = model();
        let csv = rings_csv(&model);
        let mut lines = csv.lines();
        assert_eq!(lines.next(), Some("ring,parent,x,y,z,radius,vertices"));
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert_eq!(rows.len(), model.rings.len());
        for (r, row) in rows.iter().enumerate() {
            assert_eq!(row.len(), 7);
            assert_eq!(row[0], r.to_string());
            let ring = &model.rings[r];
            assert_eq!(row[1].is_empty(), ring.parent == NO_RING);
            let radius: f32 = row[5].parse().unwrap();
            assert!((radius - 0.5 * ring.diameter).abs() < 1e-6);
            assert_eq!(row[6], ring.vertices.len().to_string());
        }
        // EZ-Tree's Aspen Small: 8 segments per trunk ring, welded from 9 with the seam copy.
        assert_eq!(rows[0][6], "8");
    }

    #[test]
    fn a_generator_tree_has_as_many_branch_orders_as_levels() {
        // Aspen Small: trunk and two levels of branches.
        let model = model();
        let orders = branch_orders(&model);
        assert_eq!(orders.iter().max(), Some(&2));
        let text = report(Path::new("aspen"), &model, &[]);
        assert!(
            text.contains("branches     20 in 3 orders (per order: 1/7/12)"),
            "{text}"
        );
    }

    #[test]
    fn options_and_bad_arguments() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            args: Args,
        }
        let args = |a: &[&str]| {
            Cli::try_parse_from(std::iter::once("tree-info").chain(a.iter().copied()))
                .map(|c| c.args)
                .map_err(|e| e.to_string())
        };
        let parsed = args(&[
            "t.glb",
            "--ground",
            "-0.5",
            "--leaf-keywords",
            "frond, leaf",
            "--rings",
            "o.csv",
        ])
        .unwrap();
        let settings = parsed.settings();
        assert_eq!(settings.analysis.ground, -0.5);
        assert_eq!(settings.leaf_keywords, ["frond", "leaf"]);
        assert_eq!(parsed.rings.as_deref(), Some(Path::new("o.csv")));
        let defaults = args(&["t.glb"]).unwrap().settings();
        assert_eq!(
            defaults.leaf_keywords,
            GltfTreeSettings::default().leaf_keywords
        );
        assert_eq!(defaults.analysis, GltfTreeSettings::default().analysis);
        assert!(args(&[]).unwrap_err().contains("FILE"));
        assert!(
            args(&["t.glb", "--ground", "x"])
                .unwrap_err()
                .contains("--ground")
        );
        assert!(
            args(&["t.glb", "--ground", "inf"])
                .unwrap_err()
                .contains("--ground")
        );
        assert!(args(&["t.glb", "--weld-tolerance", "-1"]).is_err());
        assert!(args(&["t.glb", "--bogus"]).unwrap_err().contains("--bogus"));
        assert!(load(Path::new("tree.obj"), &GltfTreeSettings::default()).is_err());
    }
}
