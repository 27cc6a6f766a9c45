//! Rendering: one vector scene per marker ([`scene`]) drawn as SVG ([`svg`]), rasters ([`raster`]),
//! printable sheets ([`sheet`]) and PDF ([`pdf`]); [`readback`] reads a raster back to categories.

pub mod opencv;
pub mod pdf;
pub mod raster;
pub mod readback;
pub mod scene;
pub mod sheet;
pub mod svg;
pub mod template;

pub use scene::{marker_scene, MarkerScene, RenderError, SceneOptions};
