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
use std::ops::RangeInclusive;
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-STAGE2\n";

/// The network widths a model file may hold: what `tagsmith train --width` and the studio build.
/// The networks need at least 4 (the stem has `width / 4` channels); the cap keeps a header from
/// asking for a network of unbounded size before its weights are read.
pub const WIDTHS: RangeInclusive<usize> = 8..=256;

/// The most optimiser steps a run makes (`tagsmith train --steps`), and so the most a model's
/// header may record.
pub const MAX_STEPS: u64 = 10_000_000;

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
    let classes = family.categories().len() + 1;
    if header.net.classes != classes {
        return Err(ModelError::bad_field(
            path,
            "net.classes",
            header.net.classes,
            format!(
                "{classes} (the family's {} categories and the background)",
                classes - 1
            ),
        ));
    }
    let patch = super::anchors::PatchSpec::for_family(family).size as usize;
    if header.net.patch != patch {
        return Err(ModelError::bad_field(
            path,
            "net.patch",
            header.net.patch,
            format!("{patch} (the patch side of family {:?})", family.name()),
        ));
    }
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

/// The bytes of model file `path`: a regular file of at most [`crate::io::MAX_MODEL_BYTES`]
/// ([`crate::io::read_input`]); a FIFO, a device or a folder is refused before anything waits on
/// it.
pub fn read_model_file(path: &Path) -> Result<Vec<u8>, ModelError> {
    crate::io::read_input(path, crate::io::MAX_MODEL_BYTES).map_err(|source| ModelError::Io {
        path: path.display().to_string(),
        source,
    })
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
