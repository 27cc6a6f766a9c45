//! One marker found, with the fields pupil-apriltags users know.

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use tagsmith::detect::{Detection as Record, Found};
use tagsmith::geometry::Homography;

/// The ROI square the homography maps from, in OpenCV's (and AprilTag's) corner order.
const UNIT_SQUARE: [[f64; 2]; 4] = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];

/// A marker the detector read.
#[pyclass(frozen, module = "tagsmith")]
pub struct Detection {
    /// The record `tagsmith detect --json` writes for it (pose scaled to the tag size asked for).
    record: Record,
    /// 1σ of the pose from the reprojection residuals: rotation (degrees), translation (metres).
    pose_sigma: Option<(f64, f64)>,
    /// The other planar pose's RMS over this one's.
    ambiguity: Option<f64>,
    /// The image's per-phase times, as JSON (shared by the image's detections).
    timings: std::sync::Arc<String>,
}

impl Detection {
    /// `scale`: the tag size asked for over the size the detector posed the marker at.
    pub fn new(found: &Found, scale: f64, timings: std::sync::Arc<String>) -> Self {
        let mut record = found.detection();
        if let Some(pose) = &mut record.pose {
            pose.translation_m = pose.translation_m.map(|t| t * scale);
        }
        let solution = found.marker.pose.as_ref();
        let pose_sigma = solution.and_then(|p| p.covariance).map(|c| {
            let rotation = (c[(0, 0)] + c[(1, 1)] + c[(2, 2)]).max(0.0).sqrt();
            let translation = (c[(3, 3)] + c[(4, 4)] + c[(5, 5)]).max(0.0).sqrt();
            (rotation.to_degrees(), translation * scale)
        });
        Self {
            record,
            pose_sigma,
            ambiguity: solution.and_then(|p| p.ambiguity_ratio),
            timings,
        }
    }

    pub fn record(&self) -> &Record {
        &self.record
    }

    fn homography_matrix(&self) -> Option<[[f64; 3]; 3]> {
        let h = Homography::from_points(&UNIT_SQUARE, &self.record.corners[..]).ok()?;
        let m = h.0 / h.0[(2, 2)];
        Some(std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)])))
    }
}

fn matrix<'py, const R: usize, const C: usize>(
    py: Python<'py>,
    rows: &[[f64; C]; R],
) -> Bound<'py, PyArray2<f64>> {
    Array2::from_shape_fn((R, C), |(i, j)| rows[i][j]).into_pyarray(py)
}

#[pymethods]
impl Detection {
    /// The family's name.
    #[getter]
    fn family(&self) -> String {
        self.record.family.clone().unwrap_or_default()
    }

    #[getter]
    fn tag_id(&self) -> usize {
        self.record.id
    }

