//! The verifier's model file: the container both stages' files use (magic line, JSON header
//! with a checksum of the weights, burnpack weights).

use super::net::{NetConfig, VerifierNet};
use crate::detect::model_file::{
    check_range, check_weight_size, family_free_bytes, family_free_parts, load_weights,
    read_model_file, FamilyFreeHeader, ModelError, WIDTHS,
};
use burn::tensor::Device;
use std::ops::RangeInclusive;
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-VERIFIER\n";

/// The patch sides a verifier may read (multiples of 8).
pub const PATCHES: RangeInclusive<usize> = 16..=128;

pub type VerifierHeader = FamilyFreeHeader<NetConfig>;

pub fn to_bytes(
    net: VerifierNet,
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
) -> Result<(VerifierNet, VerifierHeader), ModelError> {
    let (header, weights) =
        family_free_parts(bytes, MAGIC, "verifier", path, |net: &NetConfig| {
            check_range(path, "net.width", net.width, &WIDTHS)?;
            check_range(path, "net.patch", net.patch, &PATCHES)?;
            if !net.patch.is_multiple_of(8) {
                return Err(ModelError::bad_field(
                    path,
                    "net.patch",
                    net.patch,
                    "a multiple of 8",
                ));
            }
            Ok(())
        })?;
    let net = header.net.init(device);
    let network = || format!("width {}, patch {}", header.net.width, header.net.patch);
    check_weight_size(&net, network, weights, path)?;
    let net = load_weights(net, weights, path)?;
    Ok((net, header))
}

/// Loads verifier model file `path` (a regular file of bounded size).
pub fn load(path: &Path, device: &Device) -> Result<(VerifierNet, VerifierHeader), ModelError> {
    let bytes = read_model_file(path)?;
    from_bytes(&bytes, &path.display().to_string(), device)
}
