//! Codebook generation: greedy selection of q-ary codes with a minimum Hamming distance over the
//! ambiguous rotations, seeded and deterministic.
//!
//! Candidates are drawn in a seeded random order (or lexicographic order, the classic "lexicode",
//! kept as a baseline) and kept when they are far enough from every kept code and every rotation of
//! one. A random order spreads the first codes over the whole space, where a lexicographic scan
//! spends its budget on codes that share long runs of leading zeros. Small spaces (≤ 2^24 codes)
//! are scanned exhaustively in a shuffled order.

use super::packed::{permute, Packing};
use super::Codebook;
use rand::seq::SliceRandom;
use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Instant;

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Order {
    #[default]
    Random,
    Lexicographic,
}

#[derive(Debug, Clone)]
pub struct GenerateParams {
    /// Alphabet size (number of symbol categories).
    pub q: usize,
    /// Code length (number of symbol keypoints).
    pub len: usize,
    /// Required minimum Hamming distance between any two codes under any ambiguous rotation, and
    /// between a code and its own rotations.
    pub min_distance: u32,
    /// Code permutations of the ambiguous rotations (identity excluded).
    pub rotations: Vec<Vec<usize>>,
    /// Code permutations of every geometric rotation of the layout (identity excluded), used by
    /// `reject_self_symmetric`.
    pub symmetry_rotations: Vec<Vec<usize>>,
    /// Reject codes that equal one of their own geometric rotations, so the code alone shows the
    /// orientation even where the layout's fixed marks also do.
    pub reject_self_symmetric: bool,
    /// Minimum number of symbol changes between consecutive code positions (0 = no constraint).
    pub min_transitions: u32,
    /// Keep the all-zero code as ID 0 when it satisfies the constraints.
    pub start_with_zero: bool,
    pub max_codes: usize,
    /// Candidates to try before stopping.
    pub max_candidates: u64,
    pub seed: u64,
    pub order: Order,
}

impl GenerateParams {
    pub fn new(q: usize, len: usize, min_distance: u32) -> Self {
        Self {
            q,
            len,
            min_distance,
            rotations: Vec::new(),
            symmetry_rotations: Vec::new(),
            reject_self_symmetric: false,
            min_transitions: 0,
            start_with_zero: false,
            max_codes: 100_000,
            max_candidates: 20_000_000,
            seed: 0,
            order: Order::Random,
        }
    }
}

#[derive(Debug, Clone)]
pub struct GenerateReport {
    pub codebook: Codebook,
    /// Minimum distance of the result over the rotations (≥ the requested one).
    pub achieved_min_distance: Option<u32>,
    pub candidates_tried: u64,
    pub seconds: f64,
    /// Why generation stopped.
    pub stop: &'static str,
}

/// Generation parameters that cannot give a codebook; each names the value that is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GenerateError {
    #[error("q = {q} symbols: must be 2 to 10")]
    Alphabet { q: usize },
    #[error("code length {len} must be 1 to 4096")]
    Length { len: usize },
    #[error("a minimum distance of {min_distance} is impossible with {len} symbols: it must be in 0..={len}")]
    Distance { min_distance: u32, len: usize },
    /// More symbol changes between neighbours than a code of `len` symbols has places for: no
    /// candidate could pass, and the whole budget would be spent finding none.
    #[error(
        "a minimum of {min_transitions} transitions is impossible with {len} symbols: it must be in 0..={max}",
        max = len.saturating_sub(1)
    )]
    Transitions { min_transitions: u32, len: usize },
    /// `rotation` counts the ambiguous rotations first, then the symmetry rotations.
    #[error("rotation {rotation} is not a permutation of the code positions")]
    NotAPermutation { rotation: usize },
}

/// Progress: (candidates tried, codes kept).
pub type ProgressFn<'a> = &'a mut dyn FnMut(u64, usize);

