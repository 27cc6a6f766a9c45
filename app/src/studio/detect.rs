//! The Detect panel: the learned detector (the same `tagsmith::detect::Detector` as `tagsmith
//! detect`) on an opened, dropped or sample image, with its ROIs, outlines, keypoints coloured by
//! category and IDs drawn over it, a table per marker, and the detections saved as the CLI's JSON
//! or the annotated image as PNG. Results update as the families or the threshold change.
//!
//! The web build has no burn yet (DESIGN §8 asks for it; see the README's status), so there the
//! panel says so instead of detecting.

#[cfg(target_arch = "wasm32")]
use super::{files::OpenedFile, Studio};

/// Sample photographs shipped in `assets/samples/` (sources and licences in its README).
#[cfg(not(target_arch = "wasm32"))]
pub const SAMPLES: &[(&str, &[u8])] = &[
    (
        "aruco-6x6_250-tutorial.jpg",
        include_bytes!("../../../assets/samples/aruco-6x6_250-tutorial.jpg"),
    ),
    (
        "apriltag-36h11-swarmathon.jpg",
        include_bytes!("../../../assets/samples/apriltag-36h11-swarmathon.jpg"),
    ),
];

#[cfg(not(target_arch = "wasm32"))]
pub use desktop::*;

/// Nothing to keep where the panel only explains (a struct, not a unit, so the studio builds it
/// the same way on every target).
#[cfg(target_arch = "wasm32")]
#[derive(Default)]
pub struct DetectState {
    _none: (),
}

#[cfg(target_arch = "wasm32")]
pub fn open_image(studio: &mut Studio, file: OpenedFile) {
    studio.error(format!(
        "{}: detection runs in the desktop studio and `tagsmith detect`; the web build does not \
         include the detector yet",
        file.name
    ));
}

#[cfg(target_arch = "wasm32")]
pub fn show(_studio: &mut Studio, ui: &mut egui::Ui, _ctx: &egui::Context) {
    ui.heading("Detect");
    ui.label(
        "Detection runs in the desktop studio and in `tagsmith detect`; the web build does not \
         include the detector yet.",
    );
}

