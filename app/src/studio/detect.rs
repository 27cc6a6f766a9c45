//! The Detect panel: the learned detector (the same `tagsmith::detect::Detector` as `tagsmith
//! detect`) on an opened, dropped or sample image, with its ROIs, outlines, keypoints coloured by
//! category and IDs drawn over it, a table per marker, and the detections saved as the CLI's JSON
//! or the annotated image as PNG. Results update as the families or the threshold change.
//!
//! Detection runs off the UI thread ([`super::offload`]): on a thread of its own on the desktop,
//! in a web worker in a browser (burn's CPU backend compiled to wasm, the shipped weights), so
//! the window keeps drawing while the networks run. A design's own model is a file next to its
//! family file, so only the desktop offers it. The test scene and the video playback still run
//! the detector on the UI thread.

/// The sample photographs shipped in `assets/samples/` (sources and licences in its README):
/// (file name, bytes).
pub fn samples() -> impl Iterator<Item = (&'static str, &'static [u8])> {
    (tagsmith::assets::SAMPLES.iter()).map(|path| {
        let name = path.rsplit('/').next().unwrap_or(path);
        (name, tagsmith::assets::file(path))
    })
}

use super::files::{OpenedFile, Purpose};
use super::offload::{build_detector, shown, DetectRequest, Offload, Shown, Ticket};
use super::preview::{category_colour, gray_image};
use super::sequence::{Sequence, FRAMES};
use super::Studio;
use crate::settings::DetectorSettings;
use egui::{Color32, Pos2, Rect, Stroke, Vec2};
use tagsmith::detect::annotate::{annotate_all, Overlay};
use tagsmith::detect::stage2::{shipped_families, shipped_model_for, DEFAULT_FAMILIES};
use tagsmith::detect::{
    BenchDetector, DetectionsFile, Detector, DetectorOptions, Found, ImageDetections, Timings,
};
use tagsmith::geometry::Quad;
use tagsmith::image::GrayImage;

/// An image to detect on.
pub struct LoadedImage {
    pub name: String,
    pub gray: GrayImage,
    /// Bumped per image, so the texture is rebuilt.
    pub revision: u64,
}

/// The last detection: what was found and how long it took.
pub struct DetectResult {
    pub markers: Vec<Shown>,
    pub timings: Timings,
    pub time_ms: f64,
    /// The detector's name, as the detections file records it.
    pub detector: String,
}

pub struct DetectState {
    /// Families with shipped weights and whether to detect them.
    pub families: Vec<(String, bool)>,
    /// The design being edited, when a model trained in the Train panel is attached to it or a
    /// shipped model has its layout: its family, the model file (`None`: the shipped one) and
    /// whether to detect it.
    pub design: Option<(tagsmith::family::Family, Option<std::path::PathBuf>, bool)>,
    /// How the detector runs: the same settings as `tagsmith detect`'s flags.
    pub settings: DetectorSettings,
    pub image: Option<LoadedImage>,
    pub result: Option<DetectResult>,
    /// The detector of the test scene and the video, and the families it was built for.
    detector: Option<(Vec<String>, Detector)>,
    /// Where the opened image's detection runs, once the panel has been shown.
    offload: Option<Offload>,
    /// The request in flight and the image revision it was made for.
    asked: Option<(Ticket, u64)>,
    stale: bool,
    revision: u64,
    pub scene: SceneSettings,
    /// The test scenes of the last render, one per compared family.
    pub scenes: Vec<TestScene>,
    /// The opened image played as a video, while it plays or is paused.
    pub sequence: Option<Sequence>,
}

/// The synthetic test scene's conditions, the same for both families compared.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSettings {
    pub first: String,
    /// Empty: no second family.
    pub second: String,
    pub distance_m: f64,
    pub angle_deg: f64,
    pub noise: f32,
    pub blur: f32,
    /// Gray level of the marker's white (lighting).
    pub white: f32,
    pub seed: u64,
}

impl Default for SceneSettings {
    fn default() -> Self {
        let mut shipped = shipped_families();
        Self {
            first: shipped.next().unwrap_or_default().to_string(),
            second: shipped.next().unwrap_or_default().to_string(),
            distance_m: 0.5,
            angle_deg: 30.0,
            noise: 4.0,
            blur: 0.6,
            white: 220.0,
            seed: 1,
        }
    }
}

