//! Image quality of one level-of-detail frame against the full-detail frame of the same
//! view: structural similarity (SSIM) of the two pictures, and per tree the share of its
//! full-detail pixels the LOD image still covers (from the forest tool's
//! `--id-colors` pictures of both), so that a dropped or hollowed tree shows even where
//! the average error is small.
//!
//! ```sh
//! cargo run --release --bin sherwood-lab -- quality compare FULL.png FULL-ID.png LOD.png LOD-ID.png
//! ```
//!
//! Prints one line of `key=value` pairs (`scripts/quality.sh` gathers them): `ssim`
//! (mean SSIM over 8×8 windows of the luma, 1 = identical), `flip` (the mean ꟻLIP error,
//! NVIDIA's perceptual difference of two pictures shown one after the other, Andersson
//! et al. 2020: 0 = identical, 1 = opposite; at ꟻLIP's default 67 pixels per degree),
//! `trees` (trees with at least
//! `MIN_PIXELS` pixels at full detail), `coverage_mean`, `coverage_p5`, `coverage_min`,
//! and `below_95` (how many of those trees keep less than 95% of their pixels).
//!
//! `quality sheet OUT.png COLUMNS IMAGE...` instead lays the pictures out at half size,
//! `COLUMNS` to a row in the order given, as one contact sheet; `quality map OUT.png
//! FULL.png LOD.png` writes where the two pictures differ, as the SSIM of each 8×8 window
//! in false colour (blue: identical, red: unrelated); `quality shimmer FRAME...` measures
//! how a still camera's consecutive frames differ: `changed_mean` and `changed_max` (the
//! share of pixels that changed from one frame to the next) and `flip_mean`, `flip_max`
//! (ꟻLIP between them).

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

/// The mean ꟻLIP error of `test` against `reference` (pictures of the same size).
fn flip(reference: &RgbImage, test: &RgbImage) -> f32 {
    let (w, h) = reference.dimensions();
    let error = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, reference.as_raw()),
        nv_flip::FlipImageRgb8::with_data(w, h, test.as_raw()),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    );
    nv_flip::FlipPool::from_image(&error).mean()
}

/// The share of pixels that differ between two pictures of the same size.
fn changed_share(a: &RgbImage, b: &RgbImage) -> f64 {
    let changed = a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count();
    changed as f64 / (u64::from(a.width()) * u64::from(a.height())).max(1) as f64
}

/// How consecutive `frames` (of a still camera) differ.
fn shimmer(frames: &[PathBuf]) -> Result<String, String> {
    let pictures: Vec<RgbImage> = frames.iter().map(|f| open(f)).collect::<Result<_, _>>()?;
    if pictures.len() < 2 {
        return Err("shimmer: at least two frames".into());
    }
    if pictures
        .iter()
        .any(|p| p.dimensions() != pictures[0].dimensions())
    {
        return Err("shimmer: the frames must have the same size".into());
    }
    let pairs = pictures.windows(2);
    let changed: Vec<f64> = pairs.clone().map(|w| changed_share(&w[0], &w[1])).collect();
    let flips: Vec<f32> = pairs.map(|w| flip(&w[0], &w[1])).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let flips: Vec<f64> = flips.into_iter().map(f64::from).collect();
    let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
    Ok(format!(
        "pairs={} changed_mean={:.6} changed_max={:.6} flip_mean={:.6} flip_max={:.6}",
        changed.len(),
        mean(&changed),
        max(&changed),
        mean(&flips),
        max(&flips)
    ))
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
    /// How a still camera's consecutive frames differ: the share of pixels changed, and
    /// ꟻLIP between them.
    Shimmer {
        #[arg(num_args = 2.., required = true)]
        frames: Vec<PathBuf>,
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
        What::Shimmer { frames } => shimmer(frames),
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
    let flip = flip(&full, &lod);
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
        "ssim={ssim:.4} flip={flip:.4} trees={n} coverage_mean={mean:.4} coverage_p5={p5:.4} coverage_min={min:.4} below_95={below}"
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn picture(seed: u8) -> RgbImage {
        RgbImage::from_fn(32, 24, |x, y| {
            image::Rgb([(x * 8) as u8, (y * 10) as u8 ^ seed, seed])
        })
    }

    #[test]
    fn identical_pictures_differ_by_nothing_and_a_changed_one_by_its_share() {
        let a = picture(0);
        let mut b = a.clone();
        assert_eq!((changed_share(&a, &b), flip(&a, &b)), (0.0, 0.0));
        for x in 0..8 {
            b.put_pixel(x, 0, image::Rgb([255, 255, 255]));
        }
        assert!((changed_share(&a, &b) - 8.0 / (32.0 * 24.0)).abs() < 1e-9);
        assert!(flip(&a, &b) > 0.0);
        assert!(
            flip(&a, &picture(200)) > flip(&a, &b),
            "more change, more error"
        );
    }

    #[test]
    fn shimmer_needs_two_frames_of_one_size() {
        let dir = std::env::temp_dir().join(format!("sherwood-shimmer-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = |name: &str| dir.join(name);
        picture(0).save(path("a.png")).unwrap();
        picture(0).save(path("b.png")).unwrap();
        picture(9).save(path("c.png")).unwrap();
        RgbImage::new(4, 4).save(path("small.png")).unwrap();
        let line = shimmer(&[path("a.png"), path("b.png"), path("c.png")]).unwrap();
        assert!(line.starts_with("pairs=2 changed_mean="), "{line}");
        assert!(!line.contains("changed_max=0.000000"), "{line}");
        assert!(shimmer(&[path("a.png")]).is_err());
        assert!(shimmer(&[path("a.png"), path("small.png")]).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
