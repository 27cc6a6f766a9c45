//! The stage-1 network (docs/ARCHITECTURE.md §9.8): a depthwise-separable trunk to stride 4 on
//! the whole (downscaled) image, dilations 1, 2 and 4 for a ≈ 75 px receptive field, and one
//! head on the stride-4 grid with six maps: a marker-corner heat map (one logit), the corner's
//! offset within its cell (2), the unit direction from the corner to the marker's centre (2) and
//! the marker/background mask (1).
//!
//! The reference predicts ordered ROIs over multi-scale default boxes from a 512-channel trunk
//! (≈ 16 GMAC per 640×448 image). Here ROIs are assembled from the corners and their directions
//! ([`super::group`]) and large markers are found on a coarser level of an image pyramid, so one
//! small head at one scale serves markers from 12 px to the whole image (≈ 0.15 GMAC per
//! 640×480 at width 24). See [`macs`].

use crate::detect::blocks::{
    batch_norm_unless, fold_batch_norm, folded_blocks, separable_trunk, stem, trunk_blocks,
    SeparableBlock,
};
use crate::detect::plain_net::PlainNet;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

/// Output maps: heat, offset x/y, direction x/y, mask.
pub const MAPS: usize = 6;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetConfig {
    /// Channels of the stride-4 layers; the stem has a quarter, the first block half.
    pub width: usize,
}

impl NetConfig {
    pub fn init(&self, device: &Device) -> Stage1Net {
        let w = self.width;
        Stage1Net {
            stem: stem(w, device),
            stem_bn: BatchNormConfig::new(w / 4).init(device),
            trunk: trunk_blocks(w, device),
            head: SeparableBlock::new(w, w, 1, 1, device),
            out: Conv2dConfig::new([w, MAPS], [1, 1]).init(device),
            folded: false,
        }
    }
}

#[derive(Module, Debug)]
pub struct Stage1Net {
    stem: Conv2d,
    stem_bn: BatchNorm,
    trunk: Vec<SeparableBlock>,
    head: SeparableBlock,
    out: Conv2d,
    /// See [`Stage1Net::fold_batch_norms`].
    folded: bool,
}

impl Stage1Net {
    /// `x`: N × 1 × H × W normalised images (H, W multiples of [`super::STRIDE`]) → N × [`MAPS`] ×
    /// H/4 × W/4 raw maps (logits for heat and mask).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<4> {
        let mut x = relu(batch_norm_unless(
            self.folded,
            &self.stem_bn,
            self.stem.forward(x),
        ));
        for block in &self.trunk {
            x = block.forward(x);
        }
        self.out.forward(self.head.forward(x))
    }

    /// The network for inference: every batch norm folded into its convolution (the same
    /// function without the batch norms' passes; see `blocks::fold_batch_norm`).
    pub fn fold_batch_norms(mut self) -> Self {
        if !self.folded {
            fold_batch_norm(&mut self.stem, &self.stem_bn);
            self.trunk = folded_blocks(self.trunk);
            self.head = self.head.fold_batch_norms();
            self.folded = true;
        }
        self
    }
}

impl Stage1Net {
    /// The folded network as plain loops ([`PlainNet`]), which detection runs.
    pub fn plain(&self) -> PlainNet {
        let net = self.clone().fold_batch_norms();
        let mut convs: Vec<(&Conv2d, bool)> = vec![(&net.stem, true)];
        for block in net.trunk.iter().chain([&net.head]) {
            convs.extend(block.convs());
        }
        convs.push((&net.out, false));
        PlainNet::from_convs(&convs).expect("the stage-1 network's layers all have plain forms")
    }
}

/// How far from an output cell's centre (in input pixels, along either axis) the input can
/// change its value: the 3 × 3 stem, the trunk's 3 × 3 depthwise layers at their strides and
/// dilations, and the head's.
pub fn receptive_radius() -> usize {
    // The width does not change the geometry.
    let mut radius = 1;
    let mut step = 2;
    for (_, _, stride, dilation) in separable_trunk(4) {
        radius += dilation * step;
        step *= stride;
    }
    radius + step
}

/// Multiply-accumulates of one forward pass over `pixels` input pixels (convolutions only).
pub fn macs(config: &NetConfig, pixels: u64) -> u64 {
    let w = config.width as u64;
    let half = pixels / 4;
    let quarter = pixels / 16;
    let sep = |cells: u64, cin: u64, cout: u64| cells * (cin * 9 + cin * cout);
    let mut total = half * 9 * (w / 4);
    total += sep(half, w / 4, w / 2);
    total += sep(quarter, w / 2, w);
    total += 3 * sep(quarter, w, w);
    total += sep(quarter, w, w);
    total + quarter * w * MAPS as u64
}

#[cfg(test)]
mod tests {
    use super::super::model_file;
    use crate::detect::plain_net::largest_difference;

    #[test]
    fn the_receptive_field_reaches_37_pixels_from_a_cell() {
        // Stem 1, trunk 2 + 2 + 4 + 8 + 16 (stride 4 from its second block), head 4.
        assert_eq!(super::receptive_radius(), 37);
    }
    use super::super::pipeline::shipped_stage1;
    use burn::tensor::{Device, Tensor, TensorData};

    /// Every detection runs the folded network as plain loops: its maps must be the shipped
    /// network's.
    #[test]
    fn folded_batch_norms_compute_what_the_shipped_network_does() {
        let device = Device::flex();
        let (net, _) = model_file::from_bytes(shipped_stage1(), "shipped", &device).unwrap();
        let (w, h) = (96, 64);
        let pixels: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let inside = (20..52).contains(&x) && (16..48).contains(&y);
                let cell = ((x / 8 + y / 8) % 2) as f32 * 1.2 - 0.6;
                if inside {
                    cell
                } else {
                    0.8 - ((x * 5 + y * 11) % 7) as f32 * 0.04
                }
            })
            .collect();
        let input =
            || Tensor::<4>::from_data(TensorData::new(pixels.clone(), [1, 1, h, w]), &device);
        let before = net
            .forward(input())
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        let plain = net.plain().forward(&pixels, 1, h, w);
        let after = (net.fold_batch_norms().forward(input()).into_data())
            .try_to_vec::<f32>()
            .unwrap();
        let largest = before.iter().fold(1.0f32, |m, v| m.max(v.abs()));
        for (name, maps) in [("folded", after), ("plain", plain)] {
            let worst = largest_difference(&before, &maps);
            assert!(
                worst <= 1e-4 * largest,
                "{name} maps differ by {worst} (largest {largest})"
            );
        }
    }
}
