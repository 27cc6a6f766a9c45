//! Camera geometry: homographies ([`homography`]), warping images by them ([`warp`]), the
//! pinhole camera with OpenCV's distortion model ([`camera`]) and rigid poses ([`pose`]).

pub mod camera;
pub mod homography;
pub mod pose;
pub mod warp;

pub use camera::{CalibrationError, Camera};
pub use homography::Homography;
pub use pose::{Pose, PoseJson};
pub use warp::warp_bilinear;

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

/// Even-odd point-in-polygon test.
pub fn inside_polygon(polygon: &[[f64; 2]], p: [f64; 2]) -> bool {
    let mut inside = false;
    let n = polygon.len();
    for i in 0..n {
        let (a, b) = (polygon[i], polygon[(i + n - 1) % n]);
        if (a[1] > p[1]) != (b[1] > p[1])
            && p[0] < (b[0] - a[0]) * (p[1] - a[1]) / (b[1] - a[1]) + a[0]
        {
            inside = !inside;
        }
    }
    inside
}

/// The signed area of a simple polygon: positive when it runs clockwise in the image (y down).
pub fn polygon_area(polygon: &[[f64; 2]]) -> f64 {
    let n = polygon.len();
    (0..n)
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        / 2.0
}

/// The distance between two points.
pub fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// The squared distance between two points: for comparisons in hot loops, where `hypot` (a
/// library call) would cost more than the rest.
pub fn squared_distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
}

/// How far the farthest-moved corner of quad `a` lies from the same corner of `b`, in pixels.
pub fn largest_corner_move(a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .map(|i| (a[i][0] - b[i][0]).hypot(a[i][1] - b[i][1]))
        .fold(0.0, f64::max)
}

/// Axis-aligned bounds of points: [min x, min y, max x, max y].
pub fn bounding_box(points: &[[f64; 2]]) -> [f64; 4] {
    points
        .iter()
        .fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        })
}

/// Checks two lists of corresponding points: equal lengths, at least `min`, all finite.
pub fn check_correspondences(
    a: &[[f64; 2]],
    b: &[[f64; 2]],
    min: usize,
) -> Result<(), GeometryError> {
    if a.len() != b.len() {
        return Err(GeometryError::Mismatch(a.len(), b.len()));
    }
    if a.len() < min {
        return Err(GeometryError::TooFewPoints(a.len(), min));
    }
    if a.iter().chain(b).flatten().any(|v| !v.is_finite()) {
        return Err(GeometryError::NotFinite);
    }
    Ok(())
}
