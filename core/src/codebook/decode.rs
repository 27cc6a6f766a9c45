//! Nearest-code search over read symbol sequences (`None` = unread): hard decoding, and
//! errors-and-erasures decoding in Forney's generalised-minimum-distance manner. Which rotation
//! of a layout was seen, and which keypoint carries which symbol, is the family's business
//! (`family::decode`).

use super::Codebook;

/// The code chosen for a read sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CodeMatch {
    pub id: usize,
    /// Symbols of the read sequence that differ from the code: read wrong or unread.
    pub differing: usize,
    /// What the search minimised: `differing` for hard decoding, `2·errors + erasures` for
    /// errors-and-erasures decoding.
    pub cost: usize,
}

impl Codebook {
    /// Hard decoding: the nearest code, unread symbols counted as errors; `None` for an empty
    /// codebook or a sequence of the wrong length. No limit is applied: the caller judges.
    pub fn nearest(&self, symbols: &[Option<u8>]) -> Option<CodeMatch> {
        if symbols.len() != self.code_len() {
            return None;
        }
        let packing = self.packing();
        let mut packed = vec![0u64; packing.stride()];
        let mut known = vec![0u64; packing.words];
        packing.pack_into(symbols.iter().copied(), &mut packed, &mut known);
        let unknown = symbols.iter().filter(|s| s.is_none()).count();
        let (errors, id) = match (unknown, self.lookup(&packed)) {
            (0, Some(id)) => (0, id),
            _ => {
                let (d, id) = self.nearest_known(&packed, &known)?;
                (d + unknown, id)
            }
        };
        Some(CodeMatch {
            id,
            differing: errors,
            cost: errors,
        })
    }

    /// Errors-and-erasures decoding with how sure the reader was of each symbol (`reliability`,
    /// any monotone score per position). Unread symbols are erasures, and the least reliable
    /// read symbols are erased one more at a time; a code is accepted when `2·errors + erasures`
    /// stays within `2·max_errors` (≤ d − 1, so the answer is still unique within the
    /// codebook's minimum distance d). A symbol read with a coin-flip share then costs half an
    /// error instead of a whole one.
    pub fn nearest_with_erasures(
        &self,
        symbols: &[Option<u8>],
        reliability: &[f64],
        max_errors: usize,
    ) -> Option<CodeMatch> {
        if symbols.len() != self.code_len() || reliability.len() != symbols.len() {
            return None;
        }
        let packing = self.packing();
        let mut packed = vec![0u64; packing.stride()];
        let mut known = vec![0u64; packing.words];
        let unknown = symbols.iter().filter(|s| s.is_none()).count();
        // Read symbols from the least to the most reliable: the erasure order.
        let mut doubtful: Vec<usize> = (0..symbols.len())
            .filter(|&i| symbols[i].is_some())
            .collect();
        doubtful.sort_by(|&a, &b| reliability[a].total_cmp(&reliability[b]));
        let budget = 2 * max_errors;
        let mut trial = symbols.to_vec();
        let mut found: Option<(usize, usize)> = None;
        for erased in 0..=budget.saturating_sub(unknown).min(doubtful.len()) {
            if erased > 0 {
                trial[doubtful[erased - 1]] = None;
            }
            packing.pack_into(trial.iter().copied(), &mut packed, &mut known);
            let erasures = unknown + erased;
            let Some((errors, id)) = self.nearest_known(&packed, &known) else {
                break;
            };
            let cost = 2 * errors + erasures;
            if cost <= budget && found.is_none_or(|(c, _)| cost < c) {
                found = Some((cost, id));
            }
        }
        let (cost, id) = found?;
        // Report the symbols that differ from the chosen code, as the hard decoder does.
        packing.pack_into(symbols.iter().copied(), &mut packed, &mut known);
        let differing = packing.distance_known(&packed, self.packed(id), &known) as usize + unknown;
        Some(CodeMatch {
            id,
            differing,
            cost,
        })
    }

    /// The code nearest to `packed` over its `known` symbols: (distance, ID), None for an empty
    /// codebook.
    fn nearest_known(&self, packed: &[u64], known: &[u64]) -> Option<(usize, usize)> {
        let packing = self.packing();
        (0..self.len())
            .map(|id| {
                let d = packing.distance_known(packed, self.packed(id), known);
                (d as usize, id)
            })
            .min()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn book() -> Codebook {
        // Length 8, distance 5 between the two codes.
        Codebook::from_codes(
            2,
            8,
            vec![vec![0, 0, 0, 0, 0, 0, 0, 0], vec![1, 1, 1, 1, 1, 0, 0, 0]],
            Some(5),
            None,
        )
    }

    #[test]
    fn hard_decoding_counts_unread_symbols_as_errors() {
        let b = book();
        let read = [
            Some(1),
            Some(1),
            Some(1),
            None,
            Some(0),
            Some(0),
            Some(0),
            Some(0),
        ];
        assert_eq!(
            b.nearest(&read),
            Some(CodeMatch {
                id: 1,
                differing: 2,
                cost: 2
            })
        );
        assert_eq!(b.nearest(&read[..7]), None, "wrong length");
    }

    #[test]
    fn erasures_follow_the_confident_symbols_where_hard_decoding_does_not() {
        let b = book();
        // Code 1 with three misread symbols (positions 0–2), each doubtful.
        let read = [
            Some(0),
            Some(0),
            Some(0),
            Some(1),
            Some(1),
            Some(0),
            Some(0),
            Some(0),
        ];
        let doubt = [0.5, 0.5, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0];
        // Hard: code 0 is nearer (2 differing against 3).
        assert_eq!(b.nearest(&read).map(|m| m.id), Some(0));
        // With 4 erasures allowed (2·t), the three doubtful ones are erased: cost 3 for code 1
        // against 2·2 + 3 for code 0.
        let m = b.nearest_with_erasures(&read, &doubt, 2).unwrap();
        assert_eq!((m.id, m.differing, m.cost), (1, 3, 3));
    }
}
