//! Stage-2 losses (docs/ARCHITECTURE.md §10.2): softmax confidence over positives and hard
//! negatives (the SSD recipe, 3 negatives per positive), smooth-L1 on the offsets of positive
//! anchors, L2 on the mask, smooth-L1 on the template head.

use super::data::PatchSample;
use crate::detect::stage2::anchors::IGNORE;
use crate::detect::stage2::net::Outputs;
use crate::detect::stage2::pipeline::template_flat;
use burn::tensor::activation::{log_softmax, sigmoid};
use burn::tensor::{Device, Tensor, TensorData};

/// Negatives kept per positive.
const NEGATIVES_PER_POSITIVE: usize = 3;
/// The offset loss is smooth-L1 on the error in patch pixels (the network outputs strides): with
/// the switch to L1 at one pixel, every keypoint more than a pixel off pulls with full force. In
/// stride units the quadratic zone reached 4 px and a 1 px error pulled with a quarter of the
/// gradient, which left the keypoint error stalling at 1.5 px while the classes were learnt.
const OFFSET_WEIGHT: f32 = 1.0;

/// A batch on the device.
pub struct Batch {
    pub input: Tensor<4>,
    classes: Vec<i32>,
    onehot: Tensor<2>,
    offsets: Tensor<2>,
    positive: Tensor<2>,
    mask: Tensor<4>,
    template: Tensor<2>,
    n: usize,
    anchors: usize,
    positives: usize,
    /// Patch pixels per anchor.
    stride: f32,
}

impl Batch {
    pub fn new(samples: &[PatchSample], classes: usize, size: usize, device: &Device) -> Self {
        let n = samples.len();
        let anchors = samples[0].targets.classes.len();
        let g = (anchors as f64).sqrt() as usize;
        let input: Vec<f32> = samples
            .iter()
            .flat_map(|s| s.input.iter().copied())
            .collect();
        let cls: Vec<i32> = samples
            .iter()
            .flat_map(|s| s.targets.classes.iter().copied())
            .collect();
        let mut onehot = vec![0.0f32; n * anchors * classes];
        for (i, &c) in cls.iter().enumerate() {
            if c != IGNORE {
                onehot[i * classes + c as usize] = 1.0;
            }
        }
        let offsets: Vec<f32> = samples
            .iter()
            .flat_map(|s| s.targets.offsets.iter().flatten().copied())
            .collect();
        let positive: Vec<f32> = cls.iter().map(|&c| f32::from(u8::from(c > 0))).collect();
        let positives = positive.iter().filter(|&&p| p > 0.0).count();
        let mask: Vec<f32> = samples
            .iter()
            .flat_map(|s| s.targets.mask.iter().copied())
            .collect();
        let template: Vec<f32> = samples
            .iter()
            .flat_map(|s| template_flat(&s.targets.template))
            .collect();
        let t2 = |v: Vec<f32>, cols: usize| {
            Tensor::<2>::from_data(TensorData::new(v, [n * anchors, cols]), device)
        };
        Self {
            input: Tensor::from_data(TensorData::new(input, [n, 1, size, size]), device),
            classes: cls,
            onehot: t2(onehot, classes),
            offsets: t2(offsets, 2),
            positive: t2(positive, 1),
            mask: Tensor::from_data(TensorData::new(mask, [n, 1, g, g]), device),
            template: Tensor::from_data(TensorData::new(template, [n, 8]), device),
            n,
            anchors,
            positives,
            stride: (size / g) as f32,
        }
    }
}

/// Loss terms of a step (already weighted), for the progress display.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LossTerms {
    #[serde(with = "crate::io::json_float")]
    pub total: f32,
    #[serde(with = "crate::io::json_float")]
    pub confidence: f32,
    #[serde(with = "crate::io::json_float")]
    pub offset: f32,
    #[serde(with = "crate::io::json_float")]
    pub mask: f32,
    #[serde(with = "crate::io::json_float")]
    pub template: f32,
}

pub(crate) fn smooth_l1<const D: usize>(d: Tensor<D>) -> Tensor<D> {
    // 0.5·d² below 1, d − 0.5 above, written without a branch: with m = min(|d|, 1),
    // 0.5·m² + (|d| − m).
    let a = d.abs();
    let m = a.clone().clamp_max(1.0);
    m.clone().square().mul_scalar(0.5) + (a - m)
}

/// The total loss (to differentiate) and its terms.
pub fn losses(out: Outputs, batch: &Batch) -> (Tensor<1>, LossTerms) {
    let na = batch.n * batch.anchors;
    let classes = out.logits.dims()[1];
    let logits = out.logits.permute([0, 2, 3, 1]).reshape([na, classes]);
    let logp = log_softmax(logits, 1);
    let ce = (logp.clone() * batch.onehot.clone()).sum_dim(1).neg();
    // Hard negatives: the background anchors the network is most wrong about.
    let background_loss: Vec<f32> = logp
        .slice([0..na, 0..1])
        .neg()
        .into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .expect("f32 tensor");
    let mut weight = vec![0.0f32; na];
    for s in 0..batch.n {
        let range = s * batch.anchors..(s + 1) * batch.anchors;
        let positives = batch.classes[range.clone()]
            .iter()
            .filter(|&&c| c > 0)
            .count();
        let mut negatives: Vec<usize> = range.clone().filter(|&i| batch.classes[i] == 0).collect();
        negatives.sort_by(|&a, &b| background_loss[b].total_cmp(&background_loss[a]));
        let keep = (NEGATIVES_PER_POSITIVE * positives.max(1)).min(negatives.len());
        for &i in &negatives[..keep] {
            weight[i] = 1.0;
        }
        for i in range.filter(|&i| batch.classes[i] > 0) {
            weight[i] = 1.0;
        }
    }
    let device = ce.device();
    let weight = Tensor::<2>::from_data(TensorData::new(weight, [na, 1]), &device);
    let norm = batch.positives.max(1) as f32;
    let confidence = (ce * weight).sum().div_scalar(norm);

    let offsets = out.offsets.permute([0, 2, 3, 1]).reshape([na, 2]);
    let error_px = (offsets - batch.offsets.clone()).mul_scalar(batch.stride);
    let offset = (smooth_l1(error_px) * batch.positive.clone())
        .sum()
        .mul_scalar(OFFSET_WEIGHT / norm);

    let mask = (sigmoid(out.mask) - batch.mask.clone()).square().mean();

    let template = out.template.permute([0, 2, 3, 1]).reshape([batch.n, 8]);
    let template = smooth_l1(template - batch.template.clone())
        .sum()
        .div_scalar(batch.n as f32);

    let total = confidence.clone() + offset.clone() + mask.clone() + template.clone();
    let scalar = |t: Tensor<1>| -> f32 {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .expect("f32 tensor")[0]
    };
    let terms = LossTerms {
        total: 0.0,
        confidence: scalar(confidence.detach()),
        offset: scalar(offset.detach()),
        mask: scalar(mask.detach()),
        template: scalar(template.detach()),
    };
    let terms = LossTerms {
        total: terms.confidence + terms.offset + terms.mask + terms.template,
        ..terms
    };
    (total, terms)
}
