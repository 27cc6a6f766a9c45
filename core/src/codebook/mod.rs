//! Codebooks: which symbol sequences are valid IDs, their minimum Hamming distance over the
//! rotations a layout admits, nearest-code search with error and erasure correction, and
//! generation. It knows codes, lengths, alphabets and rotations as permutations, not families.

pub mod bch;
mod decode;
mod generate;
pub mod import;
pub mod packed;
pub mod spec;

pub use decode::CodeMatch;
pub use generate::{generate, GenerateError, GenerateParams, GenerateReport, Order};
pub use import::ImportError;
pub use spec::{CodeEncoding, CodebookSpec};

use crate::problem::Problem;
use packed::{permute, Packing};
use std::collections::HashMap;

/// A parsed codebook: codes as symbol vectors plus a packed copy for fast distances.
#[derive(Debug, Clone)]
pub struct Codebook {
    q: usize,
    len: usize,
    codes: Vec<Vec<u8>>,
    packing: Packing,
    packed: Vec<u64>,
    /// Exact lookup: packed code → ID.
    index: HashMap<Vec<u64>, usize>,
    max_correction: usize,
}

impl Codebook {
    /// Builds a codebook from symbol vectors (all of length `len`, symbols < `q`).
    /// `max_correction` defaults to ⌊(d − 1)/2⌋ of `min_distance`.
    pub fn from_codes(
        q: usize,
        len: usize,
        codes: Vec<Vec<u8>>,
        min_distance: Option<u32>,
        max_correction: Option<u32>,
    ) -> Self {
        let packing = Packing::new(q, len);
        let mut packed = Vec::with_capacity(codes.len() * packing.stride());
        let mut index = HashMap::with_capacity(codes.len());
        for (id, c) in codes.iter().enumerate() {
            let p = packing.pack(c);
            packed.extend_from_slice(&p);
            index.entry(p).or_insert(id);
        }
        let max_correction = match (max_correction, min_distance) {
            (Some(m), _) => m as usize,
            (None, Some(d)) => (d.max(1) as usize - 1) / 2,
            (None, None) => 0,
        };
        Self {
            q,
            len,
            codes,
            packing,
            packed,
            index,
            max_correction,
        }
    }

    /// Parses the codes of a spec. `rotations` are the code permutations under which the layout
    /// is ambiguous; a code equal to a rotation of an earlier one is a duplicate ID.
    pub fn parse(
        spec: &CodebookSpec,
        q: usize,
        len: usize,
        rotations: &[Vec<usize>],
    ) -> Result<Self, Vec<Problem>> {
        if spec.encoding == CodeEncoding::Hex && q != 2 {
            return Err(vec![Problem::new(
                "codebook.encoding",
                format!("hex codes need exactly 2 symbol categories, the family has {q}; use \"digits\""),
            )]);
        }
        if spec.codes.is_empty() {
            return Err(vec![Problem::new(
                "codebook.codes",
                "the codebook has no codes",
            )]);
        }
        let mut report = Report::default();
        let mut codes = Vec::with_capacity(spec.codes.len());
        for (i, text) in spec.codes.iter().enumerate() {
            let parsed = match spec.encoding {
                CodeEncoding::Hex => parse_hex(text, len),
                CodeEncoding::Digits => parse_digits(text, len, q),
            };
            match parsed {
                Ok(c) => codes.push(c),
                Err(msg) => report.push(Problem::new(format!("codebook.codes[{i}]"), msg)),
            }
        }
        if !report.is_empty() {
            return Err(report.finish());
        }
        // Indexed by the exact code, so the check is linear; each code's rotations are made as
        // it is checked, never all at once.
        let mut seen: HashMap<&[u8], usize> = HashMap::with_capacity(codes.len());
        for (id, c) in codes.iter().enumerate() {
            if let Some(&first) = seen.get(c.as_slice()) {
                report.push(Problem::new(
                    format!("codebook.codes[{id}]"),
                    format!("duplicate ID: the same code as ID {first}, so the two cannot be told apart"),
                ));
                continue;
            }
            if let Some((r, first)) = rotations
                .iter()
                .enumerate()
                .find_map(|(r, p)| seen.get(permute(c, p).as_slice()).map(|&f| (r, f)))
            {
                report.push(Problem::new(
                    format!("codebook.codes[{id}]"),
                    format!(
                        "duplicate ID: the code of ID {first} rotated (rotation {}), so the two \
                         cannot be told apart",
                        r + 1
                    ),
                ));
                continue;
            }
            seen.insert(c, id);
        }
        if !report.is_empty() {
            return Err(report.finish());
        }
        Ok(Self::from_codes(
            q,
            len,
            codes,
            spec.min_distance,
            spec.max_correction,
        ))
    }