/// One family's test scene: the image, its truth and how the detector did on it.
pub struct TestScene {
    pub family: String,
    pub image: GrayImage,
    pub truth: tagsmith::synth::MarkerTruth,
    pub found: Option<Shown>,
    /// Corner RMS (px), position (mm) and rotation (°) errors of the found marker.
    pub errors: Option<(f64, f64, f64)>,
    pub revision: u64,
}

impl Default for DetectState {
    fn default() -> Self {
        Self {
            families: (shipped_families())
                .map(|f| (f.to_string(), DEFAULT_FAMILIES.contains(&f)))
                .collect(),
            design: None,
            settings: DetectorSettings::default(),
            image: None,
            result: None,
            detector: None,
            offload: None,
            asked: None,
            stale: false,
            revision: 0,
            scene: SceneSettings::default(),
            scenes: Vec::new(),
            sequence: None,
        }
    }
}

impl DetectState {
    /// The options the next detection runs with.
    pub fn options(&self) -> DetectorOptions {
        let mut options = DetectorOptions::default();
        self.settings.apply(&mut options);
        options
    }

    /// A detection of the opened image is running in the background, or due.
    pub fn is_detecting(&self) -> bool {
        self.asked.is_some() || (self.stale && self.image.is_some())
    }

    /// The ticked built-ins and, when ticked, the design with its model file.
    fn request_families(
        &self,
    ) -> (
        Vec<String>,
        Option<(&tagsmith::family::Family, Option<&std::path::Path>)>,
    ) {
        let builtins = (self.families.iter())
            .filter(|(_, on)| *on)
            .map(|(f, _)| f.clone())
            .collect();
        let design = match &self.design {
            Some((family, model, true)) => Some((family, model.as_deref())),
            _ => None,
        };
        (builtins, design)
    }

    fn chosen(&self) -> Vec<String> {
        let mut chosen: Vec<String> = self
            .families
            .iter()
            .filter(|(_, on)| *on)
            .map(|(f, _)| f.clone())
            .collect();
        if let Some((family, model, true)) = &self.design {
            let weights = model
                .as_ref()
                .map_or("shipped".into(), |m| m.display().to_string());
            // A model trained again in place reads with its new weights.
            let written = model.as_deref().and_then(super::offload::written);
            chosen.push(format!("{} ({weights}, {written:?})", family.name()));
        }
        chosen
    }

    /// Follows the designer: its family is offered when a trained model is attached to it, or
    /// a shipped model has its layout (`None`: read with that one).
    fn sync_design(&mut self, studio_design: Option<&super::design::Design>) {
        let attached = studio_design.and_then(|d| {
            let family = d.validation().as_ref().ok()?;
            let trained = (d.path.as_ref())
                .map(|p| super::train::attached_model(p))
                .filter(|m| m.exists());
            match trained {
                Some(model) => Some((family, Some(model))),
                None => shipped_model_for(family).map(|_| (family, None)),
            }
        });
        match (attached, &mut self.design) {
            // The whole spec, not the name: a duplicate's code table edited reads with the new
            // one.
            (Some((f, m)), Some((family, model, _)))
                if f.spec() == family.spec() && m == *model => {}
            (Some((f, m)), design) => {
                // Cloned only when the design or its model changed, not every frame; an edit
                // of the same design keeps its tick.
                let on = design
                    .as_ref()
                    .is_none_or(|(family, _, on)| *on || family.name() != f.name());
                self.design = Some((f.clone(), m, on));
                self.detector = None;
                self.stale = true;
            }
            (None, Some(_)) => {
                self.design = None;
                self.stale = true;
            }
            (None, None) => {}
        }
    }

    /// Builds the test scene's and the video's detector for the ticked families when they
    /// changed since the last build.
    fn build_detector(&mut self) -> Result<(), String> {
        let chosen = self.chosen();
        if self.detector.as_ref().is_none_or(|(f, _)| *f != chosen) {
            let (builtins, design) = self.request_families();
            let detector = build_detector(&builtins, design, &self.settings)?;
            self.detector = Some((chosen, detector));
        }
        let (_, detector) = self.detector.as_mut().expect("built above");
        self.settings.apply(&mut detector.options);
        Ok(())
    }

