//! Benchmark sets: the paper's protocol (1280×960, 98° diagonal FOV, distances 10–100 cm in 10 cm
//! steps, view angles 0–60° by 10 then 65, 70, 75°, in-plane rotation random; Normal = ≤ 50 cm and
//! ≤ 60°, Difficult = the rest), jitter sets (one pose rendered K times with fresh noise), a
//! Gaussian noise sweep (σ 0…300) and a motion-blur sweep (kernel 0…15, 10 directions). Written to
//! disk once, seeded, so every detector sees the same images.

use super::EvalError;
use crate::detect::{BenchDetector, Detection, DetectionsFile, ImageDetections};
use crate::family::Family;
use crate::geometry::{Camera, Quad};
use crate::synth::augment::AugmentRanges;
use crate::synth::{image_seed, synthesize, Mode, SynthConfig, Truth};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

pub const DISTANCES_CM: [u32; 10] = [10, 20, 30, 40, 50, 60, 70, 80, 90, 100];
pub const ANGLES_DEG: [u32; 10] = [0, 10, 20, 30, 40, 50, 60, 65, 70, 75];
pub const NOISE_SIGMAS: [u32; 13] = [0, 25, 50, 75, 100, 125, 150, 175, 200, 225, 250, 275, 300];
pub const BLUR_LENGTHS: [u32; 9] = [0, 1, 3, 5, 7, 9, 11, 13, 15];

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Group {
    Protocol {
        distance_cm: u32,
        angle_deg: u32,
        normal: bool,
    },
    Jitter {
        pose: u32,
    },
    Noise {
        sigma: u32,
    },
    MotionBlur {
        length: u32,
        direction_deg: u32,
    },
    /// A scenario's scene: the swept condition and its value (none without sweeps).
    Scenario {
        condition: Option<super::scenario::Condition>,
        value: f64,
    },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchImage {
    pub file: String,
    pub group: Group,
    pub truth: Truth,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchmarkSet {
    pub family: String,
    pub side_m: f64,
    pub camera: Camera,
    pub seed: u64,
    pub images: Vec<BenchImage>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SetParams {
    pub side_m: f64,
    /// Images per (distance, angle) cell of the protocol.
    pub per_cell: u32,
    pub jitter_poses: u32,
    pub jitter_renders: u32,
    pub per_noise_level: u32,
    /// Directions per motion-blur length (evenly spread over 180°).
    pub blur_directions: u32,
    pub seed: u64,
}

impl Default for SetParams {
    fn default() -> Self {
        Self {
            side_m: 0.05,
            per_cell: 1,
            jitter_poses: 5,
            jitter_renders: 10,
            per_noise_level: 5,
            blur_directions: 10,
            seed: 0,
        }
    }
}

/// Clean renderings with a small sensor noise, mid-gray levels as a printed marker shows them.
fn protocol_augment() -> AugmentRanges {
    let mut a = AugmentRanges::none();
    a.marker_black = [20.0, 40.0];
    a.marker_white = [200.0, 235.0];
    a.noise_sigma = [2.0, 2.0];
    a
}

fn config(side: f64, distance_m: f64, angle_deg: f64, augment: AugmentRanges) -> SynthConfig {
    let mut c = SynthConfig::new(Mode::Camera);
    c.markers = [1, 1];
    c.side_m = [side, side];
    c.distance_m = [distance_m, distance_m];
    c.view_angle_deg = [angle_deg, angle_deg];
    c.augment = augment;
    c
}

/// The list of (group, synth config, seed) of a set, in a fixed order.
fn plan(p: &SetParams) -> Vec<(Group, SynthConfig, u64)> {
    let mut out = Vec::new();
    let mut n = 0u64;
    let mut push = |g: Group, c: SynthConfig, seed: u64| out.push((g, c, seed));
    for &d in &DISTANCES_CM {
        for &a in &ANGLES_DEG {
            for _ in 0..p.per_cell {
                let g = Group::Protocol {
                    distance_cm: d,
                    angle_deg: a,
                    normal: d <= 50 && a <= 60,
                };
                push(
                    g,
                    config(p.side_m, d as f64 / 100.0, a as f64, protocol_augment()),
                    image_seed(p.seed, n),
                );
                n += 1;
            }
        }
    }
    for pose in 0..p.jitter_poses {
        // One scene seed per pose; each render only reseeds the sensor noise.
        let scene = image_seed(p.seed ^ 0x4A17, pose as u64);
        for r in 0..p.jitter_renders {
            let mut a = protocol_augment();
            a.noise_sigma = [3.0, 3.0];
            let mut c = config(p.side_m, 0.3, 30.0, a);
            c.noise_seed = Some(image_seed(scene, r as u64 + 1));
            push(Group::Jitter { pose }, c, scene);
        }
    }
    for &sigma in &NOISE_SIGMAS {
        for _ in 0..p.per_noise_level {
            let mut a = protocol_augment();
            a.noise_sigma = [sigma as f32, sigma as f32];
            push(
                Group::Noise { sigma },
                config(p.side_m, 0.3, 20.0, a),
                image_seed(p.seed ^ 0x9015E, n),
            );
            n += 1;
        }
    }
    for &length in &BLUR_LENGTHS {
        for dir in 0..p.blur_directions {
            let mut a = protocol_augment();
            let direction = dir * 180 / p.blur_directions;
            a.motion_blur_probability = 1.0;
            a.motion_blur_length = [length.max(1), length.max(1)];
            a.motion_blur_angle_deg = [direction as f32, direction as f32];
            let g = Group::MotionBlur {
                length,
                direction_deg: direction,
            };
            push(
                g,
                config(p.side_m, 0.3, 20.0, a),
                image_seed(p.seed ^ 0xB1A4, n),
            );
            n += 1;
        }
    }
    out
}

/// The most images one set may hold: the protocol at 100 images per cell and the sweeps. The plan
/// is built in memory before anything renders, and `--per-cell 4294967295` aborted allocating it.
pub const MAX_SET_IMAGES: u64 = 20_000;

impl SetParams {
    /// The number of images the set will hold, counted without building it.
    pub fn image_count(&self) -> u64 {
        let cells = (DISTANCES_CM.len() * ANGLES_DEG.len()) as u64;
        cells * self.per_cell as u64
            + self.jitter_poses as u64 * self.jitter_renders as u64
            + NOISE_SIGMAS.len() as u64 * self.per_noise_level as u64
            + BLUR_LENGTHS.len() as u64 * self.blur_directions as u64
    }
}

/// Renders the set into `dir/images/` and writes `dir/set.json` (the manifest with the truth).
/// The parameters are checked before the folder is made; if rendering or writing fails, the
/// folders this call created are removed (folders that were there before are left).
pub fn generate(
    family: &Family,
    params: &SetParams,
    dir: &Path,
) -> Result<BenchmarkSet, EvalError> {
    if !(params.side_m.is_finite() && params.side_m > 0.0 && params.side_m <= 1.0) {
        return Err(EvalError::BadSide {
            side_m: params.side_m,
        });
    }
    let images = params.image_count();
    if images > MAX_SET_IMAGES {
        return Err(EvalError::TooLarge {
            images,
            max: MAX_SET_IMAGES,
        });
    }
    let camera =
        Camera::from_diagonal_fov(1280, 960, 98.0).expect("the protocol's camera is valid");
    render_set(
        family,
        &plan(params),
        camera,
        (params.side_m, params.seed),
        dir,
    )
}

/// Renders a scenario's scenes as a benchmark set into `dir` (as [`generate`] does the protocol):
/// the same images, truth and camera the design comparison scores.
pub fn generate_scenario(
    family: &Family,
    scenario: &super::scenario::Scenario,
    dir: &Path,
) -> Result<BenchmarkSet, EvalError> {
    if let Err(e) = scenario.validate() {
        return Err(EvalError::BadScenario {
            path: "scenario".into(),
            field: e.field,
            message: e.message,
        });
    }
    let plan: Vec<_> = (scenario.scenes().into_iter())
        .map(|s| (s.group, s.config, s.seed))
        .collect();
    let side_and_seed = (scenario.side_mm / 1000.0, scenario.seed);
    render_set(family, &plan, scenario.camera(), side_and_seed, dir)
}

/// Renders `plan` into `dir/images/` and writes `dir/set.json`; if rendering or writing fails,
/// the folders this call created are removed (folders that were there before are left).
fn render_set(
    family: &Family,
    plan: &[(Group, SynthConfig, u64)],
    camera: Camera,
    (side_m, seed): (f64, u64),
    dir: &Path,
) -> Result<BenchmarkSet, EvalError> {
    let images_dir = dir.join("images");
    let created =
        crate::io::CreatedDir::create(&images_dir).map_err(|source| EvalError::Write {
            path: images_dir,
            source,
        })?;
    let images = plan
        .par_iter()
        .enumerate()
        .map(|(i, (group, config, seed))| {
            let sample = synthesize(family, config, *seed)?;
            let file = format!("images/{i:06}.png");
            let path = dir.join(&file);
            let png = match crate::image::encode_png(&sample.image) {
                Ok(png) => png,
                Err(source) => return Err(EvalError::Encode { path, source }),
            };
            crate::io::write_atomic(&path, &png)
                .map_err(|source| EvalError::Write { path, source })?;
            Ok(BenchImage {
                file,
                group: *group,
                truth: sample.truth,
            })
        })
        .collect::<Result<Vec<_>, EvalError>>()?;
    let set = BenchmarkSet {
        family: family.name().to_string(),
        side_m,
        camera,
        seed,
        images,
    };
    let json = serde_json::to_string(&set).expect("a benchmark set serialises");
    let path = dir.join("set.json");
    crate::io::write_atomic(&path, json.as_bytes())
        .map_err(|source| EvalError::Write { path, source })?;
    created.keep();
    Ok(set)
}

/// Reads `dir/set.json` and checks what scoring relies on: a positive marker side, a camera that
/// projects, each image listed once (under any spelling of its path), every image path inside the
/// set folder (relative, never climbing out with `..`: commands read the files it names), and each
/// true ROI an outline geometry can work with ([`crate::geometry::Quad::check_with_min_area`]; a
/// far marker may cover under a pixel, so no least area). `set.json` is read as a regular file of
/// at most [`crate::io::MAX_TEXT_BYTES`].
pub fn load(dir: &Path) -> Result<BenchmarkSet, EvalError> {
    let path = dir.join("set.json");
    let text = match crate::io::read_input_text(&path, crate::io::MAX_TEXT_BYTES) {
        Ok(text) => text,
        Err(source) => return Err(EvalError::Read { path, source }),
    };
    let set: BenchmarkSet = serde_json::from_str(&text).map_err(|source| EvalError::Json {
        path: path.clone(),
        source,
    })?;
    let bad = |field: &str, message: String| EvalError::BadSet {
        path: path.clone(),
        field: field.into(),
        message,
    };
    if !(set.side_m.is_finite() && set.side_m > 0.0 && set.side_m <= 1.0) {
        return Err(bad("side_m", format!("{} m must be in (0, 1]", set.side_m)));
    }
    if let Err(e) = set.camera.validate() {
        return Err(bad("camera", e.to_string()));
    }
    let mut seen = std::collections::HashMap::new();
    for (i, img) in set.images.iter().enumerate() {
        let field = format!("images[{i}].file");
        if let Err(why) = check_image_path(&img.file) {
            return Err(bad(&field, format!("{:?} {why}", img.file)));
        }
        if let Some(first) = seen.insert(normalise_path(&img.file), i) {
            let message = if set.images[first].file == img.file {
                format!("{:?} is listed twice", img.file)
            } else {
                format!(
                    "{:?} is listed twice: images[{first}].file {:?} is the same image",
                    img.file, set.images[first].file
                )
            };
            return Err(bad(&field, message));
        }
        for (j, m) in img.truth.markers.iter().enumerate() {
            let field = format!("images[{i}].truth.markers[{j}].roi");
            let Some(quad) = m.roi.first_chunk::<4>() else {
                return Err(bad(
                    &field,
                    format!(
                        "{}: {} points; the 4 corners are needed",
                        img.file,
                        m.roi.len()
                    ),
                ));
            };
            if let Err(e) = crate::geometry::Quad(*quad).check_with_min_area(0.0) {
                return Err(bad(&field, format!("{}: {e}", img.file)));
            }
        }
    }
    Ok(set)
}

/// A path as written, spelled one way: `.` components and repeated separators dropped, `a/..`
/// folded away (lexically: the file need not exist, and symlinks are not followed). Two spellings
/// of one image (`images/000001.png`, `./images//000001.png`) normalise alike.
pub fn normalise_path(file: &str) -> String {
    use std::path::Component;
    let mut parts: Vec<Component> = Vec::new();
    for c in Path::new(file).components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir if matches!(parts.last(), Some(Component::Normal(_))) => {
                parts.pop();
            }
            c => parts.push(c),
        }
    }
    let mut text = String::new();
    for c in &parts {
        match c {
            Component::Prefix(p) => text.push_str(&p.as_os_str().to_string_lossy()),
            Component::RootDir => text.push('/'),
            c => {
                if !(text.is_empty() || text.ends_with('/')) {
                    text.push('/');
                }
                text.push_str(&c.as_os_str().to_string_lossy());
            }
        }
    }
    if text.is_empty() {
        ".".into()
    } else {
        text
    }
}

/// Why an image path of a set cannot be read relative to the set's folder, if it cannot:
/// absolute, empty, or climbing out of the folder with `..`.
fn check_image_path(file: &str) -> Result<(), &'static str> {
    use std::path::Component;
    let path = Path::new(file);
    if file.is_empty() {
        return Err("is empty; give the image's path relative to the set folder");
    }
    let mut depth = 0i64;
    for c in path.components() {
        match c {
            Component::Prefix(_) | Component::RootDir => {
                return Err("is an absolute path; image paths are relative to the set folder")
            }
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return Err("leaves the set folder (..); image paths stay inside it");
                }
            }
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
        }
    }
    if depth == 0 {
        return Err("names the set folder itself, not an image in it");
    }
    Ok(())
}

