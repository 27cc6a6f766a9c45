//! The headless commands. Everything a command does is a `tagsmith` (core) call; this module only
//! parses arguments, reports and writes files (atomically).

use anyhow::{anyhow, Context};
use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt;
use std::path::{Path, PathBuf};
use tagsmith::codebook::{self, Order};
use tagsmith::family::{self, Family};
use tagsmith::render::sheet::{layout_sheet, parse_ids, PageSize, SheetParams};
use tagsmith::render::{marker_scene, pdf, raster, svg, SceneOptions};

#[derive(Parser, Debug)]
#[command(
    name = "tagsmith",
    version,
    about = "Design, render and print fiducial-marker families"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the studio window (the default when no command is given).
    Studio(StudioArgs),
    /// List the built-in families with one-line stats.
    Families,
    /// Render one marker to SVG (exact mm) or PNG.
    Render(RenderArgs),
    /// Lay out markers on printable pages: PDF (all pages) or SVG (one file per page).
    Sheet(SheetArgs),
    /// Codebook statistics and generation.
    #[command(subcommand)]
    Codebook(CodebookCommand),
    /// Validate a family file completely (including its declared minimum distance).
    Validate {
        /// Family JSON file.
        file: PathBuf,
    },
    /// Export a binary grid family as an OpenCV ArUco dictionary (cv2.aruco readDictionary).
    ExportOpencv {
        /// Built-in family name or path to a family JSON file.
        family: String,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Print the JSON Schema of family files.
    Schema,
    /// Synthesise training images with exact ground truth (PNG + JSON each, and a contact sheet).
    Synth(SynthArgs),
    /// The evaluation harness: benchmark sets, scoring of detections.
    #[command(subcommand)]
    Eval(EvalCommand),
    /// Train a detector network for a family (stage 2: keypoints on rectified patches).
    Train(crate::cli_detect::TrainArgs),
    /// Decode the marker in a ROI of an image with the learned stage 2: ID, keypoints, pose (JSON).
    Detect(crate::cli_detect::DetectArgs),
    /// Run the learned stage 2 on a benchmark set from perturbed ground-truth ROIs (detections file).
    DetectSet(crate::cli_detect::DetectSetArgs),
}

#[derive(Subcommand, Debug)]
pub enum EvalCommand {
    /// Render a benchmark set (the paper's protocol, jitter, noise and motion-blur sweeps) to DIR.
    Generate {
        /// Built-in family name or path to a family JSON file.
        family: String,
        /// Marker side in mm (corner to corner).
        #[arg(long, default_value_t = 50.0)]
        side_mm: f64,
        /// Images per (distance, angle) cell of the protocol (10 × 10 cells).
        #[arg(long, default_value_t = 1)]
        per_cell: u32,
        #[arg(long, default_value_t = 0)]
        seed: u64,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Score a detections JSON file against a benchmark set: report.json, report.md and plots.
    Score {
        /// Benchmark set folder (with set.json).
        set: PathBuf,
        /// Detections JSON (format documented in core/src/eval/mod.rs and bench/README.md).
        detections: PathBuf,
        /// Report folder [default: SET/report-DETECTOR].
        #[arg(short, long)]
        output: Option<PathBuf>,
    },
    /// Write the ground truth as a detections file: the format's reference and a perfect score.
    Oracle {
        set: PathBuf,
        #[arg(short, long)]
        output: PathBuf,
    },
}

#[derive(Args, Debug)]
pub struct SynthArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// Number of images.
    #[arg(short = 'n', long, default_value_t = 32)]
    pub count: u64,
    /// quad: stage-1 scenes (320×320); camera: 1280×960 at 98° with the pose; patch: stage-2
    /// patches (128×128).
    #[arg(long, value_enum, default_value_t = SynthMode::Quad)]
    pub mode: SynthMode,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub height: Option<u32>,
    /// Exact renderings: no noise, blur, lighting or distortion.
    #[arg(long)]
    pub no_augment: bool,
    /// Output folder (created if missing).
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SynthMode {
    Quad,
    Camera,
    Patch,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    #[arg(long)]
    pub id: usize,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side).
    #[arg(long)]
    pub size_mm: Option<f64>,
    /// PNG only: image width in pixels, quiet zone included [default: 512].
    #[arg(long)]
    pub px: Option<u32>,
    /// Quiet zone in cells (marker units) [default: the family's].
    #[arg(long)]
    pub quiet_zone: Option<f64>,
    /// Output file: .svg or .png.
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Args, Debug)]
pub struct SheetArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    /// IDs to print: ranges and lists, e.g. 0-47 or 1,5,9-12.
    #[arg(long)]
    pub ids: String,
    /// a4, a3, letter, or WIDTHxHEIGHT in mm.
    #[arg(long, default_value = "a4")]
    pub page: String,
    #[arg(long)]
    pub landscape: bool,
    /// Tag size in mm: the distance between ROI corners (the outer black square's side).
    #[arg(long)]
    pub size_mm: Option<f64>,
    #[arg(long, default_value_t = 10.0)]
    pub margin_mm: f64,
    /// Gap between neighbouring markers' quiet zones.
    #[arg(long, default_value_t = 6.0)]
    pub spacing_mm: f64,
    /// Print family, ID and size under each marker.
    #[arg(long)]
    pub labels: bool,
    #[arg(long)]
    pub cut_marks: bool,
    /// Quiet zone in cells (marker units) [default: the family's].
    #[arg(long)]
    pub quiet_zone: Option<f64>,
    /// Output: .pdf, or .svg (several pages are written as NAME-1.svg, NAME-2.svg, …).
    #[arg(short, long)]
    pub output: PathBuf,
}

