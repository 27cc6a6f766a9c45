//! From one patch's network outputs to a decoded marker: extract the keypoints, sort them to the
//! family's template, read each slot's category, decode the ID. Inference
//! ([`super::Stage2`]) and training's validation run this same chain, so what validation scores
//! is what a user gets.

use super::anchors::{extract, Found, PatchSpec, RawOutputs};
use super::sort::{read_slots, sort_to_template, Sorted};
use crate::family::{decode_soft, Decoded, Family};
use crate::geometry::Quad;

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
    let corners = raw.template_corners(spec);
    let slot_turns = slot_turns(family);
    let mut best: Option<PatchReading> = None;
    for turn in 0..turns_to_try(family) {
        let turned = Quad(std::array::from_fn(|k| corners[(k + turn) % 4]));
        // The turn within a slot that matches the most keypoints is the one decoded.
        let Some(sorted) = (slot_turns.iter())
            .filter_map(|&angle| {
                sort_to_template(family, &found, &turned_about_centre(&turned, angle))
            })
            .max_by_key(|s| s.matched())
        else {
            continue;
        };
        let (read, reliability) = read_slots(family, &sorted, &found);
        let decoded = decode_soft(family, &read, &reliability, None);
        let reading = PatchReading {
            found: Vec::new(),
            sorted,
            read,
            reliability,
            decoded,
        };
        if best.as_ref().is_none_or(|b| reading.better_than(b)) {
            best = Some(reading);
        }
    }
    best.map(|b| PatchReading { found, ..b })
}

/// Turns of the template within one slot's angle tried on a ring family (radians; none on a
/// grid). A ring proposal's turn is wherever its ellipse left it: the network finds the dots
/// where they are but places the template as the patch is turned, up to half a slot off the
/// dots, which the sort's half-pitch match cannot span.
fn slot_turns(family: &Family) -> Vec<f64> {
    match &family.spec().layout {
        crate::family::spec::Layout::Rings(rings) if rings.slots > 0 => {
            let slot = std::f64::consts::TAU / rings.slots as f64;
            (0..SLOT_TURNS)
                .map(|j| ((j as f64 + 0.5) / SLOT_TURNS as f64 - 0.5) * slot)
                .collect()
        }
        _ => vec![0.0],
    }
}

/// Turns tried within a ring's slot (an eighth of a slot apart: RuneTag's outer dots then lie
/// within a sixteenth of their pitch of one).
const SLOT_TURNS: usize = 8;

/// `quad` turned by `angle` about its centre.
fn turned_about_centre(quad: &Quad, angle: f64) -> Quad {
    if angle == 0.0 {
        return *quad;
    }
    let c = quad.centre();
    let (s, co) = angle.sin_cos();
    quad.map(|p| {
        let (x, y) = (p[0] - c[0], p[1] - c[1]);
        [c[0] + co * x - s * y, c[1] + s * x + co * y]
    })
}

/// Quarter turns of the template tried: all four for a ring family turned by its corner marks
/// alone (RuneTag+: its ring proposals put a mark on each corner, but not which), where no
/// rotation of the layout tells them apart for the decoder; one otherwise.
fn turns_to_try(family: &Family) -> usize {
    if family.is_ring_turned_by_marks() {
        4
    } else {
        1
    }
}

impl PatchReading {
    /// A reading that decodes, with fewer corrections and fixed keypoints read wrong, or that
    /// matches more of the template.
    fn better_than(&self, other: &PatchReading) -> bool {
        let cost = |d: &Decoded| d.corrected_errors + d.fixed_mismatches;
        match (&self.decoded, &other.decoded) {
            (Some(a), Some(b)) => cost(a) < cost(b),
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => self.sorted.matched() > other.sorted.matched(),
        }
    }
}
