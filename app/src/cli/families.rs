//! `families`, `validate` and `schema`: what the family files hold.

use super::common::{load_family, print_quietly, rotations_of};
use super::error::{bad_input, Result};
use clap::Args;
use std::path::PathBuf;
use tagsmith::family;

#[derive(Args, Debug)]
pub struct FamiliesArgs {}

impl FamiliesArgs {
    pub fn run(self) -> Result<()> {
        use std::fmt::Write as _;
        use tagsmith::detect::stage2::{shipped_model, DEFAULT_FAMILIES};
        let mut out = format!(
            "{:<24} {:<6} {:>9} {:>3} {:>6} {:>5} {:<8} title\n",
            "name", "layout", "keypoints", "q", "codes", "d_min", "detects"
        );
        for name in tagsmith::builtin::names() {
            let f = load_family(name)?;
            let d = f
                .spec()
                .codebook
                .min_distance
                .map_or("?".into(), |d| d.to_string());
            // Shipped weights: read by default, or when named with --family; without, the
            // weights are trained first (`tagsmith train`).
            let detects = if DEFAULT_FAMILIES.contains(&name) {
                "default"
            } else if shipped_model(name).is_some() {
                "named"
            } else {
                "train"
            };
            let _ = writeln!(
                out,
                "{:<24} {:<6} {:>9} {:>3} {:>6} {:>5} {:<8} {}",
                name,
                if f.is_grid() { "grid" } else { "rings" },
                f.keypoints().len(),
                f.q(),
                f.codebook().len(),
                d,
                detects,
                f.title()
            );
        }
        print_quietly(&out);
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Family JSON file (at most 64 MB).
    pub file: PathBuf,
}

impl ValidateArgs {
    pub fn run(self) -> Result<()> {
        let file = &self.file;
        let family = family::load_file(file)?;
        let computed = family.codebook().min_distance(&rotations_of(&family));
        if let (Some(declared), Some(computed)) = (family.spec().codebook.min_distance, computed) {
            if declared != computed {
                return Err(bad_input!(
                    "{}: codebook.min_distance: declared {declared}, but the codes' minimum distance over \
                     the layout's rotations is {computed}",
                    file.display()
                ));
            }
        }
        for w in tagsmith::render::readback::warnings(&family) {
            eprintln!("warning: {w}");
        }
        println!(
            "{}: valid — {} keypoints, {} categories (q = {}), {} codes, minimum distance {}",
            file.display(),
            family.keypoints().len(),
            family.categories().len(),
            family.q(),
            family.codebook().len(),
            computed.map_or("-".into(), |d| d.to_string())
        );
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct SchemaArgs {}

impl SchemaArgs {
    pub fn run(self) -> Result<()> {
        print_quietly(&family::schema_json());
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_file_limit_in_the_help_is_the_one_applied() {
        use clap::Args as _;
        let help = ValidateArgs::augment_args(clap::Command::new("validate"))
            .render_long_help()
            .to_string();
        let limit = tagsmith::io::MAX_TEXT_BYTES >> 20;
        assert!(help.contains(&format!("(at most {limit} MB)")), "{help}");
    }
}
