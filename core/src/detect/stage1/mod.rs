//! Stage 1 of the learned detector: a whole image → marker ROIs (docs/ARCHITECTURE.md §9.8).
//! One model serves every square family: it finds marker corners, their directions to the
//! marker centre and the marker mask; [`group`] turns them into ROIs, and stage 2 reads each.
//!
//! [`targets`] (training targets) and [`group`] (corners → ROIs) are plain Rust; the network
//! ([`net`]), its model file and the pipeline on an image need the `detect` feature (burn).

/// Input pixels per cell of the network's output grid.
pub const STRIDE: usize = 4;

pub mod edges;
pub mod group;
pub mod outline;
pub mod stretched;
pub mod targets;
pub mod traced;

#[cfg(feature = "detect")]
pub mod bands;
#[cfg(feature = "detect")]
pub mod model_file;
#[cfg(feature = "detect")]
pub mod net;
#[cfg(feature = "detect")]
pub mod pipeline;

#[cfg(feature = "detect")]
pub use pipeline::{ProposeOptions, Stage1};
