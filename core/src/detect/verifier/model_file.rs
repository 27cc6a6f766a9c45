//! The verifier's model file: the container both stages' files use (magic line, JSON header
//! with a checksum of the weights, burnpack weights).

use super::net::{NetConfig, VerifierNet};
use crate::detect::model_file::{
    check_range, check_weight_size, checked_weights, fnv1a, load_weights, pack, read_model_file,
    unpack, weight_bytes, ModelError, MAX_STEPS, WIDTHS,
};
use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use std::ops::RangeInclusive;
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-VERIFIER\n";

/// The patch sides a verifier may read (multiples of 8).
pub const PATCHES: RangeInclusive<usize> = 16..=128;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VerifierHeader {
    pub format: u32,
    pub net: NetConfig,
    /// Optimiser steps the weights were trained for.
    pub steps: u64,
    /// Families whose markers were the positives (besides random designs).
    pub families: Vec<String>,
    /// FNV-1a 64 of the weight bytes.
    pub weights_fnv: String,
}

pub fn to_bytes(
    net: VerifierNet,
    config: &NetConfig,
    families: &[String],
    steps: u64,
) -> Result<Vec<u8>, String> {
    let weights = weight_bytes(net)?;
    let header = VerifierHeader {
        format: 1,
        net: *config,
        steps,
        families: families.to_vec(),
        weights_fnv: format!("{:016x}", fnv1a(&weights)),
    };
    Ok(pack(MAGIC, &header, &weights))
}

pub fn from_bytes(
    bytes: &[u8],
    path: &str,
    device: &Device,
) -> Result<(VerifierNet, VerifierHeader), ModelError> {
    let (header, start): (VerifierHeader, usize) = unpack(bytes, MAGIC, "verifier", path)?;
    if header.format != 1 {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: format!("unknown format {}", header.format),
        });
    }
    check_range(path, "net.width", header.net.width, &WIDTHS)?;
    check_range(path, "net.patch", header.net.patch, &PATCHES)?;
    if header.net.patch % 8 != 0 {
        return Err(ModelError::bad_field(
            path,
            "net.patch",
            header.net.patch,
            "a multiple of 8",
        ));
    }
    check_range(path, "steps", header.steps, &(0..=MAX_STEPS))?;
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    let net = header.net.init(device);
    let network = || format!("width {}", header.net.width);
    check_weight_size(&net, network, weights, path)?;
    let net = load_weights(net, weights, path)?;
    Ok((net, header))
}

/// Loads verifier model file `path` (a regular file of bounded size).
pub fn load(path: &Path, device: &Device) -> Result<(VerifierNet, VerifierHeader), ModelError> {
    let bytes = read_model_file(path)?;
    from_bytes(&bytes, &path.display().to_string(), device)
}
