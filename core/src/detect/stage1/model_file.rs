//! The trained stage-1 model file: the same container as stage 2's (magic line, JSON header with
//! a checksum of the weights, burnpack weights). Stage 1 belongs to no family — one model finds
//! the markers of every square family — so the header lists the families it was trained on for
//! the record rather than to check them.

use super::net::{NetConfig, Stage1Net};
use crate::detect::model_file::{
    check_range, check_weight_size, checked_weights, fnv1a, load_weights, pack, read_model_file,
    unpack, weight_bytes, ModelError, MAX_STEPS, WIDTHS,
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
    // The fields the network is built from, before any tensor exists (a width of 0 panics inside
    // burn, a huge one would allocate without bound).
    check_range(path, "net.width", header.net.width, &WIDTHS)?;
    check_range(path, "steps", header.steps, &(0..=MAX_STEPS))?;
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    let net = header.net.init(device);
    let network = || format!("width {}", header.net.width);
    check_weight_size(&net, network, weights, path)?;
    let net = load_weights(net, weights, path)?;
    Ok((net, header))
}

/// Loads stage-1 model file `path`: a regular file of at most [`crate::io::MAX_MODEL_BYTES`]
/// (a FIFO, a device or a folder is refused before anything waits on it).
pub fn load(path: &Path, device: &Device) -> Result<(Stage1Net, Stage1Header), ModelError> {
    let bytes = read_model_file(path)?;
    from_bytes(&bytes, &path.display().to_string(), device)
}
