//! The Compare panel: "which design suits my scene". The user picks 2–4 families that detect
//! (shipped weights, a trained model, or the shipped model of their layout) and describes the
//! scene; every family reads the same rendered scenes (`tagsmith::eval::designs`), and the panel plots recall and pose errors
//! against the swept condition as the run goes, with the verdict, a table and the worst reads.
//! `tagsmith eval compare-designs` computes the same report from the command line.

use super::families::Origin;
use super::train::attached_model;
use super::Studio;
use egui::DragValue;
use egui_plot::{Legend, Line, Plot, PlotPoints};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use tagsmith::detect::stage2::Stage2;
use tagsmith::detect::{BenchDetector, Detector};
use tagsmith::eval::designs::{detector_for, DesignReport, DesignRun, WorstCase};
use tagsmith::eval::plot::COLOURS as PALETTE;
use tagsmith::eval::scenario::{Condition, Scenario, Sweep};
use tagsmith::family::Family;
use tagsmith::geometry::Quad;

/// At most this many designs at once: the plots stay readable.
pub const MAX_DESIGNS: usize = 4;

/// What the run has produced so far, as the panel draws it.
#[derive(Clone, serde::Serialize, serde::Deserialize)]
pub struct Snapshot {
    pub report: DesignReport,
    pub worst: Vec<WorstCase>,
}

/// A run in progress. On the desktop it steps on a thread of its own, in a browser in a web
/// worker of its own ([`super::offload::web`]); either publishes a snapshot after each scene.
struct Running {
    snapshot: Arc<Mutex<Option<Snapshot>>>,
    cancel: Arc<AtomicBool>,
    finished: Arc<Mutex<Option<Result<(), String>>>>,
    /// Dropping it ends the run.
    #[cfg(target_arch = "wasm32")]
    worker: Option<super::offload::web::WebWorker>,
}

/// A comparison of families read with shipped weights (built-ins, and the user's families on a
/// shipped model's layout), as a browser's worker runs it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct CompareRequest {
    pub scenario: Scenario,
    pub families: Vec<tagsmith::family::FamilySpec>,
}

/// Runs `request` to its end, handing out the report after each scene.
pub fn run_shipped(
    request: CompareRequest,
    mut publish: impl FnMut(Snapshot),
) -> Result<(), String> {
    let mut families = Vec::new();
    for spec in request.families {
        let family = Family::from_spec(spec).map_err(|e| e.to_string())?;
        let stage2 = Stage2::shipped(&family)
            .ok_or(format!("{} has no shipped weights", family.name()))?
            .map_err(|e| e.to_string())?;
        families.push((family, stage2));
    }
    let (mut run, mut detectors) = prepare(request.scenario, families)?;
    while !run.finished() {
        publish(step(&mut run, &mut detectors)?);
    }
    Ok(())
}

/// The run and a detector per design.
fn prepare(
    scenario: Scenario,
    families: Vec<(Family, Stage2)>,
) -> Result<(DesignRun, Vec<Detector>), String> {
    let mut detectors = Vec::new();
    let mut designs = Vec::new();
    for (family, stage2) in families {
        let detector =
            detector_for(family.clone(), stage2, &scenario).map_err(|e| e.to_string())?;
        detectors.push(detector);
        designs.push(family);
    }
    let run = DesignRun::new(scenario, designs).map_err(|e| e.to_string())?;
    Ok((run, detectors))
}

pub struct CompareState {
    /// Family names ticked for the comparison.
    pub chosen: Vec<String>,
    pub scenario: Scenario,
    /// The swept condition, and its values as the user typed them.
    pub sweep: Condition,
    pub sweep_values: String,
    running: Option<Running>,
    /// The last run's report (live while it runs) and its worst reads.
    pub result: Option<Snapshot>,
    pub error: Option<String>,
    /// The worst reads' textures, and the scenes read when they were made.
    thumbnails: Vec<egui::TextureHandle>,
    thumbnails_at: usize,
}

