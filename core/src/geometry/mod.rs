//! Camera geometry: homographies ([`homography`]), warping images by them ([`warp`]), the
//! pinhole camera with OpenCV's distortion model ([`camera`]) and rigid poses ([`pose`]).

pub mod camera;
pub mod homography;
pub mod pose;
pub mod quad;
pub mod warp;

pub use camera::{CalibrationError, Camera};
pub use homography::Homography;
pub use pose::{Pose, PoseJson};
pub use quad::Quad;
pub use warp::warp_bilinear;

/// The largest coordinate geometry accepts, in any unit (pixels, metres, marker cells): far
/// beyond any image, and small enough that products and sums of a few coordinates stay exact
/// enough to solve with.
pub const MAX_COORDINATE: f64 = 1e7;

/// The smallest area a quad may enclose to be a marker's outline ([`Quad::check`]), in px².
pub const MIN_QUAD_AREA: f64 = 1.0;

/// The most iterations an SVD (or the symmetric eigensolver behind a 3×3 one) may take. A
/// well-posed 18×9 DLT system converges in a few dozen implicit-shift steps; without a cap,
/// nalgebra's solvers loop until convergence, which a matrix of NaN or of subnormal numbers never
/// reaches. Running out is reported as [`GeometryError::NoConvergence`].
pub const SVD_MAX_ITERATIONS: usize = 1000;

/// The tolerance below which the SVD takes a value as converged to zero (nalgebra's default).
pub(crate) const SVD_EPS: f64 = 5.0 * f64::EPSILON;

#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum GeometryError {
    #[error("{0} points, at least {1} are needed")]
    TooFewPoints(usize, usize),
    #[error("{0} source points but {1} destination points")]
    Mismatch(usize, usize),
    #[error("a coordinate is not a finite number")]
    NotFinite,
    /// A coordinate so close to zero that it is a subnormal number (0 < |v| < `f64::MIN_POSITIVE`):
    /// scaling by its reciprocal overflows.
    #[error("a coordinate ({0:e}) is too close to zero to compute with (a subnormal number)")]
    Subnormal(f64),
    /// A coordinate beyond ±[`MAX_COORDINATE`].
    #[error("a coordinate ({0:e}) is beyond ±{max:e}", max = MAX_COORDINATE)]
    TooLarge(f64),
    #[error(
        "the points are degenerate (collinear or coincident): they do not determine the geometry"
    )]
    Degenerate,
    /// Two corners of a quad at the same place (corners numbered from 1, in the quad's order).
    #[error("the quad's corners {0} and {1} coincide")]
    CoincidentCorners(usize, usize),
    /// Three corners of a quad on one line (numbered from 1).
    #[error("the quad's corners {0}, {1} and {2} are collinear")]
    CollinearCorners(usize, usize, usize),
    /// Two opposite edges of a quad cross: corners out of order.
    #[error("the quad crosses itself (bow-tie): its corners are not in order around it")]
    SelfIntersecting,
    /// A quad enclosing less than [`MIN_QUAD_AREA`].
    #[error("the quad's area ({0:.3e} px²) is under {min} px²", min = MIN_QUAD_AREA)]
    TooSmall(f64),
    /// An iterative solver ran out of iterations (a matrix it cannot decompose).
    #[error("the {0} did not converge within {1} iterations")]
    NoConvergence(&'static str, usize),
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

/// The length of a vector. A square root of the sum of squares, not `f64::hypot`: hypot
/// guards against overflow and underflow that coordinates within ±[`MAX_COORDINATE`] never
/// reach, and as a library call it cost the detector several per cent of a photograph's time
/// in the pairwise loops over corners and quads.
pub fn length(v: [f64; 2]) -> f64 {
    (v[0] * v[0] + v[1] * v[1]).sqrt()
}

/// The distance between two points.
pub fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    length([a[0] - b[0], a[1] - b[1]])
}

/// The squared distance between two points: for comparisons in hot loops, where `hypot` (a
/// library call) would cost more than the rest.
pub fn squared_distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)
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

/// Checks one coordinate: finite, not subnormal, within ±[`MAX_COORDINATE`].
pub fn check_coordinate(v: f64) -> Result<(), GeometryError> {
    if !v.is_finite() {
        Err(GeometryError::NotFinite)
    } else if v != 0.0 && v.abs() < f64::MIN_POSITIVE {
        Err(GeometryError::Subnormal(v))
    } else if v.abs() > MAX_COORDINATE {
        Err(GeometryError::TooLarge(v))
    } else {
        Ok(())
    }
}

/// Checks two lists of corresponding points: equal lengths, at least `min`, every coordinate one
/// [`check_coordinate`] accepts (the SVDs that follow are only bounded on such numbers).
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
    // Non-finite values first: NaN anywhere is reported as such, whatever else is wrong.
    if a.iter().chain(b).flatten().any(|v| !v.is_finite()) {
        return Err(GeometryError::NotFinite);
    }
    a.iter()
        .chain(b)
        .flatten()
        .try_for_each(|&v| check_coordinate(v))
}

/// An SVD with at most [`SVD_MAX_ITERATIONS`] iterations; `what` names the solve in the error.
pub(crate) fn svd_capped<R, C>(
    m: nalgebra::OMatrix<f64, R, C>,
    compute_u: bool,
    compute_v: bool,
    what: &'static str,
) -> Result<nalgebra::SVD<f64, R, C>, GeometryError>
where
    R: nalgebra::DimMin<C>,
    C: nalgebra::Dim,
    nalgebra::DimMinimum<R, C>: nalgebra::DimSub<nalgebra::U1>,
    nalgebra::DefaultAllocator: nalgebra::allocator::Allocator<R, C>
        + nalgebra::allocator::Allocator<C>
        + nalgebra::allocator::Allocator<R>
        + nalgebra::allocator::Allocator<nalgebra::DimDiff<nalgebra::DimMinimum<R, C>, nalgebra::U1>>
        + nalgebra::allocator::Allocator<nalgebra::DimMinimum<R, C>, C>
        + nalgebra::allocator::Allocator<R, nalgebra::DimMinimum<R, C>>
        + nalgebra::allocator::Allocator<nalgebra::DimMinimum<R, C>>,
{
    if m.iter().any(|v| !v.is_finite()) {
        return Err(GeometryError::NotFinite);
    }
    m.try_svd(compute_u, compute_v, SVD_EPS, SVD_MAX_ITERATIONS)
        .ok_or(GeometryError::NoConvergence(what, SVD_MAX_ITERATIONS))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn correspondences_refuse_what_no_solver_can_take() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mut bad = sq;
        bad[1][0] = -1e-310;
        assert_eq!(
            check_correspondences(&sq, &bad, 4),
            Err(GeometryError::Subnormal(-1e-310))
        );
        bad[1][0] = -1e8;
        assert_eq!(
            check_correspondences(&bad, &sq, 4),
            Err(GeometryError::TooLarge(-1e8))
        );
        bad[1][0] = f64::NAN;
        bad[2][0] = 1e-310;
        assert_eq!(
            check_correspondences(&sq, &bad, 4),
            Err(GeometryError::NotFinite)
        );
        assert_eq!(check_correspondences(&sq, &sq, 4), Ok(()));
        // Zero is no subnormal.
        assert_eq!(check_coordinate(0.0), Ok(()));
        assert_eq!(check_coordinate(-0.0), Ok(()));
        assert_eq!(check_coordinate(f64::MIN_POSITIVE), Ok(()));
    }
}
