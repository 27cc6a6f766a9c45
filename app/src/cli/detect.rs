//! `detect` and `detect-set`: the whole detector (or stage 2 on given ROIs) on images and benchmark sets.

use super::common::{load_family, output_folder, progress_bar, write_output};
use super::error::{bad_input, failure, Classify, CliError, Concerning, Result};
use anyhow::Context;
use clap::Args;
use std::path::{Path, PathBuf};
use tagsmith::detect::annotate::{annotate, annotate_all, Overlay};
use tagsmith::detect::detector::FamilyReader;
use tagsmith::detect::stage1::Stage1;
use tagsmith::detect::stage2::Stage2;
use tagsmith::detect::stage2::DEFAULT_FAMILIES;
use tagsmith::detect::MarkerReport;
use tagsmith::detect::{BenchDetector, DetectionsFile, Detector, Found, ImageDetections};
use tagsmith::detect::{TrackParams, Tracker};
use tagsmith::family::Family;
use tagsmith::geometry::{Camera, Quad};
use tagsmith::image::GrayImage;
use tagsmith_studio::settings::DetectorSettings;

/// Passes beyond the second rarely move a keypoint; each costs a full network run, and a million
/// of them made `detect` look hung.
#[derive(Args, Debug)]
pub struct DetectArgs {
    /// Images: PNG, JPEG, BMP, TIFF, WebP or PNM (colour is converted to gray); a folder gives
    /// its images in file-name order (a video's frames for --track).
    #[arg(required = true)]
    pub images: Vec<PathBuf>,
    /// Family to detect: built-in name or path to a family JSON file of at most 64 MB; repeat
    /// for several [default: apriltag-36h11, apriltag-xo-36h11 and aruco-6x6_250; any other
    /// built-in with shipped weights, such as artoolkitplus-bch, when named].
    #[arg(long)]
    pub family: Vec<String>,
    /// Read one known ROI instead of searching the image (one image, one family): its 4 ROI
    /// points x1,y1,…,x4,y4 (any starting corner, in the family's order around the marker:
    /// clockwise in the image for square markers).
    #[arg(long)]
    pub roi: Option<String>,
    /// Camera intrinsics: JSON ({"width","height","fx","fy","cx","cy","distortion"}) or OpenCV
    /// YAML, for images of the size it names; at most 64 MB [default: guessed from the image
    /// size and a 70° diagonal field of view].
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Stage-2 model file (one family; at most 256 MB) [default: the shipped weights of the
    /// family].
    #[arg(long)]
    pub model: Option<PathBuf>,
    /// Stage-1 model file (at most 256 MB) [default: the shipped one for square families].
    #[arg(long)]
    pub stage1: Option<PathBuf>,
    /// Marker size in mm (ROI side) for the pose [default: each family's print size].
    #[arg(long)]
    pub side_mm: Option<f64>,
    #[command(flatten)]
    pub detector: DetectorSettings,
    /// Write the detections file (the harness's format, for `tagsmith eval score`); images that
    /// could not be detected are listed under "failed" with their error.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Draw ROIs, outlines and keypoints: with --roi, the PNG to write; otherwise a folder that
    /// receives IMAGE-STEM.png for each image (IMAGE-STEM-2.png, … where two images share a
    /// stem or the name is one of the input images).
    #[arg(long)]
    pub annotate: Option<PathBuf>,
    /// Refuse images larger than this many pixels (width × height) before decoding them; with
    /// --upsample the doubled image counts [range: 1..=256000000].
    #[arg(
        long,
        default_value_t = tagsmith::image::Limits::DEFAULT_MAX_PIXELS,
        value_parser = clap::builder::RangedU64ValueParser::<u64>::new()
            .range(1..=tagsmith::image::MAX_PIXELS_CEILING)
    )]
    pub max_pixels: u64,
    /// One image at a time (each image's time is then its latency, as benchmarks quote it);
    /// by default images are detected in parallel on all cores.
    #[arg(long)]
    pub sequential: bool,
    /// The images are frames of one video, in the order given: each marker of the last frame is
    /// read again from where its motion puts it, by its family's stage 2 alone; the whole
    /// detector runs on the first frame, every --redetect-every frames and whenever a marker is
    /// lost (frames are detected one at a time)
    #[arg(long, conflicts_with = "roi")]
    pub track: bool,
    /// With --track: frames between two runs of the whole detector at most (markers coming into
    /// view are found no later than this) [range: 1..=10000]
    #[arg(
        long,
        default_value_t = 10,
        requires = "track",
        value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=10_000)
    )]
    pub redetect_every: usize,
}

