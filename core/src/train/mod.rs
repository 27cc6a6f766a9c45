//! Training the stage-2 keypoint network (docs/ARCHITECTURE.md §10): burn with autodiff on the
//! `flex` CPU backend, Adam at lr 1e-3, patches synthesised by worker threads ahead of the
//! optimiser, periodic validation on a fixed seeded set, atomic checkpoints, resume, and a JSON
//! report.
//!
//! Progress is a stream of [`Event`]s; the CLI draws them as a progress bar.
//!
//! **Output folder.** `checkpoint.bin` (model + optimiser state + step, rewritten atomically every
//! `checkpoint_every` steps, so a killed run loses at most that many steps), `model.bin` (the
//! final weights, the format of [`crate::detect::stage2::model_file`]) and `report.json`.

mod checkpoint;
pub mod data;
pub mod loss;
pub mod validate;

use crate::detect::stage2::anchors::PatchSpec;
use crate::detect::stage2::model_file;
use crate::detect::stage2::net::{macs, NetConfig, Stage2Net};
use crate::detect::stage2::pipeline::raw_outputs;
use crate::family::Family;
use burn::module::Module;
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::Device;
use data::Loader;
use loss::{losses, Batch, LossTerms};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use validate::Metrics;

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

#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum Event {
    Started {
        family: String,
        first_step: u64,
        steps: u64,
        params: usize,
        macs: u64,
    },
    Step {
        step: u64,
        loss: LossTerms,
        samples_per_s: f64,
        /// Fraction of the run's time the optimiser waited for data so far.
        data_wait: f64,
    },
    Validated {
        step: u64,
        metrics: Metrics,
    },
    Checkpointed {
        step: u64,
    },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub family: String,
    pub family_hash: String,
    pub config: TrainConfig,
    pub net: NetConfig,
    pub patch: usize,
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
    pub final_loss: LossTerms,
    pub validation: Vec<(u64, Metrics)>,
    pub model_file: String,
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
}

/// Trains stage 2 for `family` into `out`; with `resume`, continues from the folder's checkpoint.
/// `stop` ends the run early at the next step (a checkpoint is written first).
pub fn train(
    family: &Family,
    config: &TrainConfig,
    out: &Path,
    resume: bool,
    stop: &AtomicBool,
    on_event: &mut dyn FnMut(Event),
) -> Result<Report, String> {
    let dir = OutDir(out.to_path_buf());
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let spec = PatchSpec::for_family(family);
    let net_config = NetConfig {
        classes: family.categories().len() + 1,
        width: config.width,
        patch: spec.size as usize,
    };
    let device = Device::flex().autodiff();
    // Seeded initial weights: a run is a function of its config (resumed runs load theirs).
    device.seed(config.seed);
    let mut net: Stage2Net = net_config.init(&device);
    let mut optim = AdamConfig::new().init();
    let mut step = 0u64;
    let mut history: Vec<(u64, Metrics)> = Vec::new();
    let mut earlier_wall = 0.0;
    let mut resumed_from = None;
    if resume && dir.checkpoint().exists() {
        let state = checkpoint::load(&dir.checkpoint(), family, &net_config, &device)?;
        net = state.net;
        optim = optim
            .from_bytes(state.optimiser)
            .map_err(|e| format!("{}: optimiser state: {e}", dir.checkpoint().display()))?;
        step = state.meta.step;
        history = state.meta.validation;
        earlier_wall = state.meta.wall_s;
        resumed_from = Some(step);
    }
    let params = net.num_params();
    on_event(Event::Started {
        family: family.name().into(),
        first_step: step,
        steps: config.steps,
        params,
        macs: macs(&net_config),
    });

    let validation = validate::validation_set(family, &spec, config.validation_patches)?;
    let mut loader = Loader::start(
        family,
        spec,
        config.seed,
        step * config.batch as u64,
        config.workers,
        4 * config.batch,
    );
    let started = Instant::now();
    let first_step = step;
    let mut last = LossTerms::default();
    while step < config.steps && !stop.load(Ordering::Relaxed) {
        let samples = loader.batch(config.batch)?;
        let batch = Batch::new(&samples, net_config.classes, spec.size as usize, &device);
        let (loss, terms) = losses(net.forward(batch.input.clone()), &batch);
        let grads = GradientsParams::from_grads(loss.backward(), &net);
        net = optim.step(config.learning_rate_at(step), net, grads);
        step += 1;
        last = terms;
        let elapsed = started.elapsed().as_secs_f64();
        on_event(Event::Step {
            step,
            loss: terms,
            samples_per_s: ((step - first_step) as usize * config.batch) as f64 / elapsed.max(1e-9),
            data_wait: loader.waited.as_secs_f64() / elapsed.max(1e-9),
        });
        if step.is_multiple_of(config.validate_every) || step == config.steps {
            let metrics = run_validation(&net, family, &spec, &validation, net_config.classes);
            history.push((step, metrics));
            on_event(Event::Validated { step, metrics });
        }
        // A stopped run keeps the step it just made.
        if step.is_multiple_of(config.checkpoint_every)
            || step == config.steps
            || stop.load(Ordering::Relaxed)
        {
            checkpoint::save(
                &dir.checkpoint(),
                family,
                net.clone(),
                &net_config,
                &optim,
                &checkpoint::Meta {
                    step,
                    validation: history.clone(),
                    wall_s: earlier_wall + started.elapsed().as_secs_f64(),
                    config: config.clone(),
                },
            )?;
            on_event(Event::Checkpointed { step });
        }
    }
    let wall = started.elapsed().as_secs_f64();
    let bytes = model_file::to_bytes(net.valid(), &net_config, family, step)?;
    crate::io::write_atomic(&dir.model(), &bytes)
        .map_err(|e| format!("{}: {e}", dir.model().display()))?;
    let done = (step - first_step).max(1);
    let report = Report {
        family: family.name().into(),
        family_hash: model_file::family_hash(family),
        config: config.clone(),
        net: net_config,
        patch: spec.size as usize,
        params,
        macs_per_patch: macs(&net_config),
        steps: step,
        wall_s: wall,
        total_wall_s: earlier_wall + wall,
        mean_step_ms: wall * 1000.0 / done as f64,
        samples_per_s: (done as usize * config.batch) as f64 / wall.max(1e-9),
        data_wait_fraction: loader.waited.as_secs_f64() / wall.max(1e-9),
        resumed_from,
        final_loss: last,
        validation: history,
        model_file: dir.model().display().to_string(),
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    crate::io::write_atomic(&dir.report(), json.as_bytes())
        .map_err(|e| format!("{}: {e}", dir.report().display()))?;
    Ok(report)
}

/// Validation metrics of the network in inference mode (batch norm on its running statistics).
pub fn run_validation(
    net: &Stage2Net,
    family: &Family,
    spec: &PatchSpec,
    set: &[data::PatchSample],
    classes: usize,
) -> Metrics {
    let net = net.valid();
    let device = Device::flex();
    let p = spec.size as usize;
    let raw: Vec<_> = set
        .chunks(32)
        .flat_map(|chunk| {
            let pixels: Vec<f32> = chunk.iter().flat_map(|s| s.input.iter().copied()).collect();
            let x = burn::tensor::Tensor::<4>::from_data(
                burn::tensor::TensorData::new(pixels, [chunk.len(), 1, p, p]),
                &device,
            );
            raw_outputs(net.forward(x), classes)
        })
        .collect();
    validate::score(family, spec, set, &raw)
}

#[cfg(test)]
mod tests;