    /// Takes a finished detection of the opened image, and starts one when anything changed
    /// since the last (one at a time: changes made meanwhile are detected when it is back).
    pub fn refresh(&mut self, ctx: &egui::Context) -> Result<(), String> {
        let offload = self.offload.get_or_insert_with(|| Offload::new(ctx));
        if let Some((ticket, reply)) = offload.poll() {
            let asked = self.asked.take();
            let current = self.image.as_ref().map(|i| i.revision);
            // A reply for an image since replaced is dropped.
            if asked.is_some_and(|(t, revision)| t == ticket && Some(revision) == current) {
                let detected = reply?;
                let image = self.image.as_ref().expect("checked above");
                // The browser check (scripts/web-detect.sh) reads this line from the console.
                log::info!(
                    "detected {} marker(s) in {} ({}×{}) in {:.1} ms ({})",
                    detected.markers.len(),
                    image.name,
                    image.gray.width,
                    image.gray.height,
                    detected.time_ms,
                    detected.timings,
                );
                self.result = Some(DetectResult {
                    markers: detected.markers,
                    timings: detected.timings,
                    time_ms: detected.time_ms,
                    detector: detected.detector,
                });
            }
        }
        if !self.stale || self.offload.as_ref().is_some_and(Offload::is_busy) {
            return Ok(());
        }
        let Some(image) = &self.image else {
            return Ok(());
        };
        self.stale = false;
        let (families, design) = self.request_families();
        if families.is_empty() && design.is_none() {
            self.result = None;
            return Err("choose at least one family to detect".into());
        }
        let request = DetectRequest {
            families,
            design: design.map(|(f, m)| (f.spec().clone(), m.map(|m| m.to_path_buf()))),
            settings: self.settings.clone(),
            name: image.name.clone(),
            width: image.gray.width,
            height: image.gray.height,
            pixels: image.gray.pixels.to_vec(),
        };
        let revision = image.revision;
        // scripts/web-detect.sh times the page's frames from this line to the result's.
        log::info!("detecting {} in the background", image.name);
        let offload = self.offload.as_mut().expect("made above");
        let ticket = offload.send(request);
        self.asked = Some((ticket, revision));
        Ok(())
    }

    /// Renders the test scene for each compared family and detects on it with the same
    /// detector (the families ticked above), with the scene's own camera.
    pub fn render_scenes(&mut self) -> Result<(), String> {
        use tagsmith::synth::{augment::AugmentRanges, synthesize, Mode, SynthConfig};
        let settings = self.scene.clone();
        let names: Vec<String> = [settings.first.clone(), settings.second.clone()]
            .into_iter()
            .filter(|n| !n.is_empty())
            .collect();
        // The detector is built for the ticked families; the compared ones must be among them.
        for name in &names {
            if let Some(entry) = self.families.iter_mut().find(|(f, _)| f == name) {
                if !entry.1 {
                    entry.1 = true;
                    self.stale = true;
                }
            }
        }
        self.build_detector()?;
        let (_, detector) = self.detector.as_mut().expect("built above");
        self.scenes.clear();
        for name in names {
            let family = match tagsmith::builtin::get(&name) {
                Some(Ok(f)) => f,
                _ => match &self.design {
                    Some((f, _, _)) if f.name() == name => f.clone(),
                    _ => return Err(format!("{name}: no such family")),
                },
            };
            let mut config = SynthConfig::new(Mode::Camera);
            config.width = 640;
            config.height = 480;
            config.fov_deg = 70.0;
            config.markers = [1, 1];
            let side = family.spec().print.marker_side_mm / 1000.0;
            config.side_m = [side, side];
            config.distance_m = [settings.distance_m; 2];
            config.view_angle_deg = [settings.angle_deg; 2];
            let mut augment = AugmentRanges::none();
            augment.marker_black = [25.0, 25.0];
            augment.marker_white = [settings.white; 2];
            augment.noise_sigma = [settings.noise; 2];
            augment.blur_sigma = [settings.blur; 2];
            config.augment = augment;
            let sample = synthesize(&family, &config, settings.seed).map_err(|e| e.to_string())?;
            let Some(truth) = sample.truth.markers.first().cloned() else {
                continue;
            };
            detector.camera = sample.truth.camera;
            let (found, _) = Detector::detect(detector, &sample.image);
            let found = found
                .into_iter()
                .find(|f| f.family == family.name() && f.marker.id == truth.id);
            let errors = found.as_ref().map(|f| scene_errors(f, &truth));
            let found = found.map(|f| {
                let mut one = shown(detector, &[f], sample.truth.camera.as_ref());
                one.remove(0)
            });
            detector.camera = None;
            self.revision += 1;
            self.scenes.push(TestScene {
                family: family.name().to_string(),
                image: sample.image,
                truth,
                found,
                errors,
                revision: self.revision,
            });
        }
        Ok(())
    }