/// The images named, each folder replaced by the images in it in natural order of their names
/// (`frame-2.png` before `frame-10.png`: a video's numbered frames, padded or not, in sequence).
/// A folder without images is refused, named.
fn with_folders_opened(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut images = Vec::with_capacity(paths.len());
    for path in paths {
        if !path.is_dir() {
            images.push(path.clone());
            continue;
        }
        let listing = std::fs::read_dir(path)
            .map_err(|e| bad_input!("{}: cannot list the folder: {e}", path.display()))?;
        let mut inside: Vec<PathBuf> = listing
            .filter_map(|entry| entry.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && tagsmith::image::has_image_name(p))
            .collect();
        if inside.is_empty() {
            return Err(bad_input!(
                "{}: the folder holds no image ({})",
                path.display(),
                tagsmith::image::EXTENSIONS.join(", ")
            ));
        }
        inside.sort_by(|a, b| natural_order(a, b));
        images.extend(inside);
    }
    Ok(images)
}

/// Names compared with each run of digits as a number: "frame-9" < "frame-10".
fn natural_order(a: &Path, b: &Path) -> std::cmp::Ordering {
    fn runs(path: &Path) -> Vec<(bool, String)> {
        let name = path.to_string_lossy();
        let mut runs: Vec<(bool, String)> = Vec::new();
        for c in name.chars() {
            let digit = c.is_ascii_digit();
            match runs.last_mut() {
                Some((d, run)) if *d == digit => run.push(c),
                _ => runs.push((digit, c.to_string())),
            }
        }
        runs
    }
    let number = |run: &str| {
        let trimmed = run.trim_start_matches('0');
        (trimmed.len(), trimmed.to_string())
    };
    let (ra, rb) = (runs(a), runs(b));
    for (x, y) in ra.iter().zip(&rb) {
        let order = match (x, y) {
            ((true, p), (true, q)) => number(p).cmp(&number(q)),
            ((_, p), (_, q)) => p.cmp(q),
        };
        if order.is_ne() {
            return order;
        }
    }
    ra.len().cmp(&rb.len()).then_with(|| a.cmp(b))
}

impl DetectArgs {
    pub fn run(mut self) -> Result<()> {
        self.images = with_folders_opened(&self.images)?;
        if self.roi.is_some() {
            self.run_roi()
        } else {
            self.run_search()
        }
    }

    fn side_mm(&self, family: &Family) -> Result<f64> {
        let side_mm = self.side_mm.unwrap_or(family.spec().print.marker_side_mm);
        if !(side_mm.is_finite() && side_mm > 0.0) {
            return Err(bad_input!(
                "--side-mm {side_mm}: the marker side must be a positive, finite length in mm"
            ));
        }
        Ok(side_mm)
    }

    fn limits(&self) -> tagsmith::image::Limits {
        tagsmith::image::Limits {
            max_pixels: self.max_pixels,
        }
    }

