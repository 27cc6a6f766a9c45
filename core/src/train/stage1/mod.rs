//! Stage 1's part of training: one ROI network for every square family, on synthesised scenes
//! ([`data`]) with its losses ([`loss`]) and validation ([`validate`]).

pub mod data;
pub mod loss;
pub mod validate;

use super::stage::{Picture, TrainStage};
use crate::detect::stage1::model_file;
use crate::detect::stage1::net::{macs, NetConfig, Stage1Net};
use crate::detect::stage1::pipeline::{propose_with, ProposeOptions};
use crate::detect::stage2::model_file::fnv1a;
use crate::family::designs::random_square;
use crate::family::Family;
use burn::module::Module;
use burn::tensor::{Device, Tensor};
use data::{make_sample, SceneSample, SCENE};
use loss::{losses, Batch, LossTerms};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use validate::Metrics;

/// Built-in grid families stage 1 is trained on. AprilTag's circle21h7 and standard41h12 are
/// left out: their ROI corners lie inside the drawing (data cells surround the border), which a
/// corner detector cannot see as corners.
pub const TRAINING_FAMILIES: &[&str] = &[
    "apriltag-16h5",
    "apriltag-25h9",
    "apriltag-36h11",
    "apriltag-xa-36h11",
    "apriltag-xo-36h11",
    "aruco-4x4_50",
    "aruco-5x5_100",
    "aruco-6x6_250",
    "aruco-mip-36h12",
    "quaternary-6x6",
    "topotag-like",
];

/// Random designs mixed into the training scenes, and the seed that draws them.
pub const RANDOM_DESIGNS: usize = 24;
const DESIGN_SEED: u64 = 0xDE51_6715;

/// The name under which stage-1 runs and models are reported.
pub const SUBJECT: &str = "square markers";

pub struct RoiStage {
    families: Vec<Family>,
    net: NetConfig,
    /// A model file's weights to start from instead of fresh ones (fine-tuning), and its name.
    start: Option<(Vec<u8>, String)>,
}

/// What a stage-1 report says about the network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RoiInfo {
    pub net: NetConfig,
    /// Training scene side in pixels.
    pub scene: u32,
    pub families: Vec<String>,
    /// The model whose weights the run started from, when it did not start from fresh ones.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started_from: Option<String>,
}

/// `count` random square designs drawn from `seed` (designs the generator cannot turn into a
/// family, e.g. a repeated code, are skipped).
pub fn random_designs(count: usize, seed: u64) -> Vec<Family> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut index = 0;
    while out.len() < count && index < 4 * count {
        let spec = random_square(index, &mut |k| rng.random_range(0..k));
        if let Ok(f) = Family::from_spec(spec) {
            out.push(f);
        }
        index += 1;
    }
    out
}

/// The [`TRAINING_FAMILIES`] and `designs` random designs drawn from `design_seed`: what the
/// family-free networks (stage 1, the verifier) see markers of.
pub fn training_families(designs: usize, design_seed: u64) -> Result<Vec<Family>, String> {
    let mut families = Vec::new();
    for name in TRAINING_FAMILIES {
        let family = crate::builtin::get(name)
            .ok_or_else(|| format!("built-in family {name} is missing"))?
            .map_err(|e| e.to_string())?;
        families.push(family);
    }
    families.extend(random_designs(designs, design_seed));
    Ok(families)
}

impl RoiStage {
    pub fn new(width: usize) -> Result<Self, String> {
        let families = training_families(RANDOM_DESIGNS, DESIGN_SEED)?;
        Ok(Self {
            families,
            net: NetConfig { width },
            start: None,
        })
    }

    /// Stage 1 for the given families only (a family's own fine-tuned ROI model).
    pub fn for_families(families: Vec<Family>, width: usize) -> Self {
        Self {
            families,
            net: NetConfig { width },
            start: None,
        }
    }