impl Default for CompareState {
    fn default() -> Self {
        let mut scenario = Scenario::example(0.3);
        // A scene the panel finishes in about a minute on a laptop: a VGA camera at 70°.
        scenario.name = "my scene".into();
        scenario.camera.width = 640;
        scenario.camera.height = 480;
        scenario.camera.fov_deg = Some(70.0);
        scenario.distance_m = [0.3, 0.6];
        scenario.scenes = 20;
        Self {
            chosen: vec!["apriltag-36h11".into(), "apriltag-xo-36h11".into()],
            sweep: Condition::Distance,
            sweep_values: "0.5, 1, 1.5, 2, 2.5".into(),
            scenario,
            running: None,
            result: None,
            error: None,
            thumbnails: Vec::new(),
            thumbnails_at: 0,
        }
    }
}

/// The swept values typed as "0.5, 1, 2": numbers split by commas or spaces.
pub fn parse_values(text: &str) -> Result<Vec<f64>, String> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|t| !t.is_empty())
        .map(|t| {
            t.parse::<f64>()
                .map_err(|_| format!("swept values: {t:?} is not a number"))
        })
        .collect()
}

impl CompareState {
    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// The scenario as the form describes it, checked.
    pub fn scenario(&self) -> Result<Scenario, String> {
        let mut s = self.scenario.clone();
        s.sweeps = vec![Sweep {
            condition: self.sweep,
            values: parse_values(&self.sweep_values)?,
        }];
        s.validate().map_err(|e| format!("scenario: {e}"))?;
        Ok(s)
    }

    /// Starts a run of the ticked families (found in `families`, each with its weights).
    pub fn start(
        &mut self,
        families: Vec<(Family, Stage2)>,
        ctx: &egui::Context,
    ) -> Result<(), String> {
        let scenario = self.scenario()?;
        #[cfg(target_arch = "wasm32")]
        let specs: Vec<_> = families.iter().map(|(f, _)| f.spec().clone()).collect();
        let (run, detectors) = prepare(scenario.clone(), families)?;
        let snapshot = Arc::new(Mutex::new(Some(Snapshot {
            report: run.report(),
            worst: Vec::new(),
        })));
        let cancel = Arc::new(AtomicBool::new(false));
        let finished = Arc::new(Mutex::new(None));
        self.result = None;
        self.error = None;
        self.thumbnails.clear();
        #[cfg(not(target_arch = "wasm32"))]
        {
            let (published, stop, ended) = (snapshot.clone(), cancel.clone(), finished.clone());
            let repaint = ctx.clone();
            std::thread::spawn(move || {
                let (mut run, mut detectors) = (run, detectors);
                // A panic would otherwise leave the panel waiting for an end forever.
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    while !run.finished() && !stop.load(Ordering::Relaxed) {
                        let next = step(&mut run, &mut detectors)?;
                        *published.lock().unwrap_or_else(|p| p.into_inner()) = Some(next);
                        repaint.request_repaint();
                    }
                    Ok(())
                }))
                .unwrap_or_else(|_| Err("the comparison failed unexpectedly (a panic)".into()));
                *ended.lock().unwrap_or_else(|p| p.into_inner()) = Some(outcome);
            });
            self.running = Some(Running {
                snapshot,
                cancel,
                finished,
            });
        }
        #[cfg(target_arch = "wasm32")]
        {
            use super::offload::web::{FromWorker, ToWorker, WebWorker};
            // The worker builds its own run and detectors from the shipped weights; these
            // checked that it can.
            drop((run, detectors));
            let (published, ended) = (snapshot.clone(), finished.clone());
            let worker = WebWorker::spawn(ctx, move |message| match message {
                FromWorker::Compared { snapshot, .. } => {
                    *published.lock().unwrap_or_else(|p| p.into_inner()) = Some(snapshot)
                }
                FromWorker::Ended { outcome, .. } => {
                    *ended.lock().unwrap_or_else(|p| p.into_inner()) = Some(outcome)
                }
                FromWorker::Failed(e) => {
                    *ended.lock().unwrap_or_else(|p| p.into_inner()) = Some(Err(e))
                }
                _ => {}
            })?;
            let request = CompareRequest {
                scenario,
                families: specs,
            };
            worker.post(1, &ToWorker::Compare(request), &[]);
            self.running = Some(Running {
                snapshot,
                cancel,
                finished,
                worker: Some(worker),
            });
        }
        Ok(())
    }

    pub fn cancel(&mut self) {
        if let Some(r) = &self.running {
            r.cancel.store(true, Ordering::Relaxed);
        }
    }

    /// Takes what the run has published; returns a message once it ends.
    pub fn poll(&mut self) -> Option<Result<String, String>> {
        let running = self.running.as_mut()?;
        // A worker cannot be asked to stop between scenes: cancelling ends it.
        #[cfg(target_arch = "wasm32")]
        if running.cancel.load(Ordering::Relaxed) && running.worker.take().is_some() {
            let mut ended = running.finished.lock().unwrap_or_else(|p| p.into_inner());
            ended.get_or_insert(Ok(()));
        }
        // The end is read before the last snapshot: the run publishes its snapshot before it
        // ends, so a snapshot taken after the end is the final one.
        let ended = running
            .finished
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take();
        if let Some(s) = running
            .snapshot
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
        {
            self.result = Some(s);
        }
        let ended = ended?;
        let cancelled = running.cancel.load(Ordering::Relaxed);
        self.running = None;
        let done = self.result.as_ref().map_or(0, |s| s.report.scenes_done);
        Some(match ended {
            Ok(()) if cancelled => Ok(format!("comparison cancelled after {done} scenes")),
            Ok(()) => Ok(format!("comparison finished: {done} scenes per design")),
            Err(e) => Err(e),
        })
    }
}