    /// Stage 2 on one given ROI.
    fn run_roi(self) -> Result<()> {
        let [image_path] = &self.images[..] else {
            return Err(bad_input!(
                "--roi reads one image; {} were given",
                self.images.len()
            ));
        };
        let [family] = &self.family[..] else {
            return Err(bad_input!(
                "--roi reads one family: give exactly one --family"
            ));
        };
        let family = load_family(family)?;
        let roi = parse_roi(self.roi.as_deref().unwrap_or_default())?;
        let inputs = Inputs::of(&self.images);
        if let Some(path) = &self.annotate {
            inputs.refuse_as_output("--annotate", path)?;
        }
        let image = tagsmith::image::read(image_path, &self.limits())?;
        let (camera, camera_source) = self.camera_for(&image)?;
        let side_mm = self.side_mm(&family)?;
        let model = load_model(self.model.as_deref(), &family)?;
        let options = self.detector.read_options();
        let found = model.detect(&image, &roi, &options, Some((&camera, side_mm / 1000.0)));
        if let Some(path) = &self.annotate {
            let keypoints: Vec<_> = found
                .iter()
                .flat_map(|r| r.keypoints.iter().map(|k| (k.x, k.y, k.category)))
                .collect();
            let png =
                annotate(&image, &roi, found.as_ref().map(|r| &r.corners), &keypoints).failure()?;
            write_output(path, &png)?;
        }
        let report =
            MarkerReport::from_stage2(family.name(), found.as_ref(), side_mm, camera_source);
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("reports serialise")
        );
        if found.is_none() {
            return Err(failure!(
                "{}: no {} marker decoded in the ROI",
                image_path.display(),
                family.name()
            ));
        }
        Ok(())
    }

    fn camera_for(&self, image: &GrayImage) -> Result<(Camera, &'static str)> {
        Ok(match &self.camera {
            Some(path) => (
                parse_camera(path, &read_camera_file(path)?, (image.width, image.height))?,
                "given",
            ),
            None => (
                Camera::from_diagonal_fov(image.width, image.height, 70.0)?,
                "guessed (70° diagonal field of view)",
            ),
        })
    }

    /// One image through the detector: its detections file entry and the line printed for it;
    /// writes its annotated copy when asked.
    /// `camera`: the `--camera` file's path and text, read once for all images (a YAML
    /// calibration is checked against each image's size).
    fn detect_one(
        &self,
        detector: &Detector,
        path: &Path,
        camera: Option<(&Path, &str)>,
        annotation: Option<&Path>,
        tracker: Option<&std::sync::Mutex<Tracker>>,
    ) -> Result<(ImageDetections, String)> {
        let image = tagsmith::image::read(path, &self.limits())?;
        let camera = camera
            .map(|(file, text)| parse_camera(file, text, (image.width, image.height)))
            .transpose()
            .map_err(|e| e.concerning(path.display()))?;
        if self.detector.upsample {
            let doubled = 4 * image.width as u64 * image.height as u64;
            if doubled > self.max_pixels {
                return Err(bad_input!(
                    "{}: --upsample enlarges the image to {:.1} megapixels, over --max-pixels                      ({:.1} megapixels)",
                    path.display(),
                    doubled as f64 / 1e6,
                    self.max_pixels as f64 / 1e6
                ));
            }
        }
        let clock = std::time::Instant::now();
        let (found, timings, tracked) = match tracker {
            Some(tracker) => {
                let mut tracker = tracker.lock().unwrap_or_else(|e| e.into_inner());
                let frame = tracker.next(detector, &image, camera.as_ref());
                (frame.found, frame.timings, Some(!frame.full))
            }
            None => {
                let (found, timings) = detector.detect_with(&image, camera.as_ref());
                (found, timings, None)
            }
        };
        let time_ms = clock.elapsed().as_secs_f64() * 1e3;
        let listed: Vec<String> = found
            .iter()
            .map(|f| format!("{} #{}", f.family, f.marker.id))
            .collect();
        let line = format!(
            "{}: {} marker{} {}in {time_ms:.0} ms ({}{timings})",
            path.display(),
            found.len(),
            if found.len() == 1 { "" } else { "s" },
            if listed.is_empty() {
                String::new()
            } else {
                format!("({}) ", listed.join(", "))
            },
            match tracked {
                Some(true) => "tracked: ",
                Some(false) => "whole detector: ",
                None => "",
            },
        );
        if let Some(annotation) = annotation {
            let overlays: Vec<Overlay> = found.iter().map(Found::overlay).collect();
            let png = annotate_all(&image, &overlays).failure()?;
            write_output(annotation, &png)?;
        }
        let entry = ImageDetections {
            file: path_as_given(path),
            time_ms,
            detections: found.iter().map(Found::detection).collect(),
            timings: serde_json::to_value(timings).ok().map(|mut value| {
                if let (Some(tracked), Some(map)) = (tracked, value.as_object_mut()) {
                    map.insert("tracked".into(), tracked.into());
                }
                value
            }),
        };
        Ok((entry, line))
    }

    /// The full detector on every image.
    fn run_search(self) -> Result<()> {
        let names: Vec<String> = if self.family.is_empty() {
            DEFAULT_FAMILIES.iter().map(|f| f.to_string()).collect()
        } else {
            self.family.clone()
        };
        if self.model.is_some() && names.len() != 1 {
            return Err(bad_input!(
                "--model is one family's stage 2: give exactly one --family"
            ));
        }
        let mut readers = Vec::new();
        for name in &names {
            let family = load_family(name)?;
            let side_mm = self.side_mm(&family)?;
            let stage2 = load_model(self.model.as_deref(), &family)?;
            let mut reader = FamilyReader::new(family, stage2);
            reader.side_m = side_mm / 1000.0;
            readers.push(reader);
        }
        let stage1 = match &self.stage1 {
            Some(path) => Stage1::load(path)?,
            None => Stage1::shipped()?,
        };
        let mut detector = Detector::new(stage1, readers).failure()?;
        self.detector.apply(&mut detector.options);
        // Every output is checked before the first image is read: a run that would replace one
        // of its own inputs, or write into a file as if it were a folder, is refused whole.
        let inputs = Inputs::of(&self.images);
        if let Some(path) = &self.json {
            if path.is_dir() {
                return Err(bad_input!(
                    "--json {}: it is a folder; give the detections file to write",
                    path.display()
                ));
            }
            inputs.refuse_as_output("--json", path)?;
        }
        let annotations = match &self.annotate {
            Some(dir) => {
                output_folder(dir, "--annotate")?;
                std::fs::create_dir_all(dir)
                    .with_context(|| format!("cannot create the folder {}", dir.display()))
                    .failure()?;
                annotation_names(&self.images, dir, &inputs)
            }
            None => vec![None; self.images.len()],
        };
        let bar = progress_bar(
            self.images.len() as u64,
            "{bar:30} {pos}/{len} [{elapsed_precise}, ETA {eta_precise}]",
        );
        let name = BenchDetector::name(&detector);
        let camera_text = self.camera.as_deref().map(read_camera_file).transpose()?;
        let camera = self.camera.as_deref().zip(camera_text.as_deref());
        if let Some((path, text)) = camera {
            // A file that is no camera at all is one error, not one per image.
            check_camera_file(path, text)?;
        }
        let tracker = self.track.then(|| {
            std::sync::Mutex::new(Tracker::new(TrackParams {
                redetect_every: self.redetect_every,
                ..TrackParams::default()
            }))
        });
        // Images in parallel on all cores: the network's own kernels leave the second core idle
        // much of the time on small images.
        use rayon::prelude::*;
        let one = |(path, annotation): (&PathBuf, &Option<PathBuf>)| {
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                self.detect_one(
                    &detector,
                    path,
                    camera,
                    annotation.as_deref(),
                    tracker.as_ref(),
                )
            }))
            .unwrap_or_else(|_| {
                // A fault of ours: the other images keep their results and the run says which
                // image to report.
                Err(failure!(
                    "{}: internal error while detecting (the panic above); please report it \
                     with this image",
                    path.display()
                ))
            });
            match &outcome {
                Ok((_, line)) => bar.suspend(|| println!("{line}")),
                Err(e) => bar.suspend(|| eprintln!("error: {e:#}")),
            }
            bar.inc(1);
            outcome.map(|(entry, _)| entry)
        };
        let pairs = self.images.iter().zip(&annotations);
        let results: Vec<Result<ImageDetections>> = if self.sequential || self.track {
            pairs.map(one).collect()
        } else {
            let pairs: Vec<_> = pairs.collect();
            pairs.into_par_iter().with_max_len(1).map(one).collect()
        };
        let mut file = BatchDetections {
            detections: DetectionsFile {
                detector: name,
                images: Vec::new(),
            },
            failed: Vec::new(),
        };
        let mut errors = Vec::new();
        for (path, r) in self.images.iter().zip(results) {
            match r {
                Ok(entry) => file.detections.images.push(entry),
                Err(e) => {
                    file.failed.push(FailedImage {
                        file: path_as_given(path),
                        error: format!("{e:#}"),
                        exit_code: e.exit_code(),
                    });
                    errors.push(e);
                }
            }
        }
        bar.finish_and_clear();
        if let Some(path) = &self.json {
            let json = serde_json::to_string_pretty(&file).failure()?;
            write_output(path, json.as_bytes())?;
        }
        if errors.is_empty() {
            return Ok(());
        }
        let summary = format!(
            "{} of {} image(s) failed (named above); the others were detected",
            errors.len(),
            self.images.len()
        );
        // Exit 1 only when the machine (or Tagsmith) failed on some image; bad images alone are
        // the input's fault.
        if errors.iter().all(|e| e.exit_code() == 2) {
            Err(bad_input!("{summary}"))
        } else {
            Err(failure!("{summary}"))
        }
    }
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
    /// Only the protocol's Normal images (≤ 50 cm, ≤ 60°).
    #[arg(long)]
    pub normal_only: bool,
    /// The full detector: stage 1 finds the ROIs in the whole image (instead of stage 2 reading
    /// the true ROIs moved by --roi-noise).
    #[arg(long)]
    pub full: bool,
    /// Stage-1 model file for --full [default: the shipped one].
    #[arg(long)]
    pub stage1: Option<PathBuf>,
    /// How the detector runs (`--iterations` and `--refine` also without --full).
    #[command(flatten)]
    pub detector: DetectorSettings,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// The family a benchmark set was generated with: the `family.json` the set keeps (a user's own