    pub fn q(&self) -> usize {
        self.q
    }
    pub fn code_len(&self) -> usize {
        self.len
    }
    pub fn len(&self) -> usize {
        self.codes.len()
    }
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }
    pub fn code(&self, id: usize) -> Option<&[u8]> {
        self.codes.get(id).map(|c| c.as_slice())
    }
    pub fn codes(&self) -> &[Vec<u8>] {
        &self.codes
    }
    pub fn max_correction(&self) -> usize {
        self.max_correction
    }
    pub fn packing(&self) -> Packing {
        self.packing
    }
    pub(crate) fn packed(&self, id: usize) -> &[u64] {
        let s = self.packing.stride();
        &self.packed[id * s..(id + 1) * s]
    }
    pub(crate) fn lookup(&self, packed: &[u64]) -> Option<usize> {
        self.index.get(packed).copied()
    }

    /// The minimum Hamming distance over all pairs of distinct IDs under every rotation in
    /// `rotations`, and of each code against its own rotations (`None` for a single code with no
    /// rotations).
    pub fn min_distance(&self, rotations: &[Vec<usize>]) -> Option<u32> {
        use rayon::prelude::*;
        let p = self.packing;
        let (n, r, s) = (self.codes.len(), rotations.len(), p.stride());
        // Every rotated code packed into one flat array: the quadratic scan below then reads
        // memory in order (a codebook of 50 000 codes is 5·10⁹ comparisons).
        let mut variants = vec![0u64; n * r * s];
        for (i, code) in self.codes.iter().enumerate() {
            for (k, rotation) in rotations.iter().enumerate() {
                let at = (i * r + k) * s;
                variants[at..at + s].copy_from_slice(&p.pack(&permute(code, rotation)));
            }
        }
        let variant = |i: usize, k: usize| &variants[(i * r + k) * s..(i * r + k + 1) * s];
        (0..n)
            .into_par_iter()
            .filter_map(|i| {
                let a = self.packed(i);
                // u32::MAX: nothing compared yet (a single code with no rotations).
                let mut best = u32::MAX;
                for k in 0..r {
                    best = best.min(p.distance(a, variant(i, k)));
                }
                for j in i + 1..n {
                    best = best.min(p.distance(a, self.packed(j)));
                    for k in 0..r {
                        best = best.min(p.distance(a, variant(j, k)));
                    }
                    if best == 0 {
                        break;
                    }
                }
                (best != u32::MAX).then_some(best)
            })
            .min()
    }

    /// The codes written as in a family file.
    pub fn to_spec(&self, min_distance: Option<u32>, source: &str) -> CodebookSpec {
        let encoding = if self.q == 2 {
            CodeEncoding::Hex
        } else {
            CodeEncoding::Digits
        };
        CodebookSpec {
            encoding,
            min_distance,
            max_correction: None,
            source: source.to_string(),
            codes: self
                .codes
                .iter()
                .map(|c| match encoding {
                    CodeEncoding::Hex => format_hex(c),
                    CodeEncoding::Digits => c.iter().map(|&s| char::from(b'0' + s)).collect(),
                })
                .collect(),
        }
    }
}

/// Problems with individual codes, the first [`Report::SHOWN`] of them in full: a file with a
/// million bad codes gets a readable message, not a million lines.
#[derive(Default)]
struct Report {
    problems: Vec<Problem>,
    more: usize,
}

impl Report {
    const SHOWN: usize = 20;

    fn push(&mut self, p: Problem) {
        if self.problems.len() < Self::SHOWN {
            self.problems.push(p);
        } else {
            self.more += 1;
        }
    }

    fn is_empty(&self) -> bool {
        self.problems.is_empty()
    }

    fn finish(mut self) -> Vec<Problem> {
        if self.more > 0 {
            self.problems.push(Problem::new(
                "codebook.codes",
                format!(
                    "and {} more codes with problems like those above",
                    self.more
                ),
            ));
        }
        self.problems
    }
}

/// A binary code as hex, first symbol = most significant bit, ⌈len/4⌉ digits.
pub fn format_hex(bits: &[u8]) -> String {
    let digits = bits.len().div_ceil(4);
    let pad = digits * 4 - bits.len();
    let padded: Vec<u8> = std::iter::repeat_n(0, pad)
        .chain(bits.iter().copied())
        .collect();
    padded
        .chunks(4)
        .map(|nib| {
            let v = nib.iter().fold(0u32, |acc, &b| acc << 1 | b as u32);
            char::from_digit(v, 16).expect("a nibble is one hex digit")
        })
        .collect()
}

