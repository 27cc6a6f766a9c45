//! `tagsmith train` and `tagsmith detect`: the learned stage-2 detector's commands.

use crate::cli::{bad, failed, load_family, write_output, Result};
use anyhow::{anyhow, Context};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use tagsmith::detect::annotate::annotate;
use tagsmith::detect::stage2::Stage2;
use tagsmith::family::Family;
use tagsmith::geometry::Camera;
use tagsmith::train::{self, Event, TrainConfig};

#[derive(ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Stage 2: the keypoint network on rectified patches.
    Keypoints,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    /// Built-in family name or path to a family JSON file.
    pub family: String,
    #[arg(long, value_enum)]
    pub stage: Stage,
    #[arg(long, default_value_t = TrainConfig::default().steps)]
    pub steps: u64,
    #[arg(long, default_value_t = TrainConfig::default().batch)]
    pub batch: usize,
    /// Output folder (checkpoint, model, report) [default: runs/FAMILY-keypoints].
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Continue from the output folder's checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// Channels of the network's widest layers.
    #[arg(long, default_value_t = TrainConfig::default().width)]
    pub width: usize,
    /// Adam's learning rate (it falls to a tenth over the last quarter of the steps).
    #[arg(long, default_value_t = TrainConfig::default().learning_rate)]
    pub learning_rate: f64,
    #[arg(long, default_value_t = TrainConfig::default().seed)]
    pub seed: u64,
    #[arg(long, default_value_t = TrainConfig::default().checkpoint_every)]
    pub checkpoint_every: u64,
    #[arg(long, default_value_t = TrainConfig::default().validate_every)]
    pub validate_every: u64,
    #[arg(long, default_value_t = TrainConfig::default().validation_patches)]
    pub validation_patches: usize,
    /// Threads synthesising patches ahead of the optimiser.
    #[arg(long, default_value_t = TrainConfig::default().workers)]
    pub workers: usize,
}

#[derive(Args, Debug)]
pub struct DetectArgs {
    /// Image: PNG, JPEG, BMP, TIFF, WebP or PNM (colour is converted to gray).
    pub image: PathBuf,
    /// Built-in family name or path to a family JSON file.
    #[arg(long)]
    pub family: String,
    /// The marker's ROI: its 4 ROI points in the image, x1,y1,…,x4,y4 (any starting corner, in
    /// the family's order around the marker: clockwise in the image for square markers).
    #[arg(long)]
    pub roi: String,
    /// Camera intrinsics: JSON ({"width","height","fx","fy","cx","cy","distortion"}) or OpenCV
    /// YAML [default: guessed from the image size and a 70° diagonal field of view].
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Model file [default: the shipped weights of the family].
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Marker size in mm (ROI side) for the pose [default: the family's print size].
    #[arg(long)]
    pub side_mm: Option<f64>,
    /// Stage-2 passes (the second starts from the first's keypoints).
    #[arg(long, default_value_t = 2)]
    pub iterations: usize,
    /// Write the image with the ROI, outline and keypoints drawn on it (PNG).
    #[arg(long)]
    pub annotate: Option<PathBuf>,
    /// Refuse images larger than this many pixels (width × height) before decoding them.
    #[arg(long, default_value_t = tagsmith::image::Limits::DEFAULT_MAX_PIXELS)]
    pub max_pixels: u64,
}

/// Reads an image through the core's bounded decoder: a bad file is bad input (exit 2), named once.
pub(crate) fn read_image(path: &Path, max_pixels: u64) -> Result<tagsmith::image::GrayImage> {
    let limits = tagsmith::image::Limits { max_pixels };
    tagsmith::image::read(path, &limits).map_err(|e| {
        let hint = matches!(e.kind, tagsmith::image::ImageErrorKind::TooLarge { .. });
        let bad_input = e.kind.is_bad_input();
        let e = if hint {
            anyhow!("{e} (raise it with --max-pixels)")
        } else {
            anyhow!(e)
        };
        if bad_input {
            bad(e)
        } else {
            failed(e)
        }
    })
}

pub fn train(a: TrainArgs) -> Result<()> {
    let Stage::Keypoints = a.stage;
    let family = load_family(&a.family)?;
    if a.steps == 0
        || a.batch == 0
        || a.width < 8
        || a.checkpoint_every == 0
        || a.validate_every == 0
        || !(a.learning_rate > 0.0 && a.learning_rate.is_finite())
    {
        return Err(bad(anyhow!(
            "--steps, --batch, --checkpoint-every and --validate-every must be at least 1, \
             --width at least 8 and --learning-rate a positive number"
        )));
    }
    let config = TrainConfig {
        steps: a.steps,
        batch: a.batch,
        width: a.width,
        learning_rate: a.learning_rate,
        seed: a.seed,
        checkpoint_every: a.checkpoint_every,
        validate_every: a.validate_every,
        validation_patches: a.validation_patches,
        workers: a.workers,
        ..TrainConfig::default()
    };
    let out = a
        .out
        .unwrap_or_else(|| PathBuf::from(format!("runs/{}-keypoints", family.name())));
    let bar = ProgressBar::new(config.steps);
    bar.set_style(
        ProgressStyle::with_template(
            "{bar:30} {pos}/{len} {msg} [{elapsed_precise}, ETA {eta_precise}]",
        )
        .expect("valid template"),
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
    let stop = AtomicBool::new(false);
    let report = train::train(&family, &config, &out, a.resume, &stop, &mut |event| match event {
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
                "training {family}: {params} parameters, {:.1} MMAC per patch{}",
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
            loss,
            samples_per_s,
            data_wait,
        } => {
            bar.set_position(step);
            let message = format!(
                "loss {:.3} (conf {:.3} off {:.3} mask {:.3} tpl {:.3}) {:.0} samples/s, data wait {:.0} %",
                loss.total,
                loss.confidence,
                loss.offset,
                loss.mask,
                loss.template,
                samples_per_s,
                100.0 * data_wait
            );
            if plain && step.is_multiple_of(100) {
                say(format!("step {step}/{}: {message}", config.steps));
            }
            bar.set_message(message);
        }
        Event::Validated { step, metrics } => say(format!(
            "step {step}: keypoint recall {:.2} %, symbol accuracy {:.2} %, ID accuracy {:.1} % \
             (wrong {:.1} %), keypoint error RMS {:.2} px (median {:.2})",
            100.0 * metrics.keypoint_recall,
            100.0 * metrics.symbol_accuracy,
            100.0 * metrics.id_accuracy,
            100.0 * metrics.wrong_id_rate,
            metrics.keypoint_rms_px,
            metrics.keypoint_median_px
        )),
        Event::Checkpointed { .. } => {}
    })
    .map_err(|e| failed(anyhow!(e)))?;
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

fn parse_roi(text: &str) -> Result<[[f64; 2]; 4]> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| bad(anyhow!("--roi {text:?}: {e}")))?;
    if values.len() != 8 || values.iter().any(|v| !v.is_finite()) {
        return Err(bad(anyhow!(
            "--roi {text:?}: expected 8 finite numbers x1,y1,x2,y2,x3,y3,x4,y4"
        )));
    }
    Ok(std::array::from_fn(|i| [values[2 * i], values[2 * i + 1]]))
}