impl BenchImage {
    /// The ground truth as detections: what a perfect detector reports (with poses when
    /// `with_pose`). The reference for the detections format.
    pub fn truth_detections(&self, with_pose: bool) -> Vec<Detection> {
        self.truth
            .markers
            .iter()
            .map(|m| {
                Detection::plain(
                    m.id,
                    Quad([m.roi[0], m.roi[1], m.roi[2], m.roi[3]]),
                    m.pose.as_ref().filter(|_| with_pose).map(|p| p.pose),
                )
            })
            .collect()
    }
}

impl BenchmarkSet {
    /// The whole set's ground truth as a detections file (`tagsmith eval oracle`).
    pub fn oracle(&self) -> DetectionsFile {
        DetectionsFile {
            detector: "ground truth".into(),
            images: self
                .images
                .iter()
                .map(|img| ImageDetections {
                    file: img.file.clone(),
                    time_ms: 0.0,
                    detections: img.truth_detections(true),
                    timings: None,
                })
                .collect(),
        }
    }
}

/// Runs an in-process detector over the images of the set that `include` accepts, timing each
/// image's [`BenchDetector::detect`] (the image is read before the clock starts).
pub fn run_detector(
    dir: &Path,
    set: &BenchmarkSet,
    detector: &mut dyn BenchDetector,
    include: &dyn Fn(&BenchImage) -> bool,
) -> Result<DetectionsFile, crate::image::ImageError> {
    let mut images = Vec::with_capacity(set.images.len());
    for img in set.images.iter().filter(|img| include(img)) {
        let gray = crate::image::read(&dir.join(&img.file), &Default::default())?;
        detector.observe_truth(&img.truth);
        let start = Instant::now();
        let (detections, timings) = detector.detect_timed(&gray);
        images.push(ImageDetections {
            file: img.file.clone(),
            time_ms: start.elapsed().as_secs_f64() * 1e3,
            detections,
            timings,
        });
    }
    Ok(DetectionsFile {
        detector: detector.name(),
        images,
    })
}
