//! The stage-2 network (docs/ARCHITECTURE.md §9.2): a MobileNet-style depthwise-separable trunk to
//! stride 4 on a 128² patch (the reference: stride 8 on 256², the same anchors per cell pitch), a
//! mask head whose output is concatenated back onto the features (the reference's "align"), a
//! one-scale anchor predictor (C + 1 class logits and a 2-D offset per anchor) and the 2 × 2
//! template predictor.
//!
//! Sizes are chosen for two CPU cores: the reference runs five 512-channel blocks at stride 8
//! (1.76 M parameters, 1.9 GMAC per patch); here the widest layer has `width` channels (32 by
//! default: 12.7 k parameters, 10 MMAC per 128² patch) and dilations 2 and 4 give the receptive field (≈ 80 px, seven cells of 36h11) that
//! the reference gets from depth. See [`macs`] for the arithmetic.

use super::anchors::RawOutputs;
use crate::detect::blocks::{
    batch_norm_unless, fold_batch_norm, folded_blocks, separable_trunk, stem, trunk_blocks,
    SeparableBlock,
};
use crate::detect::plain_net::PlainNet;
use burn::module::Module;
use burn::nn::conv::{Conv2d, Conv2dConfig};
use burn::nn::{BatchNorm, BatchNormConfig, PaddingConfig2d};
use burn::tensor::activation::relu;
use burn::tensor::{Device, Tensor};
use serde::{Deserialize, Serialize};

/// Shape of the network; stored in the model file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct NetConfig {
    /// Anchor classes: the family's categories + background.
    pub classes: usize,
    /// Channels of the widest layers; the stem has a quarter, the first block half.
    pub width: usize,
    /// Patch side in pixels: the anchor grid is a quarter of it, and the template head halves
    /// that grid down to 2 × 2, so it is 8 times a power of two.
    pub patch: usize,
}

impl NetConfig {
    fn trunk(&self) -> [(usize, usize, usize, usize); 5] {
        separable_trunk(self.width)
    }

    /// Separable blocks of the template head: stride 2 from the anchor grid down to 2 × 2.
    fn template_blocks(&self) -> usize {
        let mut g = self.patch / 4;
        let mut n = 0;
        while g > 2 {
            g /= 2;
            n += 1;
        }
        n
    }

    /// The layer that classes each anchor (the family's categories and the background), freshly
    /// initialised.
    fn class_head(&self, device: &Device) -> Conv2d {
        Conv2dConfig::new([self.width, self.classes], [3, 3])
            .with_padding(PaddingConfig2d::Explicit(1, 1, 1, 1))
            .init(device)
    }

    pub fn init(&self, device: &Device) -> Stage2Net {
        let w = self.width;
        let conv = |cin: usize, cout: usize, k: usize| {
            Conv2dConfig::new([cin, cout], [k, k])
                .with_padding(PaddingConfig2d::Explicit(k / 2, k / 2, k / 2, k / 2))
                .init(device)
        };
        Stage2Net {
            stem: stem(w, device),
            stem_bn: BatchNormConfig::new(w / 4).init(device),
            trunk: trunk_blocks(w, device),
            mask: conv(w, 1, 1),
            align: conv(w + 1, w, 1),
            keypoint: SeparableBlock::new(w, w, 1, 1, device),
            classes: self.class_head(device),
            offsets: conv(w, 2, 3),
            template: (0..self.template_blocks())
                .map(|i| SeparableBlock::new(if i == 0 { w } else { w / 2 }, w / 2, 2, 1, device))
                .collect(),
            template_out: conv(w / 2, 2, 1),
            folded: false,
        }
    }
}

#[derive(Module, Debug)]
pub struct Stage2Net {
    stem: Conv2d,
    stem_bn: BatchNorm,
    trunk: Vec<SeparableBlock>,
    mask: Conv2d,
    align: Conv2d,
    keypoint: SeparableBlock,
    classes: Conv2d,
    offsets: Conv2d,
    template: Vec<SeparableBlock>,
    template_out: Conv2d,
    /// See [`SeparableBlock::fold_batch_norms`].
    folded: bool,
}

/// Raw outputs for a batch of N patches on a G × G anchor grid.
pub struct Outputs {
    /// N × (C + 1) × G × G class logits, background first.
    pub logits: Tensor<4>,
    /// N × 2 × G × G offsets in strides.
    pub offsets: Tensor<4>,
    /// N × 1 × G × G marker-mask logits.
    pub mask: Tensor<4>,
    /// N × 2 × 2 × 2: (x, y) × 2 × 2 anchors, encoded as the anchors module says.
    pub template: Tensor<4>,
}

impl Stage2Net {
    /// The network with a fresh class head for `config`'s classes (its width the network's):
    /// a design of other categories fine-tunes from what the trunk learned of frames, cells and
    /// perspective, and learns only what its own categories look like from scratch.
    pub(crate) fn with_class_head(self, config: &NetConfig, device: &Device) -> Self {
        Self {
            classes: config.class_head(device),
            ..self
        }
    }

    /// `x`: N × 1 × P × P normalised patches.
    pub fn forward(&self, x: Tensor<4>) -> Outputs {
        let mut x = relu(batch_norm_unless(
            self.folded,
            &self.stem_bn,
            self.stem.forward(x),
        ));
        for block in &self.trunk {
            x = block.forward(x);
        }
        let mask = self.mask.forward(x.clone());
        let features = relu(self.align.forward(Tensor::cat(vec![mask.clone(), x], 1)));
        let k = self.keypoint.forward(features.clone());
        let mut t = features;
        for block in &self.template {
            t = block.forward(t);
        }
        Outputs {
            logits: self.classes.forward(k.clone()),
            offsets: self.offsets.forward(k),
            mask,
            template: self.template_out.forward(t),
        }
    }

