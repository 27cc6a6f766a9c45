//! Training the detector's networks. One loop ([`train`]) for every stage, over a small per-stage
//! part ([`stage::TrainStage`]: network, samples, loss, validation, model file); stage 2 is
//! [`stage2::KeypointStage`] (docs/ARCHITECTURE.md §10): burn with autodiff on the `flex` CPU
//! backend, Adam (lr 1e-3 for stage 2), samples synthesised by worker threads ahead of the
//! optimiser, periodic validation on a fixed seeded set, atomic checkpoints, resume, and a JSON
//! report.
//!
//! Progress is a stream of [`Event`]s; the CLI draws them as a progress bar.
//!
//! **Output folder.** `checkpoint.bin` (model + optimiser state + step, rewritten atomically every
//! `checkpoint_every` steps, so a killed run loses at most that many steps), `model.bin` (the
//! final weights, the format of [`crate::detect::stage2::model_file`]) and `report.json`. A run
//! holds an exclusive lock on the folder's [`LOCK_FILE`] from start to end ([`OutDir::lock`]), so
//! a second run into the same folder stops at once instead of mixing its checkpoints with the
//! first's; the operating system releases the lock when a run ends, however it ends.

mod checkpoint;
pub use checkpoint::MAX_CHECKPOINT_BYTES;
pub mod loader;
pub mod stage;
pub mod stage1;
pub mod stage2;
pub mod verifier;

use crate::family::Family;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::Device;
use loader::Loader;
use serde::{Deserialize, Serialize};
use stage::TrainStage;
use stage2::KeypointStage;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    pub steps: u64,
    pub batch: usize,
    pub learning_rate: f64,
    /// The learning rate falls linearly to a tenth over this last fraction of the steps.
    pub decay_fraction: f64,
    pub width: usize,
    pub seed: u64,
    pub checkpoint_every: u64,
    pub validate_every: u64,
    pub validation_patches: usize,
    /// Synthesis threads.
    pub workers: usize,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            // The shipped models' settings: about 40 minutes on two CPU cores (BENCHMARKS.md).
            steps: 10_500,
            batch: 16,
            learning_rate: 1e-3,
            decay_fraction: 0.25,
            width: 32,
            seed: 1,
            checkpoint_every: 250,
            validate_every: 500,
            validation_patches: 200,
            workers: 1,
        }
    }
}

impl TrainConfig {
    fn learning_rate_at(&self, step: u64) -> f64 {
        let start = (self.steps as f64 * (1.0 - self.decay_fraction)) as u64;
        if step < start || self.steps <= start {
            return self.learning_rate;
        }
        let t = (step - start) as f64 / (self.steps - start) as f64;
        self.learning_rate * (1.0 - 0.9 * t)
    }
}

/// Progress of a run, for a progress bar or a live plot. `M` and `L` are the stage's metrics and
/// loss terms ([`TrainStage::Metrics`], [`TrainStage::Terms`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Event<M, L> {
    Started {
        family: String,
        first_step: u64,
        steps: u64,
        params: usize,
        macs: u64,
    },
    Step {
        step: u64,
        loss: L,
        samples_per_s: f64,
        /// Fraction of the run's time the optimiser waited for data so far.
        data_wait: f64,
    },
    Validated {
        step: u64,
        metrics: M,
    },
    Checkpointed {
        step: u64,
    },
    /// After each validation: a few of the current training samples with their ground truth,
    /// and the first validation samples with what the network finds in them.
    Pictured {
        step: u64,
        samples: Vec<stage::Picture>,
        predictions: Vec<stage::Picture>,
    },
}

/// How many samples [`Event::Pictured`] shows of each kind.
pub const PICTURES: usize = 6;

/// The run's `report.json`. `I`, `M`, `L`: the stage's network info, metrics and loss terms.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report<I, M, L> {
    pub family: String,
    pub family_hash: String,
    pub config: TrainConfig,
    #[serde(flatten)]
    pub info: I,
    pub params: usize,
    pub macs_per_patch: u64,
    pub steps: u64,
    /// Wall time of this process's part of the run, and of all parts (resumed runs add up).
    pub wall_s: f64,
    pub total_wall_s: f64,
    pub mean_step_ms: f64,
    pub samples_per_s: f64,
    pub data_wait_fraction: f64,
    pub resumed_from: Option<u64>,
    pub final_loss: L,
    pub validation: Vec<(u64, M)>,
    pub model_file: String,
}