/// Generates a codebook; `progress` is called every 65 536 candidates.
pub fn generate(
    params: &GenerateParams,
    progress: ProgressFn<'_>,
) -> Result<GenerateReport, GenerateError> {
    check(params)?;
    let start = Instant::now();
    let packing = Packing::new(params.q, params.len);
    let mut selector = Selector::new(params, packing);
    let space_log2 = params.len as f64 * (params.q as f64).log2();

    if params.start_with_zero {
        selector.consider(&vec![0; params.len]);
    }
    let mut tried: u64 = 0;
    let mut stop = "candidate budget spent";
    let mut candidate = vec![0u8; params.len];
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let exhaustive = space_log2 <= 24.0;
    let space = if space_log2 < 63.0 {
        Some((params.q as u64).pow(params.len as u32))
    } else {
        None
    };
    let mut shuffled: Vec<u32> = Vec::new();
    if exhaustive && params.order == Order::Random {
        shuffled = (0..space.expect("a small space has a size") as u32).collect();
        shuffled.shuffle(&mut rng);
    }

    // Candidates are drawn in order, checked against the codes kept so far in parallel, then
    // accepted in order against the codes kept earlier in the same batch: the result is the
    // same as a sequential scan, whatever the number of threads.
    const BATCH: u64 = 8192;
    'scan: loop {
        if selector.codes.len() >= params.max_codes {
            stop = "requested number of codes reached";
            break;
        }
        if tried >= params.max_candidates {
            break;
        }
        if space.is_some_and(|s| tried >= s) {
            stop = "every candidate tried";
            break;
        }
        let end = (tried + BATCH)
            .min(params.max_candidates)
            .min(space.unwrap_or(u64::MAX));
        let batch: Vec<Vec<u8>> = (tried..end)
            .map(|n| {
                match params.order {
                    Order::Lexicographic => write_base_q(n, params.q, &mut candidate),
                    Order::Random if exhaustive => {
                        write_base_q(shuffled[n as usize] as u64, params.q, &mut candidate)
                    }
                    Order::Random => random_code(&mut rng, params.q, &mut candidate),
                }
                candidate.clone()
            })
            .collect();
        let kept_before = selector.variants.len();
        let passed: Vec<Option<Vec<u64>>> = {
            use rayon::prelude::*;
            let sel = &selector;
            batch.par_iter().map(|c| sel.prefilter(c)).collect()
        };
        for (code, variants) in batch.iter().zip(passed) {
            tried += 1;
            if let Some(variants) = variants {
                selector.accept(code, variants, kept_before);
                if selector.codes.len() >= params.max_codes {
                    stop = "requested number of codes reached";
                    break 'scan;
                }
            }
        }
        if tried % 65_536 < BATCH {
            progress(tried, selector.codes.len());
        }
    }
    progress(tried, selector.codes.len());
    let codes = selector.codes;
    let codebook =
        Codebook::from_codes(params.q, params.len, codes, Some(params.min_distance), None);
    let achieved = codebook.min_distance(&params.rotations);
    let codebook = Codebook::from_codes(
        params.q,
        params.len,
        codebook.codes().to_vec(),
        achieved,
        None,
    );
    Ok(GenerateReport {
        codebook,
        achieved_min_distance: achieved,
        candidates_tried: tried,
        seconds: start.elapsed().as_secs_f64(),
        stop,
    })
}

fn check(p: &GenerateParams) -> Result<(), GenerateError> {
    if !(2..=10).contains(&p.q) {
        return Err(GenerateError::Alphabet { q: p.q });
    }
    if p.len == 0 || p.len > 4096 {
        return Err(GenerateError::Length { len: p.len });
    }
    if p.min_distance as usize > p.len {
        return Err(GenerateError::Distance {
            min_distance: p.min_distance,
            len: p.len,
        });
    }
    if p.min_transitions as usize >= p.len {
        return Err(GenerateError::Transitions {
            min_transitions: p.min_transitions,
            len: p.len,
        });
    }
    for (rotation, r) in p.rotations.iter().chain(&p.symmetry_rotations).enumerate() {
        let mut seen = vec![false; p.len];
        if r.len() != p.len
            || !r
                .iter()
                .all(|&i| i < p.len && !std::mem::replace(&mut seen[i], true))
        {
            return Err(GenerateError::NotAPermutation { rotation });
        }
    }
    Ok(())
}

/// Uniform random symbols. For a power-of-two alphabet the symbols are sliced out of 64-bit
/// words, one generator call per 64 bits instead of one per symbol.
fn random_code(rng: &mut ChaCha8Rng, q: usize, out: &mut [u8]) {
    if !q.is_power_of_two() {
        out.iter_mut()
            .for_each(|s| *s = rng.random_range(0..q as u8));
        return;
    }
    let bits = q.trailing_zeros();
    let mask = (q - 1) as u64;
    let (mut word, mut left) = (0u64, 0u32);
    for s in out.iter_mut() {
        if left < bits {
            word = rng.next_u64();
            left = 64;
        }
        *s = (word & mask) as u8;
        word >>= bits;
        left -= bits;
    }
}

