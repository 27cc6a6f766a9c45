//! The verifier's network: the stage-2 layers' stem and three depthwise-separable blocks on a
//! small rectified patch, down to stride 8, then one logit per cell averaged over the patch. It
//! answers one question — is a square marker of some family framed by this quad? — for a
//! thousandth of a stage-2 pass's arithmetic (see [`macs`]).

use crate::detect::blocks::{
    batch_norm_unless, fold_batch_norm, folded_blocks, stem, SeparableBlock,
};
use crate::detect::plain_net::PlainNet;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetConfig {
    /// Channels of the last blocks; the stem has a quarter, the first block half.
    pub width: usize,
    /// The rectified patch's side in pixels (a multiple of 8).
    pub patch: usize,
}

/// (input channels, output channels, stride) of the blocks after the stride-2 stem.
fn blocks(width: usize) -> [(usize, usize, usize); 3] {
    let w = width;
    [(w / 4, w / 2, 2), (w / 2, w, 2), (w, w, 1)]
}

impl NetConfig {
    pub fn init(&self, device: &Device) -> VerifierNet {
        let w = self.width;
        VerifierNet {
            stem: stem(w, device),
            stem_bn: BatchNormConfig::new(w / 4).init(device),
            blocks: blocks(w)
                .iter()
                .map(|&(cin, cout, stride)| SeparableBlock::new(cin, cout, stride, 1, device))
                .collect(),
            out: Conv2dConfig::new([w, 1], [1, 1]).init(device),
            folded: false,
        }
    }
}

#[derive(Module, Debug)]
pub struct VerifierNet {
    stem: Conv2d,
    stem_bn: BatchNorm,
    blocks: Vec<SeparableBlock>,
    out: Conv2d,
    /// See [`VerifierNet::fold_batch_norms`].
    folded: bool,
}

impl VerifierNet {
    /// `x`: N × 1 × P × P normalised patches → N logits (marker or not).
    pub fn forward(&self, x: Tensor<4>) -> Tensor<1> {
        let mut x = relu(batch_norm_unless(
            self.folded,
            &self.stem_bn,
            self.stem.forward(x),
        ));
        for block in &self.blocks {
            x = block.forward(x);
        }
        let cells = self.out.forward(x);
        let [n, _, h, w] = cells.dims();
        cells.reshape([n, h * w]).mean_dim(1).reshape([n])
    }

    /// The network for inference, its batch norms folded into the convolutions.
    pub fn fold_batch_norms(mut self) -> Self {
        if !self.folded {
            fold_batch_norm(&mut self.stem, &self.stem_bn);
            self.blocks = folded_blocks(self.blocks);
            self.folded = true;
        }
        self
    }

    /// The folded network as plain loops, up to the per-cell logits (their mean is the logit).
    pub fn plain(&self) -> PlainNet {
        let net = self.clone().fold_batch_norms();
        let mut convs: Vec<(&Conv2d, bool)> = vec![(&net.stem, true)];
        for block in &net.blocks {
            convs.extend(block.convs());
        }
        convs.push((&net.out, false));
        PlainNet::from_convs(&convs).expect("the verifier's layers all have plain forms")
    }
}

/// Multiply-accumulates of one patch (convolutions only).
pub fn macs(config: &NetConfig) -> u64 {
    let w = config.width as u64;
    let mut cells = (config.patch * config.patch) as u64 / 4;
    let mut total = cells * 9 * (w / 4);
    for (cin, cout, stride) in blocks(config.width) {
        cells /= (stride * stride) as u64;
        total += cells * (cin as u64 * 9 + (cin * cout) as u64);
    }
    total + cells * w
}