fn load_camera(path: &Path, size: (u32, u32)) -> Result<Camera> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read {}", path.display()))
        .map_err(bad)?;
    let camera = if matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("yml" | "yaml")
    ) {
        Camera::from_opencv_yaml(&text, Some(size))
            .map_err(|e| bad(anyhow!("{}: {e}", path.display())))?
    } else {
        serde_json::from_str::<Camera>(&text)
            .map_err(|e| bad(anyhow!("{}: {e}", path.display())))?
    };
    camera
        .validate()
        .map_err(|e| bad(anyhow!("{}: {e}", path.display())))?;
    Ok(camera)
}

/// The model for `family`: the given file, or the weights shipped for it.
fn load_model(model: Option<&Path>, family: &Family) -> Result<Stage2> {
    match model {
        Some(path) => Stage2::load(path, family).map_err(bad),
        None => {
            let bytes =
                tagsmith::detect::stage2::shipped_model(family.name()).ok_or_else(|| {
                    bad(anyhow!(
                    "no weights are shipped for family {:?}; train them with `tagsmith train {} \
                     --stage keypoints` and pass --model",
                    family.name(),
                    family.name()
                ))
                })?;
            Stage2::from_bytes(
                bytes,
                &format!("shipped weights of {}", family.name()),
                family,
            )
            .map_err(bad)
        }
    }
}