#[derive(Subcommand, Debug)]
pub enum CodebookCommand {
    /// Size, code length, q, minimum distance (computed) and correction limit.
    Stats {
        /// Built-in family name or path to a family JSON file.
        family: String,
    },
    /// Generate a codebook for a family's layout and write the family with it.
    Generate(GenerateArgs),
}

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Built-in family name or path to a family JSON file (its layout and categories are kept).
    pub family: String,
    /// Minimum Hamming distance over the rotations the layout cannot tell apart.
    #[arg(long)]
    pub min_distance: u32,
    /// Stop after this many codes.
    #[arg(long, default_value_t = 100_000)]
    pub count: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Candidates to try before stopping.
    #[arg(long, default_value_t = 20_000_000)]
    pub max_candidates: u64,
    /// Minimum symbol changes between consecutive code positions.
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
    /// Name of the new family [default: the old name + "-generated"].
    #[arg(long)]
    pub name: Option<String>,
    #[arg(short, long)]
    pub output: PathBuf,
}

/// A command failure: bad input (exit 2) or a failure to produce output (exit 1).
#[derive(Debug)]
pub enum CliError {
    BadInput(anyhow::Error),
    Failed(anyhow::Error),
}

impl CliError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::BadInput(_) => 2,
            CliError::Failed(_) => 1,
        }
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::BadInput(e) | CliError::Failed(e) => {
                if f.alternate() {
                    write!(f, "{e:#}")
                } else {
                    write!(f, "{e}")
                }
            }
        }
    }
}

pub(crate) fn bad(e: impl Into<anyhow::Error>) -> CliError {
    CliError::BadInput(e.into())
}

pub(crate) fn failed(e: impl Into<anyhow::Error>) -> CliError {
    CliError::Failed(e.into())
}

pub(crate) type Result<T> = std::result::Result<T, CliError>;

pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Studio(a) => crate::studio(a),
        Command::Families => families(),
        Command::Render(a) => render(a),
        Command::Sheet(a) => sheet(a),
        Command::Codebook(CodebookCommand::Stats { family }) => stats(&family),
        Command::Codebook(CodebookCommand::Generate(a)) => generate(a),
        Command::Validate { file } => validate(&file),
        Command::ExportOpencv { family, output } => export_opencv(&family, &output),
        Command::Synth(a) => synth(a),
        Command::Eval(e) => eval(e),
        Command::Train(a) => crate::cli_detect::train(a),
        Command::Detect(a) => crate::cli_detect::detect(a),
        Command::DetectSet(a) => crate::cli_detect::detect_set(a),
        Command::Schema => {
            print_quietly(&family::schema_json());
            Ok(())
        }
    }
}

#[derive(clap::Args, Debug, Default)]
pub struct StudioArgs {
    /// Start designing from this family: a built-in (duplicated) or a family JSON file (edited).
    pub family: Option<String>,
    /// The panel to show first.
    #[arg(long, value_parser = ["families", "designer", "print"])]
    pub panel: Option<String>,
    /// Start from a clean slate instead of the design kept from the last session.
    #[arg(long)]
    pub fresh: bool,
}

