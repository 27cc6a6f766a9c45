//! `eval generate`, `eval score` and `eval oracle`: the evaluation harness.

use super::common::{f64_in, load_family, output_folder, print_quietly, write_output};
use super::error::{bad_input, Classify, CliError, Concerning, Result};
use anyhow::Context;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tagsmith::detect::DetectionsFile;
use tagsmith::eval::designs::{detector_for, DesignRun};
use tagsmith::eval::scenario::Scenario;
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
    /// Write a scenario file to start from (the paper's camera at one distance, swept over the
    /// view angle), to edit for your scene and give to `generate --scenario` or `compare-designs`.
    Scenario(ScenarioArgs),
    /// Compare 2–4 designs under a scenario: every family reads the same scenes; writes a table,
    /// CSV, plots against each swept condition and a verdict with 95 % intervals to DIR.
    CompareDesigns(CompareDesignsArgs),
}

impl EvalCommand {
    pub fn run(self) -> Result<()> {
        match self {
            EvalCommand::Generate(a) => a.run(),
            EvalCommand::Score(a) => a.run(),
            EvalCommand::Compare(a) => a.run(),
            EvalCommand::Oracle(a) => a.run(),
            EvalCommand::Scenario(a) => a.run(),
            EvalCommand::CompareDesigns(a) => a.run(),
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
    /// Render a scenario file's scenes (`eval scenario` writes one) in place of the paper's
    /// protocol; the scenario sets the print size, the camera and the seed.
    #[arg(long, conflicts_with_all = ["side_mm", "per_cell", "seed"])]
    pub scenario: Option<PathBuf>,
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
        let scenario = self.scenario.as_deref().map(Scenario::load).transpose()?;
        output_folder(&self.output, "--output")?;
        let started = std::time::Instant::now();
        let s = match &scenario {
            Some(scenario) => set::generate_scenario(&family, scenario, &self.output)?,
            None => set::generate(&family, &params, &self.output)?,
        };
        // The set carries its family, so a set of a design that is no built-in scores anywhere.
        let spec = tagsmith::family::to_json_string(family.spec());
        write_output(&self.output.join(SET_FAMILY_FILE), spec.as_bytes())?;
        println!(
            "wrote {} images of {} ({} mm) to {} in {:.1} s",
            s.images.len(),
            family.name(),
            s.side_m * 1000.0,
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

#[derive(Args, Debug)]
pub struct ScenarioArgs {
    /// Camera to marker of the paper's XO study setting, in metres [range: [0.05, 10]].
    #[arg(long, default_value_t = 0.3, value_parser = f64_in(0.05, 10.0))]
    pub distance_m: f64,
    /// The scenario file to write.
    #[arg(short, long)]
    pub output: PathBuf,
}

impl ScenarioArgs {
    pub fn run(self) -> Result<()> {
        Scenario::example(self.distance_m).save(&self.output)?;
        println!("wrote {}", self.output.display());
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct CompareDesignsArgs {
    /// Scenario file (`eval scenario` writes one to start from).
    pub scenario: PathBuf,
    /// 2–4 families: built-in names or family files. A built-in reads with its shipped weights;
    /// a family file with the model the studio's Train panel saves beside it (FILE.stage2.bin),
    /// or one given with --model.
    #[arg(num_args = 2..=4, required = true)]
    pub families: Vec<String>,
    /// A family's stage-2 model, as FAMILY=MODEL (FAMILY as given above); repeatable.
    #[arg(long, value_name = "FAMILY=MODEL")]
    pub model: Vec<String>,
    /// Folder for report.md, report.json, designs.csv and the plots.
    #[arg(short, long)]
    pub output: PathBuf,
}

impl CompareDesignsArgs {
    pub fn run(self) -> Result<()> {
        let scenario = Scenario::load(&self.scenario)?;
        let mut models = std::collections::HashMap::new();
        for m in &self.model {
            let Some((family, path)) = m.split_once('=') else {
                return Err(bad_input!("--model {m:?}: give FAMILY=MODEL"));
            };
            if !self.families.iter().any(|f| f == family) {
                return Err(bad_input!(
                    "--model {m:?}: {family:?} is not one of the families compared"
                ));
            }
            models.insert(family.to_string(), PathBuf::from(path));
        }
        let mut families = Vec::new();
        let mut detectors = Vec::new();
        for name in &self.families {
            let family = load_family(name)?;
            let stage2 = design_weights(name, &family, models.get(name))?;
            detectors.push(detector_for(family.clone(), stage2, &scenario).failure()?);
            families.push(family);
        }
        let mut run = DesignRun::new(scenario, families).map_err(|e| {
            if e.field == "families" {
                bad_input!("{}", e.message)
            } else {
                bad_input!("{}: {e}", self.scenario.display())
            }
        })?;
        output_folder(&self.output, "--output")?;
        std::fs::create_dir_all(&self.output)
            .with_context(|| format!("cannot create {}", self.output.display()))
            .failure()?;
        let bar = super::common::progress_bar(
            run.len() as u64,
            "{bar:40} {pos}/{len} scenes per design, {elapsed} (eta {eta})",
        );
        while !run.finished() {
            let mut each: Vec<&mut dyn tagsmith::detect::BenchDetector> = detectors
                .iter_mut()
                .map(|d| d as &mut dyn tagsmith::detect::BenchDetector)
                .collect();
            run.step(&mut each)?;
            bar.inc(1);
        }
        bar.finish_and_clear();
        let report = run.report();
        let json = serde_json::to_string_pretty(&report).expect("serialises");
        write_output(&self.output.join("report.json"), json.as_bytes())?;
        let md = report.markdown();
        write_output(&self.output.join("report.md"), md.as_bytes())?;
        write_output(&self.output.join("designs.csv"), report.csv().as_bytes())?;
        for (name, svg) in report.plots() {
            write_output(&self.output.join(name), svg.as_bytes())?;
        }
        print_quietly(&md);
        println!("\nwrote {}", self.output.display());
        Ok(())
    }
}

/// A design's stage 2: the model given for it, the one saved beside its family file, or the
/// weights shipped for a built-in.
fn design_weights(
    name: &str,
    family: &tagsmith::family::Family,
    given: Option<&PathBuf>,
) -> Result<tagsmith::detect::stage2::Stage2> {
    use tagsmith::detect::stage2::Stage2;
    if let Some(path) = given {
        return Ok(Stage2::load(path, family)?);
    }
    let beside = tagsmith::detect::model_file::attached_to(std::path::Path::new(name));
    if tagsmith::builtin::get(name).is_none() && beside.is_file() {
        return Ok(Stage2::load(&beside, family)?);
    }
    match Stage2::shipped(family) {
        Some(shipped) => Ok(shipped?),
        None => Err(bad_input!(
            "{name}: no weights for {:?}; train them (the studio's Train panel saves them as {}) \
             or give --model {name}=MODEL",
            family.name(),
            beside.display()
        )),
    }
}