/// Writes `value` as `len` base-q digits, most significant first.
fn write_base_q(mut value: u64, q: usize, out: &mut [u8]) {
    for s in out.iter_mut().rev() {
        *s = (value % q as u64) as u8;
        value /= q as u64;
    }
}

/// The greedy acceptance test with every kept code's rotations stored flat.
struct Selector<'a> {
    params: &'a GenerateParams,
    packing: Packing,
    codes: Vec<Vec<u8>>,
    /// Packed kept codes and their rotations, `stride` words each.
    variants: Vec<u64>,
}

impl<'a> Selector<'a> {
    fn new(params: &'a GenerateParams, packing: Packing) -> Self {
        Self {
            params,
            packing,
            codes: Vec::new(),
            variants: Vec::new(),
        }
    }

    /// Keeps `code` unconditionally if it passes every check against the kept codes.
    fn consider(&mut self, code: &[u8]) {
        if let Some(variants) = self.prefilter(code) {
            let all = self.variants.len();
            self.accept(code, variants, all);
        }
    }

    /// Every check that does not depend on codes kept in the current batch; on success, the
    /// packed code followed by its packed rotations.
    fn prefilter(&self, code: &[u8]) -> Option<Vec<u64>> {
        let p = self.params;
        if p.min_transitions > 0 {
            let transitions = code.windows(2).filter(|w| w[0] != w[1]).count() as u32;
            if transitions < p.min_transitions {
                return None;
            }
        }
        let packed = self.packing.pack(code);
        if !self.far_from(&self.variants, &packed) {
            return None;
        }
        let mut variants = packed.clone();
        for r in &p.rotations {
            let v = self.packing.pack(&permute(code, r));
            if self.packing.distance(&packed, &v) < p.min_distance {
                return None;
            }
            variants.extend_from_slice(&v);
        }
        if p.reject_self_symmetric
            && p.symmetry_rotations
                .iter()
                .any(|r| permute(code, r) == code)
        {
            return None;
        }
        Some(variants)
    }

    /// Keeps a prefiltered code if it is also far from the variants kept after index `from`.
    fn accept(&mut self, code: &[u8], variants: Vec<u64>, from: usize) {
        let packed = &variants[..self.packing.stride()];
        if self.far_from(&self.variants[from..], packed) {
            self.variants.extend_from_slice(&variants);
            self.codes.push(code.to_vec());
        }
    }

    fn far_from(&self, kept: &[u64], packed: &[u64]) -> bool {
        // Two IDs with the same code could never be told apart, whatever distance was asked for.
        let d = self.params.min_distance.max(1);
        if self.packing.stride() == 1 {
            return far_from_words(kept, packed[0], d);
        }
        kept.chunks_exact(self.packing.stride())
            .all(|v| self.packing.distance(packed, v) >= d)
    }
}

/// Whether `x` differs from every word of `kept` in at least `d` bits: the hot loop of binary
/// codebooks with up to 64 symbols. Chunks of 64 words let the compiler vectorise the popcounts
/// while a close word still stops the scan early.
fn far_from_words(kept: &[u64], x: u64, d: u32) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("popcnt")
        {
            // SAFETY: the CPU was just checked for both features.
            return unsafe { far_from_words_avx2(kept, x, d) };
        }
    }
    far_from_words_portable(kept, x, d)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn far_from_words_avx2(kept: &[u64], x: u64, d: u32) -> bool {
    far_from_words_portable(kept, x, d)
}

