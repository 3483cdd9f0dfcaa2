//! Trees from EZ-Tree (npm `@dgreenheck/ez-tree`, MIT), exported by
//! `scripts/eztree/export.mjs` with three.js's `GLTFExporter` as its web app does: every
//! branch a separate open tube starting inside its parent, continuations welded to
//! their parent's last ring, bushes dipping below the ground. Each file comes with the
//! generator's own branch hierarchy (`*.branches.csv`), and the analysis must hang at
//! least 95% of the branches on their true parent.
//!
//! The shipped trees are in `assets/trees/eztree/` (their hierarchies in
//! `tests/data/eztree/`); `scripts/eztree/check.sh` exports every preset at several
//! seeds and runs this test on them too, through `SHERWOOD_EZTREE_DIR`.
#![cfg(feature = "gltf")]

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use bevy::math::Vec3;
use bevy_sherwood::tree::*;

/// One ring of the generator's output.
struct TrueRing {
    branch: usize,
    parent: Option<usize>,
    center: Vec3,
}

fn read_truth(csv: &Path) -> Vec<TrueRing> {
    let text = std::fs::read_to_string(csv).unwrap_or_else(|e| panic!("{}: {e}", csv.display()));
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("branch,parent,level,section,x,y,z,radius"),
        "{}",
        csv.display()
    );
    lines
        .map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            let number = |i: usize| -> f32 { f[i].parse().unwrap() };
            TrueRing {
                branch: f[0].parse().unwrap(),
                parent: (!f[1].is_empty()).then(|| f[1].parse().unwrap()),
                center: Vec3::new(number(4), number(5), number(6)),
            }
        })
        .collect()
}

/// How many of the generator's branches the model hangs on their true parent, of how
/// many branches that have a parent.
fn branches_on_their_parent(model: &TreeModel, truth: &[TrueRing]) -> (usize, usize) {
    let diagonal = (model.bounds.max - model.bounds.min).length();
    // Well below the spacing of sibling bases, well above the weld tolerance (1e-5).
    let tolerance = 1e-4 * diagonal;
    let ring_at = |p: Vec3| {
        model
            .rings
            .iter()
            .enumerate()
            .map(|(r, ring)| (ring.center.distance(p), r))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .filter(|&(d, _)| d <= tolerance)
            .map(|(_, r)| r)
    };
    let mut rings_of: HashMap<usize, Vec<Vec3>> = HashMap::new();
    for ring in truth {
        rings_of.entry(ring.branch).or_default().push(ring.center);
    }
    let on_branch =
        |branch: usize, p: Vec3| rings_of[&branch].iter().any(|c| c.distance(p) <= tolerance);
    let (mut right, mut total) = (0, 0);
    for (&branch, centers) in &rings_of {
        let Some(parent) = truth.iter().find(|r| r.branch == branch).unwrap().parent else {
            continue;
        };
        total += 1;
        // A continuation's first ring is its parent's last: its own begin one further.
        let Some(first_own) = centers.iter().find(|&&c| !on_branch(parent, c)) else {
            continue;
        };
        let hung_right = ring_at(*first_own).is_some_and(|r| {
            let up = model.rings[r].parent;
            up != NO_RING && on_branch(parent, model.rings[up as usize].center)
        });
        if !hung_right && std::env::var("EZ_DEBUG").is_ok() {
            let r = ring_at(*first_own);
            eprintln!(
                "branch {branch} (parent {parent}) first ring {first_own} -> {:?}",
                r.map(|r| (
                    model.rings[r].center,
                    model.rings[r].diameter,
                    model.rings[r].parent,
                    {
                        let up = model.rings[r].parent;
                        (up != NO_RING).then(|| model.rings[up as usize].center)
                    }
                ))
            );
        }
        right += usize::from(hung_right);
    }
    (right, total)
}

/// Every tree file (`*.tree.glb`) with its hierarchy (`*.branches.csv`).
fn cases() -> Vec<(PathBuf, PathBuf)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut out = Vec::new();
    let mut add = |glb_dir: &Path, csv_dir: &Path| {
        let mut entries: Vec<PathBuf> = std::fs::read_dir(csv_dir)
            .unwrap_or_else(|e| panic!("{}: {e}", csv_dir.display()))
            .map(|e| e.unwrap().path())
            .filter(|p| p.to_string_lossy().ends_with(".branches.csv"))
            .collect();
        entries.sort();
        for csv in entries {
            let stem = csv
                .file_name()
                .unwrap()
                .to_string_lossy()
                .trim_end_matches(".branches.csv")
                .to_owned();
            out.push((glb_dir.join(format!("{stem}.tree.glb")), csv));
        }
    };
    add(
        &root.join("assets/trees/eztree"),
        &root.join("tests/data/eztree"),
    );
    if let Ok(dir) = std::env::var("SHERWOOD_EZTREE_DIR") {
        add(Path::new(&dir), Path::new(&dir));
    }
    out
}

#[test]
fn eztree_exports_import_and_hang_branches_on_their_true_parent() {
    let cases = cases();
    assert!(cases.len() >= 4, "the shipped EZ-Tree trees are missing");
    let (mut report, mut failures) = (Vec::new(), Vec::new());
    for (glb, csv) in &cases {
        let name = glb.file_name().unwrap().to_string_lossy().into_owned();
        let bytes = std::fs::read(glb).unwrap_or_else(|e| panic!("{}: {e}", glb.display()));
        let analysis = match import_gltf(&bytes, &GltfTreeSettings::default(), &HashMap::new()) {
            Ok(analysis) => analysis,
            Err(e) => {
                failures.push(format!("{name}: {e}"));
                continue;
            }
        };
        let model = &analysis.model;
        model.validate().unwrap();
        let roots = model.roots().count();
        if roots != 1 || model.leaves.is_empty() {
            failures.push(format!(
                "{name}: {roots} roots and {} leaves; one trunk with leaves expected",
                model.leaves.len()
            ));
        }
        let (right, total) = branches_on_their_parent(model, &read_truth(csv));
        let share = right as f64 / total.max(1) as f64;
        report.push(format!(
            "{name}: {right}/{total} branches on their true parent ({:.1}%)",
            100.0 * share
        ));
        if share < 0.95 {
            failures.push(format!(
                "{name}: only {right} of {total} branches on their true parent"
            ));
        }
    }
    println!("{}", report.join("\n"));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
