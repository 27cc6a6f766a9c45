//! Decoding: the categories read at the keypoints → (ID, rotation, corrected errors).

use super::Codebook;
use crate::family::{Assignment, Family};

/// A decoded marker.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decoded {
    pub id: usize,
    /// Index into [`Family::rotations`]: the marker as seen is the canonical marker turned by
    /// that rotation's angle.
    pub rotation: usize,
    /// Code symbols that differed from the codebook entry (read wrong or unread).
    pub corrected_errors: usize,
    /// Fixed keypoints whose category was read wrong or unread.
    pub fixed_mismatches: usize,
}

/// Decodes the category read at every keypoint (`None` = unread), in the family's template order
/// as observed, by minimum Hamming distance over every ID and every rotation of the layout.
///
/// A rotation is scored by symbol errors plus fixed-keypoint mismatches, so families whose fixed
/// pattern marks the orientation (a distinct corner, orientation dots) decode all-symmetric codes
/// too. The result is accepted when at most `max_errors` symbols (default: the codebook's
/// correction limit) and at most as many fixed keypoints were wrong.
pub fn decode(
    family: &Family,
    observed: &[Option<usize>],
    max_errors: Option<usize>,
) -> Option<Decoded> {
    decode_with(family, observed, None, max_errors)
}

/// [`decode`] with how sure the reader was of each keypoint's category (any monotone score, e.g.
/// the read category's share of the probability): errors-and-erasures decoding in Forney's
/// generalised-minimum-distance manner. Unread symbols are erasures, and the least reliable read
/// symbols are erased one more at a time; a code is accepted when `2·errors + erasures` stays
/// within `2·max_errors` (≤ d − 1, so the answer is still unique within the codebook's minimum
/// distance d). A symbol read with a coin-flip share then costs half an error instead of a whole
/// one, which is what lets a marker with six or seven doubtful cells of 36h11 decode without
/// accepting anything a hard decoder would reject as ambiguous.
pub fn decode_soft(
    family: &Family,
    observed: &[Option<usize>],
    reliability: &[f64],
    max_errors: Option<usize>,
) -> Option<Decoded> {
    decode_with(family, observed, Some(reliability), max_errors)
}

fn decode_with(
    family: &Family,
    observed: &[Option<usize>],
    reliability: Option<&[f64]>,
    max_errors: Option<usize>,
) -> Option<Decoded> {
    let keypoints = family.keypoints();
    if observed.len() != keypoints.len() || reliability.is_some_and(|r| r.len() != observed.len()) {
        return None;
    }
    let codebook = family.codebook();
    let packing = codebook.packing();
    let limit = max_errors.unwrap_or(codebook.max_correction());
    let code_keypoints = family.code_keypoints();
    let mut packed = vec![0u64; packing.stride()];
    let mut known = vec![0u64; packing.words];
    let mut best: Option<(usize, Decoded)> = None;

    for (r, rotation) in family.rotations().iter().enumerate() {
        let perm = &rotation.keypoint_perm;
        let label = |i: usize| observed[perm[i]];
        let fixed_mismatches = keypoints
            .iter()
            .enumerate()
            .filter(|(i, k)| matches!(k.assignment, Assignment::Fixed(c) if label(*i) != Some(c)))
            .count();
        if fixed_mismatches > limit.max(1) {
            continue;
        }
        let symbols: Vec<Option<u8>> = code_keypoints
            .iter()
            .map(|&kp| label(kp).and_then(|c| family.category_symbol(c)))
            .collect();
        let unknown = symbols.iter().filter(|s| s.is_none()).count();
        // Hard decoding: the nearest code, unread symbols counted as errors.
        let Some(reliability) = reliability else {
            packing.pack_into(symbols.iter().copied(), &mut packed, &mut known);
            let nearest = match (unknown, codebook.lookup(&packed)) {
                (0, Some(id)) => Some((0, id)),
                _ => nearest_code(codebook, &packed, &known).map(|(d, id)| (d + unknown, id)),
            };
            let Some((errors, id)) = nearest else {
                continue;
            };
            keep_better(
                &mut best,
                errors + fixed_mismatches,
                id,
                r,
                errors,
                fixed_mismatches,
            );
            continue;
        };
        // Read symbols from the least to the most reliable: the erasure order.
        let mut doubtful: Vec<usize> = (0..symbols.len())
            .filter(|&i| symbols[i].is_some())
            .collect();
        doubtful.sort_by(|&a, &b| {
            reliability[perm[code_keypoints[a]]].total_cmp(&reliability[perm[code_keypoints[b]]])
        });
        let budget = 2 * limit;
        let mut trial = symbols.clone();
        let mut found: Option<(usize, usize)> = None;
        for erased in 0..=budget.saturating_sub(unknown).min(doubtful.len()) {
            if erased > 0 {
                trial[doubtful[erased - 1]] = None;
            }
            packing.pack_into(trial.iter().copied(), &mut packed, &mut known);
            let erasures = unknown + erased;
            let Some((errors, id)) = nearest_code(codebook, &packed, &known) else {
                break;
            };
            let cost = 2 * errors + erasures;
            if cost <= budget && found.is_none_or(|(c, _)| cost < c) {
                found = Some((cost, id));
            }
        }
        let Some((cost, id)) = found else {
            continue;
        };
        // Report the symbols that differ from the chosen code, as the hard decoder does.
        packing.pack_into(symbols.iter().copied(), &mut packed, &mut known);
        let differing =
            packing.distance_known(&packed, codebook.packed(id), &known) as usize + unknown;
        keep_better(
            &mut best,
            cost + 2 * fixed_mismatches,
            id,
            r,
            differing,
            fixed_mismatches,
        );
    }
    // The soft search only keeps codes within its budget; the hard one judges its nearest code.
    best.map(|(_, d)| d).filter(|d| {
        (reliability.is_some() || d.corrected_errors <= limit) && d.fixed_mismatches <= limit.max(1)
    })
}

