//! `codebook stats`, `codebook generate` and `export-opencv`: the codes of a family.

use super::common::{load_family, progress_bar, rotations_of, write_output};
use super::error::{bad_input, Classify, CliError, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;
use tagsmith::codebook::{self, Order};
use tagsmith::family;

#[derive(Subcommand, Debug)]
pub enum CodebookCommand {
    /// Size, code length, q, minimum distance (computed) and correction limit.
    Stats(StatsArgs),
    /// Generate a codebook for a family's layout and write the family with it.
    Generate(GenerateArgs),
}

impl CodebookCommand {
    pub fn run(self) -> Result<()> {
        match self {
            CodebookCommand::Stats(a) => a.run(),
            CodebookCommand::Generate(a) => a.run(),
        }
    }
}

#[derive(Args, Debug)]
pub struct StatsArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
}

impl StatsArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let cb = family.codebook();
        let rotations = rotations_of(&family);
        let d = cb.min_distance(&rotations);
        println!("family:            {}", family.name());
        println!("codes:             {}", cb.len());
        println!("code length:       {}", cb.code_len());
        println!("q (symbols):       {}", cb.q());
        println!(
            "rotations:         {} checked for distance ({} admitted by the layout)",
            rotations.len() + 1,
            family.rotations().len()
        );
        match d {
            Some(d) => {
                println!("minimum distance:  {d} (computed)");
                println!(
                    "correction limit:  {}{}",
                    cb.max_correction(),
                    if family.spec().codebook.max_correction.is_none() {
                        " (default ⌊(d_min − 1)/2⌋)"
                    } else {
                        " (set in the file)"
                    }
                );
            }
            None => println!("minimum distance:  undefined (a single code)"),
        }
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Built-in family name or path to a family JSON file (its layout and categories are kept).
    pub family: String,
    /// Minimum Hamming distance over the rotations the layout cannot tell apart [range:
    /// 0..=the family's code length].
    #[arg(long)]
    pub min_distance: u32,
    /// Stop after this many codes [range: 1..=100000, the most a family file holds].
    #[arg(long, default_value_t = 100_000,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=100_000))]
    pub count: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Candidates to try before stopping [range: 1..=10000000000, hours of search].
    #[arg(long, default_value_t = 20_000_000,
          value_parser = clap::value_parser!(u64).range(1..=10_000_000_000))]
    pub max_candidates: u64,
    /// Minimum symbol changes between consecutive code positions [range: 0..=the code length − 1].
    #[arg(long, default_value_t = 0)]
    pub min_transitions: u32,
    /// Reject codes that equal one of their own rotations.
    #[arg(long)]
    pub reject_self_symmetric: bool,
    /// Keep the all-zero code as ID 0 when admissible.
    #[arg(long)]
    pub start_with_zero: bool,
    /// Scan candidates in lexicographic order (the classic greedy lexicode) instead of a seeded
    /// random order.
    #[arg(long)]
    pub lexicographic: bool,
    /// Name of the new family: 1–64 letters, digits, '-', '_' or '.', not starting with '.'
    /// [default: the old name + "-generated"].
    #[arg(long)]
    pub name: Option<String>,
    #[arg(short, long)]
    pub output: PathBuf,
}

impl GenerateArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let name = self
            .name
            .clone()
            .unwrap_or_else(|| format!("{}-generated", family.name()));
        // The name is the user's and becomes file names; refused here, before the search, it is
        // bad input rather than a generated family that fails to load.
        if let Some(why) = family::name_problem(&name) {
            return Err(bad_input!("--name: {why}"));
        }
        // Both are bounded by the code length, which depends on the family; refused here they name
        // their option and its range (the search would only report an impossible distance).
        let len = family.code_len();
        if self.min_distance as usize > len {
            return Err(bad_input!(
                "--min-distance {}: must be in 0..={len} (the code length of {})",
                self.min_distance,
                family.name()
            ));
        }
        if self.min_transitions as usize >= len.max(1) {
            return Err(bad_input!(
                "--min-transitions {}: must be in 0..={} (one less than the code length of {})",
                self.min_transitions,
                len.saturating_sub(1),
                family.name()
            ));
        }
        let mut params = family.generate_params(self.min_distance);
        params.max_codes = self.count;
        params.seed = self.seed;
        params.max_candidates = self.max_candidates;
        params.min_transitions = self.min_transitions;
        params.reject_self_symmetric = self.reject_self_symmetric;
        params.start_with_zero = self.start_with_zero;
        params.order = if self.lexicographic {
            Order::Lexicographic
        } else {
            Order::Random
        };
        let bar = progress_bar(
            params.max_candidates,
            "{bar:30} {pos}/{len} candidates  {msg}  [{elapsed_precise}]",
        );
        let report = codebook::generate(&params, &mut |tried, kept| {
            bar.set_position(tried);
            bar.set_message(format!("{kept} codes"));
        })
        .map_err(|e| match e {
            codebook::GenerateError::Distance { .. } => {
                CliError::from(e).concerning("--min-distance")
            }
            codebook::GenerateError::Transitions { .. } => {
                CliError::from(e).concerning("--min-transitions")
            }
            e => e.into(),
        })?;
        bar.finish_and_clear();
        let mut spec = family.spec().clone();
        spec.name = name;
        spec.codebook = report.codebook.to_spec(
            report.achieved_min_distance,
            &format!(
                "Generated by tagsmith codebook generate: q={}, length {}, minimum distance {}, seed {}, {} order",
                params.q,
                params.len,
                params.min_distance,
                params.seed,
                if self.lexicographic { "lexicographic" } else { "random" }
            ),
        );
        let json = family::to_json_string(&spec);
        // The result must load like any family file before it is written.
        family::from_json_str(&json).failure()?;
        write_output(&self.output, json.as_bytes())?;
        println!(
            "{} codes, minimum distance {} (asked {}), {} candidates in {:.2} s ({}); wrote {}",
            report.codebook.len(),
            report
                .achieved_min_distance
                .map_or("-".into(), |d| d.to_string()),
            params.min_distance,
            report.candidates_tried,
            report.seconds,
            report.stop,
            self.output.display()
        );
        Ok(())
    }
}

#[derive(Args, Debug)]
pub struct ExportOpencvArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    #[arg(short, long)]
    pub output: PathBuf,
}

impl ExportOpencvArgs {
    pub fn run(self) -> Result<()> {
        let family = load_family(&self.family)?;
        let yaml = tagsmith::render::opencv::dictionary_yaml(&family)?;
        write_output(&self.output, yaml.as_bytes())?;
        println!(
            "wrote {} ({} markers) — load with cv2.aruco.Dictionary.readDictionary(cv2.FileStorage(path, cv2.FILE_STORAGE_READ).root())",
            self.output.display(),
            family.codebook().len()
        );
        Ok(())
    }
}
