//! Tagsmith: design fiducial-marker families and render, print and decode them.
//!
//! The pipeline, one module per stage: [`family`] (the data model, JSON I/O and validation) →
//! [`codebook`] (code tables, decoding, generation) → [`render`] (vector scenes, SVG, rasters,
//! sheets, PDF) → [`geometry`] (homographies, warping, cameras) → [`pose`] (planar PnP).
//! [`builtin`] holds the families shipped in `families/`.

pub mod builtin;
pub mod codebook;
pub mod color;
pub mod detect;
pub mod eval;
pub mod family;
pub mod geometry;
pub mod io;
pub mod pose;
pub mod render;
pub mod synth;
#[cfg(feature = "learn")]
pub mod train;

pub use family::{Family, FamilyError};
