//! Stage-1 losses: the CenterNet focal loss on the corner heat map (positives are the corners'
//! own cells, negatives are weighted down near a corner by (1 − bump)⁴), smooth-L1 on the
//! corner offsets and squared error on the directions in the cells around each corner, binary
//! cross-entropy on the mask, small markers' cells weighted up ([`super::data::mask_weights`]).

use super::data::SceneSample;
use crate::train::stage2::loss::smooth_l1;
use burn::tensor::activation::{log_sigmoid, sigmoid};
use burn::tensor::{Device, Tensor, TensorData};

pub struct Batch {
    pub input: Tensor<4>,
    heat: Tensor<4>,
    positive: Tensor<4>,
    regress: Tensor<4>,
    offset: Tensor<4>,
    direction: Tensor<4>,
    mask: Tensor<4>,
    mask_weight: Tensor<4>,
    positives: usize,
    regressed: usize,
}

impl Batch {
    pub fn new(samples: &[SceneSample], device: &Device) -> Self {
        let n = samples.len();
        let t0 = &samples[0].targets;
        let (rows, columns) = (t0.rows, t0.columns);
        let side = (rows * 4, columns * 4);
        let one = |f: &dyn Fn(&SceneSample) -> Vec<f32>, channels: usize| {
            let data: Vec<f32> = samples.iter().flat_map(f).collect();
            Tensor::<4>::from_data(TensorData::new(data, [n, channels, rows, columns]), device)
        };
        let planes = |v: &[[f32; 2]]| -> Vec<f32> {
            v.iter()
                .map(|p| p[0])
                .chain(v.iter().map(|p| p[1]))
                .collect()
        };
        let input: Vec<f32> = samples.iter().flat_map(|s| s.input.clone()).collect();
        let positives = samples
            .iter()
            .map(|s| s.targets.heat.iter().filter(|&&h| h == 1.0).count())
            .sum();
        let regressed = samples
            .iter()
            .map(|s| s.targets.regress.iter().filter(|&&r| r > 0.0).count())
            .sum();
        Self {
            input: Tensor::from_data(TensorData::new(input, [n, 1, side.0, side.1]), device),
            heat: one(&|s| s.targets.heat.clone(), 1),
            positive: one(
                &|s| {
                    s.targets
                        .heat
                        .iter()
                        .map(|&h| f32::from(u8::from(h == 1.0)))
                        .collect()
                },
                1,
            ),
            regress: one(&|s| s.targets.regress.clone(), 1),
            offset: one(&|s| planes(&s.targets.offset), 2),
            direction: one(&|s| planes(&s.targets.direction), 2),
            mask: one(&|s| s.targets.mask.clone(), 1),
            mask_weight: one(&|s| s.mask_weight.clone(), 1),
            positives,
            regressed,
        }
    }
}

#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LossTerms {
    #[serde(with = "crate::io::json_float")]
    pub total: f32,
    #[serde(with = "crate::io::json_float")]
    pub heat: f32,
    #[serde(with = "crate::io::json_float")]
    pub offset: f32,
    #[serde(with = "crate::io::json_float")]
    pub direction: f32,
    #[serde(with = "crate::io::json_float")]
    pub mask: f32,
}

/// The total loss (to differentiate) and its terms.
pub fn losses(out: Tensor<4>, b: &Batch) -> (Tensor<1>, LossTerms) {
    let [n, _, rows, columns] = out.dims();
    let channel = |c: std::ops::Range<usize>| out.clone().slice([0..n, c, 0..rows, 0..columns]);
    let x = channel(0..1);
    let p = sigmoid(x.clone());
    let one_minus = |t: Tensor<4>| t.neg().add_scalar(1.0);
    let pos = b.positive.clone() * one_minus(p.clone()).square() * log_sigmoid(x.clone()).neg();
    let neg = one_minus(b.positive.clone())
        * one_minus(b.heat.clone()).square().square()
        * p.square()
        * log_sigmoid(x.neg()).neg();
    let heat = (pos + neg).sum().div_scalar(b.positives.max(1) as f32);

    let norm = b.regressed.max(1) as f32;
    let offset = (smooth_l1(channel(1..3) - b.offset.clone()) * b.regress.clone())
        .sum()
        .div_scalar(norm);
    let direction = ((channel(3..5) - b.direction.clone()).square() * b.regress.clone())
        .sum()
        .div_scalar(norm);

    let m = channel(5..6);
    let mask = ((b.mask.clone() * log_sigmoid(m.clone())
        + one_minus(b.mask.clone()) * log_sigmoid(m.neg()))
        * b.mask_weight.clone())
    .mean()
    .neg();

    let total = heat.clone() + offset.clone() + direction.clone() + mask.clone();
    let scalar = |t: Tensor<1>| -> f32 {
        t.into_data()
            .convert::<f32>()
            .try_into_vec::<f32>()
            .expect("f32 tensor")[0]
    };
    let mut terms = LossTerms {
        total: 0.0,
        heat: scalar(heat.detach()),
        offset: scalar(offset.detach()),
        direction: scalar(direction.detach()),
        mask: scalar(mask.detach()),
    };
    terms.total = terms.heat + terms.offset + terms.direction + terms.mask;
    (total, terms)
}