    /// The folded network's branches as plain loops ([`PlainStage2`]), which detection runs.
    pub fn plain(&self) -> PlainStage2 {
        let net = self.clone().fold_batch_norms();
        let chain = |convs: &[(&Conv2d, bool)]| {
            PlainNet::from_convs(convs).expect("the stage-2 network's layers all have plain forms")
        };
        let mut trunk = vec![(&net.stem, true)];
        for block in &net.trunk {
            trunk.extend(block.convs());
        }
        let mut template = Vec::new();
        for block in &net.template {
            template.extend(block.convs());
        }
        template.push((&net.template_out, false));
        PlainStage2 {
            trunk: chain(&trunk),
            mask: chain(&[(&net.mask, false)]),
            align: chain(&[(&net.align, true)]),
            keypoint: chain(&net.keypoint.convs()),
            classes: chain(&[(&net.classes, false)]),
            offsets: chain(&[(&net.offsets, false)]),
            template: chain(&template),
        }
    }

    /// The network for inference: every batch norm folded into its convolution
    /// ([`fold_batch_norm`]); the same function, without the batch norms' passes.
    pub fn fold_batch_norms(mut self) -> Self {
        if !self.folded {
            fold_batch_norm(&mut self.stem, &self.stem_bn);
            self.trunk = folded_blocks(self.trunk);
            self.keypoint = self.keypoint.fold_batch_norms();
            self.template = folded_blocks(self.template);
            self.folded = true;
        }
        self
    }
}

/// Multiply-accumulates of one forward pass on one patch, counted layer by layer (convolutions
/// only; BN, ReLU and the concatenation are negligible).
pub fn macs(config: &NetConfig) -> u64 {
    let conv = |side: usize, cin: usize, cout: usize, k: usize, groups: usize| -> u64 {
        (side * side * cout * (cin / groups) * k * k) as u64
    };
    let w = config.width;
    let mut side = config.patch / 2;
    let mut total = conv(side, 1, w / 4, 3, 1);
    let sep = |side: usize, cin: usize, cout: usize| {
        conv(side, cin, cin, 3, cin) + conv(side, cin, cout, 1, 1)
    };
    for (cin, cout, s, _) in config.trunk() {
        side /= s;
        total += sep(side, cin, cout);
    }
    total += conv(side, w, 1, 1, 1) + conv(side, w + 1, w, 1, 1);
    total += sep(side, w, w) + conv(side, w, config.classes, 3, 1) + conv(side, w, 2, 3, 1);
    let mut cin = w;
    for _ in 0..config.template_blocks() {
        side /= 2;
        total += sep(side, cin, w / 2);
        cin = w / 2;
    }
    total + conv(side, w / 2, 2, 1, 1)
}

/// [`Stage2Net::forward`]'s branches as plain chains: the trunk; the mask, concatenated before
/// the trunk's channels into the alignment layer; from its features the keypoint block with
/// its class and offset heads, and the template head.
pub struct PlainStage2 {
    trunk: PlainNet,
    mask: PlainNet,
    align: PlainNet,
    keypoint: PlainNet,
    classes: PlainNet,
    offsets: PlainNet,
    template: PlainNet,
}

impl PlainStage2 {
    /// One normalised `size` × `size` patch → its outputs, class logits softmaxed.
    pub fn outputs(&self, patch: &[f32], size: usize) -> RawOutputs {
        let (g, _) = self.trunk.output_size(size, size);
        let features = self.trunk.forward(patch, 1, size, size);
        let mut with_mask = self.mask.forward(&features, 1, g, g);
        with_mask.extend_from_slice(&features);
        let aligned = self.align.forward(&with_mask, 1, g, g);
        let keypoint = self.keypoint.forward(&aligned, 1, g, g);
        let logits = self.classes.forward(&keypoint, 1, g, g);
        let offsets = self.offsets.forward(&keypoint, 1, g, g);
        let (tg, _) = self.template.output_size(g, g);
        let template = self.template.forward(&aligned, 1, g, g);
        debug_assert_eq!((tg, template.len()), (2, 8), "a 2 × 2 template grid");
        let anchors = g * g;
        let classes = self.classes.output_channels();
        let mut probs = Vec::with_capacity(anchors * classes);
        for a in 0..anchors {
            let logit = |c: usize| logits[c * anchors + a];
            let top = (0..classes).map(logit).fold(f32::NEG_INFINITY, f32::max);
            let start = probs.len();
            probs.extend((0..classes).map(|c| (logit(c) - top).exp()));
            let sum: f32 = probs[start..].iter().sum();
            probs[start..].iter_mut().for_each(|p| *p /= sum);
        }
        // Template planes x then y over the 2 × 2 grid (TL, TR, BL, BR); the outputs run
        // TL, TR, BR, BL.
        let at = |flat: usize| [template[flat], template[4 + flat]];
        RawOutputs {
            probs,
            classes,
            offsets: (0..anchors)
                .map(|a| [offsets[a], offsets[anchors + a]])
                .collect(),
            template: [at(0), at(1), at(3), at(2)],
        }
    }
}
