//! `train`: the learned detector's training, stage 2 (keypoints, per family) and stage 1 (ROIs,
//! one model for every square family).

use super::common::{load_family, positive_f64_up_to, progress_bar};
use super::error::{CliError, Result};
use clap::builder::RangedU64ValueParser;
use clap::{Args, ValueEnum};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use tagsmith::detect::stage1::pipeline::shipped_stage1;
use tagsmith::detect::stage2::model_file::{self, WIDTHS};
use tagsmith::detect::stage2::{shipped_families, shipped_model};
use tagsmith::train::stage::TrainStage;
use tagsmith::train::stage1::RoiStage;
use tagsmith::train::stage2::KeypointStage;
use tagsmith::train::verifier::VerifierStage;
use tagsmith::train::{self, Event, StageEvent, StageReport, TrainConfig};

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Stage 2: the keypoint network on rectified patches.
    Keypoints,
    /// Stage 1: the ROI network on whole scenes; without a family, for every square family.
    Roi,
    /// The verifier: marker or not, on the candidate quads stage 1 proposes in cluttered
    /// scenes, for every square family (no FAMILY).
    Verifier,
}

/// Bounds of the sizes a run may ask for. Memory grows with batch × width² (a batch of 100 000
/// grew past 1.4 GB before its first step, a width of 100 000 aborted allocating), so each is
/// capped well above any useful setting and refused before anything is built.
///
/// The widths and steps are those a model file may record ([`model_file::WIDTHS`],
/// [`model_file::MAX_STEPS`]): a run makes no model that would not load.
const MIN_WIDTH: u64 = *WIDTHS.start() as u64;
const MAX_WIDTH: u64 = *WIDTHS.end() as u64;
const MAX_BATCH: u64 = 256;
const MAX_STEPS: u64 = model_file::MAX_STEPS;
const MAX_VALIDATION_PATCHES: u64 = 10_000;

/// More synthesis threads than twice the cores only compete for them; 64 keeps small machines
/// free to oversubscribe a little.
fn max_workers() -> u64 {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    (2 * cores).max(64)
}

/// The model file `--init` names: a regular file of at most [`tagsmith::io::MAX_MODEL_BYTES`].
fn read_init(path: &str) -> Result<Vec<u8>> {
    tagsmith::io::read_input(std::path::Path::new(path), tagsmith::io::MAX_MODEL_BYTES)
        .map_err(|e| CliError::reading(format_args!("--init {path}: cannot read it"), e))
}

/// A run's error with its exit code: a folder that another run holds, or that is a file, is the
/// request's mistake (exit 2), as a checkpoint that cannot be resumed is.
fn run_error(e: train::TrainError) -> CliError {
    match e {
        train::TrainError::InUse(_) => CliError::bad_input(e),
        train::TrainError::NotAFolder(_) => CliError::bad_input(format_args!("--out {e}")),
        e => e.into(),
    }
}

fn unit_interval(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if (0.0..=1.0).contains(&v) => Ok(v),
        _ => Err(format!("{text} is not a share between 0 and 1")),
    }
}

