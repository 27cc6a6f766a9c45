//! The model-file container both stages' files share: a magic line, a JSON header, the weights
//! in burn's format; reads capped and checked field by field before any tensor is built
//! (`docs/ARCHITECTURE.md` §9.7). Each stage's own header lives with its network.

use burn::module::{Module, ModuleVisitor, Param};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Tensor};
use serde::Serialize;
use std::ops::RangeInclusive;
use std::path::Path;

/// The network widths a model file may hold: what `tagsmith train --width` and the studio build.
/// The networks need at least 4 (the stem has `width / 4` channels); the cap keeps a header from
/// asking for a network of unbounded size before its weights are read.
pub const WIDTHS: RangeInclusive<usize> = 8..=256;

/// The most optimiser steps a run makes (`tagsmith train --steps`), and so the most a model's
/// header may record.
pub const MAX_STEPS: u64 = 10_000_000;

/// Where the studio keeps the stage-2 model trained for a family file: beside it, as
/// `NAME.stage2.bin`, so that the family detects wherever the file goes.
pub fn attached_to(family_file: &Path) -> std::path::PathBuf {
    family_file.with_extension("stage2.bin")
}

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: not a Tagsmith {kind} model file (it does not start with the model header)")]
    NotAModel { path: String, kind: &'static str },
    #[error("{path}: the model file is corrupt: {reason}")]
    Corrupt { path: String, reason: String },
    #[error(
        "{path}: the model was trained for family {model:?}, not {family:?} (their layouts, \
         keypoints, categories or ROIs differ); train one with `tagsmith train {family} --stage keypoints`"
    )]
    WrongFamily {
        path: String,
        model: String,
        family: String,
    },
    #[error(
        "{path}: the model was trained for an earlier version of family {family:?} (its keypoints \
         or categories changed since); retrain it"
    )]
    FamilyChanged { path: String, family: String },
    #[error("{path}: the network's weights are not all finite numbers (training diverged)")]
    NotFinite { path: String },
    /// A header field outside what the network it describes can be.
    #[error("{path}: header field {field:?} is {value}; expected {expected}")]
    BadField {
        path: String,
        field: &'static str,
        value: String,
        expected: String,
    },
    /// The weights are not as many bytes as the network the header describes needs.
    #[error(
        "{path}: the weights are {actual} bytes of tensor data, but the network the header \
         describes ({network}) needs {expected}"
    )]
    WeightSize {
        path: String,
        network: String,
        actual: usize,
        expected: usize,
    },
}

impl ModelError {
    pub(crate) fn bad_field(
        path: &str,
        field: &'static str,
        value: impl std::fmt::Display,
        expected: impl Into<String>,
    ) -> Self {
        ModelError::BadField {
            path: path.into(),
            field,
            value: value.to_string(),
            expected: expected.into(),
        }
    }
}

/// `value` of header field `field` within `range`.
pub(crate) fn check_range<T: PartialOrd + std::fmt::Display>(
    path: &str,
    field: &'static str,
    value: T,
    range: &RangeInclusive<T>,
) -> Result<(), ModelError> {
    if range.contains(&value) {
        return Ok(());
    }
    Err(ModelError::bad_field(
        path,
        field,
        &value,
        format!("{} to {}", range.start(), range.end()),
    ))
}

/// The bytes of tensor data a network's burnpack holds: its float parameters in the order burn
/// records them, each 4 bytes a value (f32) and starting on a 256-byte boundary (burnpack's
/// `TENSOR_ALIGNMENT`), counted from their shapes without materialising them.
fn tensor_data_bytes<M: Module>(net: &M) -> usize {
    struct Layout(usize);
    impl ModuleVisitor for Layout {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            self.0 =
                self.0.next_multiple_of(BURNPACK_ALIGNMENT) + 4 * param.lazy_shape().num_elements();
        }
    }
    let mut layout = Layout(0);
    net.visit(&mut layout);
    layout.0
}

