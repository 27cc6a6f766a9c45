//! The learned detector: its stages by name and what they hand on. Stage 2 ([`stage2`]) reads a
//! marker from its ROI; [`Detection`] is what any detector reports, and [`Detector`] is the
//! interface the evaluation harness runs.

pub mod annotate;
mod detection;
pub mod refine;
mod report;
pub mod stage2;

pub use detection::{DetectedKeypoint, Detection, DetectionsFile, Detector, ImageDetections};
pub use report::{MarkerReport, PoseReport};
