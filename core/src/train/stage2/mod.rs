//! Stage 2's part of training: the keypoint network on synthesised patches ([`data`]), its losses
//! ([`loss`]) and its validation ([`validate`]).

pub mod data;
pub mod loss;
pub mod validate;

use super::stage::{Picture, TrainStage};
use crate::detect::stage2::anchors::{PatchSpec, RawOutputs};
use crate::detect::stage2::model_file;
use crate::detect::stage2::net::{macs, NetConfig, Stage2Net};
use crate::detect::stage2::pipeline::raw_outputs;
use crate::family::Family;
use crate::geometry::Quad;
use burn::module::Module;
use burn::tensor::{Device, Tensor};
use data::{make_sample, PatchSample, DEFAULT_CAMERA_SHARE};
use loss::{losses, Batch, LossTerms};
use serde::{Deserialize, Serialize};
use validate::Metrics;

/// Stage 2 of one family.
pub struct KeypointStage {
    family: Family,
    spec: PatchSpec,
    net: NetConfig,
    camera_share: f64,
    /// The model file fine-tuning starts from, with its name.
    start: Option<(Vec<u8>, String)>,
}

/// What a stage-2 report says about the network.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KeypointInfo {
    pub net: NetConfig,
    /// Patch side in pixels.
    pub patch: usize,
    /// The share of training patches cut from steep camera views.
    #[serde(default)]
    pub camera_share: f64,
    /// The model the run was fine-tuned from, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub started_from: Option<String>,
}

impl KeypointStage {
    pub fn new(family: &Family, width: usize) -> Self {
        let spec = PatchSpec::for_family(family);
        Self {
            net: NetConfig {
                classes: family.categories().len() + 1,
                width,
                patch: spec.size as usize,
            },
            family: family.clone(),
            spec,
            camera_share: DEFAULT_CAMERA_SHARE,
            start: None,
        }
    }

    /// Sets the share of training patches cut from camera views (0 = patch mode only, the
    /// first shipped models' data). Validation always uses patch mode, so runs compare.
    pub fn with_camera_share(mut self, share: f64) -> Self {
        self.camera_share = share.clamp(0.0, 1.0);
        self
    }

    /// Starts from the weights of the stage-2 model file `bytes` (called `name` in errors and
    /// the report) instead of fresh ones: fine-tuning. The network's width is the model's. The
    /// model may have learned another layout (the shipped 8 × 8 grid model for a 6 × 6 or 7 × 7
    /// grid) or other categories (its class head then starts fresh): what it learned of cells
    /// and frames carries over.
    pub fn starting_from(mut self, bytes: Vec<u8>, name: &str) -> Result<Self, String> {
        let (_, header) = model_file::to_fine_tune(&bytes, name, &self.family, &Device::flex())
            .map_err(|e| e.to_string())?;
        self.net = header.net;
        self.start = Some((bytes, name.to_string()));
        Ok(self)
    }

    /// The network's settings (those of the model it starts from, if any).
    pub fn net(&self) -> NetConfig {
        self.net
    }
}

impl TrainStage for KeypointStage {
    type Net = Stage2Net;
    type Sample = PatchSample;
    type Metrics = Metrics;
    type Terms = LossTerms;
    type Info = KeypointInfo;

    fn subject(&self) -> String {
        self.family.name().into()
    }

    fn subject_hash(&self) -> String {
        model_file::family_hash(&self.family)
    }

    fn info(&self) -> KeypointInfo {
        KeypointInfo {
            net: self.net,
            patch: self.spec.size as usize,
            camera_share: self.camera_share,
            started_from: self.start.as_ref().map(|(_, name)| name.clone()),
        }
    }

    fn macs(&self) -> u64 {
        macs(&self.net)
    }

    fn init(&self, device: &Device) -> Stage2Net {
        match &self.start {
            // Checked when the stage was made.
            Some((bytes, name)) => {
                model_file::to_fine_tune(bytes, name, &self.family, device)
                    .expect("the starting model loaded before")
                    .0
            }
            None => self.net.init(device),
        }
    }