/// Burnpack's layout: "NRUB", a u16 version, a u32 metadata length, the metadata, then the
/// tensor data from the next multiple of 256 bytes.
const BURNPACK_MAGIC: &[u8] = b"NRUB";

const BURNPACK_HEADER: usize = 10;

const BURNPACK_ALIGNMENT: usize = 256;

/// The bytes of tensor data in burnpack `weights` (what follows its header and metadata), or
/// `None` when they are not a burnpack of the version this build writes.
fn burnpack_data_bytes(weights: &[u8]) -> Option<usize> {
    if !weights.starts_with(BURNPACK_MAGIC) || weights.get(4..6)? != [1, 0] {
        return None;
    }
    let metadata = u32::from_le_bytes(weights.get(6..10)?.try_into().ok()?) as usize;
    let start = BURNPACK_HEADER
        .checked_add(metadata)?
        .next_multiple_of(BURNPACK_ALIGNMENT);
    weights.len().checked_sub(start)
}

/// Refuses `weights` whose tensor data is not exactly what `net` (described by `network`)
/// holds: weights of another width or patch, cut short or padded, are named as such before
/// burn reads them.
pub(crate) fn check_weight_size<M: Module>(
    net: &M,
    network: impl FnOnce() -> String,
    weights: &[u8],
    path: &str,
) -> Result<(), ModelError> {
    let expected = tensor_data_bytes(net);
    let Some(actual) = burnpack_data_bytes(weights) else {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: "the weights are not in burn's burnpack format (version 1)".into(),
        });
    };
    if actual == expected {
        return Ok(());
    }
    Err(ModelError::WeightSize {
        path: path.into(),
        network: network(),
        actual,
        expected,
    })
}

/// Whether every weight of the network is a finite number: weights that are not make every
/// detection garbage, so they are neither saved nor loaded.
pub fn weights_are_finite<M: Module>(net: &M) -> bool {
    struct Check(bool);
    impl ModuleVisitor for Check {
        fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
            if self.0 {
                let values = param.val().into_data().convert::<f32>();
                self.0 = values.iter::<f32>().all(f32::is_finite);
            }
        }
    }
    let mut check = Check(true);
    net.visit(&mut check);
    check.0
}

/// FNV-1a, 64 bit: a stable hash with no dependency (std's hasher may change between releases).
pub fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// A network's weights as burnpack bytes, refused when any is not finite: weights that are not
/// make every detection garbage.
pub(crate) fn weight_bytes<M: Module>(net: M) -> Result<Bytes, String> {
    if !weights_are_finite(&net) {
        return Err(
            "the network's weights are not all finite numbers (training diverged); nothing was \
             written"
                .into(),
        );
    }
    net.into_record().into_bytes().map_err(|e| e.to_string())
}

/// A model file's bytes: `magic`, the header's JSON length (u32 LE) and JSON, the weights.
pub(crate) fn pack<H: Serialize>(magic: &[u8], header: &H, weights: &[u8]) -> Vec<u8> {
    let json = serde_json::to_vec(header).expect("model headers serialise");
    let mut out = magic.to_vec();
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(weights);
    out
}

/// The header of a file written by [`pack`] and where its weights start.
pub(crate) fn unpack<H: serde::de::DeserializeOwned>(
    bytes: &[u8],
    magic: &[u8],
    kind: &'static str,
    path: &str,
) -> Result<(H, usize), ModelError> {
    let rest = bytes
        .strip_prefix(magic)
        .ok_or_else(|| ModelError::NotAModel {
            path: path.into(),
            kind,
        })?;
    let corrupt = |reason: String| ModelError::Corrupt {
        path: path.into(),
        reason,
    };
    let len = rest
        .get(..4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .ok_or_else(|| corrupt("truncated header".into()))?;
    let json = 4usize
        .checked_add(len)
        .and_then(|end| rest.get(4..end))
        .ok_or_else(|| corrupt("truncated header".into()))?;
    // The path of a field whose value has the wrong type (`net.width: invalid value: integer -1`).
    let de = &mut serde_json::Deserializer::from_slice(json);
    let header = serde_path_to_error::deserialize(de).map_err(|e| {
        let field = e.path().to_string();
        match field.as_str() {
            "." => corrupt(format!("header: {}", e.into_inner())),
            _ => corrupt(format!("header field {field:?}: {}", e.into_inner())),
        }
    })?;
    Ok((header, magic.len() + 4 + len))
}

/// The weights after `start`, checked against the header's checksum.
pub(crate) fn checked_weights<'a>(
    bytes: &'a [u8],
    start: usize,
    fnv: &str,
    path: &str,
) -> Result<&'a [u8], ModelError> {
    let weights = &bytes[start..];
    if format!("{:016x}", fnv1a(weights)) != fnv {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: "the weights' checksum does not match".into(),
        });
    }
    Ok(weights)
}