/// Why a run stopped or could not start. Each message names the file or step it concerns.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The folder's checkpoint cannot be resumed: damaged, edited, or made for another family or
    /// network.
    #[error("{0}")]
    Checkpoint(String),
    /// The output folder or a file in it could not be written.
    #[error("{0}")]
    Output(String),
    /// The loss stopped being a finite number.
    #[error("{0}")]
    Diverged(String),
    /// The synthesiser could not make a sample.
    #[error("{0}")]
    Data(String),
    /// Another run holds the output folder's lock.
    #[error("{0}")]
    InUse(String),
    /// The output folder is a file (or lies below one).
    #[error("{0}")]
    NotAFolder(String),
}

/// The lock file a run holds in its output folder ([`OutDir::lock`]). It stays after the run:
/// removing it would let a run that opened it just before lock a file no other run can see.
pub const LOCK_FILE: &str = ".tagsmith-train.lock";

/// The output folder's lock, held while it lives.
#[derive(Debug)]
pub struct OutLock {
    _file: std::fs::File,
}

/// The paths of a training folder.
pub struct OutDir(pub PathBuf);

impl OutDir {
    pub fn checkpoint(&self) -> PathBuf {
        self.0.join("checkpoint.bin")
    }
    pub fn model(&self) -> PathBuf {
        self.0.join("model.bin")
    }
    pub fn report(&self) -> PathBuf {
        self.0.join("report.json")
    }

    pub fn lock_file(&self) -> PathBuf {
        self.0.join(LOCK_FILE)
    }

    /// Creates the folder and takes the exclusive lock of its [`LOCK_FILE`] for as long as the
    /// returned guard lives, and proves the folder writable before the first step rather than at
    /// the first checkpoint minutes later. Another run holding it is
    /// [`TrainError::InUse`]; a lock a killed run left behind is no obstacle, since the system
    /// releases a dead process's locks. Where the file system has no locks, the run goes on
    /// without one.
    pub fn lock(&self) -> Result<OutLock, TrainError> {
        self.create()?;
        let path = self.lock_file();
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| self.cannot_write(e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                return Err(TrainError::InUse(format!(
                    "{} is in use by another training run (lock file {}); wait for it to end, \
                     or train into another folder with --out",
                    self.0.display(),
                    path.display()
                )))
            }
            Err(std::fs::TryLockError::Error(e)) if e.kind() == std::io::ErrorKind::Unsupported => {
            }
            Err(std::fs::TryLockError::Error(e)) => {
                return Err(TrainError::Output(format!(
                    "{}: cannot lock it: {e}",
                    path.display()
                )))
            }
        }
        // Checkpoints are written as new files beside the old: prove that works now.
        let probe = self.0.join(".tagsmith-write-check");
        std::fs::write(&probe, b"").map_err(|e| self.cannot_write(e))?;
        std::fs::remove_file(&probe).map_err(|e| self.cannot_write(e))?;
        Ok(OutLock { _file: file })
    }

    fn create(&self) -> Result<(), TrainError> {
        if self.0.exists() && !self.0.is_dir() {
            return Err(TrainError::NotAFolder(format!(
                "{}: it is a file, not a folder; the training output is a folder (checkpoint, \
                 model, report)",
                self.0.display()
            )));
        }
        std::fs::create_dir_all(&self.0).map_err(|e| match e.kind() {
            // A file where a folder above it should be.
            std::io::ErrorKind::NotADirectory | std::io::ErrorKind::AlreadyExists => {
                TrainError::NotAFolder(format!(
                    "{}: cannot make the folder there: {e}",
                    self.0.display()
                ))
            }
            _ => self.cannot_write(e),
        })
    }

    fn cannot_write(&self, e: std::io::Error) -> TrainError {
        TrainError::Output(format!(
            "{}: cannot write the training output there: {e}",
            self.0.display()
        ))
    }
}

/// The report of a stage's run.
pub type StageReport<S> =
    Report<<S as TrainStage>::Info, <S as TrainStage>::Metrics, <S as TrainStage>::Terms>;
/// The events of a stage's run.
pub type StageEvent<S> = Event<<S as TrainStage>::Metrics, <S as TrainStage>::Terms>;