    fn sample(&self, seed: u64) -> Result<PatchSample, String> {
        make_sample(&self.family, &self.spec, seed, self.camera_share)
    }

    fn loss(
        &self,
        net: &Stage2Net,
        samples: &[PatchSample],
        device: &Device,
    ) -> (Tensor<1>, LossTerms) {
        let batch = Batch::new(samples, self.net.classes, self.spec.size as usize, device);
        losses(net.forward(batch.input.clone()), &batch)
    }

    fn total(terms: &LossTerms) -> f64 {
        terms.total as f64
    }

    fn validation_set(&self, size: usize) -> Result<Vec<PatchSample>, String> {
        validate::validation_set(&self.family, &self.spec, size)
    }

    fn validate(&self, net: &Stage2Net, set: &[PatchSample]) -> Metrics {
        run_validation(net, &self.family, &self.spec, set, self.net.classes)
    }

    fn inference(&self, net: &Stage2Net) -> Stage2Net {
        net.valid()
    }

    fn model_bytes(&self, net: Stage2Net, step: u64) -> Result<Vec<u8>, String> {
        model_file::to_bytes(net, &self.net, &self.family, step)
    }

    fn picture(&self, sample: &PatchSample, net: Option<&Stage2Net>) -> Picture {
        patch_picture(&self.family, &self.spec, self.net.classes, sample, net)
    }

    fn load_model(&self, bytes: &[u8], name: &str, device: &Device) -> Result<Stage2Net, String> {
        let (net, header) =
            model_file::from_bytes(bytes, name, &self.family, device).map_err(|e| e.to_string())?;
        if header.net != self.net {
            return Err(format!(
                "{name}: the checkpoint's network ({:?}) differs from the requested one ({:?})",
                header.net, self.net
            ));
        }
        Ok(net)
    }
}

/// The patch with its true keypoints, or with those `net` finds and sorts onto the template.
fn patch_picture(
    family: &Family,
    spec: &PatchSpec,
    classes: usize,
    sample: &PatchSample,
    net: Option<&Stage2Net>,
) -> Picture {
    let keypoints = match net {
        None => sample
            .truth
            .keypoints
            .iter()
            .filter(|k| k.visible)
            .map(|k| ([k.x, k.y], k.category))
            .collect(),
        Some(net) => forward(net, spec, classes, std::slice::from_ref(sample))
            .first()
            .and_then(|raw| crate::detect::stage2::decode::read_patch(family, spec, raw))
            .map(|r| r.found.iter().map(|f| (f.pos, f.category)).collect())
            .unwrap_or_default(),
    };
    let outlines = match (net, <Quad>::try_from(sample.truth.roi.as_slice())) {
        (None, Ok(roi)) => vec![roi],
        _ => Vec::new(),
    };
    Picture {
        image: sample.image.clone(),
        keypoints,
        outlines,
    }
}

/// Validation metrics of the network in inference mode (batch norm on its running statistics).
pub fn run_validation(
    net: &Stage2Net,
    family: &Family,
    spec: &PatchSpec,
    set: &[PatchSample],
    classes: usize,
) -> Metrics {
    let raw = forward(&net.valid(), spec, classes, set);
    validate::score(family, spec, set, &raw)
}

/// The network's raw outputs for each sample, in batches of 32 (`net` in inference mode).
fn forward(
    net: &Stage2Net,
    spec: &PatchSpec,
    classes: usize,
    samples: &[PatchSample],
) -> Vec<RawOutputs> {
    let device = Device::flex();
    let p = spec.size as usize;
    samples
        .chunks(32)
        .flat_map(|chunk| {
            let pixels: Vec<f32> = chunk.iter().flat_map(|s| s.input.iter().copied()).collect();
            let x = burn::tensor::Tensor::<4>::from_data(
                burn::tensor::TensorData::new(pixels, [chunk.len(), 1, p, p]),
                &device,
            );
            raw_outputs(net.forward(x), classes)
        })
        .collect()
}
