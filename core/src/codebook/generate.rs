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
use rand::{Rng, SeedableRng};
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

    /// Parameters for a family's layout: its code length, alphabet and rotations.
    pub fn for_family(family: &crate::family::Family, min_distance: u32) -> Self {
        let mut p = Self::new(family.q(), family.code_len(), min_distance);
        p.rotations = family.ambiguous_rotations().filter_map(|r| r.code_perm.clone()).collect();
        p.symmetry_rotations = family.rotations().iter().skip(1).filter_map(|r| r.code_perm.clone()).collect();
        p
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

/// Progress: (candidates tried, codes kept).
pub type ProgressFn<'a> = &'a mut dyn FnMut(u64, usize);

/// Generates a codebook; `progress` is called every 65 536 candidates.
pub fn generate(params: &GenerateParams, progress: ProgressFn<'_>) -> Result<GenerateReport, String> {
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
    let space = if space_log2 < 63.0 { Some((params.q as u64).pow(params.len as u32)) } else { None };
    let mut shuffled: Vec<u32> = Vec::new();
    if exhaustive && params.order == Order::Random {
        shuffled = (0..space.expect("a small space has a size") as u32).collect();
        shuffled.shuffle(&mut rng);
    }

    loop {
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
        match params.order {
            Order::Lexicographic => write_base_q(tried, params.q, &mut candidate),
            Order::Random if exhaustive => write_base_q(shuffled[tried as usize] as u64, params.q, &mut candidate),
            Order::Random => candidate.iter_mut().for_each(|s| *s = rng.random_range(0..params.q as u8)),
        }
        tried += 1;
        selector.consider(&candidate);
        if tried.is_multiple_of(65_536) {
            progress(tried, selector.codes.len());
        }
    }
    progress(tried, selector.codes.len());
    let codes = selector.codes;
    let codebook = Codebook::from_codes(params.q, params.len, codes, Some(params.min_distance), None);
    let achieved = codebook.min_distance(&params.rotations);
    let codebook = Codebook::from_codes(params.q, params.len, codebook.codes().to_vec(), achieved, None);
    Ok(GenerateReport {
        codebook,
        achieved_min_distance: achieved,
        candidates_tried: tried,
        seconds: start.elapsed().as_secs_f64(),
        stop,
    })
}

fn check(p: &GenerateParams) -> Result<(), String> {
    if !(2..=10).contains(&p.q) {
        return Err(format!("q = {} symbols: must be 2 to 10", p.q));
    }
    if p.len == 0 || p.len > 4096 {
        return Err(format!("code length {} must be 1 to 4096", p.len));
    }
    if p.min_distance as usize > p.len {
        return Err(format!(
            "a minimum distance of {} is impossible with {} symbols",
            p.min_distance, p.len
        ));
    }
    for r in p.rotations.iter().chain(&p.symmetry_rotations) {
        let mut seen = vec![false; p.len];
        if r.len() != p.len || !r.iter().all(|&i| i < p.len && !std::mem::replace(&mut seen[i], true)) {
            return Err("a rotation is not a permutation of the code positions".into());
        }
    }
    Ok(())
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

    fn consider(&mut self, code: &[u8]) -> bool {
        let p = self.params;
        if p.min_transitions > 0 {
            let transitions = code.windows(2).filter(|w| w[0] != w[1]).count() as u32;
            if transitions < p.min_transitions {
                return false;
            }
        }
        let packed = self.packing.pack(code);
        if !self.far_from_kept(&packed) {
            return false;
        }
        let rotated: Vec<Vec<u64>> = p.rotations.iter().map(|r| self.packing.pack(&permute(code, r))).collect();
        if rotated.iter().any(|v| self.packing.distance(&packed, v) < p.min_distance) {
            return false;
        }
        if p.reject_self_symmetric && p.symmetry_rotations.iter().any(|r| permute(code, r) == code) {
            return false;
        }
        self.variants.extend_from_slice(&packed);
        for v in rotated {
            self.variants.extend_from_slice(&v);
        }
        self.codes.push(code.to_vec());
        true
    }

    fn far_from_kept(&self, packed: &[u64]) -> bool {
        // Two IDs with the same code could never be told apart, whatever distance was asked for.
        let d = self.params.min_distance.max(1);
        if self.packing.stride() == 1 {
            // The common case (binary, ≤ 64 symbols): one XOR + popcount per kept variant.
            let x = packed[0];
            return self.variants.iter().all(|&v| (v ^ x).count_ones() >= d);
        }
        self.variants
            .chunks_exact(self.packing.stride())
            .all(|v| self.packing.distance(packed, v) >= d)
    }
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
        assert!(r.codebook.codes().iter().all(|c| c != &vec![0, 0, 0, 0] && c != &vec![1, 1, 1, 1]));
    }

    #[test]
    fn impossible_requests_are_errors() {
        assert!(generate(&GenerateParams::new(2, 8, 9), &mut |_, _| {}).is_err());
        assert!(generate(&GenerateParams::new(1, 8, 1), &mut |_, _| {}).is_err());
    }
}
