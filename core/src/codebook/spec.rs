//! The codebook as written in a family file.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// How a code is written in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CodeEncoding {
    /// Binary codes as hexadecimal numbers, symbol 0 = most significant of `length` bits.
    #[default]
    Hex,
    /// One digit per symbol (`0`–`9`), first symbol first.
    Digits,
}

/// The codebook: which symbol sequences are valid IDs. ID = position in `codes`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CodebookSpec {
    #[serde(default)]
    pub encoding: CodeEncoding,
    /// Declared minimum Hamming distance over the admissible rotations (checked by `validate`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min_distance: Option<u32>,
    /// Most symbol errors the decoder corrects; default ⌊(d_min − 1)/2⌋.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_correction: Option<u32>,
    /// Provenance and licence of the codes.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub source: String,
    pub codes: Vec<String>,
}
