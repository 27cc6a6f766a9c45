//! ARToolKitPlus's BCH-coded ID markers, computed from their public definition rather than
//! copied as a table. Source: ARToolKitPlus (D. Wagner, D. Schmalstieg et al., TU Graz;
//! github.com/paroj/artoolkitplus, GPL-3.0-or-later): `include/ARToolKitPlus/extra/BCH.h`,
//! `src/extra/BCH.cpp` and `src/core/arBitFieldPattern.cpp`. Only the code's parameters are
//! taken from there; this file's arithmetic is our own.
//!
//! The code is the binary (36, 12, 9) BCH code: the length-63 primitive BCH code over GF(2⁶)
//! (field polynomial x⁶ + x + 1, roots α¹…α⁸) shortened to 36 bits. A 12-bit ID is encoded
//! systematically, the ID in bits 24–35 and the remainder of ID(x)·x²⁴ divided by the generator
//! in bits 0–23, and the 36 bits are then XORed with a fixed mask so that no marker is all black.
//! Bit 35 is the top-left data cell, row by row, and a 1 bit is a white cell: the convention of
//! the hexadecimal codes in family files (symbol 0 = most significant bit = first data cell),
//! with symbol 1 white as in ArUco's tables.

/// IDs the 12 data bits give.
pub const ARTOOLKITPLUS_BCH_IDS: usize = 1 << DATA_BITS;

const DATA_BITS: u32 = 12;
const PARITY_BITS: u32 = 24;
/// g(x) of degree 24, the product of the minimal polynomials of α, α³, α⁵ and α⁷ in GF(2⁶).
const GENERATOR: u64 = 0x1DB_2777;
/// ARToolKitPlus's `bchMask`.
const MASK: u64 = 0x8_F80B_8750;

/// The 36 data cells of ARToolKitPlus BCH marker `id` (bit 35 = top-left cell, 1 = white);
/// `None` past the 4096 IDs.
pub fn artoolkitplus_bch(id: usize) -> Option<u64> {
    (id < ARTOOLKITPLUS_BCH_IDS).then(|| {
        let data = id as u64;
        let mut remainder = data << PARITY_BITS;
        for bit in (PARITY_BITS..PARITY_BITS + DATA_BITS).rev() {
            if remainder >> bit & 1 == 1 {
                remainder ^= GENERATOR << (bit - PARITY_BITS);
            }
        }
        ((data << PARITY_BITS) | remainder) ^ MASK
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Read cell by cell off ARToolKitPlus's own marker images (`id-markers/bch/BchThin_*.png`).
    #[test]
    fn ids_match_artoolkitplus_marker_images() {
        assert_eq!(artoolkitplus_bch(0), Some(0x8_F80B_8750));
        assert_eq!(artoolkitplus_bch(1), Some(0x8_F9D0_A027));
        assert_eq!(artoolkitplus_bch(2), Some(0x8_FA66_EEC9));
        assert_eq!(artoolkitplus_bch(100), Some(0x8_9C72_312F));
        assert_eq!(artoolkitplus_bch(4095), Some(0x7_0759_F1F6));
        assert_eq!(artoolkitplus_bch(4096), None);
    }

    #[test]
    fn the_code_is_linear_with_distance_nine() {
        let codeword = |id| artoolkitplus_bch(id).unwrap() ^ MASK;
        // Linear: the sum of two codewords is the codeword of the sum of their IDs.
        assert_eq!(codeword(5) ^ codeword(9), codeword(5 ^ 9));
        // Its least weight is its minimum distance (d = 2t + 1 for t = 4).
        let least = (1..ARTOOLKITPLUS_BCH_IDS)
            .map(|id| codeword(id).count_ones())
            .min();
        assert_eq!(least, Some(9));
    }
}