/// A built-in name, or a path to a family file.
pub fn load_family(name_or_path: &str) -> Result<Family> {
    if let Some(found) = tagsmith::builtin::get(name_or_path) {
        return found.map_err(bad);
    }
    let path = Path::new(name_or_path);
    if path.exists() || name_or_path.ends_with(".json") {
        return family::load_file(path).map_err(bad);
    }
    let names: Vec<_> = tagsmith::builtin::names().collect();
    Err(bad(anyhow!(
        "no built-in family or file named {name_or_path:?}; built-in families: {}",
        names.join(", ")
    )))
}

pub(crate) fn write_output(path: &Path, bytes: &[u8]) -> Result<()> {
    tagsmith::io::write_atomic(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
        .map_err(failed)
}

fn extension(path: &Path) -> String {
    path.extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase()
}

fn families() -> Result<()> {
    use std::fmt::Write as _;
    let mut out = format!(
        "{:<24} {:<6} {:>9} {:>3} {:>6} {:>5}  title\n",
        "name", "layout", "keypoints", "q", "codes", "d_min"
    );
    for name in tagsmith::builtin::names() {
        let f = load_family(name)?;
        let d = f
            .spec()
            .codebook
            .min_distance
            .map_or("?".into(), |d| d.to_string());
        let _ = writeln!(
            out,
            "{:<24} {:<6} {:>9} {:>3} {:>6} {:>5}  {}",
            name,
            if f.is_grid() { "grid" } else { "rings" },
            f.keypoints().len(),
            f.q(),
            f.codebook().len(),
            d,
            f.title()
        );
    }
    print_quietly(&out);
    Ok(())
}

/// Prints to stdout, ending quietly when the reader has gone (`tagsmith families | head`).
fn print_quietly(text: &str) {
    use std::io::Write as _;
    let _ = std::io::stdout().lock().write_all(text.as_bytes());
}

fn render(a: RenderArgs) -> Result<()> {
    let family = load_family(&a.family)?;
    let options = SceneOptions {
        side_mm: a.size_mm,
        quiet_zone: a.quiet_zone,
    };
    let scene = marker_scene(&family, a.id, options).map_err(bad)?;
    let bytes = match extension(&a.output).as_str() {
        "svg" => {
            if a.px.is_some() {
                eprintln!("note: --px applies to PNG output only; the SVG is sized in mm");
            }
            svg::marker_svg(&scene).into_bytes()
        }
        "png" => {
            let pixmap = raster::rasterize_width(&scene, a.px.unwrap_or(512)).map_err(bad)?;
            raster::encode_png(&pixmap).map_err(failed)?
        }
        other => {
            return Err(bad(anyhow!(
                "output {:?}: use .svg or .png, not {other:?}",
                a.output
            )))
        }
    };
    for w in tagsmith::render::readback::warnings(&family) {
        eprintln!("warning: {w}");
    }
    write_output(&a.output, &bytes)?;
    println!(
        "wrote {} ({} ID {}, tag size {:.1} mm corner to corner, {:.1} × {:.1} mm with quiet zone)",
        a.output.display(),
        family.name(),
        a.id,
        scene.scale * family.roi_side(),
        scene.width_mm,
        scene.height_mm
    );
    Ok(())
}

fn sheet(a: SheetArgs) -> Result<()> {
    let family = load_family(&a.family)?;
    let ids = parse_ids(&a.ids).map_err(|e| bad(anyhow!("--ids: {e}")))?;
    let mut page = PageSize::parse(&a.page).map_err(|e| bad(anyhow!("--page: {e}")))?;
    if a.landscape {
        page = page.landscape();
    }
    let mut params = SheetParams::new(&family, ids);
    params.page = page;
    params.margin_mm = a.margin_mm;
    params.spacing_mm = a.spacing_mm;
    params.labels = a.labels;
    params.cut_marks = a.cut_marks;
    params.quiet_zone = a.quiet_zone;
    if let Some(s) = a.size_mm {
        params.marker_side_mm = s;
    }
    let sheet = layout_sheet(&family, &params).map_err(bad)?;
    for w in &sheet.warnings {
        eprintln!("warning: {w}");
    }
    let written: Vec<PathBuf> = match extension(&a.output).as_str() {
        "pdf" => {
            let bytes = pdf::sheet_pdf(&sheet).map_err(failed)?;
            write_output(&a.output, &bytes)?;
            vec![a.output.clone()]
        }
        "svg" if sheet.pages.len() == 1 => {
            write_output(&a.output, sheet.pages[0].as_bytes())?;
            vec![a.output.clone()]
        }
        "svg" => {
            let stem = a
                .output
                .file_stem()
                .and_then(|s| s.to_str())
                .unwrap_or("sheet");
            let mut out = Vec::new();
            for (i, page) in sheet.pages.iter().enumerate() {
                let path = a.output.with_file_name(format!("{stem}-{}.svg", i + 1));
                write_output(&path, page.as_bytes())?;
                out.push(path);
            }
            out
        }
        other => {
            return Err(bad(anyhow!(
                "output {:?}: use .pdf or .svg, not {other:?}",
                a.output
            )))
        }
    };
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    println!(
        "wrote {} ({} markers, {} per page, {} page(s), tag size {:.1} mm corner to corner)",
        names.join(", "),
        params.ids.len(),
        sheet.markers_per_page,
        sheet.pages.len(),
        params.marker_side_mm
    );
    Ok(())
}

fn rotations_of(family: &Family) -> Vec<Vec<usize>> {
    family
        .ambiguous_rotations()
        .filter_map(|r| r.code_perm.clone())
        .collect()
}

fn stats(name: &str) -> Result<()> {
    let family = load_family(name)?;
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

fn generate(a: GenerateArgs) -> Result<()> {
    let family = load_family(&a.family)?;
    let mut params = family.generate_params(a.min_distance);
    params.max_codes = a.count;
    params.seed = a.seed;
    params.max_candidates = a.max_candidates;
    params.min_transitions = a.min_transitions;
    params.reject_self_symmetric = a.reject_self_symmetric;
    params.start_with_zero = a.start_with_zero;
    params.order = if a.lexicographic {
        Order::Lexicographic
    } else {
        Order::Random
    };
    let bar = ProgressBar::new(params.max_candidates).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} candidates  {msg}  [{elapsed_precise}]")
            .expect("a valid template"),
    );
    let report = codebook::generate(&params, &mut |tried, kept| {
        bar.set_position(tried);
        bar.set_message(format!("{kept} codes"));
    })
    .map_err(|e| bad(anyhow!(e)))?;
    bar.finish_and_clear();
    let mut spec = family.spec().clone();
    spec.name = a
        .name
        .unwrap_or_else(|| format!("{}-generated", family.name()));
    spec.codebook = report.codebook.to_spec(
        report.achieved_min_distance,
        &format!(
            "Generated by tagsmith codebook generate: q={}, length {}, minimum distance {}, seed {}, {} order",
            params.q,
            params.len,
            params.min_distance,
            params.seed,
            if a.lexicographic { "lexicographic" } else { "random" }
        ),
    );
    let json = family::to_json_string(&spec);
    // The result must load like any family file before it is written.
    family::from_json_str(&json).map_err(failed)?;
    write_output(&a.output, json.as_bytes())?;
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
        a.output.display()
    );
    Ok(())
}