/// family is found there, not only a built-in of that name), else the built-in `name`.
fn set_family(set: &Path, name: &str) -> Result<tagsmith::Family> {
    let kept = set.join("family.json");
    if kept.is_file() {
        load_family(&kept.to_string_lossy())
    } else {
        load_family(name).map_err(|e| {
            e.concerning(format_args!(
                "{}: field \"family\" (and the set keeps no family.json)",
                set.join("set.json").display()
            ))
        })
    }
}

impl DetectSetArgs {
    /// Stage 2 on every marker of a benchmark set from its ground-truth ROI moved by stage-1-like
    /// noise; the time per image is stage 2 alone (warps, network, post-processing, PnP, all passes).
    pub fn run(self) -> Result<()> {
        use tagsmith::eval::set::{self, Group};
        use tagsmith::eval::stage2_from_truth::Stage2FromTruth;
        let s = set::load(&self.set)?;
        let family = set_family(&self.set, &s.family)?;
        if !(0.0..0.5).contains(&self.roi_noise) {
            return Err(bad_input!("--roi-noise must be in [0, 0.5)"));
        }
        let model = load_model(self.model.as_deref(), &family)?;
        let read = self.detector.read_options();
        let normal_only = self.normal_only;
        let include = |img: &set::BenchImage| {
            !normal_only || matches!(img.group, Group::Protocol { normal: true, .. })
        };
        if self.full {
            let stage1 = match &self.stage1 {
                Some(path) => Stage1::load(path)?,
                None => Stage1::shipped()?,
            };
            let mut reader = FamilyReader::new(family, model);
            reader.side_m = s.side_m;
            let mut detector = Detector::new(stage1, vec![reader]).failure()?;
            detector.camera = Some(s.camera);
            self.detector.apply(&mut detector.options);
            let file = set::run_detector(&self.set, &s, &mut detector, &include)?;
            let json = serde_json::to_string_pretty(&file).failure()?;
            write_output(&self.output, json.as_bytes())?;
            let mut times: Vec<f64> = file.images.iter().map(|i| i.time_ms).collect();
            times.sort_by(f64::total_cmp);
            println!(
                "{} images, full detector: median {:.1} ms per image; wrote {}",
                file.images.len(),
                times.get(times.len() / 2).copied().unwrap_or(f64::NAN),
                self.output.display()
            );
            return Ok(());
        }
        let mut detector =
            Stage2FromTruth::new(model, self.roi_noise, read, s.camera, s.side_m, self.seed);
        let file = set::run_detector(&self.set, &s, &mut detector, &include)?;
        let times: Vec<f64> = file
            .images
            .iter()
            .zip(s.images.iter().filter(|img| include(img)))
            .filter(|(_, img)| !img.truth.markers.is_empty())
            .map(|(d, img)| d.time_ms / img.truth.markers.len() as f64)
            .collect();
        let json = serde_json::to_string_pretty(&file).failure()?;
        write_output(&self.output, json.as_bytes())?;
        let median = |mut v: Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        println!(
            "{} images, stage 2 per ROI: median {:.2} ms ({} passes, refine {}); wrote {}",
            file.images.len(),
            median(times),
            self.detector.iterations,
            self.detector.refine.name(),
            self.output.display()
        );
        let refinements = detector.refinements();
        if !refinements.is_empty() {
            let refined = refinements.iter().filter(|r| r.refined).count();
            println!(
                "refinement: {refined} of {} markers refined; median {:.2} ms aligning, {:.2} ms \
                 rendering the template ({:.2} ms when not cached)",
                refinements.len(),
                median(refinements.iter().map(|r| r.time_ms).collect()),
                median(refinements.iter().map(|r| r.render_ms).collect()),
                median(
                    refinements
                        .iter()
                        .map(|r| r.render_ms)
                        .filter(|&t| t > 0.05)
                        .collect()
                ),
            );
        }
        Ok(())
    }
}

