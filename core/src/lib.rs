//! Tagsmith: design fiducial-marker families, render and print them, synthesise training images,
//! and detect them with a learned two-stage detector.
//!
//! Modules are layers, read as the pipeline; each uses only those listed before it (checked by
//! `tests/layers.rs`; the map is in `docs/ARCHITECTURE.md`).

// Foundation.
/// The data files read at run time (font, backgrounds): embedded, or fetched by the web page.
pub mod assets;
/// `#rrggbb` colours.
pub mod color;
/// Homographies, warping, the pinhole camera, rigid poses.
pub mod geometry;
/// The gray image type; reading images of any common format with limits; PNG output.
pub mod image;
/// Atomic file writes.
pub mod io;
/// A problem in an input file, located by its JSON path.
pub mod problem;

// The pipeline.
/// The families shipped in `families/`.
pub mod builtin;
/// Code tables: distances over rotations, nearest-code decoding, generation.
pub mod codebook;
/// The learned detector by stage, and what a detection reports.
pub mod detect;
/// Benchmark sets, running detectors on them, scoring.
pub mod eval;
/// The family model: file format, validation, patterns, keypoints, rotations, decoding a marker.
pub mod family;
/// 6-DoF pose of a planar marker from all its keypoints.
pub mod pose;
/// Vector scenes, SVG, rasters, printable sheets and PDF, read-back checks, OpenCV export.
pub mod render;
/// Training and test images with exact ground truth.
pub mod synth;
/// Training the detector's networks (feature `learn`).
#[cfg(feature = "learn")]
pub mod train;

pub use family::{Family, FamilyError};