/// The code nearest to `packed` over its `known` symbols: (distance, ID), None for an empty
/// codebook.
fn nearest_code(codebook: &Codebook, packed: &[u64], known: &[u64]) -> Option<(usize, usize)> {
    let packing = codebook.packing();
    (0..codebook.len())
        .map(|id| {
            let d = packing.distance_known(packed, codebook.packed(id), known);
            (d as usize, id)
        })
        .min()
}

fn keep_better(
    best: &mut Option<(usize, Decoded)>,
    cost: usize,
    id: usize,
    rotation: usize,
    corrected_errors: usize,
    fixed_mismatches: usize,
) {
    if best.as_ref().is_none_or(|(c, _)| cost < *c) {
        *best = Some((
            cost,
            Decoded {
                id,
                rotation,
                corrected_errors,
                fixed_mismatches,
            },
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn family() -> Family {
        crate::builtin::get("apriltag-36h11").unwrap().unwrap()
    }

    /// ID `id`'s categories with the first `n` code symbols read wrong; the wrong ones get
    /// reliability `doubt`, the rest 1.
    fn misread(f: &Family, id: usize, n: usize, doubt: f64) -> (Vec<Option<usize>>, Vec<f64>) {
        let mut labels: Vec<Option<usize>> = f
            .keypoint_categories(id)
            .unwrap()
            .into_iter()
            .map(Some)
            .collect();
        let mut reliability = vec![1.0; labels.len()];
        let (zero, one) = (f.symbol_category(0), f.symbol_category(1));
        for &kp in f.code_keypoints().iter().take(n) {
            labels[kp] = labels[kp].map(|c| if c == zero { one } else { zero });
            reliability[kp] = doubt;
        }
        (labels, reliability)
    }

    #[test]
    fn doubtful_misreads_beyond_the_hard_limit_decode_as_erasures() {
        let f = family();
        // 36h11: d = 11, the hard decoder corrects 5; erased, up to 10 doubtful symbols decode.
        for n in [6, 8, 10] {
            let (labels, reliability) = misread(&f, 123, n, 0.55);
            assert_eq!(decode(&f, &labels, None), None, "{n} errors are beyond 5");
            let d = decode_soft(&f, &labels, &reliability, None).expect("erasures decode");
            assert_eq!((d.id, d.rotation, d.corrected_errors), (123, 0, n));
        }
    }

    #[test]
    fn confident_misreads_are_not_decoded_beyond_the_hard_limit() {
        let f = family();
        // Six wrong symbols the reader was sure of: the soft decoder has nothing to erase but
        // correct cells, so it must refuse just as the hard one does.
        let (labels, reliability) = misread(&f, 123, 6, 1.0);
        let mut reliability = reliability;
        for &kp in f.code_keypoints().iter().skip(6) {
            reliability[kp] = 0.9;
        }
        assert_eq!(decode_soft(&f, &labels, &reliability, None), None);
        // Within the hard limit both agree.
        let (labels, reliability) = misread(&f, 123, 5, 1.0);
        assert_eq!(
            decode_soft(&f, &labels, &reliability, None).map(|d| d.id),
            Some(123)
        );
    }

    #[test]
    fn unread_symbols_cost_half_an_error() {
        let f = family();
        let (mut labels, reliability) = misread(&f, 40, 3, 1.0);
        // 3 errors + 4 unread: 2·3 + 4 = 10 ≤ d − 1, while the hard decoder counts 7 errors.
        for &kp in f.code_keypoints().iter().skip(10).take(4) {
            labels[kp] = None;
        }
        assert_eq!(decode(&f, &labels, None), None);
        let d = decode_soft(&f, &labels, &reliability, None).unwrap();
        assert_eq!((d.id, d.corrected_errors), (40, 7));
    }
}