fn parse_roi(text: &str) -> Result<Quad> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| bad_input!("--roi {text:?}: {e}"))?;
    if values.len() != 8 || values.iter().any(|v| !v.is_finite()) {
        return Err(bad_input!(
            "--roi {text:?}: expected 8 finite numbers x1,y1,x2,y2,x3,y3,x4,y4"
        ));
    }
    let quad = Quad(std::array::from_fn(|i| [values[2 * i], values[2 * i + 1]]));
    quad.check()
        .map_err(|e| bad_input!("--roi {text:?}: {e}"))?;
    Ok(quad)
}

fn read_camera_file(path: &Path) -> Result<String> {
    tagsmith::io::read_input_text(path, tagsmith::io::MAX_TEXT_BYTES)
        .map_err(|e| CliError::reading(format_args!("--camera {}", path.display()), e))
}

/// A camera file checked for everything but the image size, which each image's check does.
fn check_camera_file(path: &Path, text: &str) -> Result<()> {
    let size = match serde_json::from_str::<Camera>(text) {
        Ok(camera) => (camera.width, camera.height),
        // A YAML calibration without image_width/image_height takes each image's size.
        Err(_) => (1, 1),
    };
    parse_camera(path, text, size).map(|_| ())
}

/// A camera file's text (`path` names it and says its format): JSON, or OpenCV YAML checked
/// against the image `size`.
fn parse_camera(path: &Path, text: &str, size: (u32, u32)) -> Result<Camera> {
    let camera = if matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("yml" | "yaml")
    ) {
        Camera::from_opencv_yaml(text, Some(size)).concerning(path.display())?
    } else {
        serde_json::from_str::<Camera>(text).map_err(|e| bad_input!("{}: {e}", path.display()))?
    };
    camera
        .validate()
        .map_err(|e| bad_input!("{}: {e}", path.display()))?;
    if (camera.width, camera.height) != size {
        return Err(bad_input!(
            "{}: fields \"width\", \"height\": the camera is calibrated for {}×{} images, the \
             image is {}×{}",
            path.display(),
            camera.width,
            camera.height,
            size.0,
            size.1
        ));
    }
    Ok(camera)
}

