//! The Train panel (desktop): train stage 2 for the design being edited — or stage 1 for it
//! alone — with the defaults that made the shipped models, in the background through the same
//! `tagsmith::train` loop as `tagsmith train` (atomic checkpoints, resume), with live loss curves
//! per term (egui_plot), validation figures, samples/s, data wait and ETA. A finished run's model
//! is attached to the family: copied next to the family file as `NAME.stage2.bin`, where the
//! Detect panel finds it.
//!
//! Training is desktop-only; the web build's panel says so.

#[cfg(not(target_arch = "wasm32"))]
pub use desktop::*;

/// Nothing to keep where the panel only explains (a struct, not a unit, so the studio builds it
/// the same way on every target).
#[cfg(target_arch = "wasm32")]
#[derive(Default)]
pub struct TrainState {
    _none: (),
}

#[cfg(target_arch = "wasm32")]
pub fn show(_studio: &mut super::Studio, ui: &mut egui::Ui, _ctx: &egui::Context) {
    ui.heading("Train");
    ui.label("Training runs in the desktop studio and in `tagsmith train`, not in a browser.");
}

/// Where a family's own stage-2 model lives: next to its family file.
pub fn attached_model(family_file: &std::path::Path) -> std::path::PathBuf {
    tagsmith::detect::model_file::attached_to(family_file)
}

#[cfg(not(target_arch = "wasm32"))]
mod desktop {
    use super::super::job::Job;
    use super::super::Studio;
    use egui_plot::{Legend, Line, Plot, PlotPoints, Points};
    use std::collections::BTreeMap;
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::{Arc, Mutex};
    use std::time::Instant;
    use tagsmith::detect::stage2::model_file::{MAX_STEPS, WIDTHS};
    use tagsmith::detect::stage2::{fine_tune_start, FineTuneStart};
    use tagsmith::family::Family;
    use tagsmith::train::stage::{Picture, TrainStage};
    use tagsmith::train::stage1::RoiStage;
    use tagsmith::train::stage2::KeypointStage;
    use tagsmith::train::{self, Event, TrainConfig};

    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum StageChoice {
        Keypoints,
        Roi,
    }

    /// What the user set up for the next run.
    #[derive(Debug, Clone, PartialEq)]
    pub struct Settings {
        pub stage: StageChoice,
        pub steps: u64,
        pub batch: usize,
        pub width: usize,
        pub learning_rate: f64,
        /// Stage 2 starts from a shipped model ([`fine_tune_start`]) where the design's patch
        /// fits one, at [`FINE_TUNE_STEPS`] and [`FINE_TUNE_LEARNING_RATE`].
        pub fine_tune: bool,
        /// Where the run writes its checkpoints, model and report; empty: the default folder
        /// beside the user's families ([`run_folder`]).
        pub folder: String,
    }

    /// A fine-tune's steps and learning rate, whichever shipped model it starts from: the
    /// shipped grid model's own (3000 steps at 0.0003 from 36h11's weights, BENCHMARKS.md "One
    /// model for one layout").
    pub const FINE_TUNE_STEPS: u64 = 3000;
    pub const FINE_TUNE_LEARNING_RATE: f64 = 0.0003;

    impl Default for Settings {
        /// The shipped stage-2 models' settings, from fresh weights.
        fn default() -> Self {
            let c = TrainConfig::default();
            Self {
                stage: StageChoice::Keypoints,
                steps: c.steps,
                batch: c.batch,
                width: c.width,
                learning_rate: c.learning_rate,
                fine_tune: false,
                folder: String::new(),
            }
        }
    }

    impl Settings {
        /// Fine-tuning from a shipped model, or (`false`) training from fresh weights:
        /// each with its own steps and learning rate.
        pub fn set_fine_tune(&mut self, on: bool) {
            let fresh = Self::default();
            self.fine_tune = on;
            (self.steps, self.learning_rate) = if on {
                (FINE_TUNE_STEPS, FINE_TUNE_LEARNING_RATE)
            } else {
                (fresh.steps, fresh.learning_rate)
            };
        }
    }

    /// Points per loss curve, between this and twice this (a 10 500-step run has 5 terms:
    /// 52 500 points unthinned; the plot is about 650 px wide).
    pub const MAX_CURVE: usize = 400;

