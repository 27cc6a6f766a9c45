//! Validation on a fixed, seeded set of patches (the same for every run of a family, so numbers
//! compare across runs): keypoint recall, symbol accuracy, ID accuracy and keypoint error.

use super::data::{make_sample, PatchSample};
use crate::detect::stage2::anchors::{PatchSpec, RawOutputs};
use crate::detect::stage2::decode::read_patch;
use crate::family::Family;
use crate::synth::image_seed;
use serde::{Deserialize, Serialize};

/// The validation set's seed: different from any training run's sample seeds.
pub const VALIDATION_SEED: u64 = 0x7A11_DA7E;

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub patches: usize,
    /// Visible keypoints with a found keypoint sorted to them within half a cell pitch.
    #[serde(with = "crate::io::json_float")]
    pub keypoint_recall: f64,
    /// Of those, the category read right (the read-out the decoder uses: the most likely of the
    /// categories the keypoint's slot admits).
    #[serde(with = "crate::io::json_float")]
    pub symbol_accuracy: f64,
    /// Patches decoded to the right ID.
    #[serde(with = "crate::io::json_float")]
    pub id_accuracy: f64,
    /// Patches decoded to a wrong ID (the rest of the misses decode to nothing).
    #[serde(default, with = "crate::io::json_float")]
    pub wrong_id_rate: f64,
    /// Root-mean-square distance of found keypoints to the truth, patch pixels.
    #[serde(with = "crate::io::json_float")]
    pub keypoint_rms_px: f64,
    /// Median of that per-patch.
    #[serde(with = "crate::io::json_float")]
    pub keypoint_median_px: f64,
}

pub fn validation_set(
    family: &Family,
    spec: &PatchSpec,
    size: usize,
) -> Result<Vec<PatchSample>, String> {
    (0..size as u64)
        .map(|i| make_sample(family, spec, image_seed(VALIDATION_SEED, i), 0.0))
        .collect()
}

/// Scores network outputs against the set.
pub fn score(
    family: &Family,
    spec: &PatchSpec,
    set: &[PatchSample],
    raw: &[RawOutputs],
) -> Metrics {
    let (mut visible, mut recalled, mut right_symbol, mut right_id, mut wrong_id) =
        (0usize, 0usize, 0usize, 0usize, 0usize);
    let mut sq = 0.0;
    let mut errors = Vec::new();
    for (sample, raw) in set.iter().zip(raw) {
        let truth = &sample.truth;
        let regressed = family.regressed_keypoints();
        visible += regressed
            .iter()
            .filter(|&&k| truth.keypoints[k].visible)
            .count();
        let Some(reading) = read_patch(family, spec, raw) else {
            continue;
        };
        let (found, sorted, read) = (&reading.found, &reading.sorted, &reading.read);
        match reading.decoded {
            Some(d) if d.id == truth.id => right_id += 1,
            Some(_) => wrong_id += 1,
            None => {}
        }
        // Slots are in the order the marker is seen; the truth is canonical. Pair each truth
        // keypoint with the found keypoint nearest to it among the sorted ones.
        for &k in &regressed {
            let t = &truth.keypoints[k];
            if !t.visible {
                continue;
            }
            let pitch = pitch_px(family, spec, k);
            let nearest = sorted
                .slots
                .iter()
                .enumerate()
                .filter_map(|(slot, f)| f.map(|f| (slot, f)))
                .map(|(slot, f)| (slot, (found[f].pos[0] - t.x).hypot(found[f].pos[1] - t.y)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            if let Some((slot, d)) = nearest.filter(|(_, d)| *d < 0.5 * pitch) {
                recalled += 1;
                sq += d * d;
                errors.push(d);
                if read[slot] == Some(t.category) {
                    right_symbol += 1;
                }
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let ratio = |a: usize, b: usize| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    Metrics {
        patches: set.len(),
        keypoint_recall: ratio(recalled, visible),
        symbol_accuracy: ratio(right_symbol, recalled),
        id_accuracy: ratio(right_id, set.len()),
        wrong_id_rate: ratio(wrong_id, set.len()),
        keypoint_rms_px: if recalled == 0 {
            f64::NAN
        } else {
            (sq / recalled as f64).sqrt()
        },
        keypoint_median_px: errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN),
    }
}

/// A keypoint's cell pitch on the template square, in patch pixels.
fn pitch_px(family: &Family, spec: &PatchSpec, k: usize) -> f64 {
    family.keypoints()[k].size / family.roi_side() * (1.0 - 2.0 * spec.margin) * spec.size as f64
}