/// What `detect --json` writes: the harness's detections file, and the images that failed.
#[derive(serde::Serialize)]
struct BatchDetections {
    #[serde(flatten)]
    detections: DetectionsFile,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    failed: Vec<FailedImage>,
}

#[derive(serde::Serialize)]
struct FailedImage {
    file: String,
    error: String,
    /// What the image alone would have made the command exit with: 2 for a bad image, 1 for a
    /// failure of the machine or of Tagsmith.
    exit_code: u8,
}

/// A path as the user gave it, as text: the same as its display where it is UTF-8; elsewhere
/// each byte that is not UTF-8 is written `\xNN`, so two names that differ only there stay
/// apart (a lossy conversion made both one replacement character).
fn path_as_given(path: &Path) -> String {
    if let Some(text) = path.to_str() {
        return text.to_string();
    }
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let mut out = String::new();
        for chunk in path.as_os_str().as_bytes().utf8_chunks() {
            out.push_str(chunk.valid());
            for byte in chunk.invalid() {
                out.push_str(&format!("\\x{byte:02X}"));
            }
        }
        out
    }
    #[cfg(not(unix))]
    path.to_string_lossy().into_owned()
}

/// The files a run reads, so that no output of the run replaces one of them.
struct Inputs {
    files: Vec<FileId>,
}

/// A file's identity whatever path reaches it (a second spelling, a symlink, a hard link).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileId(u64, u64);

impl FileId {
    fn of(path: &Path) -> Option<Self> {
        let meta = std::fs::metadata(path).ok()?;
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            Some(Self(meta.dev(), meta.ino()))
        }
        #[cfg(not(unix))]
        {
            let _ = meta;
            let canonical = std::fs::canonicalize(path).ok()?;
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            canonical.hash(&mut h);
            Some(Self(0, h.finish()))
        }
    }
}

impl Inputs {
    fn of(paths: &[PathBuf]) -> Self {
        Self {
            files: paths.iter().filter_map(|p| FileId::of(p)).collect(),
        }
    }

