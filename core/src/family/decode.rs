//! Decoding a marker: the categories read at its keypoints → (ID, rotation, corrected errors).
//! Each rotation the layout admits is tried; the codebook's nearest-code search does the rest.

use super::{Assignment, Family};

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
/// the read category's share of the probability): errors-and-erasures decoding
/// ([`crate::codebook::Codebook::nearest_with_erasures`]). A symbol read with a coin-flip share
/// costs half an error instead of a whole one, which is what lets a marker with six or seven
/// doubtful cells of 36h11 decode without accepting anything a hard decoder would reject as
/// ambiguous.
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
    let limit = max_errors.unwrap_or(codebook.max_correction());
    let code_keypoints = family.code_keypoints();
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
        let (found, cost) = match reliability {
            None => {
                let Some(m) = codebook.nearest(&symbols) else {
                    continue;
                };
                (m, m.cost + fixed_mismatches)
            }
            Some(reliability) => {
                let per_symbol: Vec<f64> = code_keypoints
                    .iter()
                    .map(|&kp| reliability[perm[kp]])
                    .collect();
                let Some(m) = codebook.nearest_with_erasures(&symbols, &per_symbol, limit) else {
                    continue;
                };
                (m, m.cost + 2 * fixed_mismatches)
            }
        };
        if best.as_ref().is_none_or(|(c, _)| cost < *c) {
            best = Some((
                cost,
                Decoded {
                    id: found.id,
                    rotation: r,
                    corrected_errors: found.differing,
                    fixed_mismatches,
                },
            ));
        }
    }
    // The soft search only keeps codes within its budget; the hard one judges its nearest code.
    best.map(|(_, d)| d).filter(|d| {
        (reliability.is_some() || d.corrected_errors <= limit) && d.fixed_mismatches <= limit.max(1)
    })
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