    /// 4×2 float64, pixels: the marker's ROI corners in OpenCV's order (top-left, top-right,
    /// bottom-right, bottom-left of the upright marker; clockwise in the image).
    #[getter]
    fn corners<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        matrix(py, &self.record.corners)
    }

    /// The ROI's centre: where its homography puts the square's centre.
    #[getter]
    fn center<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let centre = match self.homography_matrix() {
            Some(h) => [h[0][2] / h[2][2], h[1][2] / h[2][2]],
            None => {
                let c = &self.record.corners;
                [0, 1].map(|k| c.iter().map(|p| p[k]).sum::<f64>() / 4.0)
            }
        };
        Array1::from(centre.to_vec()).into_pyarray(py)
    }

    /// Symbols the codebook corrected.
    #[getter]
    fn hamming(&self) -> usize {
        self.record
            .scores
            .as_ref()
            .map_or(0, |s| s.corrected_errors)
    }

    /// `roi` (stage 1's score), `keypoints` (mean keypoint confidence), `corrected_errors`,
    /// `reprojection_rms_px`, `cell_read`.
    #[getter]
    fn scores<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        if let Some(s) = &self.record.scores {
            dict.set_item("roi", s.roi)?;
            dict.set_item("keypoints", s.keypoints)?;
            dict.set_item("corrected_errors", s.corrected_errors)?;
            dict.set_item("reprojection_rms_px", s.reprojection_rms_px)?;
            dict.set_item("cell_read", s.cell_read)?;
        }
        Ok(dict)
    }

    /// N×2 float64, pixels: every keypoint stage 2 matched to the family's template.
    #[getter]
    fn keypoints<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let k = &self.record.keypoints;
        Array2::from_shape_fn((k.len(), 2), |(i, j)| if j == 0 { k[i].x } else { k[i].y })
            .into_pyarray(py)
    }

    /// (N,) int64: each keypoint's code symbol, −1 for a fixed (non-code) pattern.
    #[getter]
    fn keypoint_symbols<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let k = &self.record.keypoints;
        Array1::from_iter(k.iter().map(|k| k.symbol.map_or(-1, i64::from))).into_pyarray(py)
    }

    /// (N,) int64: each keypoint's index in the family's keypoint list.
    #[getter]
    fn keypoint_indices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let k = &self.record.keypoints;
        Array1::from_iter(k.iter().map(|k| k.index as i64)).into_pyarray(py)
    }

    /// (N,) float64: each keypoint's confidence, 0–1.
    #[getter]
    fn keypoint_confidences<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let k = &self.record.keypoints;
        Array1::from_iter(k.iter().map(|k| k.confidence)).into_pyarray(py)
    }

    /// 3×3 float64: maps the square (−1, −1), (1, −1), (1, 1), (−1, 1) onto `corners`
    /// (AprilTag's convention); `None` for a degenerate quad.
    #[getter]
    fn homography<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.homography_matrix().map(|h| matrix(py, &h))
    }

    /// 3×3 float64: the rotation from the marker's frame (origin at its centre, x to the right
    /// and y up along the upright marker, z out of it towards the camera) to the camera's
    /// (OpenCV's: x right, y down, z forward); `None` without a pose.
    #[getter(pose_R)]
    fn pose_r<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.record.pose.as_ref().map(|p| matrix(py, &p.rotation))
    }

    /// 3×1 float64, metres: the marker's centre in the camera's frame; `None` without a pose.
    #[getter]
    fn pose_t<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        self.record
            .pose
            .as_ref()
            .map(|p| matrix(py, &p.translation_m.map(|t| [t])))
    }

    /// The pose's standard deviation from the reprojection residuals: (rotation in degrees,
    /// translation in metres); `None` without a pose.
    #[getter]
    fn pose_err(&self) -> Option<(f64, f64)> {
        self.pose_sigma
    }

    /// The other planar pose's reprojection RMS over this one's (near 1: the tilt's sign is
    /// uncertain); `None` when there is one minimum or no pose.
    #[getter]
    fn pose_ambiguity(&self) -> Option<f64> {
        self.ambiguity
    }

    /// RMS reprojection error of the pose over all keypoints, pixels; `None` without a pose.
    #[getter]
    fn reprojection_error(&self) -> Option<f64> {
        self.record
            .scores
            .as_ref()
            .and_then(|s| s.reprojection_rms_px)
    }

    /// The image's per-phase times (propose, verify, read, reconcile; ms) and counts.
    #[getter]
    fn timings<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?
            .call_method1("loads", (self.timings.as_str(),))
    }

    /// The detection as `tagsmith detect --json` writes it (the harness's format).
    fn to_json(&self) -> String {
        serde_json::to_string(&self.record).expect("detections serialise")
    }

    fn __repr__(&self) -> String {
        let c = &self.record.corners;
        format!(
            "Detection(family={:?}, tag_id={}, hamming={}, corners=[{}])",
            self.family(),
            self.record.id,
            self.hamming(),
            c.iter()
                .map(|p| format!("({:.1}, {:.1})", p[0], p[1]))
                .collect::<Vec<_>>()
                .join(", ")
        )
    }
}
