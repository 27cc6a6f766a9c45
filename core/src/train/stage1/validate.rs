//! Validation on a fixed, seeded set of scenes: the proposals of the whole stage-1 pipeline
//! (network, pyramid, grouping) against the true ROIs.

use super::data::{make_sample, SceneSample};
use crate::detect::stage1::group::Proposal;
use crate::family::Family;
use crate::geometry::Quad;
use crate::synth::image_seed;
use serde::{Deserialize, Serialize};

/// The validation set's seed: different from any training run's sample seeds.
pub const VALIDATION_SEED: u64 = 0x5C3E_7A11;

#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    pub scenes: usize,
    pub markers: usize,
    /// Markers with a proposal whose every corner is within [`match_tolerance`].
    #[serde(with = "crate::io::json_float")]
    pub recall: f64,
    /// Proposals that match a marker.
    #[serde(with = "crate::io::json_float")]
    pub precision: f64,
    /// Median corner error of matched proposals, pixels.
    #[serde(with = "crate::io::json_float")]
    pub corner_median_px: f64,
    /// Mean proposals per scene (each costs a stage-2 pass per family).
    #[serde(with = "crate::io::json_float")]
    pub proposals_per_scene: f64,
}

pub fn validation_set(families: &[Family], size: usize) -> Result<Vec<SceneSample>, String> {
    (0..size as u64)
        .map(|i| make_sample(families, image_seed(VALIDATION_SEED, i)))
        .collect()
}

/// How far a proposal's corner may be from the truth and still count: stage 2 reads a ROI that
/// is off by a tenth of the side (it is trained on ROIs off by up to a quarter).
pub fn match_tolerance(quad: &Quad) -> f64 {
    let side = (0..4)
        .map(|i| {
            let (a, b) = (quad[i], quad[(i + 1) % 4]);
            (a[0] - b[0]).hypot(a[1] - b[1])
        })
        .fold(f64::MAX, f64::min);
    (0.1 * side).max(2.0)
}

/// The corner errors of `p` against `truth` in the best cyclic correspondence, if every corner is
/// within the tolerance.
pub fn matches(p: &Proposal, truth: &Quad) -> Option<[f64; 4]> {
    let tolerance = match_tolerance(truth);
    (0..4)
        .map(|shift| {
            let mut e = [0.0; 4];
            for (i, e) in e.iter_mut().enumerate() {
                let (a, b) = (p.corners[(i + shift) % 4], truth[i]);
                *e = (a[0] - b[0]).hypot(a[1] - b[1]);
            }
            e
        })
        .filter(|e| e.iter().all(|&d| d <= tolerance))
        .min_by(|a, b| a.iter().sum::<f64>().total_cmp(&b.iter().sum::<f64>()))
}

/// Scores proposals (one list per scene) against the set's truth.
pub fn score(set: &[SceneSample], proposals: &[Vec<Proposal>]) -> Metrics {
    let (mut markers, mut found, mut proposed, mut right) = (0, 0, 0, 0);
    let mut errors = Vec::new();
    for (sample, props) in set.iter().zip(proposals) {
        markers += sample.quads.len();
        proposed += props.len();
        for truth in &sample.quads {
            let best = props
                .iter()
                .filter_map(|p| matches(p, truth))
                .min_by(|a, b| a.iter().sum::<f64>().total_cmp(&b.iter().sum::<f64>()));
            if let Some(e) = best {
                found += 1;
                errors.extend(e);
            }
        }
        right += props
            .iter()
            .filter(|p| sample.quads.iter().any(|t| matches(p, t).is_some()))
            .count();
    }
    errors.sort_by(f64::total_cmp);
    Metrics {
        scenes: set.len(),
        markers,
        recall: found as f64 / markers.max(1) as f64,
        precision: if proposed == 0 {
            1.0
        } else {
            right as f64 / proposed as f64
        },
        corner_median_px: errors.get(errors.len() / 2).copied().unwrap_or(f64::NAN),
        proposals_per_scene: proposed as f64 / set.len().max(1) as f64,
    }
}