fn parse_hex(text: &str, len: usize) -> Result<Vec<u8>, String> {
    let digits = len.div_ceil(4);
    if text.len() != digits {
        return Err(format!(
            "code {text:?} has {} hex digits ({} bits), but the layout has {len} symbol keypoints \
             ({digits} digits)",
            text.len(),
            text.len() * 4
        ));
    }
    let mut bits = Vec::with_capacity(digits * 4);
    for c in text.chars() {
        let v = c
            .to_digit(16)
            .ok_or_else(|| format!("code {text:?}: {c:?} is not a hex digit"))?;
        bits.extend((0..4).rev().map(|b| ((v >> b) & 1) as u8));
    }
    let pad = digits * 4 - len;
    if bits[..pad].iter().any(|&b| b != 0) {
        return Err(format!(
            "code {text:?} is longer than {len} bits (its top {pad} bits must be 0)"
        ));
    }
    Ok(bits[pad..].to_vec())
}

fn parse_digits(text: &str, len: usize, q: usize) -> Result<Vec<u8>, String> {
    let count = text.chars().count();
    if count != len {
        return Err(format!(
            "code has {count} symbols, but the layout has {len} symbol keypoints"
        ));
    }
    text.chars()
        .enumerate()
        .map(|(i, c)| match c.to_digit(10) {
            Some(v) if (v as usize) < q => Ok(v as u8),
            Some(v) => Err(format!(
                "symbol {v} at position {i} is ≥ the number of symbol categories ({q})"
            )),
            None => Err(format!("{c:?} at position {i} is not a digit")),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_round_trips_with_padding() {
        let bits = vec![1, 0, 1, 1, 0, 1];
        assert_eq!(format_hex(&bits), "2d");
        assert_eq!(parse_hex("2d", 6).unwrap(), bits);
        assert!(parse_hex("4d", 6)
            .unwrap_err()
            .contains("longer than 6 bits"));
        assert!(parse_hex("2d0", 6)
            .unwrap_err()
            .contains("symbol keypoints"));
    }

    #[test]
    fn many_duplicate_codes_give_a_short_report_quickly() {
        // 200 000 codes, every one the same as ID 0 or one of its turns.
        let spec = CodebookSpec {
            encoding: CodeEncoding::Hex,
            min_distance: None,
            max_correction: None,
            source: String::new(),
            codes: vec!["9".to_string(); 200_000],
        };
        let rot = vec![vec![1, 3, 0, 2], vec![3, 2, 1, 0], vec![2, 0, 3, 1]];
        let started = std::time::Instant::now();
        let problems = Codebook::parse(&spec, 2, 4, &rot).unwrap_err();
        assert!(
            started.elapsed().as_secs_f64() < 5.0,
            "{:?}",
            started.elapsed()
        );
        assert_eq!(problems.len(), Report::SHOWN + 1);
        assert_eq!(problems[0].path, "codebook.codes[1]");
        assert!(problems[Report::SHOWN].message.contains("and 199979 more"));
    }

    #[test]
    fn min_distance_of_ten_thousand_codes_is_a_matter_of_seconds() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let codes: Vec<Vec<u8>> = (0..10_000)
            .map(|_| (0..36).map(|_| rng.random_range(0..2u8)).collect())
            .collect();
        let cb = Codebook::from_codes(2, 36, codes, None, None);
        // A 6 × 6 grid's three turns.
        let turn = |k: usize| -> Vec<usize> {
            (0..36)
                .map(|i| {
                    let (mut r, mut c) = (i / 6, i % 6);
                    for _ in 0..k {
                        (r, c) = (c, 5 - r);
                    }
                    r * 6 + c
                })
                .collect()
        };
        let started = std::time::Instant::now();
        let d = cb.min_distance(&[turn(1), turn(2), turn(3)]);
        assert!(d.is_some_and(|d| d < 6), "{d:?}");
        assert!(
            started.elapsed().as_secs_f64() < 20.0,
            "{:?}",
            started.elapsed()
        );
    }

    #[test]
    fn min_distance_includes_rotations_and_self_rotations() {
        // 2x2 "grid" codes, rotation by 90°: positions 0 1 / 3 2 cycle 0→1→2→3→0 (row-major 0,1,2,3
        // = TL TR BL BR; a clockwise turn sends TL→TR→BR→BL).
        let rot = vec![vec![1, 3, 0, 2], vec![3, 2, 1, 0], vec![2, 0, 3, 1]];
        let cb = Codebook::from_codes(2, 4, vec![vec![1, 0, 0, 0], vec![0, 1, 0, 1]], None, None);
        // 0101 turned twice is 1010, one symbol from 1000; unturned they differ in three.
        assert_eq!(cb.min_distance(&rot), Some(1));
        assert_eq!(cb.min_distance(&[]), Some(3));
        let symmetric = Codebook::from_codes(2, 4, vec![vec![1, 1, 1, 1]], None, None);
        assert_eq!(symmetric.min_distance(&rot), Some(0));
    }
}
