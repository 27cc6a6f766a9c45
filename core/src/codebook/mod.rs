//! Codebooks: which symbol sequences are valid IDs, their minimum Hamming distance over the
//! rotations a layout admits, nearest-code search with error and erasure correction, and
//! generation. It knows codes, lengths, alphabets and rotations as permutations, not families.

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
        let mut problems = Vec::new();
        if spec.encoding == CodeEncoding::Hex && q != 2 {
            problems.push(Problem::new(
                "codebook.encoding",
                format!("hex codes need exactly 2 symbol categories, the family has {q}; use \"digits\""),
            ));
            return Err(problems);
        }
        if spec.codes.is_empty() {
            problems.push(Problem::new("codebook.codes", "the codebook has no codes"));
        }
        let mut codes = Vec::with_capacity(spec.codes.len());
        for (i, text) in spec.codes.iter().enumerate() {
            let parsed = match spec.encoding {
                CodeEncoding::Hex => parse_hex(text, len),
                CodeEncoding::Digits => parse_digits(text, len, q),
            };
            match parsed {
                Ok(c) => codes.push(c),
                Err(msg) => problems.push(Problem::new(format!("codebook.codes[{i}]"), msg)),
            }
        }
        if !problems.is_empty() {
            return Err(problems);
        }
        let mut seen: HashMap<&[u8], usize> = HashMap::with_capacity(codes.len());
        let rotated: Vec<Vec<Vec<u8>>> = codes
            .iter()
            .map(|c| rotations.iter().map(|p| permute(c, p)).collect())
            .collect();
        for (id, c) in codes.iter().enumerate() {
            if let Some(&first) = seen.get(c.as_slice()) {
                problems.push(Problem::new(
                    format!("codebook.codes[{id}]"),
                    format!("duplicate ID: the same code as ID {first}, so the two cannot be told apart"),
                ));
                continue;
            }
            if let Some((r, &first)) = rotated[id]
                .iter()
                .enumerate()
                .find_map(|(r, rc)| seen.get(rc.as_slice()).map(|f| (r, f)))
            {
                problems.push(Problem::new(
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
        if !problems.is_empty() {
            return Err(problems);
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
        let n = self.codes.len();
        let variants: Vec<Vec<Vec<u64>>> = self
            .codes
            .iter()
            .map(|c| rotations.iter().map(|r| p.pack(&permute(c, r))).collect())
            .collect();
        (0..n)
            .into_par_iter()
            .filter_map(|i| {
                let own = variants[i].iter().map(|v| p.distance(self.packed(i), v));
                let others = (i + 1..n).flat_map(|j| {
                    std::iter::once(p.distance(self.packed(i), self.packed(j))).chain(
                        variants[j]
                            .iter()
                            .map(move |v| p.distance(self.packed(i), v)),
                    )
                });
                own.chain(others).min()
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