fn validate(file: &Path) -> Result<()> {
    let family = family::load_file(file).map_err(bad)?;
    let computed = family.codebook().min_distance(&rotations_of(&family));
    if let (Some(declared), Some(computed)) = (family.spec().codebook.min_distance, computed) {
        if declared != computed {
            return Err(bad(anyhow!(
                "{}: codebook.min_distance: declared {declared}, but the codes' minimum distance over \
                 the layout's rotations is {computed}",
                file.display()
            )));
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

fn export_opencv(name: &str, output: &Path) -> Result<()> {
    let family = load_family(name)?;
    let yaml = tagsmith::render::opencv::dictionary_yaml(&family).map_err(|e| bad(anyhow!(e)))?;
    write_output(output, yaml.as_bytes())?;
    println!(
        "wrote {} ({} markers) — load with cv2.aruco.Dictionary.readDictionary(cv2.FileStorage(path, cv2.FILE_STORAGE_READ).root())",
        output.display(),
        family.codebook().len()
    );
    Ok(())
}

fn synth(a: SynthArgs) -> Result<()> {
    use rayon::prelude::*;
    use tagsmith::synth::{self, contact, Mode, SynthConfig};
    let family = load_family(&a.family)?;
    let mode = match a.mode {
        SynthMode::Quad => Mode::Quad,
        SynthMode::Camera => Mode::Camera,
        SynthMode::Patch => Mode::Patch,
    };
    let mut config = SynthConfig::new(mode);
    config.width = a.width.unwrap_or(config.width);
    config.height = a.height.unwrap_or(config.height);
    if a.no_augment {
        config.augment = synth::augment::AugmentRanges::none();
    }
    if a.count == 0 || a.count > 1_000_000 {
        return Err(bad(anyhow!("-n {}: between 1 and 1000000 images", a.count)));
    }
    std::fs::create_dir_all(&a.output)
        .with_context(|| format!("cannot create {}", a.output.display()))
        .map_err(failed)?;
    let bar = ProgressBar::new(a.count).with_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} images  [{elapsed_precise}, ETA {eta}]")
            .expect("a valid template"),
    );
    // Every image has its own seed, so the set is the same whatever the number of threads.
    let kept: Vec<_> = (0..a.count)
        .into_par_iter()
        .map(|i| -> Result<_> {
            let sample = synth::synthesize(&family, &config, synth::image_seed(a.seed, i))
                .map_err(|e| bad(anyhow!(e)))?;
            let stem = format!("{i:06}");
            let png = tagsmith::image::encode_png(&sample.image).map_err(failed)?;
            write_output(&a.output.join(format!("{stem}.png")), &png)?;
            let json =
                serde_json::to_string_pretty(&sample.truth).expect("ground truth serialises");
            write_output(&a.output.join(format!("{stem}.json")), json.as_bytes())?;
            bar.inc(1);
            Ok((i < 36).then_some((sample.image, sample.truth)))
        })
        .collect::<Result<Vec<_>>>()?;
    bar.finish_and_clear();
    let thumbs: Vec<_> = kept.into_iter().flatten().collect();
    let sheet = contact::contact_sheet(&thumbs, 6, 256)
        .ok_or_else(|| failed(anyhow!("cannot draw the contact sheet")))?;
    let png = sheet
        .encode_png()
        .map_err(|e| failed(anyhow!(e.to_string())))?;
    write_output(&a.output.join("contact.png"), &png)?;
    println!(
        "wrote {} images ({}×{}, {} mode, seed {}) with ground truth to {}, and contact.png",
        a.count,
        config.width,
        config.height,
        format!("{mode:?}").to_lowercase(),
        a.seed,
        a.output.display()
    );
    Ok(())
}

fn eval(command: EvalCommand) -> Result<()> {
    use tagsmith::detect::DetectionsFile;
    use tagsmith::eval::{score, set};
    match command {
        EvalCommand::Generate {
            family,
            side_mm,
            per_cell,
            seed,
            output,
        } => {
            let family = load_family(&family)?;
            let params = set::SetParams {
                side_m: side_mm / 1000.0,
                per_cell,
                seed,
                ..set::SetParams::default()
            };
            let started = std::time::Instant::now();
            let s = set::generate(&family, &params, &output).map_err(|e| bad(anyhow!(e)))?;
            println!(
                "wrote {} images of {} ({} mm) to {} in {:.1} s",
                s.images.len(),
                family.name(),
                side_mm,
                output.display(),
                started.elapsed().as_secs_f64()
            );
        }
        EvalCommand::Oracle { set: dir, output } => {
            let s = set::load(&dir).map_err(|e| bad(anyhow!(e)))?;
            let file = s.oracle();
            write_output(
                &output,
                serde_json::to_string_pretty(&file)
                    .expect("serialises")
                    .as_bytes(),
            )?;
            println!("wrote {}", output.display());
        }
        EvalCommand::Score {
            set: dir,
            detections,
            output,
        } => {
            let s = set::load(&dir).map_err(|e| bad(anyhow!(e)))?;
            let text = std::fs::read_to_string(&detections)
                .with_context(|| format!("cannot read {}", detections.display()))
                .map_err(bad)?;
            let file: DetectionsFile = serde_json::from_str(&text)
                .map_err(|e| bad(anyhow!("{}: {e}", detections.display())))?;
            let family = load_family(&s.family).ok();
            let report = score::score(&s, family.as_ref(), &file)
                .map_err(|e| bad(anyhow!("{}: {e}", detections.display())))?;
            let slug: String = file
                .detector
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect();
            let out = output.unwrap_or_else(|| dir.join(format!("report-{slug}")));
            std::fs::create_dir_all(&out)
                .with_context(|| format!("cannot create {}", out.display()))
                .map_err(failed)?;
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
        }
    }
    Ok(())
}