/// One scene for every design, then the report so far.
fn step(run: &mut DesignRun, detectors: &mut [Detector]) -> Result<Snapshot, String> {
    let mut each: Vec<&mut dyn BenchDetector> = detectors
        .iter_mut()
        .map(|d| d as &mut dyn BenchDetector)
        .collect();
    run.step(&mut each).map_err(|e| e.to_string())?;
    Ok(Snapshot {
        report: run.report(),
        worst: run.worst_cases().to_vec(),
    })
}

/// The families that detect, by name, with where their weights come from.
fn candidates(studio: &Studio) -> Vec<(String, Option<std::path::PathBuf>)> {
    (studio.library.entries.iter())
        .filter(|e| e.detection().0)
        .map(|e| {
            let file = match &e.origin {
                Origin::Builtin => None,
                Origin::UserFolder(p) => Some(p.clone()),
                Origin::Opened { path, .. } => path.clone(),
            };
            (e.spec.name.clone(), file)
        })
        .collect()
}

/// The ticked families with their weights.
fn load_chosen(studio: &Studio) -> Result<Vec<(Family, Stage2)>, String> {
    let candidates = candidates(studio);
    let mut out = Vec::new();
    for name in &studio.compare.chosen {
        let Some((_, file)) = candidates.iter().find(|(n, _)| n == name) else {
            return Err(format!("{name} has no weights: train them in Train"));
        };
        let entry = (studio.library.entries.iter())
            .find(|e| &e.spec.name == name)
            .expect("a candidate is an entry");
        let family = Family::from_spec(entry.spec.clone()).map_err(|e| e.to_string())?;
        // A user's family reads with its trained model, else with the shipped model of its
        // layout (what `Entry::detection` offered it for).
        let trained = file
            .as_ref()
            .map(|f| attached_model(f))
            .filter(|m| m.is_file());
        let stage2 = match trained {
            Some(model) => Stage2::load(&model, &family).map_err(|e| e.to_string())?,
            None => Stage2::shipped(&family)
                .ok_or(format!("{name} has no shipped weights"))?
                .map_err(|e| e.to_string())?,
        };
        out.push((family, stage2));
    }
    Ok(out)
}

/// Runs the comparison the form describes for the ticked families: the Run button, and a link
/// in the browser (`#compare=…`).
pub fn run_chosen(studio: &mut Studio, ctx: &egui::Context) -> Result<(), String> {
    let chosen = load_chosen(studio)?;
    studio.compare.start(chosen, ctx)?;
    log::info!(
        "comparing {} in the background",
        studio.compare.chosen.join(", ")
    );
    Ok(())
}

pub fn show(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
    if let Some(ended) = studio.compare.poll() {
        match ended {
            Ok(m) => {
                log::info!("{m}");
                studio.info(m)
            }
            Err(e) => {
                log::error!("comparison stopped: {e}");
                studio.error(format!("comparison stopped: {e}"))
            }
        }
    }
    if studio.compare.is_running() {
        ctx.request_repaint_after(std::time::Duration::from_millis(100));
    }
    ui.heading("Compare designs under your scene");
    let export = egui::ScrollArea::vertical()
        .show(ui, |ui| {
            settings(studio, ui);
            ui.separator();
            results(&mut studio.compare, ui, ctx)
        })
        .inner;
    if let Some(export) = export {
        save(studio, export);
    }
}

