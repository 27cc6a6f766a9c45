//! 6-DoF pose of a planar marker from many keypoints: homography decomposition for the start, then
//! Levenberg–Marquardt on the reprojection error of every keypoint. A plane seen in perspective has
//! two poses that reproject almost alike (the tilt mirrored about the line of sight); both are
//! solved and the ratio of their errors is reported, with the pose's uncertainty from the
//! Jacobian.
//!
//! The marker frame is OpenCV ArUco's: origin at the centre of the ROI square, x right, y up,
//! z out of the marker face (towards a camera that sees it). Poses map marker to camera frame.

use crate::geometry::{check_correspondences, Camera, GeometryError, Homography};
use nalgebra::{DMatrix, DVector, Matrix3, Matrix6, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

pub use crate::family::marker_plane_points;
pub use crate::geometry::{Pose, PoseJson};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpSolution {
    pub pose: Pose,
    /// Root-mean-square reprojection error in pixels.
    pub rms_px: f64,
    pub iterations: usize,
    /// The other planar solution's RMS error over this one's (≥ 1; near 1: the tilt's sign is
    /// uncertain). `None` when the mirrored start converges back to this pose: one minimum.
    pub ambiguity_ratio: Option<f64>,
    /// Covariance of the pose: a rotation vector applied on the left (camera axes, radians) and
    /// the translation (metres), from the reprojection residuals and the Jacobian.
    pub covariance: Option<Matrix6<f64>>,
}

/// The marker frame's origin and the ends of its x, y and z axes, `length_m` long, in image
/// pixels: how a pose is drawn (x red, y green, z blue, by convention).
pub fn axes_in_image(pose: &Pose, camera: &Camera, length_m: f64) -> [[f64; 2]; 4] {
    let ends = [
        [0.0, 0.0, 0.0],
        [length_m, 0.0, 0.0],
        [0.0, length_m, 0.0],
        [0.0, 0.0, length_m],
    ];
    ends.map(|p| camera.project(pose.apply(p)))
}

/// The 1-σ uncertainty of a pose along the camera's axes.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseUncertainty {
    /// Rotation about the camera's x, y and z axes, degrees.
    pub rotation_deg: [f64; 3],
    /// Position along the camera's x, y and z axes, millimetres.
    pub position_mm: [f64; 3],
}

impl PoseUncertainty {
    pub fn from_covariance(c: &Matrix6<f64>) -> Self {
        let sd = |i: usize| c[(i, i)].max(0.0).sqrt();
        Self {
            rotation_deg: std::array::from_fn(|i| sd(i).to_degrees()),
            position_mm: std::array::from_fn(|i| sd(i + 3) * 1000.0),
        }
    }
}

/// Solves the pose of a planar marker from ≥ 4 correspondences between marker-plane points
/// (metres, z = 0) and image pixels: both planar solutions, the better one returned.
pub fn solve_planar(
    camera: &Camera,
    object: &[[f64; 2]],
    image: &[[f64; 2]],
) -> Result<PnpSolution, GeometryError> {
    camera.validate()?;
    check_correspondences(object, image, 4)?;
    let normalised: Vec<[f64; 2]> = image.iter().map(|&p| camera.normalise(p)).collect();
    let start = decompose(&Homography::from_points(object, &normalised)?)?;
    let first = refine(camera, object, image, start)?;
    let second = refine(camera, object, image, mirrored(&first.pose)).ok();
    let (mut best, other) = match second {
        Some(s) if s.rms_px < first.rms_px => (s, Some(first)),
        s => (first, s),
    };
    best.ambiguity_ratio = other
        .filter(|o| o.pose.rotation_error_deg(&best.pose) > 0.5)
        .map(|o| o.rms_px / best.rms_px.max(1e-12));
    best.covariance = covariance(camera, object, &best.pose, PointNoise::Residuals(image));
    Ok(best)
}

/// The other planar pose: the marker's normal mirrored about the line of sight to its centre.
fn mirrored(pose: &Pose) -> Pose {
    let sight = pose.translation.normalize();
    let normal = pose.rotation * Vector3::z();
    let mirror = sight * (2.0 * sight.dot(&normal)) - normal;
    let turn = Rotation3::rotation_between(&normal, &mirror).unwrap_or_else(|| {
        // Normal along the line of sight exactly: the two solutions coincide.
        Rotation3::identity()
    });
    Pose {
        rotation: turn * pose.rotation,
        translation: pose.translation,
    }
}

/// d(residuals)/d(pose parameters) at `pose`: 2n × 6, central differences.
pub fn jacobian(camera: &Camera, object: &[[f64; 2]], pose: &Pose) -> DMatrix<f64> {
    let mut j = DMatrix::zeros(2 * object.len(), 6);
    let scale = pose.translation.norm().max(1e-3);
    for k in 0..6 {
        let eps = if k < 3 { 1e-6 } else { 1e-6 * scale };
        let mut d = [0.0; 6];
        d[k] = eps;
        let plus = project_all(camera, object, &perturb(pose, &d));
        d[k] = -eps;
        let minus = project_all(camera, object, &perturb(pose, &d));
        j.set_column(k, &((plus - minus) / (2.0 * eps)));
    }
    j
}

