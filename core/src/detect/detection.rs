//! What a detector reports, and the interface through which the evaluation harness runs one.
//! The detections file (`eval`'s documented JSON format) is [`DetectionsFile`].

use crate::geometry::Quad;
use crate::image::GrayImage;
use crate::pose::PoseJson;
use serde::{Deserialize, Serialize};

/// One detected marker. `id`, `corners` (the family's ROI points 0–3, canonical order) and
/// `pose` are what every detector reports and the harness scores; the learned detector adds
/// the family, the keypoints and its scores.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub id: usize,
    pub corners: Quad,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseJson>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub family: Option<String>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub keypoints: Vec<DetectedKeypoint>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scores: Option<Scores>,
}

impl Detection {
    /// A detection with only what every detector reports.
    pub fn plain(id: usize, corners: Quad, pose: Option<PoseJson>) -> Self {
        Self {
            id,
            corners,
            pose,
            family: None,
            keypoints: Vec::new(),
            scores: None,
        }
    }
}

/// How sure the learned detector is of a marker.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// Stage 1's ROI score (mean corner confidence × mask cover), 0–1.
    pub roi: f64,
    /// Mean confidence of the keypoints stage 2 matched to the template, 0–1.
    pub keypoints: f64,
    /// Symbols the codebook corrected.
    pub corrected_errors: usize,
    /// Reprojection error of the pose, pixels (absent without a pose).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reprojection_rms_px: Option<f64>,
    /// The code was read from the cells straight off the image, not by stage 2's network (a
    /// sliver the network could not read; the keypoints' confidences are then how far each
    /// cell's gray level lies from the other category's).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cell_read: bool,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImageDetections {
    pub file: String,
    #[serde(default)]
    pub time_ms: f64,
    pub detections: Vec<Detection>,
    /// Where the time went, as the detector that wrote the file reports it (Tagsmith's: each
    /// phase and each proposal source, with ROIs, stage-2 reads and passes).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub timings: Option<serde_json::Value>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionsFile {
    pub detector: String,
    pub images: Vec<ImageDetections>,
}

/// What the learned detector (and any in-process baseline) implements to be benchmarked.
pub trait BenchDetector {
    fn name(&self) -> String;
    fn detect(&mut self, image: &GrayImage) -> Vec<Detection>;
    /// [`BenchDetector::detect`], and where the time went for a detector that times its own
    /// steps (what `tagsmith detect --json` writes as an image's `timings`).
    fn detect_timed(&mut self, image: &GrayImage) -> (Vec<Detection>, Option<serde_json::Value>) {
        (self.detect(image), None)
    }
    /// The harness shows each image's ground truth before [`BenchDetector::detect`], untimed. Real
    /// detectors ignore it; a stage measured on its own (stage 2 from perturbed true ROIs, in
    /// place of stage 1) takes its input from it.
    fn observe_truth(&mut self, _truth: &crate::synth::Truth) {}
}

/// One keypoint of a detected marker, in the family's canonical order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectedKeypoint {
    /// Index in the family's keypoint list.
    pub index: usize,
    /// Image pixels.
    pub x: f64,
    pub y: f64,
    pub category: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub symbol: Option<u8>,
    pub confidence: f64,
}
