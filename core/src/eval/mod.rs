//! The evaluation harness (DESIGN §7): a benchmark set rendered once to disk ([`set`]), detectors
//! run on it through one interface or read from a JSON file of detections, and scoring the way
//! the DeepTag paper does ([`score`]).
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

mod plot;
pub mod score;
pub mod set;

use crate::geometry::GrayImage;
use serde::{Deserialize, Serialize};

/// One detected marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub id: usize,
    pub corners: [[f64; 2]; 4],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseJson>,
}

/// A pose as written in JSON: row-major rotation (marker → camera) and translation in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseJson {
    pub rotation: [[f64; 3]; 3],
    pub translation_m: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageDetections {
    pub file: String,
    #[serde(default)]
    pub time_ms: f64,
    pub detections: Vec<Detection>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionsFile {
    pub detector: String,
    pub images: Vec<ImageDetections>,
}

/// What the learned detector (and any in-process baseline) implements to be benchmarked.
pub trait Detector {
    fn name(&self) -> String;
    fn detect(&mut self, image: &GrayImage) -> Vec<Detection>;
}
