//! The trained stage-2 model file: a magic line, a JSON header naming the family the weights were
//! trained for (name + a hash of its geometry and categories) with a checksum of the weights, then
//! the weights in burn's burnpack format. Loading checks all three, so weights trained for another
//! family, or damaged bytes, fail with a message rather than detecting garbage.

use super::net::{NetConfig, Stage2Net};
use crate::family::Family;
use burn::module::{Module, ModuleVisitor, Param};
use burn::store::ModuleRecord;
use burn::tensor::{Bytes, Device, Tensor};
use serde::{Deserialize, Serialize};
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-STAGE2\n";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ModelHeader {
    pub format: u32,
    pub family: String,
    /// [`family_hash`] of the family the model was trained for.
    pub family_hash: String,
    pub net: NetConfig,
    /// Optimiser steps the weights were trained for.
    pub steps: u64,
    /// FNV-1a 64 of the weight bytes.
    pub weights_fnv: String,
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
        "{path}: the model was trained for family {model:?}, not {family:?}; train one with \
         `tagsmith train {family} --stage keypoints`"
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

/// A hash of what the network's outputs mean for a family: the layout, extra keypoints,
/// categories, the regressed keypoint set and the ROI. The codebook is left out on purpose: a
/// family with the same layout and another codebook uses the same weights.
pub fn family_hash(family: &Family) -> String {
    let s = family.spec();
    let text =
        serde_json::to_string(&(&s.layout, &s.extra, &s.categories, &s.keypoint_set, &s.roi))
            .expect("family specs serialise");
    format!("{:016x}", fnv1a(text.as_bytes()))
}

/// Serialises a model for `family`.
pub fn to_bytes(
    net: Stage2Net,
    config: &NetConfig,
    family: &Family,
    steps: u64,
) -> Result<Vec<u8>, String> {
    let weights = weight_bytes(net)?;
    let header = ModelHeader {
        format: 1,
        family: family.name().to_string(),
        family_hash: family_hash(family),
        net: *config,
        steps,
        weights_fnv: format!("{:016x}", fnv1a(&weights)),
    };
    Ok(pack(MAGIC, &header, &weights))
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
    let json = rest
        .get(4..4 + len)
        .ok_or_else(|| corrupt("truncated header".into()))?;
    let header = serde_json::from_slice(json).map_err(|e| corrupt(format!("header: {e}")))?;
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

/// Reads the header without the weights.
pub fn read_header(bytes: &[u8], path: &str) -> Result<(ModelHeader, usize), ModelError> {
    let (header, start): (ModelHeader, usize) = unpack(bytes, MAGIC, "stage-2", path)?;
    if header.format != 1 {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: format!("unknown format {}", header.format),
        });
    }
    Ok((header, start))
}

/// Loads a model for `family` onto `device`, checking that it was trained for that family and
/// that its bytes are intact.
pub fn from_bytes(
    bytes: &[u8],
    path: &str,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let (header, start) = read_header(bytes, path)?;
    if header.family != family.name() {
        return Err(ModelError::WrongFamily {
            path: path.into(),
            model: header.family,
            family: family.name().into(),
        });
    }
    if header.family_hash != family_hash(family) {
        return Err(ModelError::FamilyChanged {
            path: path.into(),
            family: family.name().into(),
        });
    }
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    let corrupt = |reason: String| ModelError::Corrupt {
        path: path.into(),
        reason,
    };
    let classes = family.categories().len() + 1;
    if header.net.classes != classes {
        return Err(corrupt(format!(
            "{} classes for a family with {classes}",
            header.net.classes
        )));
    }
    let net = load_weights(header.net.init(device), weights, path)?;
    Ok((net, header))
}

pub fn load(
    path: &Path,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ModelError::Io {
        path: name.clone(),
        source,
    })?;
    from_bytes(&bytes, &name, family, device)
}
