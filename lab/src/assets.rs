//! Where the tools find the crate's assets, and files named on the command line.

use std::path::{Path, PathBuf};

use bevy_sherwood::cost::Calibration;

/// The crate's `assets/` folder: the tools load species, calibrations and wind from it
/// however the binary is started.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets")
}

/// A file named on the command line: `path` as given (relative to the working directory,
/// or absolute) when it exists, otherwise the same path under `assets/` (so the default
/// `forests/default.ecosystem.ron` works from anywhere). Neither: an error naming both.
pub fn resolve(path: &Path) -> Result<PathBuf, String> {
    if path.is_file() {
        return Ok(path.to_owned());
    }
    let under_assets = root().join(path);
    if path.is_relative() && under_assets.is_file() {
        return Ok(under_assets);
    }
    Err(if path.is_relative() {
        format!(
            "{}: no such file (nor {})",
            path.display(),
            under_assets.display()
        )
    } else {
        format!("{}: no such file", path.display())
    })
}

/// The calibration in `file` (a path, or one under `assets/`).
pub fn read_calibration(file: &Path) -> Result<Calibration, String> {
    let path = resolve(file)?;
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    Calibration::from_ron_str(&text).map_err(|e| format!("{}: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_found_as_given_or_under_the_assets() {
        let default = resolve(Path::new("forests/default.ecosystem.ron")).unwrap();
        assert!(default.starts_with(root()), "{}", default.display());
        // Absolute, outside the assets.
        let dir = std::env::temp_dir().join(format!("sherwood-lab-assets-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("mine.ecosystem.ron");
        std::fs::write(&file, "()").unwrap();
        assert_eq!(resolve(&file).unwrap(), file);
        let missing = resolve(&dir.join("none.ron")).unwrap_err();
        assert!(missing.contains("none.ron"), "{missing}");
        let missing = resolve(Path::new("forests/none.ron")).unwrap_err();
        assert!(missing.contains("nor "), "{missing}");
        std::fs::remove_dir_all(dir).unwrap();
    }
}