    /// Neighbouring points averaged in pairs.
    fn halve(curve: &[[f64; 2]]) -> Vec<[f64; 2]> {
        curve
            .chunks(2)
            .map(|pair| {
                let n = pair.len() as f64;
                let sum = pair
                    .iter()
                    .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
                [sum[0] / n, sum[1] / n]
            })
            .collect()
    }

    /// What the run has reported so far, shared with its thread.
    #[derive(Debug, Default, Clone)]
    pub struct Live {
        pub family: String,
        pub first_step: u64,
        pub step: u64,
        pub steps: u64,
        /// (step, value) per loss term, by name.
        pub losses: BTreeMap<String, Vec<[f64; 2]>>,
        /// (step, figures as JSON) of each validation.
        pub validation: Vec<(u64, serde_json::Value)>,
        pub samples_per_s: f64,
        pub data_wait: f64,
        pub last_checkpoint: Option<u64>,
        pub started: Option<Instant>,
        /// Steps per loss-curve point (doubles as the run grows) and each term's running sums
        /// (step, value, count) towards its next point.
        pub stride: u64,
        pending: BTreeMap<String, [f64; 3]>,
        /// The latest pictures: current training samples with their truth, validation samples
        /// with the network's findings (shared: `Live` is cloned every frame).
        pub pictures: Option<Arc<Pictures>>,
    }

    #[derive(Debug)]
    pub struct Pictures {
        pub step: u64,
        pub samples: Vec<Picture>,
        pub predictions: Vec<Picture>,
    }

    impl Live {
        /// Seconds to the end at the rate so far.
        pub fn eta_s(&self) -> Option<f64> {
            let done = self.step.checked_sub(self.first_step)?;
            let elapsed = self.started?.elapsed().as_secs_f64();
            (done > 0).then(|| elapsed / done as f64 * (self.steps - self.step) as f64)
        }

        fn record<M: serde::Serialize, L: serde::Serialize>(&mut self, event: Event<M, L>) {
            match event {
                Event::Started {
                    family,
                    first_step,
                    steps,
                    ..
                } => {
                    self.family = family;
                    self.first_step = first_step;
                    self.step = first_step;
                    self.steps = steps;
                    self.started = Some(Instant::now());
                }
                Event::Step {
                    step,
                    loss,
                    samples_per_s,
                    data_wait,
                } => {
                    self.step = step;
                    self.samples_per_s = samples_per_s;
                    self.data_wait = data_wait;
                    // Each stage has its own terms; their names come from the serialised struct.
                    if let Ok(serde_json::Value::Object(terms)) = serde_json::to_value(&loss) {
                        for (name, value) in terms {
                            if let Some(v) = value.as_f64() {
                                // Plotting cost grows with the points: each point is the
                                // mean of `stride` steps, and the stride doubles (the curve
                                // halved) whenever a curve reaches 2 × MAX_CURVE points, so
                                // every point of a curve covers as many steps.
                                let bin = self.pending.entry(name.clone()).or_default();
                                bin[0] += step as f64;
                                bin[1] += v;
                                bin[2] += 1.0;
                                if bin[2] as u64 >= self.stride.max(1) {
                                    let point = [bin[0] / bin[2], bin[1] / bin[2]];
                                    *bin = [0.0; 3];
                                    self.losses.entry(name).or_default().push(point);
                                }
                            }
                        }
                    }
                    if self.losses.values().any(|c| c.len() >= 2 * MAX_CURVE) {
                        let stride = self.stride.max(1) as f64;
                        for (name, curve) in self.losses.iter_mut() {
                            // An odd last point goes back to its term's running sums, so that
                            // every point after the halving covers twice the steps.
                            if curve.len() % 2 == 1 {
                                let [x, y] = curve.pop().expect("odd length");
                                let bin = self.pending.entry(name.clone()).or_default();
                                bin[0] += x * stride;
                                bin[1] += y * stride;
                                bin[2] += stride;
                            }
                            *curve = halve(curve);
                        }
                        self.stride = 2 * self.stride.max(1);
                    }
                }
                Event::Validated { step, metrics } => {
                    let figures = serde_json::to_value(&metrics).unwrap_or_default();
                    self.validation.push((step, figures));
                }
                Event::Checkpointed { step } => self.last_checkpoint = Some(step),
                Event::Pictured {
                    step,
                    samples,
                    predictions,
                } => {
                    self.pictures = Some(Arc::new(Pictures {
                        step,
                        samples,
                        predictions,
                    }))
                }
            }
        }
    }

