//! A rigid pose (marker frame → camera frame) and its JSON form.

use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Rotation3<f64>,
    /// Metres, camera frame.
    pub translation: Vector3<f64>,
}

/// A pose as written in JSON (detections files, ground truth): row-major rotation (marker →
/// camera) and translation in metres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseJson {
    pub rotation: [[f64; 3]; 3],
    pub translation_m: [f64; 3],
}

impl From<&Pose> for PoseJson {
    fn from(pose: &Pose) -> Self {
        let m = pose.rotation.matrix();
        Self {
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])),
            translation_m: [
                pose.translation[0],
                pose.translation[1],
                pose.translation[2],
            ],
        }
    }
}

impl From<&PoseJson> for Pose {
    /// The rotation is taken as written (a detector's rounding is not re-orthogonalised away).
    fn from(p: &PoseJson) -> Self {
        Pose {
            rotation: Rotation3::from_matrix_unchecked(Matrix3::from_fn(|i, j| p.rotation[i][j])),
            translation: Vector3::from(p.translation_m),
        }
    }
}

impl Pose {
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let q = self.rotation * Vector3::new(p[0], p[1], p[2]) + self.translation;
        [q[0], q[1], q[2]]
    }

    /// Angle of the rotation between two poses, in degrees.
    pub fn rotation_error_deg(&self, other: &Pose) -> f64 {
        // atan2(sin, cos) stays accurate near zero, where acos of the trace loses half the digits
        // (and returns NaN when rounding pushes the trace past 3).
        let m = (self.rotation.inverse() * other.rotation).into_inner();
        let sin = Vector3::new(
            m[(2, 1)] - m[(1, 2)],
            m[(0, 2)] - m[(2, 0)],
            m[(1, 0)] - m[(0, 1)],
        )
        .norm()
            / 2.0;
        let cos = (m.trace() - 1.0) / 2.0;
        sin.atan2(cos).to_degrees()
    }

    /// Distance between the two marker origins, in metres.
    pub fn position_error(&self, other: &Pose) -> f64 {
        (self.translation - other.translation).norm()
    }
}