    /// The detections in the CLI's `--json` format.
    pub fn detections_file(&self) -> Option<DetectionsFile> {
        let (image, result) = (self.image.as_ref()?, self.result.as_ref()?);
        Some(DetectionsFile {
            detector: result.detector.clone(),
            images: vec![ImageDetections {
                file: image.name.clone(),
                time_ms: result.time_ms,
                detections: result.markers.iter().map(|m| m.detection.clone()).collect(),
                timings: serde_json::to_value(result.timings).ok(),
            }],
        })
    }

    /// Plays the opened image as a video ([`Sequence::moving`]), from its first frame.
    pub fn play_sequence(&mut self) {
        if let Some(image) = &self.image {
            let name = image.name.clone();
            self.sequence = Some(Sequence::moving(&name, &image.gray, FRAMES));
        }
    }

    /// Detects on the sequence's next frame with the detector's tracking and shows it.
    pub fn step_sequence(&mut self) -> Result<(), String> {
        self.build_detector()?;
        let (Some(sequence), Some((_, detector))) = (&mut self.sequence, &self.detector) else {
            return Ok(());
        };
        let Some((index, frame, time_ms)) = sequence.step(detector) else {
            return Ok(());
        };
        let gray = sequence.frames[index].clone();
        let name = format!(
            "{} (frame {} of {})",
            sequence.name,
            index + 1,
            sequence.frames.len()
        );
        let camera = detector.camera_for(&gray);
        let markers = shown(detector, &frame.found, camera.as_ref());
        let name_of_detector = BenchDetector::name(detector);
        self.set_image(name, gray);
        self.stale = false;
        self.result = Some(DetectResult {
            markers,
            timings: frame.timings,
            time_ms,
            detector: name_of_detector,
        });
        Ok(())
    }

    fn set_image(&mut self, name: String, gray: GrayImage) {
        self.revision += 1;
        self.image = Some(LoadedImage {
            name,
            gray,
            revision: self.revision,
        });
        self.result = None;
        self.stale = true;
    }
}

fn scene_errors(f: &Found, truth: &tagsmith::synth::MarkerTruth) -> (f64, f64, f64) {
    let corners = f
        .marker
        .corners
        .iter()
        .zip(&truth.roi)
        .map(|(a, b)| (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2))
        .sum::<f64>()
        / 4.0;
    let (mut position, mut rotation) = (f64::NAN, f64::NAN);
    if let (Some(p), Some(t)) = (&f.marker.pose, &truth.pose) {
        let want = tagsmith::geometry::Pose::from(&t.pose);
        position = 1000.0 * (p.pose.translation - want.translation).norm();
        rotation = p.pose.rotation_error_deg(&want);
    }
    (corners.sqrt(), position, rotation)
}