    /// A run in the background.
    pub struct Running {
        pub job: Job<Result<String, String>>,
        pub live: Arc<Mutex<Live>>,
        stop: Arc<AtomicBool>,
        pub out: PathBuf,
        pub family_file: Option<PathBuf>,
    }

    #[derive(Default)]
    pub struct TrainState {
        pub settings: Settings,
        pub running: Option<Running>,
        /// The last run's figures, kept after it ends.
        pub last: Option<Live>,
        /// How the last run ended.
        pub outcome: Option<Result<String, String>>,
        /// The runs list while it is open.
        runs: Option<Vec<RunSummary>>,
        /// The design's run folder as last read (its report is not re-read every frame); dropped
        /// when a run starts or ends.
        this_run: Option<RunSummary>,
        /// Start was pressed on a folder with an unfinished run: waiting for "Start over".
        pub confirm_start_over: bool,
        /// The UI's recent frame times (ms) while a run trains: their median is shown.
        pub frame_times: std::collections::VecDeque<f32>,
        /// The user chose between fine-tuning and fresh weights: the panel stops choosing.
        pub fine_tune_chosen: bool,
    }

    impl TrainState {
        pub fn is_running(&self) -> bool {
            self.running.as_ref().is_some_and(|r| !r.job.is_finished())
        }

        /// Asks the run to stop after its current step; it writes a checkpoint first.
        pub fn stop(&self) {
            if let Some(r) = &self.running {
                r.stop.store(true, Ordering::Relaxed);
            }
        }

        pub fn live(&self) -> Option<Live> {
            match &self.running {
                Some(r) => Some(r.live.lock().unwrap_or_else(|e| e.into_inner()).clone()),
                None => self.last.clone(),
            }
        }

        /// Collects a finished run's outcome.
        fn poll(&mut self) -> Option<Result<String, String>> {
            let running = self.running.as_mut()?;
            let outcome = running.job.take()?.and_then(|r| r);
            let running = self.running.take().expect("checked above");
            self.last = Some(
                running
                    .live
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .clone(),
            );
            let outcome = outcome.and_then(|message| {
                // A complete run's model goes next to the family file, for Detect.
                match &running.family_file {
                    Some(file) if running.out.join("model.bin").exists() => {
                        let target = super::attached_model(file);
                        std::fs::copy(running.out.join("model.bin"), &target)
                            .map(|_| format!("{message}; model attached as {}", target.display()))
                            .map_err(|e| format!("{}: {e}", target.display()))
                    }
                    _ => Ok(message),
                }
            });
            self.outcome = Some(outcome.clone());
            self.runs = None;
            self.this_run = None;
            Some(outcome)
        }
    }

    /// The run folder of a family and stage: beside the user's families folder.
    pub fn run_folder(studio: &Studio, family: &str, stage: StageChoice) -> PathBuf {
        let chosen = studio.train.settings.folder.trim();
        if !chosen.is_empty() {
            return PathBuf::from(chosen);
        }
        let name = match stage {
            StageChoice::Keypoints => format!("{family}-keypoints"),
            StageChoice::Roi => format!("{family}-roi"),
        };
        match studio.files.user_folder() {
            Some(dir) => dir.with_file_name("runs").join(name),
            None => PathBuf::from("runs").join(name),
        }
    }

    /// A run folder as the runs list shows it, read from its `report.json` and checkpoint.
    #[derive(Debug, Clone, PartialEq)]
    pub struct RunSummary {
        pub folder: PathBuf,
        /// Steps done and asked for, from the report (`None`: no report yet: killed or running).
        pub steps: Option<(u64, u64)>,
        pub wall_s: Option<f64>,
        /// The last validation's figures, as text.
        pub validation: Option<String>,
        pub checkpoint: bool,
        pub model: bool,
    }

