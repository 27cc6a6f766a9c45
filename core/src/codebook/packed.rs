//! Bit-plane packing of q-ary codes so that a Hamming distance is a few XOR/OR/popcounts.
//!
//! A symbol of a q-ary alphabet takes `planes = ceil(log2 q)` bits; bit b of every symbol goes to
//! plane b. Two codes differ at a position iff any plane differs there, so the distance is
//! `popcount(OR_b (x_b XOR y_b))` summed over 64-symbol words.

/// The packing shape shared by all codes of a codebook.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Packing {
    pub planes: usize,
    pub words: usize,
}

impl Packing {
    pub fn new(q: usize, len: usize) -> Self {
        let planes = (usize::BITS - (q.max(2) - 1).leading_zeros()) as usize;
        Self {
            planes,
            words: len.div_ceil(64).max(1),
        }
    }

    /// Words per packed code.
    pub fn stride(&self) -> usize {
        self.planes * self.words
    }

    /// Packs a code; `None` symbols (unknown) pack as 0 and are left out of `known`.
    pub fn pack_into(
        &self,
        code: impl Iterator<Item = Option<u8>>,
        out: &mut [u64],
        known: &mut [u64],
    ) {
        out.fill(0);
        known.fill(0);
        for (i, s) in code.enumerate() {
            let (w, bit) = (i / 64, 1u64 << (i % 64));
            if let Some(s) = s {
                known[w] |= bit;
                for p in 0..self.planes {
                    if (s >> p) & 1 == 1 {
                        out[p * self.words + w] |= bit;
                    }
                }
            }
        }
    }

    pub fn pack(&self, code: &[u8]) -> Vec<u64> {
        let mut out = vec![0; self.stride()];
        let mut known = vec![0; self.words];
        self.pack_into(code.iter().map(|&s| Some(s)), &mut out, &mut known);
        out
    }

    /// Number of positions where `a` and `b` differ.
    #[inline]
    pub fn distance(&self, a: &[u64], b: &[u64]) -> u32 {
        let mut total = 0;
        for w in 0..self.words {
            let mut diff = 0;
            for p in 0..self.planes {
                let k = p * self.words + w;
                diff |= a[k] ^ b[k];
            }
            total += diff.count_ones();
        }
        total
    }

    /// Differences at known positions only.
    #[inline]
    pub fn distance_known(&self, a: &[u64], b: &[u64], known: &[u64]) -> u32 {
        let mut total = 0;
        for (w, &mask) in known.iter().enumerate().take(self.words) {
            let mut diff = 0;
            for p in 0..self.planes {
                let k = p * self.words + w;
                diff |= a[k] ^ b[k];
            }
            total += (diff & mask).count_ones();
        }
        total
    }
}

/// Applies a code permutation: symbol `j` moves to position `perm[j]`.
pub fn permute(code: &[u8], perm: &[usize]) -> Vec<u8> {
    let mut out = vec![0; code.len()];
    for (j, &s) in code.iter().enumerate() {
        out[perm[j]] = s;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_counts_differing_symbols_for_binary_and_quaternary() {
        let p = Packing::new(2, 70);
        assert_eq!((p.planes, p.words), (1, 2));
        let mut a = vec![0u8; 70];
        let mut b = a.clone();
        b[0] = 1;
        b[69] = 1;
        assert_eq!(p.distance(&p.pack(&a), &p.pack(&b)), 2);

        let p = Packing::new(4, 10);
        assert_eq!(p.planes, 2);
        a = vec![0, 1, 2, 3, 0, 1, 2, 3, 0, 0];
        b = vec![3, 1, 2, 0, 0, 2, 2, 3, 1, 0];
        // positions 0, 3, 5, 8 differ; 1→2 flips both planes but counts once
        assert_eq!(p.distance(&p.pack(&a), &p.pack(&b)), 4);
    }

    #[test]
    fn unknown_symbols_are_left_out_of_known_distance() {
        let p = Packing::new(2, 4);
        let mut obs = vec![0; 1];
        let mut known = vec![0; 1];
        p.pack_into(
            [Some(1), None, Some(0), Some(1)].into_iter(),
            &mut obs,
            &mut known,
        );
        let code = p.pack(&[1, 1, 1, 1]);
        assert_eq!(p.distance_known(&obs, &code, &known), 1);
    }
}
