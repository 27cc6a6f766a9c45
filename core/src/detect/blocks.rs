//! The layers both networks are built from (stage 1's and stage 2's, `docs/ARCHITECTURE.md`
//! §9.2): a stride-2 stem, MobileNet-style depthwise-separable blocks, and the folding of their
//! batch norms into the convolutions for inference; and the contrast normalisation of their
//! input. Neither stage's module imports the other: both import this one.

use crate::image::GrayImage;
use burn::module::{Module, Param};
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, PaddingConfig2d};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};

/// The stride-2 3 × 3 stem both networks start with (`width / 4` channels, batch norm after).
pub(crate) fn stem(width: usize, device: &Device) -> Conv2d {
    Conv2dConfig::new([1, width / 4], [3, 3])
        .with_stride([2, 2])
        .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
        .with_bias(false)
        .init(device)
}

/// (input channels, output channels, stride, dilation) of the separable blocks both networks'
/// trunks use after a stride-2 stem of `width / 4` channels: to stride 4, then dilations 1, 2, 4.
pub(crate) fn separable_trunk(width: usize) -> [(usize, usize, usize, usize); 5] {
    let w = width;
    [
        (w / 4, w / 2, 1, 1),
        (w / 2, w, 2, 1),
        (w, w, 1, 1),
        (w, w, 1, 2),
        (w, w, 1, 4),
    ]
}

/// The blocks of [`separable_trunk`].
pub(crate) fn trunk_blocks(width: usize, device: &Device) -> Vec<SeparableBlock> {
    separable_trunk(width)
        .iter()
        .map(|&(cin, cout, s, d)| SeparableBlock::new(cin, cout, s, d, device))
        .collect()
}

/// Depthwise 3 × 3 → BN → ReLU → pointwise 1 × 1 → BN → ReLU.
#[derive(Module, Debug)]
pub struct SeparableBlock {
    depthwise: Conv2d,
    bn1: BatchNorm,
    pointwise: Conv2d,
    bn2: BatchNorm,
    /// The batch norms are folded into the convolutions ([`fold_batch_norm`]) and skipped.
    folded: bool,
}

impl SeparableBlock {
    pub(crate) fn new(
        cin: usize,
        cout: usize,
        stride: usize,
        dilation: usize,
        device: &Device,
    ) -> Self {
        Self {
            depthwise: Conv2dConfig::new([cin, cin], [3, 3])
                .with_stride([stride, stride])
                .with_dilation([dilation, dilation])
                .with_padding(PaddingConfig2d::Explicit(
                    dilation, dilation, dilation, dilation,
                ))
                .with_groups(cin)
                .with_bias(false)
                .init(device),
            bn1: BatchNormConfig::new(cin).init(device),
            pointwise: Conv2dConfig::new([cin, cout], [1, 1])
                .with_bias(false)
                .init(device),
            bn2: BatchNormConfig::new(cout).init(device),
            folded: false,
        }
    }

    pub(crate) fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let x = relu(batch_norm_unless(
            self.folded,
            &self.bn1,
            self.depthwise.forward(x),
        ));
        relu(batch_norm_unless(
            self.folded,
            &self.bn2,
            self.pointwise.forward(x),
        ))
    }

    /// The two convolutions, each followed by a ReLU (with the batch norms, only once folded).
    pub(crate) fn convs(&self) -> [(&Conv2d, bool); 2] {
        [(&self.depthwise, true), (&self.pointwise, true)]
    }

    pub(crate) fn fold_batch_norms(mut self) -> Self {
        if !self.folded {
            fold_batch_norm(&mut self.depthwise, &self.bn1);
            fold_batch_norm(&mut self.pointwise, &self.bn2);
            self.folded = true;
        }
        self
    }
}

pub(crate) fn folded_blocks(blocks: Vec<SeparableBlock>) -> Vec<SeparableBlock> {
    blocks
        .into_iter()
        .map(SeparableBlock::fold_batch_norms)
        .collect()
}

pub(crate) fn batch_norm_unless(folded: bool, bn: &BatchNorm, x: Tensor<4>) -> Tensor<4> {
    if folded {
        x
    } else {
        bn.forward(x)
    }
}

/// Folds an inference-mode batch norm into the convolution before it. Burn's batch norm is four
/// broadcast passes over the activation (subtract, divide, multiply, add) — a fifth of the
/// detector's time on a 640×480 image — where γ (conv(x) + b − μ) / √(σ² + ε) + β is itself a
/// convolution: weights scaled by s = γ / √(σ² + ε) per output channel, bias s (b − μ) + β. The
/// batch norm is left as it was but skipped; a folded network is for inference only (its model
/// file would not load: the biases have no place in the network's layout).
pub(crate) fn fold_batch_norm(conv: &mut Conv2d, bn: &BatchNorm) {
    let weight = conv.weight.val();
    let [out_channels, ..] = weight.dims();
    let scale = bn.gamma.val() / (bn.running_var.value() + bn.epsilon).sqrt();
    let bias = match &conv.bias {
        Some(bias) => bias.val(),
        None => Tensor::zeros([out_channels], &weight.device()),
    };
    let bias = (bias - bn.running_mean.value()) * scale.clone() + bn.beta.val();
    conv.weight = Param::from_tensor(weight * scale.reshape([out_channels, 1, 1, 1]));
    conv.bias = Some(Param::from_tensor(bias));
}

/// The mean and the scale that stage 2's `normalise_patch` maps an image's pixels with: taken from one
/// image, they can normalise another (a crop as it looks within the whole image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contrast {
    mean: f32,
    scale: f32,
}

impl Contrast {
    pub fn of(image: &GrayImage) -> Self {
        let n = image.pixels.len().max(1) as f32;
        let mean = image.pixels.iter().map(|&p| p as f32).sum::<f32>() / n;
        let var = image
            .pixels
            .iter()
            .map(|&p| (p as f32 - mean).powi(2))
            .sum::<f32>()
            / n;
        // A flat patch has no contrast to normalise; 8 gray levels keeps its noise from blowing up.
        Self {
            mean,
            scale: 1.0 / var.sqrt().max(8.0),
        }
    }

    pub fn normalise(&self, image: &GrayImage) -> Vec<f32> {
        (image.pixels.iter())
            .map(|&p| (p as f32 - self.mean) * self.scale)
            .collect()
    }
}
