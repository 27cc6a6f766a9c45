//! The verifier's part of training: one network for every square family, on the candidate
//! quads of cluttered scenes ([`data`]), with a class-balanced binary cross-entropy and, as
//! validation, the share of markers it keeps and of false quads it turns away at the detector's
//! threshold.

pub mod data;

use super::stage::{Picture, TrainStage};
use super::stage1::training_families;
use crate::detect::stage1::Stage1;
use crate::detect::stage2::model_file::fnv1a;
use crate::detect::verifier::model_file;
use crate::detect::verifier::net::{macs, NetConfig, VerifierNet};
use crate::detect::verifier::{Verifier, VerifierParams};
use crate::family::Family;
use crate::synth::image_seed;
use burn::module::Module;
use burn::tensor::activation::log_sigmoid;
use burn::tensor::{Device, Tensor, TensorData};
use data::{make_sample, VerifierSample};
use serde::{Deserialize, Serialize};

/// The name under which verifier runs and models are reported.
pub const SUBJECT: &str = "square-marker verifier";
/// The default patch side.
pub const PATCH: usize = 32;
/// Random designs among the positives, drawn from a seed of their own (not stage 1's): the
/// verifier must pass designs it never saw.
const RANDOM_DESIGNS: usize = 24;
const DESIGN_SEED: u64 = 0x7E41_F1E5;
/// The validation set's seed: different from any training run's sample seeds.
pub const VALIDATION_SEED: u64 = 0x7E41_F1ED;

