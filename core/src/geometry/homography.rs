//! Plane-to-plane homographies from point correspondences (normalised DLT, least squares for more
//! than four points).

use super::GeometryError;
use nalgebra::{DMatrix, Matrix3, Vector3};

/// A 3×3 homography mapping `src` points to `dst` points: `dst ~ H · src`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography(pub Matrix3<f64>);

impl Homography {
    /// Estimates the homography with Hartley's normalised DLT: points are centred and scaled to a
    /// mean distance of √2 before the SVD, which keeps the system well conditioned whatever the
    /// coordinate units (pixels, millimetres, cells). With more than four points it is the
    /// algebraic least-squares solution.
    ///
    /// Every coordinate must pass [`super::check_coordinate`] (finite, not subnormal, within
    /// ±[`super::MAX_COORDINATE`]); the SVD is capped at [`super::SVD_MAX_ITERATIONS`].
    pub fn from_points(src: &[[f64; 2]], dst: &[[f64; 2]]) -> Result<Self, GeometryError> {
        super::check_correspondences(src, dst, 4)?;
        let (ts, ns) = normalise(src)?;
        let (td, nd) = normalise(dst)?;
        let n = src.len();
        let mut a = DMatrix::<f64>::zeros(2 * n.max(5), 9);
        for (i, (s, d)) in ns.iter().zip(&nd).enumerate() {
            let (x, y, u, v) = (s[0], s[1], d[0], d[1]);
            a.row_mut(2 * i)
                .copy_from_slice(&[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]);
            a.row_mut(2 * i + 1)
                .copy_from_slice(&[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
        }
        // Four points give 8 equations; the zero row added above makes the SVD return all 9
        // right singular vectors.
        // Capped: nalgebra's own `svd` iterates until convergence, and never returns on a
        // matrix it cannot decompose.
        let svd = super::svd_capped(a, false, true, "homography's SVD")?;
        let v_t = svd.v_t.ok_or(GeometryError::Degenerate)?;
        let sv = &svd.singular_values;
        let (mut smallest, mut second) = (0, 1);
        if sv[1] < sv[0] {
            (smallest, second) = (1, 0);
        }
        for i in 2..sv.len() {
            if sv[i] < sv[smallest] {
                second = smallest;
                smallest = i;
            } else if sv[i] < sv[second] {
                second = i;
            }
        }
        // A second null direction means the points do not pin the homography down (collinear or
        // coincident points).
        if sv[second] < 1e-9 * sv.max() {
            return Err(GeometryError::Degenerate);
        }
        let h = v_t.row(smallest);
        let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
        let td_inv = td.try_inverse().ok_or(GeometryError::Degenerate)?;
        let m = td_inv * hn * ts;
        if m[(2, 2)].abs() < 1e-300 {
            return Err(GeometryError::Degenerate);
        }
        Ok(Self(m / m[(2, 2)]))
    }

    pub fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let q = self.0 * Vector3::new(p[0], p[1], 1.0);
        [q[0] / q[2], q[1] / q[2]]
    }

    pub fn inverse(&self) -> Option<Self> {
        self.0.try_inverse().map(|m| Self(m / m[(2, 2)]))
    }
}

/// Similarity that moves the centroid to the origin and the mean distance to √2.
fn normalise(points: &[[f64; 2]]) -> Result<(Matrix3<f64>, Vec<[f64; 2]>), GeometryError> {
    let n = points.len() as f64;
    let c = points
        .iter()
        .fold([0.0, 0.0], |a, p| [a[0] + p[0] / n, a[1] + p[1] / n]);
    let mean = points
        .iter()
        .map(|p| (p[0] - c[0]).hypot(p[1] - c[1]))
        .sum::<f64>()
        / n;
    // Also catches NaN: only a positive spread passes.
    if mean.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(GeometryError::Degenerate);
    }
    let s = std::f64::consts::SQRT_2 / mean;
    let t = Matrix3::new(s, 0.0, -s * c[0], 0.0, s, -s * c[1], 0.0, 0.0, 1.0);
    Ok((
        t,
        points
            .iter()
            .map(|p| [s * (p[0] - c[0]), s * (p[1] - c[1])])
            .collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth() -> Homography {
        Homography(Matrix3::new(
            1.2, 0.1, 30.0, -0.2, 0.9, 12.0, 1e-3, -2e-3, 1.0,
        ))
    }

    #[test]
    fn recovers_a_homography_from_four_and_from_many_points() {
        let h = truth();
        let src4 = [[0.0, 0.0], [8.0, 0.0], [8.0, 8.0], [0.0, 8.0]];
        let dst4: Vec<_> = src4.iter().map(|&p| h.apply(p)).collect();
        let e = Homography::from_points(&src4, &dst4).unwrap();
        assert!((e.0 - h.0).abs().max() < 1e-9, "{}", e.0);
        let src: Vec<[f64; 2]> = (0..64)
            .map(|i| [(i % 8) as f64 + 0.5, (i / 8) as f64 + 0.5])
            .collect();
        let dst: Vec<_> = src.iter().map(|&p| h.apply(p)).collect();
        let e = Homography::from_points(&src, &dst).unwrap();
        assert!((e.0 - h.0).abs().max() < 1e-9);
        let back = e.inverse().unwrap().apply(dst[9]);
        assert!((back[0] - src[9][0]).abs() < 1e-9 && (back[1] - src[9][1]).abs() < 1e-9);
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(matches!(
            Homography::from_points(&sq[..3], &sq[..3]),
            Err(GeometryError::TooFewPoints(3, 4))
        ));
        assert!(matches!(
            Homography::from_points(&sq, &sq[..3]),
            Err(GeometryError::Mismatch(4, 3))
        ));
        let collinear = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]];
        assert!(matches!(
            Homography::from_points(&collinear, &sq),
            Err(GeometryError::Degenerate)
        ));
        let same = [[1.0, 1.0]; 4];
        assert!(Homography::from_points(&same, &sq).is_err());
        let mut nan = sq;
        nan[2][1] = f64::NAN;
        assert!(matches!(
            Homography::from_points(&nan, &sq),
            Err(GeometryError::NotFinite)
        ));
    }

    /// The `--roi` that spun in the SVD forever: the centring scale is 1/5e-324 = ∞.
    #[test]
    fn subnormal_and_huge_points_are_refused_at_once() {
        let sq = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let tiny = [[0.0, 0.0], [5e-324, 0.0], [5e-324, 5e-324], [0.0, 5e-324]];
        let started = std::time::Instant::now();
        assert_eq!(
            Homography::from_points(&sq, &tiny),
            Err(GeometryError::Subnormal(5e-324))
        );
        assert_eq!(
            Homography::from_points(&tiny, &sq),
            Err(GeometryError::Subnormal(5e-324))
        );
        let huge = [[0.0, 0.0], [1e300, 0.0], [1e300, 1e300], [0.0, 1e300]];
        assert_eq!(
            Homography::from_points(&sq, &huge),
            Err(GeometryError::TooLarge(1e300))
        );
        assert!(started.elapsed().as_secs_f64() < 1.0);
    }

    #[test]
    fn the_capped_svd_reports_what_does_not_converge() {
        let nan = nalgebra::DMatrix::<f64>::from_element(10, 9, f64::NAN);
        assert_eq!(
            crate::geometry::svd_capped(nan, false, true, "test").err(),
            Some(GeometryError::NotFinite)
        );
        let m = Matrix3::new(2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 1.0);
        let svd = crate::geometry::svd_capped(m, true, true, "test").unwrap();
        assert!((svd.singular_values.max() - 3.0).abs() < 1e-12);
    }
}
