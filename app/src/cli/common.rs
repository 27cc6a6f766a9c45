//! Helpers every command group shares; command modules use these and never each other.

use super::error::{bad_input, Classify, Result};
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use tagsmith::family::{self, Family};

/// A built-in name, or a path to a family file.
pub fn load_family(name_or_path: &str) -> Result<Family> {
    if let Some(found) = tagsmith::builtin::get(name_or_path) {
        return Ok(found?);
    }
    let path = Path::new(name_or_path);
    if path.exists() || name_or_path.ends_with(".json") {
        return Ok(family::load_file(path)?);
    }
    let names: Vec<_> = tagsmith::builtin::names().collect();
    Err(bad_input!(
        "no built-in family or file named {name_or_path:?}; built-in families: {}",
        names.join(", ")
    ))
}

/// Refuses an output folder that names a file, or lies under one, as bad input naming `option`:
/// creating the folder there would fail as if the disk had.
pub(crate) fn output_folder(path: &Path, option: &str) -> Result<()> {
    let mut at = Some(path);
    while let Some(p) = at.filter(|p| !p.as_os_str().is_empty()) {
        match std::fs::metadata(p) {
            Ok(m) if m.is_dir() => return Ok(()),
            Ok(_) if p == path => {
                return Err(bad_input!(
                    "{option} {}: it exists and is not a folder",
                    path.display()
                ))
            }
            Ok(_) => {
                return Err(bad_input!(
                    "{option} {}: {} is not a folder",
                    path.display(),
                    p.display()
                ))
            }
            Err(_) => at = p.parent(),
        }
    }
    Ok(())
}

pub(crate) fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    tagsmith::io::write_atomic(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
        .failure()
}

pub(crate) fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

/// Prints to stdout, ending quietly when the reader has gone (`tagsmith families | head`).
pub(crate) fn print_quietly(text: &str) {
    use std::io::Write as _;
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

/// The code permutations of the rotations the layout cannot tell apart: the codebook's distance
/// is measured over these, in `validate` and `codebook stats` alike.
pub(crate) fn rotations_of(family: &Family) -> Vec<Vec<usize>> {
    family
        .ambiguous_rotations()
        .filter_map(|r| r.code_perm.clone())
        .collect()
}

pub(crate) fn progress_bar(len: u64, template: &str) -> ProgressBar {
    ProgressBar::new(len)
        .with_style(ProgressStyle::with_template(template).expect("a valid template"))
}

/// A clap value parser for a number in `[min, max]` whose error names the range (clap puts the
/// option in front). Floats have no ranged parser in clap, and a size of `1e300` or `5e-324` must
/// fail here rather than as an allocation or a NaN further on.
pub(crate) fn f64_in(
    min: f64,
    max: f64,
) -> impl Fn(&str) -> std::result::Result<f64, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v: f64 = text.trim().parse().map_err(|e| format!("{e}"))?;
        if v >= min && v <= max {
            Ok(v)
        } else {
            Err(format!("{v} is not in [{min}, {max}]"))
        }
    }
}

/// As [`f64_in`], for ranges open at zero: `(0, max]`.
pub(crate) fn positive_f64_up_to(
    max: f64,
) -> impl Fn(&str) -> std::result::Result<f64, String> + Clone + Send + Sync + 'static {
    move |text| {
        let v: f64 = text.trim().parse().map_err(|e| format!("{e}"))?;
        if v > 0.0 && v <= max {
            Ok(v)
        } else {
            Err(format!("{v} is not in (0, {max}]"))
        }
    }
}