#[inline(always)]
fn far_from_words_portable(kept: &[u64], x: u64, d: u32) -> bool {
    kept.chunks(64).all(|c| {
        c.iter()
            .map(|&v| u32::from((v ^ x).count_ones() < d))
            .sum::<u32>()
            == 0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_rotations(n: usize) -> Vec<Vec<usize>> {
        // Clockwise quarter turn of an n×n row-major grid: (r, c) → (c, n-1-r).
        let quarter: Vec<usize> = (0..n * n).map(|i| (i % n) * n + (n - 1 - i / n)).collect();
        let mut out = vec![quarter.clone()];
        for _ in 0..2 {
            let last = out.last().unwrap().clone();
            out.push(last.iter().map(|&j| quarter[j]).collect());
        }
        out
    }

    #[test]
    fn generated_codes_meet_the_distance_and_are_deterministic() {
        let mut params = GenerateParams::new(2, 16, 5);
        params.rotations = grid_rotations(4);
        params.seed = 7;
        let a = generate(&params, &mut |_, _| {}).unwrap();
        let b = generate(&params, &mut |_, _| {}).unwrap();
        assert_eq!(a.codebook.codes(), b.codebook.codes());
        assert!(a.codebook.len() >= 20, "only {} codes", a.codebook.len());
        assert!(a.achieved_min_distance.unwrap() >= 5);
        assert_eq!(a.stop, "every candidate tried");
        params.seed = 8;
        let c = generate(&params, &mut |_, _| {}).unwrap();
        assert_ne!(a.codebook.codes(), c.codebook.codes());
    }

    #[test]
    fn quaternary_codes_and_transitions() {
        let mut params = GenerateParams::new(4, 12, 4);
        params.min_transitions = 6;
        params.max_codes = 50;
        params.start_with_zero = false;
        let r = generate(&params, &mut |_, _| {}).unwrap();
        assert_eq!(r.codebook.len(), 50);
        for c in r.codebook.codes() {
            assert!(c.windows(2).filter(|w| w[0] != w[1]).count() >= 6);
            assert!(c.iter().all(|&s| s < 4));
        }
        assert!(r.achieved_min_distance.unwrap() >= 4);
    }

    #[test]
    fn all_zero_code_is_kept_when_asked_and_no_rotation_is_ambiguous() {
        let mut params = GenerateParams::new(4, 36, 8);
        params.start_with_zero = true;
        params.max_codes = 10;
        let r = generate(&params, &mut |_, _| {}).unwrap();
        assert!(r.codebook.code(0).unwrap().iter().all(|&s| s == 0));
    }

    #[test]
    fn self_symmetric_codes_are_rejected_on_request() {
        let mut params = GenerateParams::new(2, 4, 0);
        params.symmetry_rotations = grid_rotations(2);
        params.reject_self_symmetric = true;
        let r = generate(&params, &mut |_, _| {}).unwrap();
        assert!(r
            .codebook
            .codes()
            .iter()
            .all(|c| c != &vec![0, 0, 0, 0] && c != &vec![1, 1, 1, 1]));
    }

    #[test]
    fn random_order_keeps_more_codes_than_the_lexicographic_greedy_on_6x6_at_distance_10() {
        let mut params = GenerateParams::new(2, 36, 10);
        params.rotations = grid_rotations(6);
        params.max_candidates = 1_000_000;
        let ours = generate(&params, &mut |_, _| {}).unwrap();
        params.order = Order::Lexicographic;
        let lexicode = generate(&params, &mut |_, _| {}).unwrap();
        assert!(
            ours.codebook.len() > 5 * lexicode.codebook.len(),
            "{} vs {}",
            ours.codebook.len(),
            lexicode.codebook.len()
        );
        assert!(
            ours.achieved_min_distance.unwrap() >= 10
                && lexicode.achieved_min_distance.unwrap() >= 10
        );
    }

    #[test]
    fn impossible_requests_are_errors() {
        let run = |p: &GenerateParams| generate(p, &mut |_, _| {}).unwrap_err();
        assert_eq!(
            run(&GenerateParams::new(2, 8, 9)),
            GenerateError::Distance {
                min_distance: 9,
                len: 8
            }
        );
        assert_eq!(
            run(&GenerateParams::new(1, 8, 1)).to_string(),
            "q = 1 symbols: must be 2 to 10"
        );
        let mut params = GenerateParams::new(2, 4, 1);
        params.symmetry_rotations = vec![vec![0, 1, 2, 3], vec![0, 0, 1, 2]];
        assert_eq!(run(&params), GenerateError::NotAPermutation { rotation: 1 });
        let mut params = GenerateParams::new(2, 16, 1);
        params.min_transitions = 16;
        let e = run(&params);
        assert_eq!(
            e,
            GenerateError::Transitions {
                min_transitions: 16,
                len: 16
            }
        );
        assert!(e.to_string().contains("0..=15"), "{e}");
        assert!(run(&GenerateParams::new(2, 16, 1_000_000_000))
            .to_string()
            .contains("0..=16"));
    }
}