/// What the user asked to export.
enum Export {
    Csv,
    Plots,
}

/// Writes an export through the studio's file access (a dialog on the desktop, downloads in a
/// browser), saying where it went.
fn save(studio: &mut Studio, export: Export) {
    let Some(snapshot) = &studio.compare.result else {
        return;
    };
    let files: Result<Vec<(String, Vec<u8>)>, String> = match export {
        Export::Csv => Ok(vec![(
            "designs.csv".into(),
            snapshot.report.csv().into_bytes(),
        )]),
        Export::Plots => (snapshot.report.plots().into_iter())
            .map(|(name, svg)| {
                let png = tagsmith::render::raster::rasterize_svg(&svg, 960)
                    .map_err(|e| e.to_string())?
                    .encode_png()
                    .map_err(|e| e.to_string())?;
                Ok((name.replace(".svg", ".png"), png))
            })
            .collect(),
    };
    let saved = files.and_then(|files| {
        let mut written = Vec::new();
        for (name, bytes) in files {
            if let Some(at) = studio.files.save_as(&name, &bytes)? {
                written.push(at);
            }
        }
        Ok(written)
    });
    match saved {
        Ok(written) if written.is_empty() => {}
        Ok(written) => studio.info(format!("saved {}", written.join(", "))),
        Err(e) => studio.error(format!("export failed: {e}")),
    }
}

fn settings(studio: &mut Studio, ui: &mut egui::Ui) {
    let running = studio.compare.is_running();
    let candidates = candidates(studio);
    let c = &mut studio.compare;
    ui.add_enabled_ui(!running, |ui| {
        ui.horizontal_wrapped(|ui| {
            ui.label(format!("Designs (2–{MAX_DESIGNS}, with weights):"));
            for (name, _) in &candidates {
                let mut on = c.chosen.contains(name);
                let full = c.chosen.len() >= MAX_DESIGNS && !on;
                if ui
                    .add_enabled(!full, egui::Checkbox::new(&mut on, name))
                    .changed()
                {
                    if on {
                        c.chosen.push(name.clone());
                    } else {
                        c.chosen.retain(|n| n != name);
                    }
                }
            }
        });
        let s = &mut c.scenario;
        egui::Grid::new("compare-scenario")
            .num_columns(2)
            .show(ui, |ui| {
                value_row(ui, "Scene name", egui::TextEdit::singleline(&mut s.name));
                value_row(
                    ui,
                    "Print size (mm)",
                    DragValue::new(&mut s.side_mm).range(1.0..=1000.0),
                );
                let width = DragValue::new(&mut s.camera.width).range(16..=8192);
                value_row(ui, "Camera width (px)", width);
                let height = DragValue::new(&mut s.camera.height).range(16..=8192);
                value_row(ui, "Camera height (px)", height);
                let mut fov = s.camera.fov_deg.unwrap_or(70.0);
                let fov_drag = DragValue::new(&mut fov).range(2.0..=178.0);
                if value_row(ui, "Field of view (° diagonal)", fov_drag).changed() {
                    s.camera.fov_deg = Some(fov);
                    s.camera.focal_px = None;
                }
                range_row(ui, "Distance (m)", &mut s.distance_m, 0.01..=100.0, 0.01);
                range_row(ui, "View angle (°)", &mut s.angle_deg, 0.0..=85.0, 1.0);
                range_row(ui, "Blur sigma (px)", &mut s.blur_px, 0.0..=20.0, 0.1);
                range_row(ui, "Motion blur (px)", &mut s.motion_px, 0.0..=60.0, 1.0);
                range_row(ui, "Noise sigma", &mut s.noise_sigma, 0.0..=300.0, 1.0);
                range_row(
                    ui,
                    "Marker black (gray)",
                    &mut s.black_level,
                    0.0..=255.0,
                    1.0,
                );
                range_row(
                    ui,
                    "Marker white (gray)",
                    &mut s.white_level,
                    1.0..=255.0,
                    1.0,
                );
                ui.label("Background");
                ui.horizontal(|ui| {
                    use tagsmith::synth::BackgroundKind;
                    ui.radio_value(&mut s.background, BackgroundKind::Clutter, "cluttered");
                    ui.radio_value(&mut s.background, BackgroundKind::Plain, "plain wall");
                });
                ui.end_row();
                let markers = DragValue::new(&mut s.markers_per_image).range(1..=20);
                value_row(ui, "Markers per image", markers);
                let sweep = ui.label("Sweep");
                ui.horizontal(|ui| {
                    egui::ComboBox::from_id_salt("compare-sweep")
                        .selected_text(c.sweep.label())
                        .show_ui(ui, |ui| {
                            for condition in Condition::ALL {
                                ui.selectable_value(&mut c.sweep, condition, condition.label());
                            }
                        })
                        .response
                        .labelled_by(sweep.id);
                    let label = ui.label("values");
                    ui.text_edit_singleline(&mut c.sweep_values)
                        .labelled_by(label.id);
                });
                ui.end_row();
                value_row(
                    ui,
                    "Scenes per value",
                    DragValue::new(&mut s.scenes).range(1..=1000),
                );
                value_row(ui, "Seed", DragValue::new(&mut s.seed));
            });
    });
    ui.horizontal(|ui| {
        if running {
            if ui.button("Cancel comparison").clicked() {
                studio.compare.cancel();
            }
            if let Some(s) = &studio.compare.result {
                let r = &s.report;
                ui.add(
                    egui::ProgressBar::new(r.scenes_done as f32 / r.scenes.max(1) as f32).text(
                        format!("{} of {} scenes per design", r.scenes_done, r.scenes),
                    ),
                );
            }
        } else if ui.button("Run comparison").clicked() {
            if let Err(e) = run_chosen(studio, ui.ctx()) {
                studio.compare.error = Some(e);
            }
        }
    });
    if let Some(e) = &studio.compare.error {
        ui.colored_label(ui.visuals().error_fg_color, e);
    }
}

