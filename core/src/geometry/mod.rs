//! Camera geometry: homographies ([`homography`]), warping images by them ([`warp`]) and the
//! pinhole camera with OpenCV's distortion model ([`camera`]).

pub mod camera;
pub mod homography;
pub mod warp;

pub use camera::Camera;
pub use homography::Homography;
pub use warp::{warp_bilinear, GrayImage};

#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("{0} points, at least {1} are needed")]
    TooFewPoints(usize, usize),
    #[error("{0} source points but {1} destination points")]
    Mismatch(usize, usize),
    #[error("a coordinate is not a finite number")]
    NotFinite,
    #[error(
        "the points are degenerate (collinear or coincident): they do not determine the geometry"
    )]
    Degenerate,
    #[error("the camera parameters are not valid: {0}")]
    BadCamera(&'static str),
}
