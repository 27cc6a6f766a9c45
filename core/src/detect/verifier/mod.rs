//! The learned verifier (docs/ARCHITECTURE.md §9.8, the verify phase): before a candidate quad
//! costs stage-2 passes, a small network looks at the image rectified by the quad and says how
//! likely a square marker of any family frames it. Stage 1 and the image searches propose 20–130
//! quads on a cluttered photograph, most of them windows, tiles, text and shadows; a stage-2
//! pass costs a thousand times the verifier's arithmetic.
//!
//! The verifier belongs to no family: it is trained on the markers of the square built-ins and of
//! random designs against the false quads stage 1 itself proposes on cluttered scenes
//! (`train::verifier`), so a user's own square design passes it without training.

pub mod model_file;
pub mod net;

use super::blocks::Contrast;
use super::cells::square_to_quad;
use super::model_file::ModelError;
use super::plain_net::PlainNet;
use crate::geometry::{warp_bilinear, Homography, Quad};
use crate::image::GrayImage;
use burn::tensor::Device;
use model_file::VerifierHeader;
use net::{NetConfig, VerifierNet};
use std::path::Path;

/// Where the verifier's weights ship, under `assets/`.
pub const SHIPPED: &str = "models/square.verifier.bin";

/// The share of the patch's side left around the quad on each side: the verifier sees the
/// quiet zone and the surroundings a marker stands out from.
pub const MARGIN: f64 = 0.15;

/// Gray level of a patch pixel outside the image (normalised to about zero).
const OUTSIDE: u8 = 128;

/// How the verify phase uses the verifier.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct VerifierParams {
    /// Quads the verifier scores below this (a probability) get no stage-2 pass. 0 turns the
    /// verifier off. The figure that sets it — markers kept against passes saved on fresh
    /// seeds and photographs — is in BENCHMARKS.md ("A learned verifier").
    pub min_score: f32,
}

impl Default for VerifierParams {
    fn default() -> Self {
        Self { min_score: 0.5 }
    }
}

pub struct Verifier {
    /// The folded network as plain loops, up to its per-cell logits.
    net: PlainNet,
    pub config: NetConfig,
    pub header: VerifierHeader,
}

impl Verifier {
    pub fn load(path: &Path) -> Result<Self, ModelError> {
        let (net, header) = model_file::load(path, &Device::flex())?;
        Ok(Self::new(&net, header))
    }

    pub fn from_bytes(bytes: &[u8], name: &str) -> Result<Self, ModelError> {
        let (net, header) = model_file::from_bytes(bytes, name, &Device::flex())?;
        Ok(Self::new(&net, header))
    }

    /// The verifier shipped in `assets/models/`, when this build ships one.
    pub fn shipped() -> Option<Result<Self, ModelError>> {
        crate::assets::MODELS
            .contains(&SHIPPED)
            .then(|| Self::from_bytes(crate::assets::file(SHIPPED), "shipped verifier"))
    }

    /// A network in training, as the detector would run it (validation, pictures).
    pub fn of_network(net: &VerifierNet, config: NetConfig) -> Self {
        let header = VerifierHeader {
            format: 1,
            net: config,
            steps: 0,
            families: Vec::new(),
            weights_fnv: String::new(),
        };
        Self::new(net, header)
    }

    pub(crate) fn new(net: &VerifierNet, header: VerifierHeader) -> Self {
        Self {
            net: net.plain(),
            config: header.net,
            header,
        }
    }

    /// The probability that each quad frames a marker (0 for a quad no homography maps to).
    pub fn scores(&self, image: &GrayImage, quads: &[Quad]) -> Vec<f32> {
        let side = self.config.patch;
        let mut input = Vec::with_capacity(quads.len() * side * side);
        let mut mapped = Vec::with_capacity(quads.len());
        for quad in quads {
            match input_patch(image, quad, side) {
                Some(patch) => {
                    input.extend(patch);
                    mapped.push(true);
                }
                None => mapped.push(false),
            }
        }
        let n = mapped.iter().filter(|&&m| m).count();
        let logits = if n == 0 {
            Vec::new()
        } else {
            mean_logits(&self.net.forward(&input, n, side, side), n)
        };
        let mut logits = logits.into_iter();
        mapped
            .into_iter()
            .map(|m| match m {
                true => sigmoid(logits.next().unwrap_or(f32::NEG_INFINITY)),
                false => 0.0,
            })
            .collect()
    }
}

/// The network's input for `quad`: its [`rectified`] patch, normalised as stage 2's patches are
/// (training and detection both take it from here).
pub fn input_patch(image: &GrayImage, quad: &Quad, side: usize) -> Option<Vec<f32>> {
    let patch = rectified(image, quad, side)?;
    Some(Contrast::of(&patch).normalise(&patch))
}

/// Each of `n` patches' per-cell logits, averaged: the network's logit.
fn mean_logits(cells: &[f32], n: usize) -> Vec<f32> {
    let per = cells.len() / n.max(1);
    cells
        .chunks(per.max(1))
        .map(|c| c.iter().sum::<f32>() / per as f32)
        .collect()
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// The image rectified by `quad` into a `side` × `side` patch, the quad's corners at
/// [`MARGIN`] of the side from the patch's edges (corner 0 top left, then clockwise on screen for
/// a quad that is so in the image); `None` for a degenerate quad.
pub fn rectified(image: &GrayImage, quad: &Quad, side: usize) -> Option<GrayImage> {
    let to_image = square_to_quad(quad)?;
    // Patch pixel centres (u + ½) / side, the quad spanning [MARGIN, 1 − MARGIN] of the side.
    let a = 1.0 / (side as f64 * (1.0 - 2.0 * MARGIN));
    let b = (0.5 / side as f64 - MARGIN) / (1.0 - 2.0 * MARGIN);
    let to_square = nalgebra::Matrix3::new(a, 0.0, b, 0.0, a, b, 0.0, 0.0, 1.0);
    let h = Homography(to_image * to_square);
    let side = side as u32;
    Some(warp_bilinear(image, &h, side, side, OUTSIDE))
}

#[cfg(test)]
mod tests;
