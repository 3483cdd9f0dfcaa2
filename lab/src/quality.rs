//! Image quality of one level-of-detail frame against the full-detail frame of the same
//! view: structural similarity (SSIM) of the two pictures, and per tree the share of its
//! full-detail pixels the LOD image still covers (from the forest tool's
//! `--id-colors` pictures of both), so that a dropped or hollowed tree shows even where
//! the average error is small.
//!
//! ```sh
//! cargo run --release -p sherwood-lab -- quality compare FULL.png FULL-ID.png LOD.png LOD-ID.png
//! ```
//!
//! Prints one line of `key=value` pairs (`scripts/quality.sh` gathers them): `ssim`
//! (mean SSIM over 8×8 windows of the luma, 1 = identical), `trees` (trees with at least
//! `MIN_PIXELS` pixels at full detail), `coverage_mean`, `coverage_p5`, `coverage_min`,
//! and `below_95` (how many of those trees keep less than 95% of their pixels).
//!
//! `quality sheet OUT.png COLUMNS IMAGE...` instead lays the pictures out at half size,
//! `COLUMNS` to a row in the order given, as one contact sheet; `quality map OUT.png
//! FULL.png LOD.png` writes where the two pictures differ, as the SSIM of each 8×8 window
//! in false colour (blue: identical, red: unrelated).

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use image::RgbImage;
use image_compare::Algorithm;

use crate::id_colors;

/// Trees smaller than this at full detail are left out of the coverage figures: a few
/// pixels of a distant tree move between frames for reasons other than its detail.
const MIN_PIXELS: u32 = 30;

fn open(path: &Path) -> Result<RgbImage, String> {
    image::open(path)
        .map(|i| i.to_rgb8())
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// Per tree: (pixels at full detail, of those the LOD image also gives to that tree).
fn coverage(full: &RgbImage, lod: &RgbImage) -> HashMap<u32, (u32, u32)> {
    let mut trees: HashMap<u32, (u32, u32)> = HashMap::new();
    for (a, b) in full.pixels().zip(lod.pixels()) {
        if let Some(tree) = id_colors::decode(a.0) {
            let entry = trees.entry(tree).or_default();
            entry.0 += 1;
            if id_colors::decode(b.0) == Some(tree) {
                entry.1 += 1;
            }
        }
    }
    trees
}

/// Lays `images` out at half size, `columns` to a row, into `out`.
fn contact_sheet(out: &Path, columns: u32, images: &[PathBuf]) -> Result<String, String> {
    let pictures: Vec<RgbImage> = images
        .iter()
        .map(|path| {
            open(path).map(|i| {
                image::imageops::resize(
                    &i,
                    (i.width() / 2).max(1),
                    (i.height() / 2).max(1),
                    image::imageops::FilterType::Triangle,
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let Some(first) = pictures.first() else {
        return Err("sheet: no pictures".into());
    };
    let (w, h) = (first.width(), first.height());
    let rows = (pictures.len() as u32).div_ceil(columns);
    let mut sheet = RgbImage::from_pixel(w * columns, h * rows, image::Rgb([255, 255, 255]));
    for (i, picture) in pictures.iter().enumerate() {
        let (x, y) = (i as u32 % columns * w, i as u32 / columns * h);
        image::imageops::overlay(&mut sheet, picture, i64::from(x), i64::from(y));
    }
    sheet
        .save(out)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(format!("wrote {}", out.display()))
}

/// The luma's structural similarity of two pictures of the same size.
fn ssim(full: &RgbImage, lod: &RgbImage) -> Result<image_compare::Similarity, String> {
    let gray = |i: &RgbImage| image::DynamicImage::ImageRgb8(i.clone()).to_luma8();
    image_compare::gray_similarity_structure(&Algorithm::MSSIMSimple, &gray(full), &gray(lod))
        .map_err(|e| format!("SSIM: {e}"))
}

/// Writes the per-window SSIM of `lod` against `full` into `out` as a colour map.
fn ssim_map(out: &Path, full: &Path, lod: &Path) -> Result<String, String> {
    let similarity = ssim(&open(full)?, &open(lod)?)?;
    similarity
        .image
        .to_color_map()
        .save(out)
        .map_err(|e| format!("{}: {e}", out.display()))?;
    Ok(format!(
        "wrote {} (ssim={:.4})",
        out.display(),
        similarity.score
    ))
}

/// The quality tool's command line.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(clap::Subcommand, Debug)]
enum What {
    /// SSIM of the LOD picture against the full-detail one, and per tree the share of
    /// its full-detail pixels the LOD picture keeps (from the `--id-colors` pictures).
    Compare {
        full: PathBuf,
        full_id: PathBuf,
        lod: PathBuf,
        lod_id: PathBuf,
    },
    /// The pictures at half size, COLUMNS to a row, as one contact sheet.
    Sheet {
        out: PathBuf,
        #[arg(value_parser = clap::value_parser!(u32).range(1..))]
        columns: u32,
        #[arg(required = true)]
        images: Vec<PathBuf>,
    },
    /// Where two pictures differ, as the SSIM of each 8×8 window in false colour.
    Map {
        out: PathBuf,
        full: PathBuf,
        lod: PathBuf,
    },
}

/// Runs the quality tool; prints its line.
pub fn run(args: Args) -> ExitCode {
    let line = match &args.what {
        What::Compare {
            full,
            full_id,
            lod,
            lod_id,
        } => compare(full, full_id, lod, lod_id),
        What::Sheet {
            out,
            columns,
            images,
        } => contact_sheet(out, *columns, images),
        What::Map { out, full, lod } => ssim_map(out, full, lod),
    };
    crate::report("quality", line.map(|line| println!("{line}")))
}

fn compare(full: &Path, full_id: &Path, lod: &Path, lod_id: &Path) -> Result<String, String> {
    let (full, lod) = (open(full)?, open(lod)?);
    let (full_id, lod_id) = (open(full_id)?, open(lod_id)?);
    let size = full.dimensions();
    if [lod.dimensions(), full_id.dimensions(), lod_id.dimensions()]
        .iter()
        .any(|d| *d != size)
    {
        return Err("the four pictures must have the same size".into());
    }
    let ssim = ssim(&full, &lod)?.score;
    let mut shares: Vec<f64> = coverage(&full_id, &lod_id)
        .values()
        .filter(|(pixels, _)| *pixels >= MIN_PIXELS)
        .map(|&(pixels, kept)| f64::from(kept) / f64::from(pixels))
        .collect();
    shares.sort_by(f64::total_cmp);
    let n = shares.len();
    let mean = shares.iter().sum::<f64>() / n.max(1) as f64;
    let p5 = shares.get(n / 20).copied().unwrap_or(1.0);
    let min = shares.first().copied().unwrap_or(1.0);
    let below = shares.iter().filter(|&&s| s < 0.95).count();
    Ok(format!(
        "ssim={ssim:.4} trees={n} coverage_mean={mean:.4} coverage_p5={p5:.4} coverage_min={min:.4} below_95={below}"
    ))
}
