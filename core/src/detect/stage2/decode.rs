//! From one patch's network outputs to a decoded marker: extract the keypoints, sort them to the
//! family's template, read each slot's category, decode the ID. Inference
//! ([`super::Stage2`]) and training's validation run this same chain, so what validation scores
//! is what a user gets.

use super::anchors::{extract, Found, PatchSpec, RawOutputs};
use super::sort::{read_slots, sort_to_template, Sorted};
use crate::family::{decode_soft, Decoded, Family};

/// Anchors whose best symbol probability is below this are background (the reference's 0.3).
pub const MIN_CONFIDENCE: f64 = 0.3;

/// What a patch shows, step by step.
#[derive(Debug, Clone)]
pub struct PatchReading {
    pub found: Vec<Found>,
    pub sorted: Sorted,
    /// Per template slot (in the order the marker is seen): the category read, if any.
    pub read: Vec<Option<usize>>,
    /// Per slot: the read category's share of the votes (the decoder's reliability).
    pub reliability: Vec<f64>,
    /// The ID, when the reading decodes.
    pub decoded: Option<Decoded>,
}

/// Runs the chain; `None` when too few keypoints fit the template to place it.
pub fn read_patch(family: &Family, spec: &PatchSpec, raw: &RawOutputs) -> Option<PatchReading> {
    let found = extract(spec, raw, MIN_CONFIDENCE);
    let sorted = sort_to_template(family, &found, &raw.template_corners(spec))?;
    let (read, reliability) = read_slots(family, &sorted, &found);
    let decoded = decode_soft(family, &read, &reliability, None);
    Some(PatchReading {
        found,
        sorted,
        read,
        reliability,
        decoded,
    })
}