/// Where the image points' noise comes from, for [`covariance`].
#[derive(Debug, Clone, Copy)]
pub enum PointNoise<'a> {
    /// Independent, with the variance of the reprojection residuals to these image points.
    Residuals(&'a [[f64; 2]]),
    /// The points' own 2n × 2n covariance (x, y interleaved), e.g. from an image alignment.
    Covariance(&'a DMatrix<f64>),
}

/// The pose's covariance (parameters as in [`PnpSolution::covariance`]), to first order.
pub fn covariance(
    camera: &Camera,
    object: &[[f64; 2]],
    pose: &Pose,
    noise: PointNoise,
) -> Option<Matrix6<f64>> {
    let j = jacobian(camera, object, pose);
    let inverse = (j.transpose() * &j).try_inverse()?;
    let c = match noise {
        PointNoise::Residuals(image) => {
            let dof = (2 * object.len()).checked_sub(6).filter(|&d| d > 0)?;
            let variance = residuals(camera, object, image, pose).norm_squared() / dof as f64;
            inverse * variance
        }
        PointNoise::Covariance(points) => {
            let map = &inverse * j.transpose();
            &map * points * map.transpose()
        }
    };
    let m = Matrix6::from_fn(|r, k| c[(r, k)]);
    m.iter().all(|v| v.is_finite()).then_some(m)
}

fn project_all(camera: &Camera, object: &[[f64; 2]], pose: &Pose) -> DVector<f64> {
    let mut r = DVector::zeros(2 * object.len());
    for (i, o) in object.iter().enumerate() {
        let q = camera.project(pose.apply([o[0], o[1], 0.0]));
        r[2 * i] = q[0];
        r[2 * i + 1] = q[1];
    }
    r
}

/// H ~ [r1 r2 t] for a plane at z = 0 seen through an identity camera.
fn decompose(h: &Homography) -> Result<Pose, GeometryError> {
    let m = h.0;
    let (h1, h2, h3) = (
        m.column(0).into_owned(),
        m.column(1).into_owned(),
        m.column(2).into_owned(),
    );
    let norm = (h1.norm() + h2.norm()) / 2.0;
    if norm.is_nan() || norm <= 1e-12 {
        return Err(GeometryError::Degenerate);
    }
    // The marker is in front of the camera: t_z > 0 fixes the sign of the scale.
    let lambda = if h3[2] < 0.0 { -1.0 / norm } else { 1.0 / norm };
    let (r1, r2, t) = (h1 * lambda, h2 * lambda, h3 * lambda);
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    // Nearest rotation matrix (the columns are only approximately orthonormal with noise).
    let svd = crate::geometry::svd_capped(r, true, true, "pose's rotation fit (SVD)")?;
    let (u, v_t) = (
        svd.u.ok_or(GeometryError::Degenerate)?,
        svd.v_t.ok_or(GeometryError::Degenerate)?,
    );
    let mut rot = u * v_t;
    if rot.determinant() < 0.0 {
        let mut u = u;
        u.column_mut(2).neg_mut();
        rot = u * v_t;
    }
    Ok(Pose {
        rotation: Rotation3::from_matrix_unchecked(rot),
        translation: t,
    })
}

fn residuals(
    camera: &Camera,
    object: &[[f64; 2]],
    image: &[[f64; 2]],
    pose: &Pose,
) -> DVector<f64> {
    let mut r = DVector::zeros(2 * object.len());
    for (i, (o, px)) in object.iter().zip(image).enumerate() {
        let p = pose.apply([o[0], o[1], 0.0]);
        let q = camera.project(p);
        r[2 * i] = q[0] - px[0];
        r[2 * i + 1] = q[1] - px[1];
    }
    r
}

/// A small change of pose: rotation vector applied on the left, then a translation step.
fn perturb(pose: &Pose, d: &[f64]) -> Pose {
    Pose {
        rotation: Rotation3::new(Vector3::new(d[0], d[1], d[2])) * pose.rotation,
        translation: pose.translation + Vector3::new(d[3], d[4], d[5]),
    }
}

fn refine(
    camera: &Camera,
    object: &[[f64; 2]],
    image: &[[f64; 2]],
    start: Pose,
) -> Result<PnpSolution, GeometryError> {
    let n = object.len();
    let mut pose = start;
    let mut r = residuals(camera, object, image, &pose);
    let mut cost = r.norm_squared();
    let mut mu = 1e-3;
    let mut iterations = 0;
    for it in 0..100 {
        iterations = it + 1;
        // Central differences: six parameters, cheap, and exact enough for convergence to 1e-9.
        let mut j = DMatrix::zeros(2 * n, 6);
        let scale = pose.translation.norm().max(1e-3);
        for k in 0..6 {
            let eps = if k < 3 { 1e-6 } else { 1e-6 * scale };
            let mut d = [0.0; 6];
            d[k] = eps;
            let plus = residuals(camera, object, image, &perturb(&pose, &d));
            d[k] = -eps;
            let minus = residuals(camera, object, image, &perturb(&pose, &d));
            j.set_column(k, &((plus - minus) / (2.0 * eps)));
        }
        let jt = j.transpose();
        let jtj = &jt * &j;
        let g = &jt * &r;
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for k in 0..6 {
                a[(k, k)] += mu * jtj[(k, k)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
                mu *= 10.0;
                continue;
            };
            let candidate = perturb(&pose, step.as_slice());
            let rc = residuals(camera, object, image, &candidate);
            let c = rc.norm_squared();
            if c.is_finite() && c <= cost {
                let small =
                    step.norm() < 1e-14 * (1.0 + scale) || cost - c <= 1e-16 * cost.max(1e-300);
                pose = candidate;
                r = rc;
                cost = c;
                mu = (mu / 3.0).max(1e-12);
                improved = !small;
                break;
            }
            mu *= 4.0;
        }
        if !improved {
            break;
        }
    }
    if !cost.is_finite() {
        return Err(GeometryError::Degenerate);
    }
    Ok(PnpSolution {
        pose,
        rms_px: (cost / n as f64).sqrt(),
        iterations,
        ambiguity_ratio: None,
        covariance: None,
    })
}

#[cfg(test)]
mod tests;