    impl RunSummary {
        pub fn read(folder: PathBuf) -> Self {
            // A regular file of bounded size: a FIFO in a runs folder must not hang the panel.
            let report: Option<serde_json::Value> =
                tagsmith::io::read_input(&folder.join("report.json"), tagsmith::io::MAX_TEXT_BYTES)
                    .ok()
                    .and_then(|b| serde_json::from_slice(&b).ok());
            let number = |v: &serde_json::Value, path: &str| v.pointer(path)?.as_f64();
            let steps = report.as_ref().and_then(|r| {
                Some((
                    number(r, "/steps")? as u64,
                    number(r, "/config/steps")? as u64,
                ))
            });
            let validation = report.as_ref().and_then(|r| {
                let last = r.pointer("/validation")?.as_array()?.last()?;
                Some(format!(
                    "step {}: {}",
                    last.get(0)?,
                    figures_text(last.get(1)?)
                ))
            });
            Self {
                steps,
                wall_s: report.as_ref().and_then(|r| number(r, "/total_wall_s")),
                validation,
                checkpoint: folder.join("checkpoint.bin").exists(),
                model: folder.join("model.bin").exists(),
                folder,
            }
        }

        /// Stopped or killed before its last step, with a checkpoint to continue from.
        pub fn unfinished(&self) -> bool {
            self.checkpoint && self.steps.is_none_or(|(done, asked)| done < asked)
        }
    }

    /// Every run folder beside the user's families, newest name order.
    pub fn runs(studio: &Studio) -> Vec<RunSummary> {
        let Some(dir) = studio.files.user_folder().map(|d| d.with_file_name("runs")) else {
            return Vec::new();
        };
        let mut folders: Vec<PathBuf> = std::fs::read_dir(dir)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .collect();
        folders.sort();
        folders.into_iter().map(RunSummary::read).collect()
    }

    /// Why the design cannot be trained yet, in the designer's words.
    pub fn blocker(studio: &Studio) -> Option<String> {
        let Some(design) = &studio.design else {
            return Some("Open or start a design in the Families panel first.".into());
        };
        if let Err(e) = design.validation() {
            return Some(format!(
                "The design has {} problem(s) to fix in the Designer first (the first: {}).",
                e.problems.len(),
                e.problems
                    .first()
                    .map(|p| format!("{}: {}", p.path, p.message))
                    .unwrap_or_default()
            ));
        }
        if design.is_dirty() || design.path.is_none() {
            return Some(
                "Save the design first (Save, Ctrl+S): a trained model belongs to a saved family \
                 file."
                    .into(),
            );
        }
        None
    }

