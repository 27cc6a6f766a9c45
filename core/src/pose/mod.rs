//! 6-DoF pose of a planar marker from many keypoints: homography decomposition for the start, then
//! Levenberg–Marquardt on the reprojection error of every keypoint.
//!
//! The marker frame is OpenCV ArUco's: origin at the centre of the ROI square, x right, y up,
//! z out of the marker face (towards a camera that sees it). Poses map marker to camera frame.

use crate::geometry::{check_correspondences, Camera, GeometryError, Homography};
use nalgebra::{DMatrix, DVector, Matrix3, Rotation3, Vector3};

pub use crate::family::marker_plane_points;
pub use crate::geometry::{Pose, PoseJson};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PnpSolution {
    pub pose: Pose,
    /// Root-mean-square reprojection error in pixels.
    pub rms_px: f64,
    pub iterations: usize,
}

/// Solves the pose of a planar marker from ≥ 4 correspondences between marker-plane points
/// (metres, z = 0) and image pixels.
pub fn solve_planar(
    camera: &Camera,
    object: &[[f64; 2]],
    image: &[[f64; 2]],
) -> Result<PnpSolution, GeometryError> {
    camera.validate()?;
    check_correspondences(object, image, 4)?;
    let normalised: Vec<[f64; 2]> = image.iter().map(|&p| camera.normalise(p)).collect();
    let start = decompose(&Homography::from_points(object, &normalised)?)?;
    refine(camera, object, image, start)
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
    let svd = r.svd(true, true);
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
    })
}

#[cfg(test)]
mod tests;
