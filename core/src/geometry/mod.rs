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

/// The largest coordinate geometry accepts, in any unit (pixels, metres, marker cells): far
/// beyond any image, and small enough that products and sums of a few coordinates stay exact
/// enough to solve with.
pub const MAX_COORDINATE: f64 = 1e7;

/// The smallest area a quad may enclose to be a marker's outline ([`check_quad`]), in px².
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

/// Checks that a quad (an ROI: four corners in order around it, in pixels) can be an outline a
/// marker projects to, before any solver runs on it: every coordinate finite, not subnormal and
/// within ±[`MAX_COORDINATE`]; no two corners coincident; no three collinear; opposite edges not
/// crossing (a bow-tie); and an area of at least [`MIN_QUAD_AREA`]. The error says which, naming
/// corners from 1.
pub fn check_quad(quad: &[[f64; 2]; 4]) -> Result<(), GeometryError> {
    check_quad_with_min_area(quad, MIN_QUAD_AREA)
}

/// [`check_quad`] with another least area (0 for outlines known to come from a projection, such as
/// a benchmark set's ground truth, where a marker far away may cover less than a pixel).
pub fn check_quad_with_min_area(quad: &[[f64; 2]; 4], min_area: f64) -> Result<(), GeometryError> {
    if quad.iter().flatten().any(|v| !v.is_finite()) {
        return Err(GeometryError::NotFinite);
    }
    quad.iter()
        .flatten()
        .try_for_each(|&v| check_coordinate(v))?;
    // Coordinates within ±1e7 px: differences, products and areas below are exact enough.
    for i in 0..4 {
        for j in i + 1..4 {
            if distance(quad[i], quad[j]) <= 1e-9 {
                return Err(GeometryError::CoincidentCorners(i + 1, j + 1));
            }
        }
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    // With four points every triple is three consecutive corners: each one's sign is its turn.
    let mut turns = [0.0; 4];
    for (k, turn) in turns.iter_mut().enumerate() {
        let (a, o, b) = (quad[(k + 3) % 4], quad[k], quad[(k + 1) % 4]);
        let c = cross(o, a, b);
        // Collinear to rounding: the sine of the angle at `o` under 1e-9.
        if c.abs() <= 1e-9 * distance(o, a) * distance(o, b) {
            let mut ids = [(k + 3) % 4 + 1, k + 1, (k + 1) % 4 + 1];
            ids.sort_unstable();
            return Err(GeometryError::CollinearCorners(ids[0], ids[1], ids[2]));
        }
        *turn = c;
    }
    // Segments p–q and r–s cross when each one's ends lie on both sides of the other's line;
    // with no three corners collinear no orientation is zero.
    let crosses = |p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]| {
        (cross(p, q, r) > 0.0) != (cross(p, q, s) > 0.0)
            && (cross(r, s, p) > 0.0) != (cross(r, s, q) > 0.0)
    };
    if crosses(quad[0], quad[1], quad[2], quad[3]) || crosses(quad[1], quad[2], quad[3], quad[0]) {
        return Err(GeometryError::SelfIntersecting);
    }
    let area = polygon_area(quad).abs();
    if area < min_area {
        return Err(GeometryError::TooSmall(area));
    }
    Ok(())
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

    /// A marker seen at an angle: a valid, convex, non-square outline.
    const PERSPECTIVE: [[f64; 2]; 4] = [
        [329.95, 442.66],
        [286.03, 446.36],
        [285.24, 402.35],
        [328.57, 398.87],
    ];

    /// The `--roi` that spun in the homography's SVD forever.
    #[test]
    fn the_subnormal_roi_is_refused_at_once() {
        let roi = [[0.0, 0.0], [5e-324, 0.0], [5e-324, 5e-324], [0.0, 5e-324]];
        let started = std::time::Instant::now();
        let e = check_quad(&roi).unwrap_err();
        assert_eq!(e, GeometryError::Subnormal(5e-324));
        assert!(e.to_string().contains("subnormal"), "{e}");
        // And no solver reached with it runs unbounded either.
        let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(Homography::from_points(&unit, &roi).is_err());
        assert!(started.elapsed().as_secs_f64() < 1.0);
    }

    #[test]
    fn a_perspective_quad_passes_in_either_direction() {
        assert_eq!(check_quad(&PERSPECTIVE), Ok(()));
        let mut reversed = PERSPECTIVE;
        reversed.reverse();
        assert_eq!(check_quad(&reversed), Ok(()));
        // Concave outlines are not refused: they do not cross themselves.
        let dart = [[0.0, 0.0], [10.0, 5.0], [0.0, 10.0], [3.0, 5.0]];
        assert_eq!(check_quad(&dart), Ok(()));
    }

    #[test]
    fn each_bad_quad_is_named_for_what_is_wrong() {
        let bow_tie = [[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]];
        let e = check_quad(&bow_tie).unwrap_err();
        assert_eq!(e, GeometryError::SelfIntersecting);
        assert!(e.to_string().contains("bow-tie"), "{e}");
        let other_tie = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
        assert_eq!(check_quad(&other_tie), Err(GeometryError::SelfIntersecting));

        let collinear = [[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [3.0, 8.0]];
        let e = check_quad(&collinear).unwrap_err();
        assert_eq!(e, GeometryError::CollinearCorners(1, 2, 3));
        assert_eq!(e.to_string(), "the quad's corners 1, 2 and 3 are collinear");
        let wrapping = [[0.0, 10.0], [3.0, 8.0], [0.0, 0.0], [0.0, 5.0]];
        assert_eq!(
            check_quad(&wrapping),
            Err(GeometryError::CollinearCorners(1, 3, 4))
        );

        let coincident = [[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        let e = check_quad(&coincident).unwrap_err();
        assert_eq!(e, GeometryError::CoincidentCorners(2, 3));
        assert!(e.to_string().contains("corners 2 and 3 coincide"), "{e}");
        assert_eq!(
            check_quad(&[[4.0, 4.0]; 4]),
            Err(GeometryError::CoincidentCorners(1, 2))
        );

        let mut nan = PERSPECTIVE;
        nan[2][1] = f64::NAN;
        assert_eq!(check_quad(&nan), Err(GeometryError::NotFinite));
        let mut inf = PERSPECTIVE;
        inf[0][0] = f64::NEG_INFINITY;
        assert_eq!(check_quad(&inf), Err(GeometryError::NotFinite));

        let mut far = PERSPECTIVE;
        far[3][0] = 2e7;
        let e = check_quad(&far).unwrap_err();
        assert_eq!(e, GeometryError::TooLarge(2e7));
        assert!(e.to_string().contains("beyond"), "{e}");

        let tiny = [[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]];
        let e = check_quad(&tiny).unwrap_err();
        assert_eq!(e, GeometryError::TooSmall(0.25));
        assert!(e.to_string().contains("under 1 px²"), "{e}");
        assert_eq!(check_quad_with_min_area(&tiny, 0.0), Ok(()));
    }

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
