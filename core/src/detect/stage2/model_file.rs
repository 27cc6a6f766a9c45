//! The trained stage-2 model file: a magic line, a JSON header naming the family the weights were
//! trained for (name + a hash of its geometry and categories) with a checksum of the weights, then
//! the weights in burn's burnpack format. Loading checks all three, so weights trained for another
//! family, or damaged bytes, fail with a message rather than detecting garbage.

use super::net::{NetConfig, Stage2Net};
pub(crate) use crate::detect::model_file::{
    check_range, check_weight_size, checked_weights, load_weights, pack, unpack, weight_bytes,
};
pub use crate::detect::model_file::{
    fnv1a, read_model_file, weights_are_finite, ModelError, MAX_STEPS, WIDTHS,
};
use crate::family::Family;
use burn::tensor::Device;
use serde::{Deserialize, Serialize};
use std::ops::RangeInclusive;
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-STAGE2\n";

/// Patch sides a stage-2 model may hold: a power of two from 8 (the anchor grid, a quarter of the
/// patch, must reach the template head's 2 × 2) to 512 (the largest
/// [`PatchSpec::for_family`](super::anchors::PatchSpec::for_family) picks).
pub const PATCHES: RangeInclusive<usize> = 8..=512;

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

/// Checks the fields of a stage-2 header that the network is built from (`net.width`,
/// `net.patch`, `net.classes`) and `steps`, before any tensor exists: a width of 0 panics inside
/// burn, a huge one would allocate without bound.
fn check_header(header: &ModelHeader, path: &str) -> Result<(), ModelError> {
    check_range(path, "net.width", header.net.width, &WIDTHS)?;
    let patch = header.net.patch;
    check_range(path, "net.patch", patch, &PATCHES)?;
    if !patch.is_power_of_two() {
        return Err(ModelError::bad_field(
            path,
            "net.patch",
            patch,
            "a power of two (8, 16, … 512)",
        ));
    }
    // One class per category and the background; a family has 1 to 64 categories (the family
    // format's `MAX_CATEGORIES`). `from_bytes` then wants the family's own count.
    check_range(path, "net.classes", header.net.classes, &(2..=65))?;
    check_range(path, "steps", header.steps, &(0..=MAX_STEPS))
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

/// Reads the header without the weights; its fields are checked against what a network can be
/// (`ModelError::BadField` names the one that is not).
pub fn read_header(bytes: &[u8], path: &str) -> Result<(ModelHeader, usize), ModelError> {
    let (header, start): (ModelHeader, usize) = unpack(bytes, MAGIC, "stage-2", path)?;
    if header.format != 1 {
        return Err(ModelError::Corrupt {
            path: path.into(),
            reason: format!("unknown format {}", header.format),
        });
    }
    check_header(&header, path)?;
    Ok((header, start))
}

/// Loads a model for `family` onto `device`, checking that it was trained for that family's
/// layout (under whatever name) and that its bytes are intact.
pub fn from_bytes(
    bytes: &[u8],
    path: &str,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    load_checked(bytes, path, family, device)
}

/// The weights of a model to fine-tune for `family`, which may have another layout than the one
/// they learned (a user's 7 × 7 grid from the 8 × 8 grid model) and other categories (a
/// quaternary design from it): the patch side must fit; where the classes differ, the class head
/// starts fresh ([`Stage2Net::with_class_head`]) and the header says the family's classes.
/// Reading with them takes training.
pub fn to_fine_tune(
    bytes: &[u8],
    path: &str,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let (header, start) = read_header(bytes, path)?;
    check_patch(&header.net, path, family)?;
    let (net, mut header) = load_weights_as_stored(header, start, bytes, path, device)?;
    let classes = family.categories().len() + 1;
    if header.net.classes == classes {
        return Ok((net, header));
    }
    header.net.classes = classes;
    Ok((net.with_class_head(&header.net, device), header))
}

/// Whether a network of `net`'s shape fits `family`: its classes (the family's categories and
/// the background) and its patch side, whatever layout it learned.
pub fn check_network(net: &NetConfig, path: &str, family: &Family) -> Result<(), ModelError> {
    let classes = family.categories().len() + 1;
    if net.classes != classes {
        return Err(ModelError::bad_field(
            path,
            "net.classes",
            net.classes,
            format!(
                "{classes} (the family's {} categories and the background)",
                classes - 1
            ),
        ));
    }
    check_patch(net, path, family)
}

/// Whether a network of `net`'s patch side fits `family`'s: what a fine-tune needs.
pub fn check_patch(net: &NetConfig, path: &str, family: &Family) -> Result<(), ModelError> {
    let patch = super::anchors::PatchSpec::for_family(family).size as usize;
    if net.patch != patch {
        return Err(ModelError::bad_field(
            path,
            "net.patch",
            net.patch,
            format!("{patch} (the patch side of family {:?})", family.name()),
        ));
    }
    Ok(())
}

fn load_checked(
    bytes: &[u8],
    path: &str,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let (header, start) = read_header(bytes, path)?;
    // The weights fit any family with the layout they learned, whatever its name: the codebook
    // only decodes what they read.
    if header.family_hash != family_hash(family) {
        if header.family != family.name() {
            return Err(ModelError::WrongFamily {
                path: path.into(),
                model: header.family,
                family: family.name().into(),
            });
        }
        return Err(ModelError::FamilyChanged {
            path: path.into(),
            family: family.name().into(),
        });
    }
    check_network(&header.net, path, family)?;
    load_weights_as_stored(header, start, bytes, path, device)
}

/// The network `header` (read from `bytes`, its weights at `start`) describes, its weights
/// loaded and checked.
fn load_weights_as_stored(
    header: ModelHeader,
    start: usize,
    bytes: &[u8],
    path: &str,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let weights = checked_weights(bytes, start, &header.weights_fnv, path)?;
    let net = header.net.init(device);
    let network = || {
        format!(
            "width {}, patch {}, {} classes",
            header.net.width, header.net.patch, header.net.classes
        )
    };
    check_weight_size(&net, network, weights, path)?;
    let net = load_weights(net, weights, path)?;
    Ok((net, header))
}

pub fn load(
    path: &Path,
    family: &Family,
    device: &Device,
) -> Result<(Stage2Net, ModelHeader), ModelError> {
    let bytes = read_model_file(path)?;
    from_bytes(&bytes, &path.display().to_string(), family, device)
}

/// `bytes` of a model file with its JSON header changed by `edit`, the weights and their checksum
/// untouched: what a hand-edited (or hostile) header looks like.
#[cfg(test)]
pub(crate) fn edited_header(
    bytes: &[u8],
    magic: &[u8],
    edit: impl FnOnce(&mut serde_json::Value),
) -> Vec<u8> {
    let rest = &bytes[magic.len()..];
    let len = u32::from_le_bytes(rest[..4].try_into().unwrap()) as usize;
    let mut header: serde_json::Value = serde_json::from_slice(&rest[4..4 + len]).unwrap();
    edit(&mut header);
    let json = serde_json::to_vec(&header).unwrap();
    let mut out = magic.to_vec();
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(&json);
    out.extend_from_slice(&rest[4 + len..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::stage2::anchors::PatchSpec;

    fn family() -> Family {
        crate::builtin::get("apriltag-16h5").unwrap().unwrap()
    }

    fn config(family: &Family, width: usize) -> NetConfig {
        NetConfig {
            classes: family.categories().len() + 1,
            width,
            patch: PatchSpec::for_family(family).size as usize,
        }
    }

    /// A valid model file of the smallest network for apriltag-16h5.
    fn model(width: usize) -> Vec<u8> {
        let family = family();
        let config = config(&family, width);
        to_bytes(config.init(&Device::flex()), &config, &family, 1).unwrap()
    }

    fn load(bytes: &[u8]) -> Result<(Stage2Net, ModelHeader), ModelError> {
        from_bytes(bytes, "m.bin", &family(), &Device::flex())
    }

    fn set(bytes: &[u8], field: &str, value: serde_json::Value) -> Vec<u8> {
        edited_header(bytes, MAGIC, |h| {
            let mut at = h;
            let mut names = field.split('.').peekable();
            while let Some(name) = names.next() {
                if names.peek().is_none() {
                    at[name] = value.clone();
                    return;
                }
                at = &mut at[name];
            }
        })
    }

    #[test]
    fn a_valid_model_loads_and_every_bad_header_field_is_named() {
        let good = model(8);
        load(&good).unwrap();
        let patch = PatchSpec::for_family(&family()).size as u64;
        let cases: &[(&str, serde_json::Value, &str)] = &[
            ("net.width", 0.into(), "is 0; expected 8 to 256"),
            ("net.width", 7.into(), "is 7; expected 8 to 256"),
            ("net.width", 1_000_000_000u64.into(), "expected 8 to 256"),
            ("net.patch", 0.into(), "is 0; expected 8 to 512"),
            ("net.patch", 100.into(), "a power of two"),
            ("net.patch", 4096.into(), "expected 8 to 512"),
            ("net.patch", (patch * 2).into(), "the patch side of family"),
            ("net.classes", 0.into(), "expected 2 to 65"),
            ("net.classes", 1_000_000.into(), "expected 2 to 65"),
            ("net.classes", 9.into(), "the family's 2 categories"),
            ("steps", u64::MAX.into(), "expected 0 to 10000000"),
        ];
        for (field, value, says) in cases {
            let bytes = set(&good, field, value.clone());
            let err = load(&bytes).map(drop).unwrap_err().to_string();
            let name = format!("m.bin: header field \"{field}\" is");
            assert!(err.starts_with(&name), "{field} = {value}: {err}");
            assert!(err.contains(says), "{field} = {value}: {err}");
        }
        // Values JSON cannot give a usize are the header's JSON being wrong.
        for (field, value) in [("net.width", (-1).into()), ("net.patch", "128".into())] {
            let err = load(&set(&good, field, value)).map(drop).unwrap_err();
            assert!(matches!(err, ModelError::Corrupt { .. }), "{err}");
            assert!(err.to_string().contains("width") || err.to_string().contains("patch"));
        }
    }

    #[test]
    fn weights_of_another_width_are_refused_by_their_size_not_a_panic() {
        let narrow = model(8);
        for width in [16, 256] {
            let err = load(&set(&narrow, "net.width", width.into()))
                .map(drop)
                .unwrap_err();
            assert!(matches!(err, ModelError::WeightSize { .. }), "{err}");
            let text = err.to_string();
            assert!(
                text.starts_with("m.bin: the weights are")
                    && text.contains(&format!("width {width}")),
                "{text}"
            );
        }
        // Wider weights under a narrower header.
        let wide = model(16);
        let err = load(&set(&wide, "net.width", 8.into()))
            .map(drop)
            .unwrap_err();
        assert!(matches!(err, ModelError::WeightSize { .. }), "{err}");
        // The shipped models are within the bounds.
        for name in super::super::shipped_families() {
            let family = crate::builtin::get(name).unwrap().unwrap();
            let bytes = super::super::shipped_model(name).unwrap();
            from_bytes(bytes, name, &family, &Device::flex()).unwrap();
        }
    }

    #[test]
    fn damaged_weights_with_a_matching_checksum_are_an_error_not_a_panic() {
        let good = model(8);
        let (header, start) = read_header(&good, "m.bin").unwrap();
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for _ in 0..64 {
            let mut weights = good[start..].to_vec();
            // A few bytes anywhere, mostly in the burnpack's header and metadata.
            for _ in 0..1 + next() % 4 {
                let at = if next() % 2 == 0 {
                    next() as usize % weights.len().min(2048)
                } else {
                    next() as usize % weights.len()
                };
                weights[at] = next() as u8;
            }
            let header = ModelHeader {
                weights_fnv: format!("{:016x}", fnv1a(&weights)),
                ..header.clone()
            };
            let bytes = pack(MAGIC, &header, &weights);
            let loaded = std::panic::catch_unwind(|| load(&bytes).map(drop));
            assert!(loaded.is_ok(), "a damaged burnpack panicked");
        }
    }

    #[test]
    fn a_model_file_that_is_not_a_regular_file_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let err = super::load(dir.path(), &family(), &Device::flex())
            .map(drop)
            .unwrap_err()
            .to_string();
        assert!(err.contains(&dir.path().display().to_string()), "{err}");
        #[cfg(unix)]
        {
            if Path::new("/dev/zero").exists() {
                let err = super::load(Path::new("/dev/zero"), &family(), &Device::flex())
                    .map(drop)
                    .unwrap_err()
                    .to_string();
                assert!(
                    err.starts_with("/dev/zero: ") && err.contains("device"),
                    "{err}"
                );
            }
            let fifo = dir.path().join("m.bin");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let err = super::load(&fifo, &family(), &Device::flex())
                    .map(drop)
                    .unwrap_err()
                    .to_string();
                assert!(err.contains("m.bin") && err.contains("FIFO"), "{err}");
            }
        }
    }
}
