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
        let most_erased = budget.saturating_sub(unknown).min(doubtful.len());
        // Each erasure takes at most one error off any code, so with e more symbols erased the
        // cost is at least 2·(errors with none) + unknown − e, and at least unknown + e: the
        // steps that cannot come within the budget, or under a cost found, are skipped without
        // changing the answer (a clean read or clutter then costs one scan of the codebook, not
        // one per erasure).
        let mut erased = 0;
        while erased <= most_erased {
            let erasures = unknown + erased;
            if found.is_some_and(|(c, _)| erasures >= c) {
                break;
            }
            packing.pack_into(trial.iter().copied(), &mut packed, &mut known);
            let Some((errors, id)) = self.nearest_known(&packed, &known) else {
                break;
            };
            let cost = 2 * errors + erasures;
            if cost <= budget && found.is_none_or(|(c, _)| cost < c) {
                found = Some((cost, id));
            }
            let next = if erased == 0 && found.is_none() {
                (cost.saturating_sub(budget)).max(1)
            } else {
                erased + 1
            };
            for &i in &doubtful[erased..next.min(doubtful.len())] {
                trial[i] = None;
            }
            erased = next;
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

    /// Every erasure count tried in turn, as the decoder is defined: the steps it skips must
    /// not change its answer.
    fn erasures_by_definition(
        book: &Codebook,
        symbols: &[Option<u8>],
        reliability: &[f64],
        max_errors: usize,
    ) -> Option<(usize, usize)> {
        let unknown = symbols.iter().filter(|s| s.is_none()).count();
        let mut doubtful: Vec<usize> = (0..symbols.len())
            .filter(|&i| symbols[i].is_some())
            .collect();
        doubtful.sort_by(|&a, &b| reliability[a].total_cmp(&reliability[b]));
        let mut found: Option<(usize, usize)> = None;
        for erased in 0..=(2 * max_errors).saturating_sub(unknown).min(doubtful.len()) {
            let mut trial = symbols.to_vec();
            for &i in &doubtful[..erased] {
                trial[i] = None;
            }
            let (errors, id) = (0..book.len())
                .map(|id| {
                    let code = book.code(id).unwrap();
                    let d = (trial.iter().zip(code))
                        .filter(|(t, c)| t.is_some_and(|t| t != **c))
                        .count();
                    (d, id)
                })
                .min()?;
            let cost = 2 * errors + unknown + erased;
            if cost <= 2 * max_errors && found.is_none_or(|(c, _)| cost < c) {
                found = Some((cost, id));
            }
        }
        found.map(|(cost, id)| (id, cost))
    }

    #[test]
    fn skipped_erasure_steps_never_change_the_code_chosen() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let codes: Vec<Vec<u8>> = (0..40)
            .map(|_| (0..25).map(|_| rng.random_range(0..2)).collect())
            .collect();
        let book = Codebook::from_codes(2, 25, codes, None, None);
        for trial in 0..3000 {
            // Reads from near a code to clutter: 0–12 symbols flipped, 0–3 unread.
            let base = book.code(trial % book.len()).unwrap().to_vec();
            let mut read: Vec<Option<u8>> = base.iter().map(|&s| Some(s)).collect();
            for _ in 0..rng.random_range(0..=12) {
                let i = rng.random_range(0..25);
                read[i] = read[i].map(|s| 1 - s);
            }
            for _ in 0..rng.random_range(0..=3) {
                read[rng.random_range(0..25)] = None;
            }
            let reliability: Vec<f64> = (0..25).map(|_| rng.random()).collect();
            let max_errors = trial % 6;
            let fast = book
                .nearest_with_erasures(&read, &reliability, max_errors)
                .map(|m| (m.id, m.cost));
            let defined = erasures_by_definition(&book, &read, &reliability, max_errors);
            assert_eq!(fast, defined, "trial {trial}: {read:?}");
        }
    }
}