    fn contains(&self, path: &Path) -> bool {
        FileId::of(path).is_some_and(|id| self.files.contains(&id))
    }

    /// Refuses `path` as the output of `option` when it is one of the run's inputs.
    fn refuse_as_output(&self, option: &str, path: &Path) -> Result<()> {
        if self.contains(path) {
            return Err(bad_input!(
                "{option} {}: it is one of the input images, which the output would replace",
                path.display()
            ));
        }
        Ok(())
    }
}

/// Where each image's annotated copy goes in `dir`: IMAGE-STEM.png, or IMAGE-STEM-2.png, -3, …
/// when an earlier image of the run took that name or the name is one of the run's inputs.
fn annotation_names(images: &[PathBuf], dir: &Path, inputs: &Inputs) -> Vec<Option<PathBuf>> {
    let mut taken: Vec<PathBuf> = Vec::new();
    images
        .iter()
        .map(|image| {
            let stem = image.file_stem().unwrap_or_default();
            let named = |suffix: String| {
                let mut name = stem.to_os_string();
                name.push(suffix);
                dir.join(name)
            };
            let mut candidate = named(".png".into());
            let mut k = 2;
            while taken.contains(&candidate) || inputs.contains(&candidate) {
                candidate = named(format!("-{k}.png"));
                k += 1;
            }
            taken.push(candidate.clone());
            Some(candidate)
        })
        .collect()
}

/// The model for `family`: the given file, or the weights shipped for it.
fn load_model(model: Option<&Path>, family: &Family) -> Result<Stage2> {
    match model {
        Some(path) => Ok(Stage2::load(path, family)?),
        None => Ok(Stage2::shipped(family).ok_or_else(|| {
            bad_input!(
                "no weights are shipped for family {:?}; train them with `tagsmith train {} \
                 --stage keypoints` and pass --model",
                family.name(),
                family.name()
            )
        })??),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folders_frames_come_in_the_order_of_their_numbers() {
        let mut names: Vec<PathBuf> = ["f-10.png", "f-2.png", "f-1.png", "f-02b.png", "e-3.png"]
            .iter()
            .map(PathBuf::from)
            .collect();
        names.sort_by(|a, b| natural_order(a, b));
        let sorted: Vec<&str> = names.iter().map(|p| p.to_str().unwrap()).collect();
        assert_eq!(
            sorted,
            ["e-3.png", "f-1.png", "f-2.png", "f-02b.png", "f-10.png"]
        );
    }

    /// A set generated from a user's family file names a family no built-in has: detect-set
    /// finds it in the set's `family.json`; a set without one falls back to the built-in name.
    #[test]
    fn a_sets_own_family_file_is_found_before_the_builtins() {
        let dir = tempfile::tempdir().unwrap();
        let bench =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../bench/unseen/bardot-7x7.json");
        std::fs::copy(&bench, dir.path().join("family.json")).unwrap();
        let family = set_family(dir.path(), "bardot-7x7").unwrap();
        assert_eq!(family.name(), "bardot-7x7");
        let empty = tempfile::tempdir().unwrap();
        assert!(set_family(empty.path(), "bardot-7x7").is_err());
        assert_eq!(
            set_family(empty.path(), "apriltag-36h11").unwrap().name(),
            "apriltag-36h11"
        );
    }

    #[test]
    fn a_broken_image_is_bad_input_named_once() {
        let dir = tempfile::tempdir().unwrap();
        let image = dir.path().join("broken.png");
        std::fs::write(&image, b"\x89PNG\r\n\x1a\n").unwrap();
        let args = DetectArgs {
            images: vec![image.clone()],
            family: vec!["apriltag-36h11".into()],
            roi: Some("0,0,10,0,10,10,0,10".into()),
            camera: None,
            model: None,
            stage1: None,
            detector: DetectorSettings::default(),
            json: None,
            sequential: false,
            side_mm: None,
            annotate: None,
            max_pixels: tagsmith::image::Limits::DEFAULT_MAX_PIXELS,
            track: false,
            redetect_every: 10,
        };
        let e = args.run().unwrap_err();
        assert_eq!(e.exit_code(), 2);
        let text = format!("{e:#}");
        let name = image.display().to_string();
        assert_eq!(text.matches(&name).count(), 1, "{text}");
    }
}
