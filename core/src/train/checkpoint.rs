//! One checkpoint file, rewritten atomically (temporary file, fsync, rename): a magic line, the
//! run's state as JSON, the model in its stage's model-file format (so it carries the family
//! check), the optimiser state (Adam moments) in burnpack, and a checksum of all of it. A kill at
//! any moment leaves the previous checkpoint or the new one, never a mix; an edited or damaged
//! file (a changed step, trailing bytes) fails the checksum.
//!
//! JSON has no NaN or infinity, and a validation that found nothing has NaN errors: the stages'
//! metrics write such floats as strings (`crate::io::json_float`), so a checkpoint gives back
//! exactly the values it was given.

use super::TrainConfig;
use crate::detect::stage2::model_file::fnv1a;
use burn::tensor::Bytes;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::path::Path;

const MAGIC: &[u8] = b"TAGSMITH-CHECKPOINT\n";

/// The most a checkpoint file may hold: a model, the optimiser's two moments of each weight (as
/// large again, twice) and the run's state as JSON.
pub const MAX_CHECKPOINT_BYTES: u64 = 3 * crate::io::MAX_MODEL_BYTES + crate::io::MAX_TEXT_BYTES;

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Meta<M> {
    /// Steps done; the data stream resumes at sample `step × batch`.
    pub step: u64,
    pub validation: Vec<(u64, M)>,
    pub wall_s: f64,
    pub config: TrainConfig,
}

pub struct State<M> {
    pub model: Vec<u8>,
    pub optimiser: Bytes,
    pub meta: Meta<M>,
}

fn section(out: &mut Vec<u8>, bytes: &[u8]) {
    out.extend_from_slice(&(bytes.len() as u64).to_le_bytes());
    out.extend_from_slice(bytes);
}

pub fn save<M: Serialize>(
    path: &Path,
    model: &[u8],
    optimiser: &[u8],
    meta: &Meta<M>,
) -> Result<(), String> {
    let json = serde_json::to_vec(meta).map_err(|e| e.to_string())?;
    let mut out = MAGIC.to_vec();
    section(&mut out, &json);
    section(&mut out, model);
    section(&mut out, optimiser);
    let sum = fnv1a(&out);
    out.extend_from_slice(&sum.to_le_bytes());
    crate::io::write_atomic(path, &out).map_err(|e| format!("{}: {e}", path.display()))
}

pub fn load<M: DeserializeOwned>(path: &Path) -> Result<State<M>, String> {
    let name = path.display().to_string();
    // A regular file of bounded size: a FIFO or a device in the folder must not hang the run.
    let bytes = crate::io::read_input(path, MAX_CHECKPOINT_BYTES)
        .map_err(|e| format!("{name}: cannot read the checkpoint: {e}"))?;
    let corrupt = || format!("{name}: not a Tagsmith checkpoint, or a damaged one");
    let (body, sum) = bytes
        .split_at_checked(bytes.len().saturating_sub(8))
        .ok_or_else(corrupt)?;
    if sum.len() != 8 || fnv1a(body).to_le_bytes() != sum {
        return Err(format!(
            "{name}: the checkpoint is damaged or was edited (its checksum does not match)"
        ));
    }
    let mut rest = body.strip_prefix(MAGIC).ok_or_else(corrupt)?;
    let mut next = || -> Result<&[u8], String> {
        let len = rest
            .get(..8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")) as usize)
            .ok_or_else(corrupt)?;
        let end = len.checked_add(8).ok_or_else(corrupt)?;
        let body = rest.get(8..end).ok_or_else(corrupt)?;
        rest = &rest[end..];
        Ok(body)
    };
    let meta: Meta<M> = serde_json::from_slice(next()?).map_err(|e| format!("{name}: {e}"))?;
    let model = next()?.to_vec();
    let optimiser = Bytes::from_bytes_vec(next()?.to_vec());
    if !rest.is_empty() {
        return Err(corrupt());
    }
    Ok(State {
        model,
        optimiser,
        meta,
    })
}
