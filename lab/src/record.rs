//! The forest example's `--record` files, read back by column name.

use std::path::{Path, PathBuf};

/// A record: its columns' names and one row of numbers per frame (an empty or unreadable
/// cell is NaN).
pub struct Record {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Record {
    /// Reads `csv`.
    pub fn read(csv: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(csv).map_err(|e| format!("{}: {e}", csv.display()))?;
        let mut lines = text.lines();
        let header: Vec<String> = lines
            .next()
            .unwrap_or_default()
            .split(',')
            .map(str::to_owned)
            .collect();
        let rows = lines
            .map(|line| {
                line.split(',')
                    .map(|cell| cell.parse().unwrap_or(f64::NAN))
                    .collect()
            })
            .collect();
        Ok(Self { header, rows })
    }

    /// The column `name`, one value per frame.
    pub fn column(&self, name: &str) -> Result<Vec<f64>, String> {
        let c = self
            .header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| format!("no column {name}"))?;
        Ok(self
            .rows
            .iter()
            .map(|row| row.get(c).copied().unwrap_or(f64::NAN))
            .collect())
    }
}

/// The `*.csv` files of `dir`, sorted.
pub fn csv_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "csv"))
        .collect();
    paths.sort();
    Ok(paths)
}