/// The video controls: play the opened image as a sequence, pause, step, stop; each frame's
/// time and the medians so far.
fn sequence_controls(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
    let state = &mut studio.detect;
    let mut step = false;
    ui.horizontal_wrapped(|ui| {
        let Some(sequence) = &mut state.sequence else {
            let can = state.image.is_some();
            if ui
                .add_enabled(can, egui::Button::new("Play as video"))
                .on_hover_text(
                    "the image moved along a hand-held camera's path, 60 frames, detected with \
                     tracking: stage 2 alone on the markers it follows, the whole detector on \
                     the first frame, every 10 frames and after a loss (detect --track)",
                )
                .clicked()
            {
                state.play_sequence();
            }
            return;
        };
        let label = if sequence.playing { "Pause" } else { "Play" };
        if ui.button(label).clicked() {
            sequence.playing = !sequence.playing;
        }
        step = ui.button("Step").clicked() || sequence.playing;
        let stop = ui.button("Stop").clicked();
        if let Some(shown) = sequence.shown {
            let (ms, full) = sequence.times[shown];
            let (all, tracked) = sequence.medians();
            let median = |m: Option<f64>| m.map_or("–".to_string(), |m| format!("{m:.1} ms"));
            ui.label(format!(
                "frame {} of {}: {ms:.1} ms ({}); median {}, tracked frames {}",
                shown + 1,
                sequence.frames.len(),
                if full { "whole detector" } else { "tracked" },
                median(all),
                median(tracked),
            ));
        }
        if stop {
            state.sequence = None;
            step = false;
        }
    });
    if step {
        if let Err(e) = studio.detect.step_sequence() {
            studio.error(e);
        }
        if studio.detect.sequence.as_ref().is_some_and(|s| s.playing) {
            ctx.request_repaint();
        }
    }
}

/// An image file opened or dropped: decoded (with the CLI's size limits) and detected on.
pub fn open_image(studio: &mut Studio, file: OpenedFile) {
    match tagsmith::image::decode(&file.bytes, &Default::default()) {
        Ok(gray) => {
            studio.detect.sequence = None;
            studio.detect.set_image(file.name.clone(), gray);
            studio.panel = super::Panel::Detect;
            studio.info(format!("opened {}", file.name));
        }
        Err(e) => studio.error(format!("{}: {e}", file.name)),
    }
}

/// Pasted text naming an image file (a path, or a `file://` address per line, as file
/// managers copy files): the first one is opened. Other text is ignored.
pub fn open_pasted(studio: &mut Studio, text: &str) {
    let Some(path) = text
        .lines()
        .map(|l| l.trim())
        .map(|l| l.strip_prefix("file://").unwrap_or(l))
        .find(|l| super::files::is_image_name(l))
    else {
        return;
    };
    match tagsmith::io::read_input(std::path::Path::new(path), super::files::MAX_IMAGE_BYTES) {
        Ok(bytes) => open_image(
            studio,
            OpenedFile {
                purpose: Purpose::Image,
                name: path.to_string(),
                path: Some(path.into()),
                bytes,
            },
        ),
        Err(e) => studio.error(format!("{path}: cannot read the pasted image: {e}")),
    }
}

/// Opens one of [`samples`] by file name; `false` when there is no such sample.
pub fn open_sample(studio: &mut Studio, name: &str) -> bool {
    let Some((name, bytes)) = samples().find(|(n, _)| *n == name) else {
        return false;
    };
    open_image(
        studio,
        OpenedFile {
            purpose: Purpose::Image,
            name: name.to_string(),
            path: None,
            bytes: bytes.to_vec(),
        },
    );
    true
}