/// `weights` (burnpack bytes) loaded into a fresh network, refused when they do not fit it or
/// are not all finite numbers.
pub(crate) fn load_weights<M: Module>(net: M, weights: &[u8], path: &str) -> Result<M, ModelError> {
    let corrupt = |reason: String| ModelError::Corrupt {
        path: path.into(),
        reason,
    };
    let record = ModuleRecord::from_bytes(Bytes::from_bytes_vec(weights.to_vec()))
        .map_err(|e| corrupt(format!("weights: {e}")))?;
    let net = net
        .try_load_record(record)
        .map_err(|e| corrupt(format!("weights: {e}")))?;
    if !weights_are_finite(&net) {
        return Err(ModelError::NotFinite { path: path.into() });
    }
    Ok(net)
}

/// The bytes of model file `path`: a regular file of at most [`crate::io::MAX_MODEL_BYTES`]
/// ([`crate::io::read_input`]); a FIFO, a device or a folder is refused before anything waits on
/// it.
pub fn read_model_file(path: &Path) -> Result<Vec<u8>, ModelError> {
    crate::io::read_input(path, crate::io::MAX_MODEL_BYTES).map_err(|source| ModelError::Io {
        path: path.display().to_string(),
        source,
    })
}

/// The header of a model that belongs to no family (stage 1, the verifier): its network's
/// settings, the steps it was trained for, the families whose markers were in its training
/// scenes (for the record, not to check) and a checksum of its weights.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub struct FamilyFreeHeader<C> {
    pub format: u32,
    pub net: C,
    /// Optimiser steps the weights were trained for.
    pub steps: u64,
    /// Families whose markers were in the training scenes (besides random designs).
    pub families: Vec<String>,
    /// FNV-1a 64 of the weight bytes.
    pub weights_fnv: String,
}

/// A family-free model file of `net` (settings `config`) after `steps` steps.
pub(crate) fn family_free_bytes<M: Module, C: Serialize + Copy>(
    magic: &[u8],
    net: M,
    config: &C,
    families: &[String],
    steps: u64,
) -> Result<Vec<u8>, String> {
    let weights = weight_bytes(net)?;
    let header = FamilyFreeHeader {
        format: 1,
        net: *config,
        steps,
        families: families.to_vec(),
        weights_fnv: format!("{:016x}", fnv1a(&weights)),
    };
    Ok(pack(magic, &header, &weights))
}

/// The header of a family-free model file and its weights, checked against the checksum;
/// `check` refuses the network's settings before anything is built from them.
pub(crate) fn family_free_parts<'a, C: serde::de::DeserializeOwned>(
    bytes: &'a [u8],
    magic: &[u8],
    kind: &'static str,
    path: &str,
    check: impl FnOnce(&C) -> Result<(), ModelError>,
) -> Result<(FamilyFreeHeader<C>, &'a [u8]), ModelError> {
    let (header, start): (FamilyFreeHeader<C>, usize) = unpack(bytes, magic, kind, path)?;
    if header.format != 1 {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: format!("unknown format {}", header.format),
        });
    }
    check(&header.net)?;
    check_range(path, "steps", header.steps, &(0..=MAX_STEPS))?;
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    Ok((header, weights))
}
