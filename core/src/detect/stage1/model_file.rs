//! The trained stage-1 model file: the same container as stage 2's (magic line, JSON header with
//! a checksum of the weights, burnpack weights). Stage 1 belongs to no family — one model finds
//! the markers of every square family — so the header lists the families it was trained on for
//! the record rather than to check them.

use super::net::{NetConfig, Stage1Net};
use crate::detect::model_file::{
    check_range, check_weight_size, family_free_bytes, family_free_parts, load_weights,
    read_model_file, FamilyFreeHeader, ModelError, WIDTHS,
};
use burn::tensor::Device;
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-STAGE1\n";

pub type Stage1Header = FamilyFreeHeader<NetConfig>;

pub fn to_bytes(
    net: Stage1Net,
    config: &NetConfig,
    families: &[String],
    steps: u64,
) -> Result<Vec<u8>, String> {
    family_free_bytes(MAGIC, net, config, families, steps)
}

pub fn from_bytes(
    bytes: &[u8],
    path: &str,
    device: &Device,
) -> Result<(Stage1Net, Stage1Header), ModelError> {
    // The fields the network is built from, before any tensor exists (a width of 0 panics inside
    // burn, a huge one would allocate without bound).
    let (header, weights) = family_free_parts(bytes, MAGIC, "stage-1", path, |net: &NetConfig| {
        check_range(path, "net.width", net.width, &WIDTHS)
    })?;
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