pub fn detect(a: DetectArgs) -> Result<()> {
    let family = load_family(&a.family)?;
    let roi = parse_roi(&a.roi)?;
    let image = read_image(&a.image, a.max_pixels)?;
    let (camera, camera_source) = match &a.camera {
        Some(path) => (load_camera(path, (image.width, image.height))?, "given"),
        None => (
            Camera::from_diagonal_fov(image.width, image.height, 70.0)
                .map_err(|e| bad(anyhow!(e)))?,
            "guessed (70° diagonal field of view)",
        ),
    };
    let side_mm = a.side_mm.unwrap_or(family.spec().print.marker_side_mm);
    if side_mm.is_nan() || side_mm <= 0.0 {
        return Err(bad(anyhow!("--side-mm must be positive")));
    }
    let model = load_model(a.model.as_deref(), &family)?;
    let found = model.detect(
        &image,
        &roi,
        a.iterations,
        Some((&camera, side_mm / 1000.0)),
    );
    if let Some(path) = &a.annotate {
        let keypoints: Vec<_> = found
            .iter()
            .flat_map(|r| r.keypoints.iter().map(|k| (k.x, k.y, k.category)))
            .collect();
        let png = annotate(&image, &roi, found.as_ref().map(|r| &r.corners), &keypoints)
            .map_err(|e| failed(anyhow!(e)))?;
        write_output(path, &png)?;
    }
    let json = match &found {
        None => serde_json::json!({
            "family": family.name(),
            "decoded": false,
        }),
        Some(r) => {
            let pose = r.pose.map(|p| {
                let m = p.pose.rotation.matrix();
                serde_json::json!({
                    "rotation": [[m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                                 [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                                 [m[(2, 0)], m[(2, 1)], m[(2, 2)]]],
                    "translation_m": [p.pose.translation[0], p.pose.translation[1], p.pose.translation[2]],
                    "reprojection_rms_px": p.rms_px,
                    "side_mm": side_mm,
                    "camera": camera_source,
                })
            });
            serde_json::json!({
                "family": family.name(),
                "decoded": true,
                "id": r.id,
                "rotation_deg": r.rotation_deg,
                "corrected_errors": r.corrected_errors,
                "fixed_mismatches": r.fixed_mismatches,
                "iterations": r.iterations,
                "corners": r.corners,
                "missing_keypoints": r.missing,
                "keypoints": r.keypoints,
                "pose": pose,
            })
        }
    };
    println!(
        "{}",
        serde_json::to_string_pretty(&json).expect("JSON values serialise")
    );
    if found.is_none() {
        return Err(failed(anyhow!(
            "{}: no {} marker decoded in the ROI",
            a.image.display(),
            family.name()
        )));
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct DetectSetArgs {
    /// Benchmark set folder (from `tagsmith eval generate`).
    pub set: PathBuf,
    /// Detections file to write (for `tagsmith eval score`).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Model file [default: the shipped weights of the set's family].
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Each ground-truth ROI corner moves by up to this fraction of the marker side in x and y
    /// (uniform), standing in for stage 1's error.
    #[arg(long, default_value_t = 0.05)]
    pub roi_noise: f64,
    #[arg(long, default_value_t = 2)]
    pub iterations: usize,
    /// Only the protocol's Normal images (≤ 50 cm, ≤ 60°).
    #[arg(long)]
    pub normal_only: bool,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// Stage 2 on every marker of a benchmark set from its ground-truth ROI moved by stage-1-like
/// noise; the time per image is stage 2 alone (warps, network, post-processing, PnP, all passes).
pub fn detect_set(a: DetectSetArgs) -> Result<()> {
    use tagsmith::eval::set::{self, Group};
    use tagsmith::eval::stage2_from_truth::Stage2FromTruth;
    let s = set::load(&a.set).map_err(|e| bad(anyhow!(e)))?;
    let family = load_family(&s.family)?;
    if !(0.0..0.5).contains(&a.roi_noise) {
        return Err(bad(anyhow!("--roi-noise must be in [0, 0.5)")));
    }
    let model = load_model(a.model.as_deref(), &family)?;
    let mut detector =
        Stage2FromTruth::new(model, a.roi_noise, a.iterations, s.camera, s.side_m, a.seed);
    let normal_only = a.normal_only;
    let include = |img: &set::BenchImage| {
        !normal_only || matches!(img.group, Group::Protocol { normal: true, .. })
    };
    let file = set::run_detector(&a.set, &s, &mut detector, &include).map_err(|e| {
        if e.kind.is_bad_input() {
            bad(e)
        } else {
            failed(e)
        }
    })?;
    let mut times: Vec<f64> = file
        .images
        .iter()
        .zip(s.images.iter().filter(|img| include(img)))
        .filter(|(_, img)| !img.truth.markers.is_empty())
        .map(|(d, img)| d.time_ms / img.truth.markers.len() as f64)
        .collect();
    let json = serde_json::to_string_pretty(&file).map_err(|e| failed(anyhow!(e)))?;
    write_output(&a.output, json.as_bytes())?;
    times.sort_by(f64::total_cmp);
    let median = times.get(times.len() / 2).copied().unwrap_or(f64::NAN);
    println!(
        "{} images, stage 2 per ROI: median {:.2} ms ({} passes); wrote {}",
        file.images.len(),
        median,
        a.iterations,
        a.output.display()
    );
    Ok(())
}