pub struct VerifierStage {
    families: Vec<Family>,
    stage1: Stage1,
    net: NetConfig,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerifierInfo {
    pub net: NetConfig,
    pub families: Vec<String>,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub scenes: usize,
    pub positives: usize,
    pub negatives: usize,
    /// Positives scored at or above the detector's default threshold.
    #[serde(with = "crate::io::json_float")]
    pub kept: f64,
    /// Negatives scored below it.
    #[serde(with = "crate::io::json_float")]
    pub rejected: f64,
    /// Stage 1's own candidates that frame no marker, scored below it (the passes saved).
    #[serde(with = "crate::io::json_float")]
    pub candidates_rejected: f64,
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct LossTerms {
    #[serde(with = "crate::io::json_float")]
    pub total: f32,
}

impl VerifierStage {
    pub fn new(width: usize, patch: usize) -> Result<Self, String> {
        let families = training_families(RANDOM_DESIGNS, DESIGN_SEED)?;
        let stage1 = Stage1::shipped().map_err(|e| e.to_string())?;
        Ok(Self {
            families,
            stage1,
            net: NetConfig { width, patch },
        })
    }

    pub fn net(&self) -> NetConfig {
        self.net
    }

    fn family_names(&self) -> Vec<String> {
        self.families.iter().map(|f| f.name().to_string()).collect()
    }
}

/// Stacks the samples' patches and labels.
fn batch(samples: &[VerifierSample], patch: usize, device: &Device) -> (Tensor<4>, Vec<f32>) {
    let labels: Vec<f32> = samples.iter().flat_map(|s| s.labels.clone()).collect();
    let pixels: Vec<f32> = samples.iter().flat_map(|s| s.patches.clone()).collect();
    let n = labels.len();
    let input = Tensor::from_data(TensorData::new(pixels, [n, 1, patch, patch]), device);
    (input, labels)
}

impl TrainStage for VerifierStage {
    type Net = VerifierNet;
    type Sample = VerifierSample;
    type Metrics = Metrics;
    type Terms = LossTerms;
    type Info = VerifierInfo;

    fn subject(&self) -> String {
        SUBJECT.into()
    }

    fn subject_hash(&self) -> String {
        format!("{:016x}", fnv1a(self.family_names().join(",").as_bytes()))
    }

    fn info(&self) -> VerifierInfo {
        VerifierInfo {
            net: self.net,
            families: self.family_names(),
        }
    }

    fn macs(&self) -> u64 {
        macs(&self.net)
    }

    fn init(&self, device: &Device) -> VerifierNet {
        self.net.init(device)
    }

    fn sample(&self, seed: u64) -> Result<VerifierSample, String> {
        make_sample(&self.families, &self.stage1, self.net.patch, seed)
    }

    /// Binary cross-entropy with the positives and the negatives weighing half each: a scene
    /// brings a few markers and many false quads.
    fn loss(
        &self,
        net: &VerifierNet,
        samples: &[VerifierSample],
        device: &Device,
    ) -> (Tensor<1>, LossTerms) {
        let (input, labels) = batch(samples, self.net.patch, device);
        let n = labels.len();
        if n == 0 {
            let zero = Tensor::<1>::zeros([1], device);
            return (zero, LossTerms::default());
        }
        let positives = labels.iter().filter(|&&l| l > 0.5).count();
        let negatives = n - positives;
        let weights: Vec<f32> = (labels.iter())
            .map(|&l| match l > 0.5 {
                true => 0.5 / positives.max(1) as f32,
                false => 0.5 / negatives.max(1) as f32,
            })
            .collect();
        let y = Tensor::<1>::from_data(TensorData::new(labels, [n]), device);
        let w = Tensor::<1>::from_data(TensorData::new(weights, [n]), device);
        let x = net.forward(input);
        let nll = (y.clone() * log_sigmoid(x.clone())
            + y.neg().add_scalar(1.0) * log_sigmoid(x.neg()))
        .neg();
        let total = (nll * w).sum();
        let value = total
            .clone()
            .detach()
            .into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .expect("f32 tensor")[0];
        (total, LossTerms { total: value })
    }

    fn total(terms: &LossTerms) -> f64 {
        terms.total as f64
    }

    fn validation_set(&self, size: usize) -> Result<Vec<VerifierSample>, String> {
        (0..size as u64)
            .map(|i| self.sample(image_seed(VALIDATION_SEED, i)))
            .collect()
    }

    fn validate(&self, net: &VerifierNet, set: &[VerifierSample]) -> Metrics {
        let verifier = Verifier::of_network(&net.valid(), self.net);
        let threshold = VerifierParams::default().min_score;
        let mut m = Metrics {
            scenes: set.len(),
            ..Metrics::default()
        };
        let (mut kept, mut rejected, mut candidates, mut candidates_rejected) = (0, 0, 0, 0);
        for sample in set {
            let scores = verifier.scores(&sample.image, &sample.quads);
            // The scene's own candidates come first, before the added outlines.
            let own = sample.candidates;
            for (i, (&score, &label)) in scores.iter().zip(&sample.labels).enumerate() {
                let pass = score >= threshold;
                if label > 0.5 {
                    m.positives += 1;
                    kept += usize::from(pass);
                } else {
                    m.negatives += 1;
                    rejected += usize::from(!pass);
                    if i < own {
                        candidates += 1;
                        candidates_rejected += usize::from(!pass);
                    }
                }
            }
        }
        m.kept = kept as f64 / m.positives.max(1) as f64;
        m.rejected = rejected as f64 / m.negatives.max(1) as f64;
        m.candidates_rejected = candidates_rejected as f64 / candidates.max(1) as f64;
        m
    }

    fn inference(&self, net: &VerifierNet) -> VerifierNet {
        net.valid()
    }

    fn model_bytes(&self, net: VerifierNet, step: u64) -> Result<Vec<u8>, String> {
        model_file::to_bytes(net, &self.net, &self.family_names(), step)
    }

    fn load_model(&self, bytes: &[u8], name: &str, device: &Device) -> Result<VerifierNet, String> {
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

    fn picture(&self, sample: &VerifierSample, net: Option<&VerifierNet>) -> Picture {
        let outlines = match net {
            None => (sample.quads.iter().zip(&sample.labels))
                .filter(|(_, &l)| l > 0.5)
                .map(|(q, _)| *q)
                .collect(),
            Some(net) => {
                let verifier = Verifier::of_network(&net.valid(), self.net);
                let threshold = VerifierParams::default().min_score;
                let scores = verifier.scores(&sample.image, &sample.quads);
                (sample.quads.iter().zip(scores))
                    .filter(|(_, s)| *s >= threshold)
                    .map(|(q, _)| *q)
                    .collect()
            }
        };
        Picture {
            image: sample.image.clone(),
            keypoints: Vec::new(),
            outlines,
        }
    }
}