/// A grid row: the label, and the widget named by it (for screen readers and tests).
fn value_row(ui: &mut egui::Ui, label: &str, widget: impl egui::Widget) -> egui::Response {
    let label = ui.label(label);
    let response = ui.add(widget).labelled_by(label.id);
    ui.end_row();
    response
}

fn range_row(
    ui: &mut egui::Ui,
    label: &str,
    r: &mut [f64; 2],
    limits: std::ops::RangeInclusive<f64>,
    speed: f64,
) {
    let label = ui.label(label);
    ui.horizontal(|ui| {
        ui.add(
            egui::DragValue::new(&mut r[0])
                .range(limits.clone())
                .speed(speed),
        )
        .labelled_by(label.id);
        let to = ui.label("to");
        ui.add(egui::DragValue::new(&mut r[1]).range(limits).speed(speed))
            .labelled_by(to.id);
    });
    ui.end_row();
}

fn results(c: &mut CompareState, ui: &mut egui::Ui, ctx: &egui::Context) -> Option<Export> {
    let Some(snapshot) = &c.result else {
        ui.label("Run a comparison to see recall and pose errors against the swept condition.");
        return None;
    };
    let mut export = None;
    let report = &snapshot.report;
    ui.heading("Verdict");
    for v in &report.verdict {
        ui.label(&v.sentence);
    }
    // The run's own condition: the sweep box may have changed since.
    let x_label = (report.rows.first())
        .and_then(|r| r.condition)
        .map_or("scenes", Condition::label);
    let width = (ui.available_width() / 3.0 - 8.0).max(200.0);
    ui.horizontal(|ui| {
        for (id, title, pick) in [
            ("compare-recall", "recall (%)", 0),
            (
                "compare-position",
                "position error mm (median, p99 dashed)",
                1,
            ),
            (
                "compare-rotation",
                "rotation error ° (median, p99 dashed)",
                2,
            ),
        ] {
            ui.vertical(|ui| {
                ui.label(title);
                Plot::new(id)
                    .legend(Legend::default())
                    .width(width)
                    .height(220.0)
                    .x_axis_label(x_label)
                    .show(ui, |plot| {
                        for (k, family) in report.families.iter().enumerate() {
                            let [r, g, b] = PALETTE[k % PALETTE.len()];
                            let colour = egui::Color32::from_rgb(r, g, b);
                            let rows = || report.rows.iter().filter(|r| &r.family == family);
                            let series = |tail: bool| -> Vec<[f64; 2]> {
                                rows()
                                    .filter_map(|r| {
                                        let stats = match pick {
                                            0 => return Some([r.value, 100.0 * r.recall]),
                                            1 => r.position_mm,
                                            _ => r.rotation_deg,
                                        }?;
                                        Some([r.value, if tail { stats.p99 } else { stats.median }])
                                    })
                                    .collect()
                            };
                            plot.line(
                                Line::new(family.clone(), PlotPoints::new(series(false)))
                                    .color(colour),
                            );
                            if pick > 0 {
                                plot.line(
                                    Line::new(
                                        format!("{family} p99"),
                                        PlotPoints::new(series(true)),
                                    )
                                    .color(colour)
                                    .style(egui_plot::LineStyle::dashed_loose()),
                                );
                            }
                        }
                    });
            });
        }
    });
    ui.horizontal(|ui| {
        if ui.button("Export CSV").clicked() {
            export = Some(Export::Csv);
        }
        if ui.button("Export plots (PNG)").clicked() {
            export = Some(Export::Plots);
        }
    });
    egui::Grid::new("compare-table")
        .striped(true)
        .num_columns(7)
        .show(ui, |ui| {
            for h in [
                "design",
                "value",
                "recall",
                "position mm (med / p95 / p99)",
                "rotation ° (med / p95 / p99)",
                "flips",
                "ms/image",
            ] {
                ui.strong(h);
            }
            ui.end_row();
            let tail = |s: &Option<tagsmith::eval::score::Stats>| {
                s.map_or("–".to_string(), |s| {
                    format!("{:.2} / {:.2} / {:.2}", s.median, s.p95, s.p99)
                })
            };
            for r in &report.rows {
                ui.label(&r.family);
                ui.label(format!("{}", r.value));
                ui.label(format!("{:.1} % of {}", 100.0 * r.recall, r.markers));
                ui.label(tail(&r.position_mm));
                ui.label(tail(&r.rotation_deg));
                ui.label(r.flips.to_string());
                ui.label(format!("{:.0}", r.time_ms));
                ui.end_row();
            }
        });
    ui.heading("Worst reads");
    ui.label("Green: the true outline; red: what the detector read (none: missed).");
    if c.thumbnails.len() != snapshot.worst.len() || c.thumbnails_at != report.scenes_done {
        c.thumbnails_at = report.scenes_done;
        c.thumbnails = (snapshot.worst.iter().enumerate())
            .map(|(i, w)| {
                let image = egui::ColorImage::from_gray(
                    [w.crop.width as usize, w.crop.height as usize],
                    &w.crop.pixels,
                );
                ctx.load_texture(format!("compare-worst-{i}"), image, Default::default())
            })
            .collect();
    }
    ui.horizontal_wrapped(|ui| {
        for (w, texture) in snapshot.worst.iter().zip(&c.thumbnails) {
            ui.vertical(|ui| {
                let side = 120.0;
                let scale = side / w.crop.width.max(w.crop.height) as f32;
                let size = egui::vec2(w.crop.width as f32, w.crop.height as f32) * scale;
                let response = ui.image((texture.id(), size));
                let at = response.rect.min;
                let to_screen =
                    |p: [f64; 2]| at + egui::vec2(p[0] as f32 * scale, p[1] as f32 * scale);
                let outline = |q: &Quad, colour: egui::Color32| {
                    let mut points: Vec<egui::Pos2> = q.iter().map(|&p| to_screen(p)).collect();
                    points.push(points[0]);
                    egui::Shape::line(points, egui::Stroke::new(1.5, colour))
                };
                // Clipped to the thumbnail: a marker partly outside its scene reaches past it.
                let painter = ui.painter_at(response.rect);
                painter.add(outline(&w.truth, egui::Color32::GREEN));
                if let Some(read) = &w.read {
                    painter.add(outline(read, egui::Color32::RED));
                }
                let what = match w.group {
                    tagsmith::eval::set::Group::Scenario {
                        value,
                        condition: Some(c),
                    } => format!("{} {value}", c.name()),
                    _ => String::new(),
                };
                let family = &report.families[w.family];
                let verdict = match (&w.read, w.rotation_deg) {
                    (None, _) => "missed".to_string(),
                    (Some(_), Some(deg)) => format!("{deg:.1}° off"),
                    (Some(_), None) => "read, no pose".to_string(),
                };
                ui.small(format!("{family}\n{what}: {verdict}"));
            });
        }
    });
    export
}