#[cfg(not(target_arch = "wasm32"))]
mod desktop {
    use super::super::files::{OpenedFile, Purpose};
    use super::super::preview::{category_colour, gray_image};
    use super::super::Studio;
    use super::SAMPLES;
    use egui::{Color32, Pos2, Rect, Stroke, Vec2};
    use tagsmith::detect::annotate::{annotate_all, Overlay};
    use tagsmith::detect::detector::{FamilyReader, SHIPPED_STAGE1};
    use tagsmith::detect::stage1::group::GroupOptions;
    use tagsmith::detect::stage1::Stage1;
    use tagsmith::detect::stage2::{shipped_families, Stage2};
    use tagsmith::detect::{
        BenchDetector, DetectionsFile, Detector, Found, ImageDetections, Timings,
    };
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
        pub found: Vec<Found>,
        pub timings: Timings,
        pub time_ms: f64,
    }

    pub struct DetectState {
        /// Families with shipped weights and whether to detect them.
        pub families: Vec<(String, bool)>,
        /// The design being edited, when a model trained in the Train panel is attached to it:
        /// its family, model file and whether to detect it.
        pub design: Option<(tagsmith::family::Family, std::path::PathBuf, bool)>,
        pub corner_threshold: f32,
        pub image: Option<LoadedImage>,
        pub result: Option<DetectResult>,
        /// The loaded detector and the families it was built for.
        detector: Option<(Vec<String>, Detector)>,
        stale: bool,
        revision: u64,
    }

    impl Default for DetectState {
        fn default() -> Self {
            Self {
                families: shipped_families().map(|f| (f.to_string(), true)).collect(),
                design: None,
                corner_threshold: GroupOptions::default().corner,
                image: None,
                result: None,
                detector: None,
                stale: false,
                revision: 0,
            }
        }
    }

    impl DetectState {
        fn chosen(&self) -> Vec<String> {
            let mut chosen: Vec<String> = self
                .families
                .iter()
                .filter(|(_, on)| *on)
                .map(|(f, _)| f.clone())
                .collect();
            if let Some((family, model, true)) = &self.design {
                chosen.push(format!("{} ({})", family.name(), model.display()));
            }
            chosen
        }

        /// Follows the designer: its family is offered when a trained model is attached to it.
        fn sync_design(&mut self, studio_design: Option<&super::super::design::Design>) {
            let attached = studio_design.and_then(|d| {
                let family = d.validation().as_ref().ok()?.clone();
                let model = super::super::train::attached_model(d.path.as_ref()?);
                model.exists().then_some((family, model))
            });
            match (attached, &mut self.design) {
                (Some((f, m)), Some((family, model, _)))
                    if f.name() == family.name() && m == *model => {}
                (Some((f, m)), _) => {
                    self.design = Some((f, m, true));
                    self.stale = true;
                }
                (None, Some(_)) => {
                    self.design = None;
                    self.stale = true;
                }
                (None, None) => {}
            }
        }

        /// Runs the detector on the image if anything changed since the last run.
        pub fn refresh(&mut self) -> Result<(), String> {
            if !self.stale {
                return Ok(());
            }
            self.stale = false;
            let Some(image) = &self.image else {
                return Ok(());
            };
            let chosen = self.chosen();
            if chosen.is_empty() {
                self.result = None;
                return Err("choose at least one family to detect".into());
            }
            if self.detector.as_ref().is_none_or(|(f, _)| *f != chosen) {
                let mut readers = Vec::new();
                for (name, _) in self.families.iter().filter(|(_, on)| *on) {
                    let family = match tagsmith::builtin::get(name) {
                        Some(Ok(f)) => f,
                        Some(Err(e)) => return Err(e.to_string()),
                        None => return Err(format!("{name} is not a built-in family")),
                    };
                    readers.push(FamilyReader::shipped(family).map_err(|e| e.to_string())?);
                }
                if let Some((family, model, true)) = &self.design {
                    let stage2 = Stage2::load(model, family).map_err(|e| e.to_string())?;
                    readers.push(FamilyReader::new(family.clone(), stage2));
                }
                let stage1 = Stage1::from_bytes(SHIPPED_STAGE1, "shipped stage-1 model")
                    .map_err(|e| e.to_string())?;
                let detector = Detector::new(stage1, readers).map_err(|e| e.to_string())?;
                self.detector = Some((chosen, detector));
            }
            let (_, detector) = self.detector.as_mut().expect("loaded above");
            detector.options.propose.group.corner = self.corner_threshold;
            let clock = std::time::Instant::now();
            let (found, timings) = Detector::detect(detector, &image.gray);
            self.result = Some(DetectResult {
                found,
                timings,
                time_ms: clock.elapsed().as_secs_f64() * 1e3,
            });
            Ok(())
        }

        /// The detections in the CLI's `--json` format.
        pub fn detections_file(&self) -> Option<DetectionsFile> {
            let (image, result) = (self.image.as_ref()?, self.result.as_ref()?);
            let (_, detector) = self.detector.as_ref()?;
            Some(DetectionsFile {
                detector: BenchDetector::name(detector),
                images: vec![ImageDetections {
                    file: image.name.clone(),
                    time_ms: result.time_ms,
                    detections: result.found.iter().map(Found::detection).collect(),
                }],
            })
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

    /// An image file opened or dropped: decoded (with the CLI's size limits) and detected on.
    pub fn open_image(studio: &mut Studio, file: OpenedFile) {
        match tagsmith::image::decode(&file.bytes, &Default::default()) {
            Ok(gray) => {
                studio.detect.set_image(file.name.clone(), gray);
                studio.panel = super::super::Panel::Detect;
                studio.info(format!("opened {}", file.name));
            }
            Err(e) => studio.error(format!("{}: {e}", file.name)),
        }
    }

    pub fn show(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
        ui.horizontal_wrapped(|ui| {
            if ui.button("Open image…").clicked() {
                studio.files.request_open(Purpose::Image);
            }
            ui.label("Samples:");
            for (name, bytes) in SAMPLES {
                if ui.button(*name).clicked() {
                    open_image(
                        studio,
                        OpenedFile {
                            purpose: Purpose::Image,
                            name: name.to_string(),
                            path: None,
                            bytes: bytes.to_vec(),
                        },
                    );
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
            if let Some((family, _, on)) = &mut state.design {
                let label = format!("{} (the design's trained model)", family.name());
                if ui.checkbox(on, label).changed() {
                    state.stale = true;
                }
            }
            ui.separator();
            let slider = egui::Slider::new(&mut state.corner_threshold, 0.05..=0.95)
                .text("corner threshold");
            if ui
                .add(slider)
                .on_hover_text("stage 1's corner confidence: lower finds more, costs more time")
                .changed()
            {
                state.stale = true;
            }
        });
        if let Err(e) = studio.detect.refresh() {
            studio.error(e);
        }
        let state = &studio.detect;
        let (Some(image), Some(result)) = (&state.image, &state.result) else {
            ui.label("Open an image, drop one on the window, or pick a sample.");
            return;
        };
        ui.horizontal(|ui| {
            ui.label(format!(
                "{}: {} marker(s) in {:.0} ms (stage 1 {:.0} ms, {} ROI(s); stage 2 {:.0} ms)",
                image.name,
                result.found.len(),
                result.time_ms,
                result.timings.stage1_ms,
                result.timings.proposals,
                result.timings.stage2_ms
            ));
        });
        let mut save_json = false;
        let mut save_png = false;
        ui.horizontal(|ui| {
            save_json = ui.button("Save detections (JSON)…").clicked();
            save_png = ui.button("Save annotated image (PNG)…").clicked();
        });
        table(ui, &result.found);
        let tex = studio
            .textures
            .get_or_make(ctx, "detect-image", image.revision, || {
                Ok(gray_image(&image.gray))
            });
        if let Ok(tex) = tex {
            let size = Vec2::new(image.gray.width as f32, image.gray.height as f32);
            let scale = (ui.available_width() / size.x).min(1.5);
            let response = ui.image((tex.id(), size * scale));
            draw_overlays(ui, response.rect, scale, &result.found);
        }
        if save_json {
            save_detections(studio);
        }
        if save_png {
            save_annotated(studio);
        }
    }

    fn table(ui: &mut egui::Ui, found: &[Found]) {
        egui::Grid::new("detections")
            .striped(true)
            .num_columns(6)
            .show(ui, |ui| {
                for head in [
                    "family",
                    "ID",
                    "corrected",
                    "reprojection px",
                    "distance mm",
                    "refined",
                ] {
                    ui.strong(head);
                }
                ui.end_row();
                for f in found {
                    let m = &f.marker;
                    ui.label(f.family.as_str());
                    ui.label(m.id.to_string());
                    ui.label(m.corrected_errors.to_string());
                    match &m.pose {
                        Some(p) => {
                            ui.label(format!("{:.2}", p.rms_px));
                            let t = p.pose.translation;
                            ui.label(format!("{:.0}", 1000.0 * t.norm()));
                        }
                        None => {
                            ui.label("–");
                            ui.label("–");
                        }
                    }
                    let refined = m.refinement.as_ref().is_some_and(|r| r.refined);
                    ui.label(if refined { "yes" } else { "no" });
                    ui.end_row();
                }
            });
    }

    fn draw_overlays(ui: &egui::Ui, rect: Rect, scale: f32, found: &[Found]) {
        let painter = ui.painter_at(rect);
        let at = |p: [f64; 2]| {
            // Pixel centres at whole coordinates: pixel 0 covers [0, 1) on screen.
            Pos2::new(
                rect.min.x + (p[0] as f32 + 0.5) * scale,
                rect.min.y + (p[1] as f32 + 0.5) * scale,
            )
        };
        let outline = |q: &[[f64; 2]; 4], colour: Color32| {
            let points: Vec<Pos2> = q.iter().map(|&p| at(p)).collect();
            painter.add(egui::Shape::closed_line(points, Stroke::new(1.5, colour)));
        };
        for f in found {
            outline(&f.proposal.corners, Color32::from_rgb(255, 220, 0));
            outline(&f.marker.corners, Color32::from_rgb(0, 200, 60));
            painter.circle_stroke(at(f.marker.corners[0]), 5.0, Stroke::new(1.5, Color32::RED));
            for k in &f.marker.keypoints {
                painter.circle_filled(at([k.x, k.y]), 2.0, category_colour(k.category));
            }
            let centre = tagsmith::detect::stage1::group::quad_centre(&f.marker.corners);
            painter.text(
                at(centre),
                egui::Align2::CENTER_CENTER,
                format!("#{}", f.marker.id),
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
        let overlays: Vec<Overlay> = result
            .found
            .iter()
            .map(|f| Overlay {
                roi: &f.proposal.corners,
                corners: Some(&f.marker.corners),
                keypoints: f
                    .marker
                    .keypoints
                    .iter()
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
}