pub fn show(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
    ui.horizontal_wrapped(|ui| {
        if ui.button("Open image…").clicked() {
            studio.files.request_open(Purpose::Image);
        }
        ui.label("Samples:");
        for (name, _) in samples() {
            if ui.button(name).clicked() {
                open_sample(studio, name);
            }
        }
    });
    studio.detect.sync_design(studio.design.as_ref());
    let state = &mut studio.detect;
    ui.horizontal_wrapped(|ui| {
        ui.label("Families:");
        for (name, on) in &mut state.families {
            if ui.checkbox(on, name.as_str()).changed() {
                state.stale = true;
            }
        }
        if let Some((family, model, on)) = &mut state.design {
            let weights = match model {
                Some(_) => "the design's trained model",
                None => "the shipped model of its layout",
            };
            let label = format!("{} ({weights})", family.name());
            if ui.checkbox(on, label).changed() {
                state.stale = true;
            }
        }
        ui.separator();
        let slider = egui::Slider::new(&mut state.settings.corner_threshold, 0.05..=0.95)
            .text("corner threshold");
        if ui
            .add(slider)
            .on_hover_text("stage 1's corner confidence: lower finds more, costs more time")
            .changed()
        {
            state.stale = true;
        }
        let slider = egui::Slider::new(&mut state.settings.verifier_threshold, 0.0..=0.95)
            .text("verifier threshold");
        if ui
            .add(slider)
            .on_hover_text(
                "the learned verifier's say on each candidate quad: quads it scores below this \
                 get no stage-2 read (higher is faster on clutter; 0 reads every quad)",
            )
            .changed()
        {
            state.stale = true;
        }
        if ui
            .checkbox(&mut state.settings.upsample, "tiny markers")
            .on_hover_text(
                "stage 1 also looks at the image enlarged twice: finds markers down to about \
                 10 px wide, stage 1 takes about five times as long",
            )
            .changed()
        {
            state.stale = true;
        }
        let mut steep_views = !state.settings.no_outline;
        if ui
            .checkbox(&mut steep_views, "steep views")
            .on_hover_text(
                "stage 1's weaker corners are also joined where the image shows a quad's sides, \
                 and quads are traced around dark blobs the network calls marker: finds markers \
                 seen nearly edge-on, for a few milliseconds (detect --no-outline turns it off)",
            )
            .changed()
        {
            state.settings.no_outline = !steep_views;
            state.stale = true;
        }
    });
    if let Err(e) = studio.detect.refresh(ctx) {
        studio.error(e);
    }
    egui::CollapsingHeader::new("Test scene")
        .default_open(false)
        .show(ui, |ui| test_scene(studio, ui, ctx));
    sequence_controls(studio, ui, ctx);
    let state = &studio.detect;
    if state.is_detecting() {
        // No spinner: it would repaint every frame; the reply asks for the next frame itself.
        ui.label("detecting…");
    }
    let (Some(image), Some(result)) = (&state.image, &state.result) else {
        if state.image.is_none() {
            ui.label("Open an image, drop one on the window, or pick a sample.");
        }
        return;
    };
    ui.horizontal(|ui| {
        ui.label(format!(
            "{}: {} marker(s) in {:.0} ms ({})",
            image.name,
            result.markers.len(),
            result.time_ms,
            result.timings,
        ));
    });
    let mut save_json = false;
    let mut save_png = false;
    ui.horizontal(|ui| {
        save_json = ui.button("Save detections (JSON)…").clicked();
        save_png = ui.button("Save annotated image (PNG)…").clicked();
    });
    table(ui, &result.markers);
    let tex = studio
        .textures
        .get_or_make(ctx, "detect-image", image.revision, || {
            Ok(gray_image(&image.gray))
        });
    if let Ok(tex) = tex {
        let size = Vec2::new(image.gray.width as f32, image.gray.height as f32);
        let scale = (ui.available_width() / size.x).min(1.5);
        let response = ui.image((tex.id(), size * scale));
        draw_overlays(ui, response.rect, scale, &result.markers);
    }
    if save_json {
        save_detections(studio);
    }
    if save_png {
        save_annotated(studio);
    }
}

