//! Decoding: the categories read at the keypoints → (ID, rotation, corrected errors).

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
    let keypoints = family.keypoints();
    if observed.len() != keypoints.len() {
        return None;
    }
    let codebook = family.codebook();
    let packing = codebook.packing();
    let limit = max_errors.unwrap_or(codebook.max_correction());
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
        let symbols = family
            .code_keypoints()
            .iter()
            .map(|&kp| label(kp).and_then(|c| family.category_symbol(c)));
        packing.pack_into(symbols, &mut packed, &mut known);
        let unknown =
            family.code_len() - known.iter().map(|w| w.count_ones() as usize).sum::<usize>();

        let nearest = match (unknown, codebook.lookup(&packed)) {
            (0, Some(id)) => Some((0, id)),
            _ => (0..codebook.len())
                .map(|id| {
                    let d = packing.distance_known(&packed, codebook.packed(id), &known) as usize;
                    (d + unknown, id)
                })
                .min(),
        };
        let Some((errors, id)) = nearest else {
            continue;
        };
        let cost = errors + fixed_mismatches;
        if best.is_none_or(|(c, _)| cost < c) {
            best = Some((
                cost,
                Decoded {
                    id,
                    rotation: r,
                    corrected_errors: errors,
                    fixed_mismatches,
                },
            ));
        }
    }
    best.map(|(_, d)| d)
        .filter(|d| d.corrected_errors <= limit && d.fixed_mismatches <= limit.max(1))
}
