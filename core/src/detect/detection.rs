//! What a detector reports, and the interface through which the evaluation harness runs one.
//! The detections file (`eval`'s documented JSON format) is [`DetectionsFile`].

use crate::image::GrayImage;
use crate::pose::PoseJson;
use serde::{Deserialize, Serialize};

/// One detected marker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub id: usize,
    pub corners: [[f64; 2]; 4],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseJson>,
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
    /// The harness shows each image's ground truth before [`Detector::detect`], untimed. Real
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
