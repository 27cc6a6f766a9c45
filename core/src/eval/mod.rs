//! The evaluation harness (docs/ARCHITECTURE.md §11): a benchmark set rendered once to disk
//! ([`set`]), detectors run on it through one interface or read from a JSON file of detections, and
//! scoring the way the DeepTag paper does ([`score`]).
//!
//! **Detections file** (what external detectors write; corners in Tagsmith's convention: the
//! family's ROI points in order — TL, TR, BR, BL of the outer black square as OpenCV renders the
//! marker — with pixel centres at integer coordinates):
//! ```json
//! {"detector": "opencv-aruco",
//!  "images": [{"file": "images/000012.png", "time_ms": 4.1,
//!              "detections": [{"id": 7, "corners": [[x, y], [x, y], [x, y], [x, y]],
//!                              "pose": {"rotation": [[…], […], […]], "translation_m": [x, y, z]}}]}]}
//! ```
//! `pose` is optional: without it the scorer solves it from the four corners with the set's camera.
//! `tagsmith detect --json` may add `"failed": [{"file", "error", "exit_code"}]` for images it
//! could not detect; the scorer ignores it.

pub mod compare;
pub mod designs;
pub mod plot;
pub mod scenario;
pub mod score;
pub mod set;
#[cfg(feature = "detect")]
pub mod stage2_from_truth;

use std::path::PathBuf;

/// A benchmark set that cannot be written, read or scored; each names the file or value that
/// failed. The messages carry their cause, so callers print them as they are.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error("marker side {side_m} m must be in (0, 1]")]
    BadSide { side_m: f64 },
    #[error("{path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Json {
        path: PathBuf,
        source: serde_json::Error,
    },
    #[error("{path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Encode {
        path: PathBuf,
        source: ::image::ImageError,
    },
    #[error(transparent)]
    Synth(#[from] crate::synth::SynthError),
    #[error("detections for {file:?}, which is not an image of this set")]
    UnknownImage { file: String },
    #[error("a set of {images} images is more than {max}; lower the images per cell")]
    TooLarge { images: u64, max: u64 },
    /// A set manifest that loads as JSON but cannot be scored: `field` is its JSON path.
    #[error("{path}: {field}: {message}")]
    BadSet {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// A scenario file that does not load or holds a value out of range: `field` is its JSON path.
    #[error("{path}: {field}: {message}")]
    BadScenario {
        path: PathBuf,
        field: String,
        message: String,
    },
    /// A detections file that cannot be scored; the caller puts the file's name in front.
    #[error("{field}: {message}")]
    BadDetections { field: String, message: String },
}