/// Trains stage 2 (the keypoint network) for `family`: [`train`] with [`KeypointStage`].
pub fn train_keypoints(
    family: &Family,
    config: &TrainConfig,
    out: &Path,
    resume: bool,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(StageEvent<KeypointStage>),
) -> Result<StageReport<KeypointStage>, TrainError> {
    let stage = Arc::new(KeypointStage::new(family, config.width));
    train(stage, config, out, resume, stop, on_event)
}

/// Trains `stage` into `out`; with `resume`, continues from the folder's checkpoint. `stop` ends
/// the run early at the next step (a checkpoint is written first).
pub fn train<S: TrainStage>(
    stage: Arc<S>,
    config: &TrainConfig,
    out: &Path,
    resume: bool,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(StageEvent<S>),
) -> Result<StageReport<S>, TrainError> {
    let dir = OutDir(out.to_path_buf());
    // Held to the end of the run, the final model and report included.
    let _lock = dir.lock()?;
    let mut run = Run::start(stage.clone(), config, &dir, resume)?;
    on_event(Event::Started {
        family: stage.subject(),
        first_step: run.step,
        steps: config.steps,
        params: run.params,
        macs: stage.macs(),
    });
    let validation = stage
        .validation_set(config.validation_patches)
        .map_err(TrainError::Data)?;
    let make: loader::MakeSample<S::Sample> = {
        let stage = stage.clone();
        Arc::new(move |seed| stage.sample(seed))
    };
    let mut loader = Loader::start(
        make,
        config.seed,
        run.step * config.batch as u64,
        config.workers,
        4 * config.batch,
    );
    run.started = Instant::now();
    while run.step < config.steps && !stop.load(Ordering::Relaxed) {
        let samples = loader.batch(config.batch).map_err(TrainError::Data)?;
        run.optimise(&samples)?;
        on_event(run.progress(&loader));
        if run.step.is_multiple_of(config.validate_every) || run.step == config.steps {
            on_event(run.validate(&validation));
            on_event(run.pictures(&samples, &validation));
        }
        // A stopped run keeps the step it just made.
        if run.step.is_multiple_of(config.checkpoint_every)
            || run.step == config.steps
            || stop.load(Ordering::Relaxed)
        {
            on_event(run.checkpoint(&dir)?);
        }
    }
    run.finish(&dir, &loader)
}

/// A run in progress: the network, its optimiser and what the report needs.
struct Run<S: TrainStage> {
    stage: Arc<S>,
    config: TrainConfig,
    device: Device,
    net: S::Net,
    optim: ModuleOptimizer,
    step: u64,
    first_step: u64,
    params: usize,
    history: Vec<(u64, S::Metrics)>,
    last: S::Terms,
    earlier_wall: f64,
    resumed_from: Option<u64>,
    started: Instant,
}

impl<S: TrainStage> Run<S> {
    /// Fresh seeded weights, or the folder's checkpoint when resuming.
    fn start(
        stage: Arc<S>,
        config: &TrainConfig,
        dir: &OutDir,
        resume: bool,
    ) -> Result<Self, TrainError> {
        let device = Device::flex().autodiff();
        // Seeded initial weights: a run is a function of its config (resumed runs load theirs).
        device.seed(config.seed);
        let mut net = stage.init(&device);
        let mut optim = AdamConfig::new().init();
        let (mut step, mut history, mut earlier_wall, mut resumed_from) =
            (0, Vec::new(), 0.0, None);
        if resume && dir.checkpoint().exists() {
            let path = dir.checkpoint();
            let state = checkpoint::load::<S::Metrics>(&path).map_err(TrainError::Checkpoint)?;
            net = stage
                .load_model(&state.model, &path.display().to_string(), &device)
                .map_err(TrainError::Checkpoint)?;
            optim = optim.from_bytes(state.optimiser).map_err(|e| {
                TrainError::Checkpoint(format!("{}: optimiser state: {e}", path.display()))
            })?;
            step = state.meta.step;
            history = state.meta.validation;
            earlier_wall = state.meta.wall_s;
            resumed_from = Some(step);
        }
        Ok(Self {
            params: net.num_params(),
            stage,
            config: config.clone(),
            device,
            net,
            optim,
            step,
            first_step: step,
            history,
            last: S::Terms::default(),
            earlier_wall,
            resumed_from,
            started: Instant::now(),
        })
    }

