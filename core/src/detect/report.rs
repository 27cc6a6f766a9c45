//! What `tagsmith detect` prints and the studio's Detect panel shows for one marker read from a
//! ROI: one serialisable type, so both show the same thing.

use super::refine::RefineReport;
use super::DetectedKeypoint;
use crate::geometry::{PoseJson, Quad};
use crate::pose::PoseUncertainty;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MarkerReport {
    pub family: String,
    pub decoded: bool,
    /// Present when `decoded`.
    #[serde(flatten)]
    pub marker: Option<DecodedMarker>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DecodedMarker {
    pub id: usize,
    /// Clockwise angle in degrees by which the marker is turned relative to the ROI's order.
    pub rotation_deg: f64,
    pub corrected_errors: usize,
    pub fixed_mismatches: usize,
    /// Stage-2 passes that decoded.
    pub iterations: usize,
    /// The first pass over the ROI decoded nothing; this read started from where its keypoints
    /// placed the marker (and the alignment with the rendering accepted it).
    #[serde(default)]
    pub from_keypoints: bool,
    /// The family's ROI points in the image, canonical order.
    pub corners: Quad,
    pub missing_keypoints: usize,
    pub keypoints: Vec<DetectedKeypoint>,
    /// The alignment against the family's rendering: whether it replaced stage 2's keypoints,
    /// or why not, and its residual.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refinement: Option<RefineReport>,
    pub pose: Option<PoseReport>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PoseReport {
    #[serde(flatten)]
    pub pose: PoseJson,
    pub reprojection_rms_px: f64,
    /// 1-σ uncertainty along the camera's axes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<PoseUncertainty>,
    /// The other planar solution's reprojection error over this one's; absent when there is
    /// only one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambiguity_ratio: Option<f64>,
    /// The marker size the pose assumes (ROI side).
    pub side_mm: f64,
    /// Where the camera came from ("given", or how it was guessed).
    pub camera: String,
}

#[cfg(feature = "detect")]
impl MarkerReport {
    /// The report of a stage-2 result (`None`: nothing decoded); the pose, when solved, for a
    /// marker of `side_mm` seen by a camera described by `camera`.
    pub fn from_stage2(
        family: &str,
        result: Option<&super::stage2::Stage2Result>,
        side_mm: f64,
        camera: &str,
    ) -> Self {
        Self {
            family: family.to_string(),
            decoded: result.is_some(),
            marker: result.map(|r| DecodedMarker {
                id: r.id,
                rotation_deg: r.rotation_deg,
                corrected_errors: r.corrected_errors,
                fixed_mismatches: r.fixed_mismatches,
                iterations: r.iterations,
                from_keypoints: r.from_keypoints,
                corners: r.corners,
                missing_keypoints: r.missing,
                keypoints: r.keypoints.clone(),
                refinement: r.refinement.clone(),
                pose: r.pose.map(|p| PoseReport {
                    pose: PoseJson::from(&p.pose),
                    reprojection_rms_px: p.rms_px,
                    uncertainty: p.covariance.as_ref().map(PoseUncertainty::from_covariance),
                    ambiguity_ratio: p.ambiguity_ratio,
                    side_mm,
                    camera: camera.to_string(),
                }),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_undecoded_marker_reports_only_its_family() {
        let r = MarkerReport {
            family: "f".into(),
            decoded: false,
            marker: None,
        };
        let json = serde_json::to_value(&r).unwrap();
        assert_eq!(json, serde_json::json!({"family": "f", "decoded": false}));
        assert_eq!(serde_json::from_value::<MarkerReport>(json).unwrap(), r);
    }
}