    fn start(studio: &mut Studio, resume: bool) {
        let Some(design) = &studio.design else { return };
        let Ok(family) = design.validation().clone() else {
            return;
        };
        let family_file = design.path.clone();
        let settings = studio.train.settings.clone();
        let stage = settings.stage;
        let out = run_folder(studio, family.name(), settings.stage);
        let config = TrainConfig {
            steps: settings.steps,
            batch: settings.batch,
            width: settings.width,
            learning_rate: settings.learning_rate,
            // Small runs still checkpoint and validate a few times.
            checkpoint_every: (settings.steps / 10).clamp(1, 250),
            validate_every: (settings.steps / 10).clamp(1, 500),
            validation_patches: if settings.steps < 100 { 8 } else { 200 },
            ..TrainConfig::default()
        };
        let live = Arc::new(Mutex::new(Live::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let job = {
            let (live, stop, out) = (live.clone(), stop.clone(), out.clone());
            Job::start(move |reporter| {
                let with = RunWith {
                    config: &config,
                    out: &out,
                    resume,
                    stop: &stop,
                    live: &live,
                    reporter,
                };
                run(&family, &settings, with)
            })
        };
        studio.train.outcome = None;
        studio.train.this_run = None;
        studio.train.running = Some(Running {
            job,
            live,
            stop,
            out: out.clone(),
            family_file: (stage == StageChoice::Keypoints)
                .then_some(family_file)
                .flatten(),
        });
        studio.info(format!("training into {}", out.display()));
    }

    /// What a run needs besides its stage.
    struct RunWith<'a> {
        config: &'a TrainConfig,
        out: &'a std::path::Path,
        resume: bool,
        stop: &'a AtomicBool,
        live: &'a Mutex<Live>,
        reporter: &'a super::super::job::Reporter,
    }

    /// Which shipped model a fine-tune starts from, in the user's words.
    fn fine_tune_words(start: FineTuneStart) -> String {
        let name = start
            .asset
            .trim_start_matches("models/")
            .trim_end_matches(".stage2.bin");
        if start.fresh_class_head {
            format!("{name}, its trunk; the class head learns this design's categories afresh")
        } else {
            format!("{name}: the same number of categories as this design")
        }
    }

    fn run(family: &Family, settings: &Settings, with: RunWith) -> Result<String, String> {
        match settings.stage {
            StageChoice::Keypoints => {
                let stage = KeypointStage::new(family, with.config.width);
                match fine_tune_start(family).filter(|_| settings.fine_tune) {
                    Some(start) => {
                        let name = format!("the shipped model assets/{}", start.asset);
                        go(stage.starting_from(start.bytes().to_vec(), &name)?, with)
                    }
                    None => go(stage, with),
                }
            }
            StageChoice::Roi => go(
                RoiStage::for_families(vec![family.clone()], with.config.width),
                with,
            ),
        }
    }

    fn go<S: TrainStage>(stage: S, w: RunWith) -> Result<String, String> {
        let report = train::train(
            Arc::new(stage),
            w.config,
            w.out,
            w.resume,
            w.stop,
            &mut |e| {
                let mut l = w.live.lock().unwrap_or_else(|e| e.into_inner());
                l.record(e);
                w.reporter.progress(
                    l.step as f32 / l.steps.max(1) as f32,
                    format!("step {}/{}", l.step, l.steps),
                );
            },
        )
        .map_err(|e| e.to_string())?;
        Ok(if report.steps < w.config.steps {
            format!(
                "stopped at step {} (checkpoint kept: Resume continues)",
                report.steps
            )
        } else {
            format!("trained {} steps in {:.0} s", report.steps, report.wall_s)
        })
    }

    pub fn show(studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
        if let Some(outcome) = studio.train.poll() {
            match outcome {
                Ok(m) => studio.info(m),
                Err(e) => studio.error(format!("training stopped: {e}")),
            }
        }
        let blocker = blocker(studio);
        let running = studio.train.is_running();
        if let Some(why) = &blocker {
            ui.label(why.as_str());
        }
        let family_name = studio
            .design
            .as_ref()
            .map(|d| d.spec().name.clone())
            .unwrap_or_default();
        let shipped_start = (studio.design.as_ref())
            .and_then(|d| d.validation().as_ref().ok())
            .and_then(fine_tune_start);
        let fine_tunable = shipped_start.is_some();
        let chosen = &mut studio.train.fine_tune_chosen;
        let s = &mut studio.train.settings;
        // A design a shipped model fits starts from it, until the user says otherwise.
        if !running && s.fine_tune != fine_tunable && (!*chosen || !fine_tunable) {
            s.set_fine_tune(fine_tunable);
        }
        ui.add_enabled_ui(!running, |ui| {
            egui::Grid::new("train-settings")
                .num_columns(2)
                .show(ui, |ui| {
                    ui.label("Stage");
                    ui.horizontal(|ui| {
                        ui.radio_value(&mut s.stage, StageChoice::Keypoints, "keypoints (stage 2)");
                        ui.radio_value(
                            &mut s.stage,
                            StageChoice::Roi,
                            "ROI (stage 1, this family)",
                        );
                    });
                    ui.end_row();
                    if s.stage == StageChoice::Keypoints {
                        ui.label("Start from");
                        let mut on = s.fine_tune;
                        let response = ui
                            .add_enabled(
                                fine_tunable,
                                egui::Checkbox::new(&mut on, "a shipped model (fine-tune)"),
                            )
                            .on_disabled_hover_text(
                                "fresh weights: the design's patch is not the shipped models' size",
                            );
                        if response.changed() {
                            s.set_fine_tune(on);
                            *chosen = true;
                        }
                        ui.end_row();
                        if let Some(shipped) = shipped_start.filter(|_| s.fine_tune) {
                            ui.label("");
                            ui.weak(fine_tune_words(shipped));
                            ui.end_row();
                        }
                    }
                    let label = ui.label("Steps");
                    ui.add(egui::DragValue::new(&mut s.steps).range(1..=MAX_STEPS))
                        .labelled_by(label.id);
                    ui.end_row();
                    let label = ui.label("Batch");
                    ui.add(egui::DragValue::new(&mut s.batch).range(1..=256))
                        .labelled_by(label.id);
                    ui.end_row();
                    let label = ui.label("Width");
                    // A fine-tune keeps the model's width.
                    let fresh = !(s.fine_tune && s.stage == StageChoice::Keypoints);
                    ui.add_enabled(fresh, egui::DragValue::new(&mut s.width).range(WIDTHS))
                        .labelled_by(label.id);
                    ui.end_row();
                    let label = ui.label("Learning rate");
                    ui.add(
                        egui::DragValue::new(&mut s.learning_rate)
                            .range(1e-6..=1.0)
                            .speed(1e-4),
                    )
                    .labelled_by(label.id);
                    ui.end_row();
                    let label = ui.label("Run folder");
                    ui.add(
                        egui::TextEdit::singleline(&mut s.folder)
                            .hint_text("default: beside your families (shown below)")
                            .desired_width(360.0),
                    )
                    .labelled_by(label.id);
                    ui.end_row();
                });
            // The shipped stage-2 models: 10 500 steps of 16 at width 32 in about 51 minutes of
            // this machine's two cores (BENCHMARKS.md), ≈ 0.29 s per step.
            if s.stage == StageChoice::Keypoints {
                let minutes = s.steps as f64
                    * 0.29
                    * (s.batch as f64 / 16.0)
                    * (s.width as f64 / 32.0).powi(2)
                    / 60.0;
                ui.weak(format!(
                    "about {minutes:.0} min on two CPU cores (the shipped models' rate)"
                ));
            }
        });
        let can_start = blocker.is_none() && !running;
        let out = (!family_name.is_empty())
            .then(|| run_folder(studio, &family_name, studio.train.settings.stage));
        if studio.train.this_run.as_ref().map(|r| &r.folder) != out.as_ref() {
            studio.train.this_run = out.clone().map(RunSummary::read);
        }
        let this_run = studio.train.this_run.clone();
        let resumable = this_run.as_ref().is_some_and(|r| r.checkpoint);
        // After a quit or a crash mid-run: say so, and offer to carry on.
        if let Some(run) = this_run.as_ref().filter(|r| r.unfinished() && !running) {
            let at = run
                .steps
                .map(|(done, asked)| format!(" at step {done} of {asked}"))
                .unwrap_or_default();
            ui.colored_label(
                ui.visuals().warn_fg_color,
                format!(
                    "An unfinished run of {family_name} stopped{at}; its checkpoint is kept: \
                     Resume carries on from it."
                ),
            );
        }
        let unfinished = this_run.as_ref().is_some_and(|r| r.unfinished());
        ui.horizontal(|ui| {
            if ui
                .add_enabled(can_start, egui::Button::new("Start"))
                .clicked()
            {
                // A fresh start replaces the folder's checkpoint: never without asking.
                if unfinished {
                    studio.train.confirm_start_over = true;
                } else {
                    start(studio, false);
                }
            }
            if ui
                .add_enabled(can_start && resumable, egui::Button::new("Resume"))
                .on_hover_text("continue from the run folder's last checkpoint")
                .clicked()
            {
                start(studio, true);
            }
            if ui
                .add_enabled(running, egui::Button::new("Stop"))
                .on_hover_text("stop after the current step; a checkpoint is written first")
                .clicked()
            {
                studio.train.stop();
            }
            if let Some(o) = &out {
                ui.weak(format!("run folder: {}", o.display()));
            }
        });
        if studio.train.confirm_start_over && can_start {
            ui.horizontal(|ui| {
                ui.label("Starting afresh replaces the unfinished run's checkpoint.");
                if ui.button("Start over").clicked() {
                    studio.train.confirm_start_over = false;
                    start(studio, false);
                }
                if ui.button("Cancel").clicked() {
                    studio.train.confirm_start_over = false;
                }
            });
        }
        if running {
            ui.ctx()
                .request_repaint_after(std::time::Duration::from_millis(200));
        }
        runs_list(studio, ui);
        let Some(live) = studio.train.live() else {
            return;
        };
        ui.label(format!(
            "step {}/{}, {:.1} samples/s, data wait {:.0} %{}{}{}",
            live.step,
            live.steps,
            live.samples_per_s,
            100.0 * live.data_wait,
            live.eta_s()
                .filter(|_| running)
                .map(|s| format!(", ETA {:.0} min", s / 60.0))
                .unwrap_or_default(),
            live.last_checkpoint
                .map(|s| format!(", checkpoint at step {s}"))
                .unwrap_or_default(),
            frame_median(studio, running)
                .map(|ms| format!(", UI frame {ms:.1} ms (median)"))
                .unwrap_or_default(),
        ));
        if let Some((step, figures)) = live.validation.last() {
            ui.label(format!(
                "validation at step {step}: {}",
                figures_text(figures)
            ));
        }
        ui.columns(2, |columns| {
            Plot::new("losses")
                .legend(Legend::default())
                .height(240.0)
                .x_axis_label("step")
                .y_axis_label("loss")
                .show(&mut columns[0], |plot| {
                    for (name, points) in &live.losses {
                        plot.line(Line::new(name.as_str(), PlotPoints::from(points.clone())));
                    }
                });
            Plot::new("validation")
                .legend(Legend::default())
                .height(240.0)
                .x_axis_label("step")
                .y_axis_label("validation")
                .show(&mut columns[1], |plot| {
                    // Markers as well as lines: validations are few (one is no line at all).
                    // One colour per figure for both, so the legend shows it (not mixed grey).
                    for (i, (name, points)) in
                        validation_curves(&live.validation).into_iter().enumerate()
                    {
                        let colour = super::super::preview::category_colour(i);
                        plot.line(
                            Line::new(name.as_str(), PlotPoints::from(points.clone()))
                                .color(colour),
                        );
                        plot.points(
                            Points::new(name, PlotPoints::from(points))
                                .radius(3.0)
                                .color(colour),
                        );
                    }
                });
        });
        if let Some(pictures) = &live.pictures {
            let rows = [
                (
                    "Training samples with their truth",
                    "train-sample",
                    &pictures.samples,
                ),
                (
                    "Validation: what the network finds",
                    "train-prediction",
                    &pictures.predictions,
                ),
            ];
            for (title, key, row) in rows {
                let title = format!("{title} (step {})", pictures.step);
                picture_row(ui, ctx, studio, &title, key, pictures.step, row);
            }
        }
    }

    /// The median of the UI's last 200 frame times while training (eframe's CPU time per frame,
    /// layout and painting), `None` before there are any.
    fn frame_median(studio: &mut Studio, running: bool) -> Option<f32> {
        let times = &mut studio.train.frame_times;
        match (running, studio.frame_ms) {
            (true, Some(ms)) => {
                if times.len() == 200 {
                    times.pop_front();
                }
                times.push_back(ms);
            }
            (false, _) => times.clear(),
            _ => {}
        }
        let mut sorted: Vec<f32> = times.iter().copied().collect();
        sorted.sort_by(f32::total_cmp);
        sorted.get(sorted.len() / 2).copied()
    }

    /// The run folders with their reports; read when the list is opened, not every frame.
    fn runs_list(studio: &mut Studio, ui: &mut egui::Ui) {
        let header = egui::CollapsingHeader::new("Runs").default_open(false);
        let shown = header.show(ui, |ui| {
            if studio.train.runs.is_none() {
                studio.train.runs = Some(runs(studio));
            }
            let runs = studio.train.runs.clone().unwrap_or_default();
            if runs.is_empty() {
                ui.weak("No runs yet.");
            }
            egui::Grid::new("runs").striped(true).show(ui, |ui| {
                for head in ["run", "steps", "wall", "last validation", "state"] {
                    ui.strong(head);
                }
                ui.end_row();
                for run in &runs {
                    let name = run.folder.file_name().unwrap_or_default().to_string_lossy();
                    ui.label(name)
                        .on_hover_text(run.folder.display().to_string());
                    ui.label(
                        run.steps
                            .map(|(d, a)| format!("{d}/{a}"))
                            .unwrap_or_else(|| "–".into()),
                    );
                    ui.label(
                        run.wall_s
                            .map(|s| format!("{:.0} min", s / 60.0))
                            .unwrap_or_else(|| "–".into()),
                    );
                    ui.label(run.validation.clone().unwrap_or_else(|| "–".into()));
                    ui.label(if run.unfinished() {
                        "unfinished (resumable)"
                    } else if run.model {
                        "finished"
                    } else {
                        "no model"
                    });
                    ui.end_row();
                }
            });
        });
        // Closed: forget the list, so reopening it reads the folders again.
        if shown.body_returned.is_none() {
            studio.train.runs = None;
        }
    }

    /// Validation figures over steps, one curve per figure that is a fraction (recall,
    /// accuracy…), so they share the 0–1 axis; pixel errors are in the line above the plots.
    fn validation_curves(
        validation: &[(u64, serde_json::Value)],
    ) -> BTreeMap<String, Vec<[f64; 2]>> {
        let mut curves: BTreeMap<String, Vec<[f64; 2]>> = BTreeMap::new();
        for (step, figures) in validation {
            let serde_json::Value::Object(map) = figures else {
                continue;
            };
            for (name, value) in map {
                let is_fraction = ["recall", "accuracy", "precision", "rate"]
                    .iter()
                    .any(|w| name.contains(w));
                if let Some(v) = value.as_f64().filter(|_| is_fraction) {
                    curves
                        .entry(name.clone())
                        .or_default()
                        .push([*step as f64, v]);
                }
            }
        }
        curves
    }

    /// A row of pictures with their marks: outlines (corner 0 ringed) and keypoints coloured by
    /// category, as the Detect panel draws them.
    fn picture_row(
        ui: &mut egui::Ui,
        ctx: &egui::Context,
        studio: &mut Studio,
        title: &str,
        key: &str,
        step: u64,
        pictures: &[Picture],
    ) {
        use super::super::preview::{category_colour, gray_image};
        use egui::{Color32, Pos2, Stroke, Vec2};
        ui.label(title);
        ui.horizontal_wrapped(|ui| {
            for (i, picture) in pictures.iter().enumerate() {
                let tex = studio
                    .textures
                    .get_or_make(ctx, &format!("{key}-{i}"), step, || {
                        Ok(gray_image(&picture.image))
                    });
                let Ok(tex) = tex else { continue };
                let size = Vec2::new(picture.image.width as f32, picture.image.height as f32);
                let scale = 128.0 / size.x.max(size.y).max(1.0);
                let rect = ui.image((tex.id(), size * scale)).rect;
                let painter = ui.painter_at(rect);
                let at = |p: [f64; 2]| {
                    Pos2::new(
                        rect.min.x + (p[0] as f32 + 0.5) * scale,
                        rect.min.y + (p[1] as f32 + 0.5) * scale,
                    )
                };
                for quad in &picture.outlines {
                    let points: Vec<Pos2> = quad.iter().map(|&p| at(p)).collect();
                    painter.add(egui::Shape::closed_line(
                        points,
                        Stroke::new(1.5, Color32::from_rgb(0, 200, 60)),
                    ));
                    painter.circle_stroke(at(quad[0]), 3.0, Stroke::new(1.0, Color32::RED));
                }
                for &(p, category) in &picture.keypoints {
                    painter.circle_filled(at(p), 1.5, category_colour(category));
                }
            }
        });
    }

    fn figures_text(figures: &serde_json::Value) -> String {
        match figures {
            serde_json::Value::Object(map) => map
                .iter()
                .filter_map(|(k, v)| match (v.as_u64(), v.as_f64()) {
                    (Some(n), _) => Some(format!("{k} {n}")),
                    (None, Some(v)) => Some(format!("{k} {v:.3}")),
                    _ => None,
                })
                .collect::<Vec<_>>()
                .join(", "),
            other => other.to_string(),
        }
    }

    #[cfg(test)]
    mod tests {
        use super::*;

        #[derive(serde::Serialize)]
        struct Loss {
            total: f64,
        }

        /// The shipped models' 10 500 steps: the curve stays short enough to draw every frame
        /// and still spans the run, in step order.
        #[test]
        fn a_long_runs_loss_curve_stays_short_enough_to_draw() {
            let mut live = Live::default();
            for step in 1..=10_500u64 {
                live.record::<(), Loss>(Event::Step {
                    step,
                    loss: Loss {
                        total: 1.0 / step as f64,
                    },
                    samples_per_s: 1.0,
                    data_wait: 0.0,
                });
            }
            let curve = &live.losses["total"];
            assert!(curve.len() < 2 * MAX_CURVE && curve.len() >= MAX_CURVE / 2);
            // From the first per cent of the run to its last.
            assert!(curve[0][0] < 105.0 && curve[curve.len() - 1][0] > 10_395.0);
            assert!(curve.windows(2).all(|w| w[0][0] < w[1][0]));
            // Every point covers as many steps: evenly spaced, no seam where it was halved.
            let gaps: Vec<f64> = curve.windows(2).map(|w| w[1][0] - w[0][0]).collect();
            assert!(gaps.iter().all(|&g| (g - gaps[0]).abs() < 1e-9), "{gaps:?}");
        }
    }
}
