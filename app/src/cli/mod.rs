//! The headless commands. Everything a command does is a `tagsmith` (core) call; these modules
//! only parse arguments, report and write files (atomically).
//!
//! One module per command group; shared helpers live in `common` and `error`, so that no command
//! module depends on another.

mod codebook;
mod common;
mod detect;
mod error;
mod eval;
mod families;
mod render;
mod studio;
mod synth;
mod train;

use clap::{Parser, Subcommand};

use error::Result;

#[derive(Parser, Debug)]
#[command(
    name = "tagsmith",
    version,
    about = "Design fiducial-marker families, print them, train their learned detector and detect them in \
             images"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the studio window (the default when no command is given).
    Studio(studio::StudioArgs),
    /// List the built-in families with one-line stats.
    Families(families::FamiliesArgs),
    /// Render one marker to SVG (exact mm) or PNG.
    Render(render::RenderArgs),
    /// Lay out markers on printable pages: PDF (all pages) or SVG (one file per page).
    Sheet(render::SheetArgs),
    /// Codebook statistics and generation.
    #[command(subcommand)]
    Codebook(codebook::CodebookCommand),
    /// Validate a family file completely (including its declared minimum distance).
    Validate(families::ValidateArgs),
    /// Export a binary grid family as an OpenCV ArUco dictionary (cv2.aruco readDictionary).
    ExportOpencv(codebook::ExportOpencvArgs),
    /// Print the JSON Schema of family files.
    Schema(families::SchemaArgs),
    /// Synthesise training images with exact ground truth (PNG + JSON each, and a contact sheet).
    Synth(synth::SynthArgs),
    /// The evaluation harness: benchmark sets, scoring of detections.
    #[command(subcommand)]
    Eval(eval::EvalCommand),
    /// Train a detector network: stage 2 of a family (`--stage keypoints`: keypoints and symbols on
    /// rectified patches) or stage 1 (`--stage roi`: marker ROIs in whole scenes); a killed run
    /// resumes from its checkpoint.
    Train(train::TrainArgs),
    /// Find and read every marker of the chosen families in images (stage 1 and the image
    /// searches propose, stage 2 reads, the pose comes from all keypoints): a line per image,
    /// the detections file with --json, video frames with --track, or one known ROI with --roi.
    Detect(detect::DetectArgs),
    /// Run the detector on a benchmark set (detections file for `eval score`): stage 2 from the
    /// true ROIs moved by --roi-noise, or the whole detector with --full.
    DetectSet(detect::DetectSetArgs),
}

impl Cli {
    /// Runs the command given, or opens the studio when there is none.
    pub fn run(self) -> Result<()> {
        self.command
            .unwrap_or(Command::Studio(studio::StudioArgs::default()))
            .run()
    }
}

impl Command {
    pub fn run(self) -> Result<()> {
        match self {
            Command::Studio(a) => a.run(),
            Command::Families(a) => a.run(),
            Command::Render(a) => a.run(),
            Command::Sheet(a) => a.run(),
            Command::Codebook(c) => c.run(),
            Command::Validate(a) => a.run(),
            Command::ExportOpencv(a) => a.run(),
            Command::Schema(a) => a.run(),
            Command::Synth(a) => a.run(),
            Command::Eval(c) => c.run(),
            Command::Train(a) => a.run(),
            Command::Detect(a) => a.run(),
            Command::DetectSet(a) => a.run(),
        }
    }
}