    /// Starts from the weights of the stage-1 model file `bytes` (called `name` in errors and
    /// the report) instead of fresh ones: fine-tuning. The network's width is the model's.
    pub fn starting_from(mut self, bytes: Vec<u8>, name: &str) -> Result<Self, String> {
        let (_, header) =
            model_file::from_bytes(&bytes, name, &Device::flex()).map_err(|e| e.to_string())?;
        self.net = header.net;
        self.start = Some((bytes, name.to_string()));
        Ok(self)
    }

    /// The network's settings (those of the model it starts from, if any).
    pub fn net(&self) -> NetConfig {
        self.net
    }

    fn family_names(&self) -> Vec<String> {
        self.families.iter().map(|f| f.name().to_string()).collect()
    }
}

impl TrainStage for RoiStage {
    type Net = Stage1Net;
    type Sample = SceneSample;
    type Metrics = Metrics;
    type Terms = LossTerms;
    type Info = RoiInfo;

    fn subject(&self) -> String {
        SUBJECT.into()
    }

    fn subject_hash(&self) -> String {
        format!("{:016x}", fnv1a(self.family_names().join(",").as_bytes()))
    }

    fn info(&self) -> RoiInfo {
        RoiInfo {
            net: self.net,
            scene: SCENE,
            families: self.family_names(),
            started_from: self.start.as_ref().map(|(_, name)| name.clone()),
        }
    }

    fn macs(&self) -> u64 {
        macs(&self.net, (SCENE * SCENE) as u64)
    }

    fn init(&self, device: &Device) -> Stage1Net {
        match &self.start {
            // Checked when the stage was made.
            Some((bytes, name)) => {
                model_file::from_bytes(bytes, name, device)
                    .expect("the starting model loaded before")
                    .0
            }
            None => self.net.init(device),
        }
    }

    fn sample(&self, seed: u64) -> Result<SceneSample, String> {
        make_sample(&self.families, seed)
    }

    fn loss(
        &self,
        net: &Stage1Net,
        samples: &[SceneSample],
        device: &Device,
    ) -> (Tensor<1>, LossTerms) {
        let batch = Batch::new(samples, device);
        losses(net.forward(batch.input.clone()), &batch)
    }

    fn total(terms: &LossTerms) -> f64 {
        terms.total as f64
    }

    fn validation_set(&self, size: usize) -> Result<Vec<SceneSample>, String> {
        validate::validation_set(&self.families, size)
    }

    fn validate(&self, net: &Stage1Net, set: &[SceneSample]) -> Metrics {
        let net = net.valid().plain();
        let options = ProposeOptions::default();
        let proposals: Vec<_> = set
            .iter()
            .map(|s| propose_with(&net, &s.image, &options))
            .collect();
        validate::score(set, &proposals)
    }

    fn inference(&self, net: &Stage1Net) -> Stage1Net {
        net.valid()
    }

    fn model_bytes(&self, net: Stage1Net, step: u64) -> Result<Vec<u8>, String> {
        model_file::to_bytes(net, &self.net, &self.family_names(), step)
    }

    fn picture(&self, sample: &SceneSample, net: Option<&Stage1Net>) -> Picture {
        let outlines = match net {
            None => sample.quads.clone(),
            Some(net) => propose_with(&net.plain(), &sample.image, &Default::default())
                .into_iter()
                .map(|p| p.corners)
                .collect(),
        };
        Picture {
            image: sample.image.clone(),
            keypoints: Vec::new(),
            outlines,
        }
    }

    fn load_model(&self, bytes: &[u8], name: &str, device: &Device) -> Result<Stage1Net, String> {
        let (net, header) =
            model_file::from_bytes(bytes, name, device).map_err(|e| e.to_string())?;
        if header.net != self.net {
            return Err(format!(
                "{name}: the checkpoint's network ({:?}) differs from the requested one ({:?})",
                header.net, self.net
            ));
        }
        Ok(net)
    }
}

#[cfg(test)]
mod tests;
