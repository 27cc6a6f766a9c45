//! The trained stage-1 model file: the same container as stage 2's (magic line, JSON header with
//! a checksum of the weights, burnpack weights). Stage 1 belongs to no family — one model finds
//! the markers of every square family — so the header lists the families it was trained on for
//! the record rather than to check them.

use super::net::{NetConfig, Stage1Net};
use crate::detect::stage2::model_file::{
    checked_weights, fnv1a, load_weights, pack, unpack, weight_bytes, ModelError,
};
use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-STAGE1\n";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stage1Header {
    pub format: u32,
    pub net: NetConfig,
    /// Optimiser steps the weights were trained for.
    pub steps: u64,
    /// Families whose markers were in the training scenes (besides random designs).
    pub families: Vec<String>,
    /// FNV-1a 64 of the weight bytes.
    pub weights_fnv: String,
}

pub fn to_bytes(
    net: Stage1Net,
    config: &NetConfig,
    families: &[String],
    steps: u64,
) -> Result<Vec<u8>, String> {
    let weights = weight_bytes(net)?;
    let header = Stage1Header {
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
) -> Result<(Stage1Net, Stage1Header), ModelError> {
    let (header, start): (Stage1Header, usize) = unpack(bytes, MAGIC, "stage-1", path)?;
    let corrupt = |reason: String| ModelError::Corrupt {
        path: path.into(),
        reason,
    };
    if header.format != 1 {
        return Err(corrupt(format!("unknown format {}", header.format)));
    }
    if header.net.width < 8 || header.net.width > 512 || !header.net.width.is_multiple_of(4) {
        return Err(corrupt(format!("network width {}", header.net.width)));
    }
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    let net = load_weights(header.net.init(device), weights, path)?;
    Ok((net, header))
}

pub fn load(path: &Path, device: &Device) -> Result<(Stage1Net, Stage1Header), ModelError> {
    let name = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ModelError::Io {
        path: name.clone(),
        source,
    })?;
    from_bytes(&bytes, &name, device)
}
