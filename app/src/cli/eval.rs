//! `eval generate`, `eval score` and `eval oracle`: the evaluation harness.

use super::common::{f64_in, load_family, output_folder, print_quietly, write_output};
use super::error::{bad_input, Classify, CliError, Concerning, Result};
use anyhow::Context;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tagsmith::detect::DetectionsFile;
use tagsmith::eval::{compare, score, set};
use tagsmith::io::{read_input_text, MAX_TEXT_BYTES};

#[derive(Subcommand, Debug)]
pub enum EvalCommand {
    /// Render a benchmark set (the paper's protocol, jitter, noise and motion-blur sweeps) to DIR.
    Generate(GenerateSetArgs),
    /// Score a detections JSON file against a benchmark set: report.json, report.md and plots.
    Score(ScoreArgs),
    /// Two detections files of one set side by side, marker by marker: per subset the markers
    /// each read alone and a 95 % interval of the recall difference (is a gap more than chance?).
    Compare(CompareArgs),
    /// Write the ground truth as a detections file: the format's reference and a perfect score.
    Oracle(OracleArgs),
}

impl EvalCommand {
    pub fn run(self) -> Result<()> {
        match self {
            EvalCommand::Generate(a) => a.run(),
            EvalCommand::Score(a) => a.run(),
            EvalCommand::Compare(a) => a.run(),
            EvalCommand::Oracle(a) => a.run(),
        }
    }
}

#[derive(Args, Debug)]
pub struct GenerateSetArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// Marker side in mm (corner to corner) [range: [1, 1000]].
    #[arg(long, default_value_t = 50.0, value_parser = f64_in(1.0, 1000.0))]
    pub side_mm: f64,
    /// Images per (distance, angle) cell of the protocol (10 × 10 cells) [range: 1..=100: at most
    /// 10 000 protocol images, plus 205 for the sweeps].
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub per_cell: u32,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(short, long)]
    pub output: PathBuf,
}

impl GenerateSetArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let params = set::SetParams {
            side_m: self.side_mm / 1000.0,
            per_cell: self.per_cell,
            seed: self.seed,
            ..set::SetParams::default()
        };
        output_folder(&self.output, "--output")?;
        let started = std::time::Instant::now();
        let s = set::generate(&family, &params, &self.output)?;
        // The set carries its family, so a set of a design that is no built-in scores anywhere.
        let spec = tagsmith::family::to_json_string(family.spec());
        write_output(&self.output.join(SET_FAMILY_FILE), spec.as_bytes())?;
        println!(
            "wrote {} images of {} ({} mm) to {} in {:.1} s",
            s.images.len(),
            family.name(),
            self.side_mm,
            self.output.display(),
            started.elapsed().as_secs_f64()
        );
        Ok(())
    }
}

/// The family file `eval generate` writes beside `set.json`.
const SET_FAMILY_FILE: &str = "family.json";

#[derive(Args, Debug)]
pub struct ScoreArgs {
    /// Benchmark set folder (with set.json).
    pub set: PathBuf,
    /// Detections JSON (format documented in core/src/eval/mod.rs and bench/README.md).
    pub detections: PathBuf,
    /// Report folder [default: SET/report-DETECTOR].
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

/// A set and the family its truth was drawn from.
fn load_set(dir: &std::path::Path) -> Result<(set::BenchmarkSet, tagsmith::family::Family)> {
    let s = set::load(dir)?;
    // A set names the family its truth was drawn from; one that does not load is a broken
    // manifest, not a reason to score without the family's geometry.
    let kept = dir.join(SET_FAMILY_FILE);
    let family = if kept.exists() {
        load_family(&kept.display().to_string())?
    } else {
        load_family(&s.family)
            .map_err(|e| e.concerning(format_args!("{}: family", dir.join("set.json").display())))?
    };
    if family.name() != s.family {
        return Err(bad_input!(
            "{}: family {:?} is not the set's {:?}",
            kept.display(),
            family.name(),
            s.family
        ));
    }
    Ok((s, family))
}

/// A detections file: a regular file of at most `MAX_TEXT_BYTES` (a FIFO is refused rather than
/// waited on, `/dev/zero` rather than read forever).
fn read_detections(path: &std::path::Path) -> Result<DetectionsFile> {
    let text = read_input_text(path, MAX_TEXT_BYTES)
        .map_err(|e| CliError::reading(format_args!("cannot read {}", path.display()), e))?;
    serde_json::from_str(&text).map_err(|e| bad_input!("{}: {e}", path.display()))
}

impl ScoreArgs {
    pub fn run(self) -> Result<()> {
        let (dir, detections) = (&self.set, &self.detections);
        let (s, family) = load_set(dir)?;
        let file = read_detections(detections)?;
        let report = score::score(&s, Some(&family), &file).concerning(detections.display())?;
        let slug: String = file
            .detector
            .chars()
            .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
            .collect();
        let out = self
            .output
            .unwrap_or_else(|| dir.join(format!("report-{slug}")));
        std::fs::create_dir_all(&out)
            .with_context(|| format!("cannot create {}", out.display()))
            .failure()?;
        write_output(
            &out.join("report.json"),
            serde_json::to_string_pretty(&report)
                .expect("serialises")
                .as_bytes(),
        )?;
        let md = report.markdown();
        write_output(&out.join("report.md"), md.as_bytes())?;
        for (name, svg) in report.plots() {
            write_output(&out.join(name), svg.as_bytes())?;
        }
        print_quietly(&md);
        println!("\nwrote {}", out.display());
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct CompareArgs {
    /// Benchmark set folder (with set.json).
    pub set: PathBuf,
    /// Detections JSON of the first detector (A).
    pub a: PathBuf,
    /// Detections JSON of the second detector (B), on the same set.
    pub b: PathBuf,
    /// Also write the comparison (every marker read by one only) as JSON here.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

impl CompareArgs {
    pub fn run(self) -> Result<()> {
        let (s, family) = load_set(&self.set)?;
        let reads = |path: &PathBuf| -> Result<compare::Reads> {
            let file = read_detections(path)?;
            compare::Reads::of(&s, Some(&family), &file).concerning(path.display())
        };
        let comparison = compare::compare(&s, &reads(&self.a)?, &reads(&self.b)?);
        if let Some(path) = &self.json {
            write_output(
                path,
                serde_json::to_string_pretty(&comparison)
                    .expect("serialises")
                    .as_bytes(),
            )?;
        }
        print_quietly(&comparison.markdown());
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct OracleArgs {
    pub set: PathBuf,
    #[arg(short, long)]
    pub output: PathBuf,
}

impl OracleArgs {
    pub fn run(self) -> Result<()> {
        let s = set::load(&self.set)?;
        let file = s.oracle();
        write_output(
            &self.output,
            serde_json::to_string_pretty(&file)
                .expect("serialises")
                .as_bytes(),
        )?;
        println!("wrote {}", self.output.display());
        Ok(())
    }
}