    /// One optimiser step on a batch; a loss that is not finite stops the run before its weights
    /// reach a checkpoint.
    fn optimise(&mut self, samples: &[S::Sample]) -> Result<(), TrainError> {
        let (loss, terms) = self.stage.loss(&self.net, samples, &self.device);
        if !S::total(&terms).is_finite() {
            return Err(TrainError::Diverged(format!(
                "training diverged at step {}: the loss is not a finite number; the last \
                 checkpoint is kept (resume it with a lower --learning-rate)",
                self.step + 1
            )));
        }
        let grads = GradientsParams::from_grads(loss.backward(), &self.net);
        let lr = self.config.learning_rate_at(self.step);
        self.net = self.optim.step(lr, self.net.clone(), grads);
        self.step += 1;
        self.last = terms;
        Ok(())
    }

    fn progress(&self, loader: &Loader<S::Sample>) -> StageEvent<S> {
        let elapsed = self.started.elapsed().as_secs_f64().max(1e-9);
        let samples = (self.step - self.first_step) as usize * self.config.batch;
        Event::Step {
            step: self.step,
            loss: self.last,
            samples_per_s: samples as f64 / elapsed,
            data_wait: loader.waited.as_secs_f64() / elapsed,
        }
    }

    fn validate(&mut self, set: &[S::Sample]) -> StageEvent<S> {
        let metrics = self.stage.validate(&self.net, set);
        self.history.push((self.step, metrics));
        Event::Validated {
            step: self.step,
            metrics,
        }
    }

    fn pictures(&self, batch: &[S::Sample], validation: &[S::Sample]) -> StageEvent<S> {
        let net = self.stage.inference(&self.net);
        Event::Pictured {
            step: self.step,
            samples: batch
                .iter()
                .take(PICTURES)
                .map(|s| self.stage.picture(s, None))
                .collect(),
            predictions: validation
                .iter()
                .take(PICTURES)
                .map(|s| self.stage.picture(s, Some(&net)))
                .collect(),
        }
    }

    fn checkpoint(&self, dir: &OutDir) -> Result<StageEvent<S>, TrainError> {
        let model = self
            .stage
            .model_bytes(self.net.clone(), self.step)
            .map_err(TrainError::Diverged)?;
        let meta = checkpoint::Meta {
            step: self.step,
            validation: self.history.clone(),
            wall_s: self.earlier_wall + self.started.elapsed().as_secs_f64(),
            config: self.config.clone(),
        };
        let optimiser = self
            .optim
            .into_bytes()
            .map_err(|e| TrainError::Output(e.to_string()))?;
        checkpoint::save(&dir.checkpoint(), &model, &optimiser, &meta)
            .map_err(TrainError::Output)?;
        Ok(Event::Checkpointed { step: self.step })
    }

    /// Writes the final model and the report.
    fn finish(
        self,
        dir: &OutDir,
        loader: &Loader<S::Sample>,
    ) -> Result<StageReport<S>, TrainError> {
        let wall = self.started.elapsed().as_secs_f64();
        let bytes = self
            .stage
            .model_bytes(self.stage.inference(&self.net), self.step)
            .map_err(TrainError::Diverged)?;
        crate::io::write_atomic(&dir.model(), &bytes)
            .map_err(|e| TrainError::Output(format!("{}: {e}", dir.model().display())))?;
        // A resumed run that was already complete made no step here: no rate to report.
        let done = self.step - self.first_step;
        let per = |x: f64| if done == 0 { 0.0 } else { x };
        let report = Report {
            family: self.stage.subject(),
            family_hash: self.stage.subject_hash(),
            config: self.config.clone(),
            info: self.stage.info(),
            params: self.params,
            macs_per_patch: self.stage.macs(),
            steps: self.step,
            wall_s: wall,
            total_wall_s: self.earlier_wall + wall,
            mean_step_ms: per(wall * 1000.0 / done.max(1) as f64),
            samples_per_s: per((done as usize * self.config.batch) as f64 / wall.max(1e-9)),
            data_wait_fraction: loader.waited.as_secs_f64() / wall.max(1e-9),
            resumed_from: self.resumed_from,
            final_loss: self.last,
            validation: self.history,
            model_file: dir.model().display().to_string(),
        };
        let json = serde_json::to_string_pretty(&report).expect("reports serialise");
        crate::io::write_atomic(&dir.report(), json.as_bytes())
            .map_err(|e| TrainError::Output(format!("{}: {e}", dir.report().display())))?;
        Ok(report)
    }
}

#[cfg(test)]
mod tests;