/// A synthetic scene per compared family under the same conditions, detected, with the errors
/// against its truth: where a user sees which design holds up in their conditions.
fn test_scene(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
    let state = &mut studio.detect;
    let mut names: Vec<String> = state.families.iter().map(|(f, _)| f.clone()).collect();
    if let Some((f, _, _)) = &state.design {
        names.push(f.name().to_string());
    }
    let before = state.scene.clone();
    let s = &mut state.scene;
    ui.horizontal(|ui| {
        for (label, value, optional) in [
            ("first family", &mut s.first, false),
            ("second family", &mut s.second, true),
        ] {
            egui::ComboBox::from_label(label)
                .selected_text(if value.is_empty() {
                    "none".to_string()
                } else {
                    value.clone()
                })
                .show_ui(ui, |ui| {
                    if optional {
                        ui.selectable_value(value, String::new(), "none");
                    }
                    for n in &names {
                        ui.selectable_value(value, n.clone(), n.as_str());
                    }
                });
        }
    });
    ui.horizontal_wrapped(|ui| {
        ui.add(egui::Slider::new(&mut s.distance_m, 0.15..=2.0).text("distance m"));
        ui.add(egui::Slider::new(&mut s.angle_deg, 0.0..=75.0).text("angle °"));
        ui.add(egui::Slider::new(&mut s.noise, 0.0..=120.0).text("noise σ"));
        ui.add(egui::Slider::new(&mut s.blur, 0.0..=4.0).text("blur σ px"));
        ui.add(egui::Slider::new(&mut s.white, 60.0..=255.0).text("white level"));
        if ui.button("New pose").clicked() {
            s.seed += 1;
        }
    });
    let changed = *s != before;
    if changed || (state.scenes.is_empty() && ui.button("Render test scene").clicked()) {
        if let Err(e) = state.render_scenes() {
            studio.error(e);
            return;
        }
    }
    let state = &studio.detect;
    ui.horizontal(|ui| {
        for scene in &state.scenes {
            ui.vertical(|ui| {
                ui.strong(scene.family.as_str());
                match (&scene.found, scene.errors) {
                    (Some(f), Some((c, p, r))) => ui.label(format!(
                        "found #{}: corners {c:.2} px RMS, position {p:.1} mm, rotation {r:.2}°",
                        f.detection.id
                    )),
                    _ => ui.label(format!("#{} not found", scene.truth.id)),
                };
                let key = format!("test-scene-{}", scene.family);
                let tex = studio
                    .textures
                    .get_or_make(ctx, &key, scene.revision, || Ok(gray_image(&scene.image)));
                if let Ok(tex) = tex {
                    let size = Vec2::new(scene.image.width as f32, scene.image.height as f32);
                    let scale = 0.6;
                    let response = ui.image((tex.id(), size * scale));
                    draw_overlays(ui, response.rect, scale, scene.found.as_slice());
                }
            });
        }
    });
}

fn table(ui: &mut egui::Ui, markers: &[Shown]) {
    egui::Grid::new("detections")
        .striped(true)
        .num_columns(8)
        .show(ui, |ui| {
            for head in [
                "family",
                "ID",
                "corrected",
                "reprojection px",
                "distance mm",
                "position x, y, z mm",
                "tilt °",
                "refined",
            ] {
                ui.strong(head);
            }
            ui.end_row();
            for m in markers {
                let d = &m.detection;
                ui.label(d.family.as_deref().unwrap_or_default());
                ui.label(d.id.to_string());
                let scores = d.scores.as_ref();
                ui.label(scores.map_or(0, |s| s.corrected_errors).to_string());
                match (&d.pose, scores.and_then(|s| s.reprojection_rms_px)) {
                    (Some(pose), Some(rms_px)) => {
                        let pose = tagsmith::geometry::Pose::from(pose);
                        ui.label(format!("{rms_px:.2}"));
                        let t = 1000.0 * pose.translation;
                        ui.label(format!("{:.0}", t.norm()));
                        ui.label(format!("{:.1}, {:.1}, {:.1}", t[0], t[1], t[2]));
                        ui.label(format!("{:.1}", tilt_deg(&pose)));
                    }
                    _ => {
                        for _ in 0..4 {
                            ui.label("–");
                        }
                    }
                }
                ui.label(if m.refined { "yes" } else { "no" });
                ui.end_row();
            }
        });
}

/// The angle between the marker's face normal and the line of sight to it: 0° face-on.
fn tilt_deg(pose: &tagsmith::geometry::Pose) -> f64 {
    // The marker's z axis in the camera frame is the rotation's third column.
    let r = pose.rotation.matrix();
    let t = pose.translation.normalize();
    let cos = -(r[(0, 2)] * t[0] + r[(1, 2)] * t[1] + r[(2, 2)] * t[2]);
    cos.clamp(-1.0, 1.0).acos().to_degrees()
}