fn in_range(range: std::ops::RangeInclusive<u64>) -> RangedU64ValueParser<usize> {
    RangedU64ValueParser::<usize>::new().range(range)
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Built-in family name or path to a family JSON file of at most 64 MB (optional with
    /// `--stage roi`: without one, stage 1 is trained for every square family and random
    /// designs).
    pub family: Option<String>,
    #[arg(long, value_enum)]
    pub stage: Stage,
    /// Optimiser steps [range: 1..=10000000].
    #[arg(long, default_value_t = TrainConfig::default().steps,
          value_parser = clap::value_parser!(u64).range(1..=MAX_STEPS))]
    pub steps: u64,
    /// Patches per step [range: 1..=256].
    #[arg(long, default_value_t = TrainConfig::default().batch,
          value_parser = in_range(1..=MAX_BATCH))]
    pub batch: usize,
    /// Output folder (checkpoint, model, report) [default: runs/FAMILY-keypoints, runs/roi]. A run
    /// locks it: a second run into the same folder stops at once.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue from the output folder's checkpoint (at most 832 MB).
    #[arg(long)]
    pub resume: bool,
    /// The weights to start from — a model file of the stage (at most 256 MB), `shipped` (the
    /// shipped model: fine-tuning) or `none` (fresh weights) [default: `--stage roi` shipped with
    /// a FAMILY, otherwise none]. The network's width is then the model's.
    #[arg(long)]
    pub init: Option<String>,
    /// `--stage keypoints`: the share of training patches cut from steep camera views, as the
    /// detector cuts them (the rest are drawn at patch resolution) [range: 0..=1].
    #[arg(long, default_value_t = tagsmith::train::stage2::data::DEFAULT_CAMERA_SHARE,
          value_parser = unit_interval)]
    pub camera_patches: f64,
    /// Channels of the network's widest layers [range: 8..=256].
    #[arg(long, default_value_t = TrainConfig::default().width,
          value_parser = in_range(MIN_WIDTH..=MAX_WIDTH))]
    pub width: usize,
    /// Adam's learning rate (it falls to a tenth over the last quarter of the steps)
    /// [range: (0, 1]].
    #[arg(long, default_value_t = TrainConfig::default().learning_rate,
          value_parser = positive_f64_up_to(1.0))]
    pub learning_rate: f64,
    #[arg(long, default_value_t = TrainConfig::default().seed)]
    pub seed: u64,
    /// Steps between checkpoints [range: 1..].
    #[arg(long, default_value_t = TrainConfig::default().checkpoint_every,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub checkpoint_every: u64,
    /// Steps between validations [range: 1..].
    #[arg(long, default_value_t = TrainConfig::default().validate_every,
          value_parser = clap::value_parser!(u64).range(1..))]
    pub validate_every: u64,
    /// Patches synthesised once for validation [range: 1..=10000].
    #[arg(long, default_value_t = TrainConfig::default().validation_patches,
          value_parser = in_range(1..=MAX_VALIDATION_PATCHES))]
    pub validation_patches: usize,
    /// Threads synthesising patches ahead of the optimiser [range: 1..=64, or up to twice the
    /// cores where that is more].
    #[arg(long, default_value_t = TrainConfig::default().workers,
          value_parser = in_range(1..=max_workers()))]
    pub workers: usize,
}

