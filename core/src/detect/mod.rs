//! The learned detector: its stages by name and what they hand on. Stage 2 ([`stage2`]) reads a
//! marker from its ROI; [`Detection`] is what any detector reports, and [`BenchDetector`] is the
//! interface the evaluation harness runs.

pub mod annotate;
#[cfg(feature = "detect")]
pub(crate) mod blocks;
pub mod cells;
mod detection;
#[cfg(feature = "detect")]
pub mod detector;
pub mod memory;
#[cfg(feature = "detect")]
pub mod model_file;
#[cfg(feature = "detect")]
pub(crate) mod outline;
#[cfg(feature = "detect")]
pub mod plain_net;
pub mod precheck;
pub mod refine;
mod report;
pub mod rings;
pub mod stage1;
pub mod stage2;
#[cfg(feature = "detect")]
pub mod verifier;

pub use detection::{
    BenchDetector, DetectedKeypoint, Detection, DetectionsFile, ImageDetections, Scores,
};
#[cfg(feature = "detect")]
pub use detector::{Detector, DetectorOptions, Found, Frame, Timings, TrackParams, Tracker};
pub use report::{MarkerReport, PoseReport};