fn draw_overlays(ui: &egui::Ui, rect: Rect, scale: f32, markers: &[Shown]) {
    let painter = ui.painter_at(rect);
    let at = |p: [f64; 2]| {
        // Pixel centres at whole coordinates: pixel 0 covers [0, 1) on screen.
        Pos2::new(
            rect.min.x + (p[0] as f32 + 0.5) * scale,
            rect.min.y + (p[1] as f32 + 0.5) * scale,
        )
    };
    let outline = |q: &Quad, colour: Color32| {
        let points: Vec<Pos2> = q.iter().map(|&p| at(p)).collect();
        painter.add(egui::Shape::closed_line(points, Stroke::new(1.5, colour)));
    };
    for m in markers {
        let d = &m.detection;
        outline(&m.roi, Color32::from_rgb(255, 220, 0));
        outline(&d.corners, Color32::from_rgb(0, 200, 60));
        painter.circle_stroke(at(d.corners[0]), 5.0, Stroke::new(1.5, Color32::RED));
        for k in &d.keypoints {
            painter.circle_filled(at([k.x, k.y]), 2.0, category_colour(k.category));
        }
        // The ID above the marker, clear of the axes drawn from its centre.
        let top = d
            .corners
            .iter()
            .copied()
            .min_by(|a, b| a[1].total_cmp(&b[1]))
            .unwrap_or_default();
        if let Some([origin, ends @ ..]) = &m.axes {
            // x red, y green, z blue: the usual colours of a pose's axes.
            let colours = [
                Color32::from_rgb(255, 40, 40),
                Color32::from_rgb(40, 230, 40),
                Color32::from_rgb(60, 120, 255),
            ];
            for (end, colour) in ends.iter().zip(colours) {
                painter.line_segment([at(*origin), at(*end)], Stroke::new(2.5, colour));
            }
        }
        painter.text(
            at(top) - Vec2::new(0.0, 4.0),
            egui::Align2::CENTER_BOTTOM,
            format!("#{}", d.id),
            egui::FontId::proportional(14.0),
            Color32::from_rgb(255, 60, 200),
        );
    }
}

fn stem(name: &str) -> String {
    std::path::Path::new(name)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into())
}

fn save_detections(studio: &mut Studio) {
    let Some(file) = studio.detect.detections_file() else {
        return;
    };
    let name = format!("{}.detections.json", stem(&file.images[0].file));
    let json = serde_json::to_string_pretty(&file).expect("detections serialise");
    match studio.files.save_as(&name, json.as_bytes()) {
        Ok(Some(place)) => studio.info(format!("saved {place}")),
        Ok(None) => {}
        Err(e) => studio.error(format!("not saved: {e}")),
    }
}

fn save_annotated(studio: &mut Studio) {
    let state = &studio.detect;
    let (Some(image), Some(result)) = (&state.image, &state.result) else {
        return;
    };
    let overlays: Vec<Overlay> = (result.markers.iter())
        .map(|m| Overlay {
            roi: &m.roi,
            corners: Some(&m.detection.corners),
            keypoints: (m.detection.keypoints.iter())
                .map(|k| (k.x, k.y, k.category))
                .collect(),
        })
        .collect();
    let name = format!("{}.annotated.png", stem(&image.name));
    let saved =
        annotate_all(&image.gray, &overlays).and_then(|png| studio.files.save_as(&name, &png));
    match saved {
        Ok(Some(place)) => studio.info(format!("saved {place}")),
        Ok(None) => {}
        Err(e) => studio.error(format!("not saved: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::tilt_deg;
    use tagsmith::geometry::Pose;

    /// Face-on is 0° wherever the marker is in the view; turning it about its own x axis
    /// tilts it by that angle; seen from the side of a line of sight, not the optical axis.
    #[test]
    fn tilt_is_the_angle_between_the_face_and_the_line_of_sight() {
        let facing = Pose::from(&tagsmith::geometry::PoseJson {
            rotation: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            translation_m: [0.0, 0.0, 1.0],
        });
        assert!(tilt_deg(&facing) < 1e-6);
        let c = 30f64.to_radians().cos();
        let s = 30f64.to_radians().sin();
        // Turned 30° about the marker's x axis, after facing the camera.
        let turned = Pose::from(&tagsmith::geometry::PoseJson {
            rotation: [[1.0, 0.0, 0.0], [0.0, -c, s], [0.0, -s, -c]],
            translation_m: [0.0, 0.0, 1.0],
        });
        assert!(
            (tilt_deg(&turned) - 30.0).abs() < 1e-6,
            "{}",
            tilt_deg(&turned)
        );
    }
}