impl TrainArgs {
    pub fn run(self) -> Result<()> {
        let family = self.family.as_deref().map(load_family).transpose()?;
        let config = TrainConfig {
            steps: self.steps,
            batch: self.batch,
            width: self.width,
            learning_rate: self.learning_rate,
            seed: self.seed,
            checkpoint_every: self.checkpoint_every,
            validate_every: self.validate_every,
            validation_patches: self.validation_patches,
            workers: self.workers,
            ..TrainConfig::default()
        };
        let stop = AtomicBool::new(false);
        match self.stage {
            Stage::Keypoints => {
                let family = family.ok_or_else(|| {
                    CliError::bad_input("--stage keypoints needs a FAMILY to train for")
                })?;
                let stage = KeypointStage::new(&family, config.width)
                    .with_camera_share(self.camera_patches);
                let stage = match self.init.as_deref().unwrap_or("none") {
                    "none" => stage,
                    "shipped" => {
                        let bytes = shipped_model(family.name()).ok_or_else(|| {
                            CliError::bad_input(format!(
                                "--init shipped: no stage-2 model is shipped for {} (shipped: {})",
                                family.name(),
                                shipped_families().collect::<Vec<_>>().join(", ")
                            ))
                        })?;
                        let name = format!("shipped {} stage-2 model", family.name());
                        stage
                            .starting_from(bytes.to_vec(), &name)
                            .map_err(CliError::failure)?
                    }
                    path => stage
                        .starting_from(read_init(path)?, path)
                        .map_err(CliError::bad_input)?,
                };
                let config = TrainConfig {
                    width: stage.net().width,
                    ..config
                };
                let out = self
                    .out
                    .unwrap_or_else(|| PathBuf::from(format!("runs/{}-keypoints", family.name())));
                let stage = Arc::new(stage);
                with_progress::<KeypointStage>(
                    &config,
                    |on_event| train::train(stage, &config, &out, self.resume, &stop, on_event),
                    |l: &LossTerms2| {
                        format!(
                            "loss {:.3} (conf {:.3} off {:.3} mask {:.3} tpl {:.3})",
                            l.total, l.confidence, l.offset, l.mask, l.template
                        )
                    },
                    |m: &Metrics2| {
                        format!(
                        "keypoint recall {:.2} %, symbol accuracy {:.2} %, ID accuracy {:.1} % \
                         (wrong {:.1} %), keypoint error RMS {:.2} px (median {:.2})",
                        100.0 * m.keypoint_recall,
                        100.0 * m.symbol_accuracy,
                        100.0 * m.id_accuracy,
                        100.0 * m.wrong_id_rate,
                        m.keypoint_rms_px,
                        m.keypoint_median_px
                    )
                    },
                )
            }
            Stage::Verifier => {
                if family.is_some() {
                    return Err(CliError::bad_input(
                        "--stage verifier trains one model for every square family: give no FAMILY",
                    ));
                }
                let stage = VerifierStage::new(config.width, tagsmith::train::verifier::PATCH)
                    .map_err(CliError::failure)?;
                let out = self.out.unwrap_or_else(|| PathBuf::from("runs/verifier"));
                with_progress::<VerifierStage>(
                    &config,
                    |on_event| {
                        train::train(Arc::new(stage), &config, &out, self.resume, &stop, on_event)
                    },
                    |l: &LossTerms3| format!("loss {:.4}", l.total),
                    |m: &Metrics3| {
                        format!(
                            "markers kept {:.2} % of {}, false quads turned away {:.1} % of {} \
                             (stage 1's own {:.1} %)",
                            100.0 * m.kept,
                            m.positives,
                            100.0 * m.rejected,
                            m.negatives,
                            100.0 * m.candidates_rejected
                        )
                    },
                )
            }
            Stage::Roi => {
                let stage = match &family {
                    Some(f) => RoiStage::for_families(vec![f.clone()], config.width),
                    None => RoiStage::new(config.width).map_err(CliError::failure)?,
                };
                let init = self.init.as_deref().unwrap_or(if family.is_some() {
                    "shipped"
                } else {
                    "none"
                });
                let stage = match init {
                    "none" => stage,
                    "shipped" => stage
                        .starting_from(shipped_stage1().to_vec(), "shipped stage-1 model")
                        .map_err(CliError::failure)?,
                    path => stage
                        .starting_from(read_init(path)?, path)
                        .map_err(CliError::bad_input)?,
                };
                let config = TrainConfig {
                    width: stage.net().width,
                    ..config
                };
                let out = self.out.unwrap_or_else(|| match &family {
                    Some(f) => PathBuf::from(format!("runs/{}-roi", f.name())),
                    None => PathBuf::from("runs/roi"),
                });
                with_progress::<RoiStage>(
                    &config,
                    |on_event| {
                        train::train(Arc::new(stage), &config, &out, self.resume, &stop, on_event)
                    },
                    |l: &LossTerms1| {
                        format!(
                            "loss {:.3} (heat {:.3} off {:.3} dir {:.3} mask {:.3})",
                            l.total, l.heat, l.offset, l.direction, l.mask
                        )
                    },
                    |m: &Metrics1| {
                        format!(
                            "ROI recall {:.1} %, precision {:.1} %, corner error median {:.2} px, \
                         {:.2} proposals per scene",
                            100.0 * m.recall,
                            100.0 * m.precision,
                            m.corner_median_px,
                            m.proposals_per_scene
                        )
                    },
                )
            }
        }
    }
}

type LossTerms1 = <RoiStage as TrainStage>::Terms;
type Metrics1 = <RoiStage as TrainStage>::Metrics;
type LossTerms2 = <KeypointStage as TrainStage>::Terms;
type LossTerms3 = <VerifierStage as TrainStage>::Terms;
type Metrics3 = <VerifierStage as TrainStage>::Metrics;
type Metrics2 = <KeypointStage as TrainStage>::Metrics;

/// Runs `train` with a progress bar (plain lines without a terminal), then prints the summary.
fn with_progress<S: TrainStage>(
    config: &TrainConfig,
    train: impl FnOnce(
        &mut dyn FnMut(StageEvent<S>),
    ) -> std::result::Result<StageReport<S>, train::TrainError>,
    loss: impl Fn(&S::Terms) -> String,
    metrics: impl Fn(&S::Metrics) -> String,
) -> Result<()> {
    let bar = progress_bar(
        config.steps,
        "{bar:30} {pos}/{len} {msg} [{elapsed_precise}, ETA {eta_precise}]",
    );
    // Without a terminal (a log file) the bar is hidden: print plain lines instead.
    let plain = bar.is_hidden();
    let say = |line: String| {
        if plain {
            eprintln!("{line}");
        } else {
            bar.println(line);
        }
    };
    let report = train(&mut |event| match event {
        Event::Started {
            family,
            first_step,
            params,
            macs,
            ..
        } => {
            bar.set_position(first_step);
            bar.reset_eta();
            say(format!(
                "training {family}: {params} parameters, {:.1} MMAC per input{}",
                macs as f64 / 1e6,
                if first_step > 0 {
                    format!(", resumed at step {first_step}")
                } else {
                    String::new()
                }
            ));
        }
        Event::Step {
            step,
            loss: l,
            samples_per_s,
            data_wait,
        } => {
            bar.set_position(step);
            let message = format!(
                "{} {:.0} samples/s, data wait {:.0} %",
                loss(&l),
                samples_per_s,
                100.0 * data_wait
            );
            if plain && step.is_multiple_of(100) {
                say(format!("step {step}/{}: {message}", config.steps));
            }
            bar.set_message(message);
        }
        Event::Validated { step, metrics: m } => say(format!("step {step}: {}", metrics(&m))),
        Event::Checkpointed { .. } | Event::Pictured { .. } => {}
    })
    .map_err(run_error)?;
    bar.finish();
    println!(
        "{} steps in {:.0} s ({:.1} ms/step, {:.0} samples/s, data wait {:.1} %); model: {}",
        report.steps,
        report.wall_s,
        report.mean_step_ms,
        report.samples_per_s,
        100.0 * report.data_wait_fraction,
        report.model_file
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_file_limits_in_the_help_are_the_ones_applied() {
        use clap::Args as _;
        let help = TrainArgs::augment_args(clap::Command::new("train"))
            .render_long_help()
            .to_string();
        let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
        for (what, bytes) in [
            ("family", tagsmith::io::MAX_TEXT_BYTES),
            ("--init", tagsmith::io::MAX_MODEL_BYTES),
            ("--resume", tagsmith::train::MAX_CHECKPOINT_BYTES),
        ] {
            let limit = format!("at most {} MB", bytes >> 20);
            assert!(help.contains(&limit), "{what}: {limit} not in {help}");
        }
        let widths = format!("[range: {}..={}]", WIDTHS.start(), WIDTHS.end());
        assert!(help.contains(&widths), "{help}");
    }

    #[test]
    fn a_folder_in_use_or_that_is_a_file_is_bad_input() {
        let busy = run_error(train::TrainError::InUse("r is in use".into()));
        assert_eq!(busy.exit_code(), 2);
        let file = run_error(train::TrainError::NotAFolder("r: it is a file".into()));
        assert_eq!(
            (file.exit_code(), file.to_string()),
            (2, "--out r: it is a file".into())
        );
        let disk = run_error(train::TrainError::Output("r: disk full".into()));
        assert_eq!(disk.exit_code(), 1);
    }
}
