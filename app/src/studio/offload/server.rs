//! The work behind an [`super::Offload`]: builds the detector a request names (kept while the
//! families stay the same), detects, and turns what it found into what the panel draws.

use super::{DetectRequest, Detected, Reply, Shown};
use crate::settings::DetectorSettings;
use std::path::{Path, PathBuf};
use std::time::SystemTime;
use tagsmith::detect::detector::FamilyReader;
use tagsmith::detect::stage1::Stage1;
use tagsmith::detect::stage2::Stage2;
use tagsmith::detect::{BenchDetector, Detector, Found};
use tagsmith::family::{Family, FamilySpec};
use tagsmith::geometry::Camera;
use tagsmith::image::GrayImage;

/// Which families a detector reads: built-ins by name, and the design (its whole spec: an edited
/// code table is another detector) with its model file and when that was written.
type DetectorKey = (
    Vec<String>,
    Option<(FamilySpec, Option<PathBuf>, Option<SystemTime>)>,
);

#[derive(Default)]
pub struct Server {
    detector: Option<(DetectorKey, Detector)>,
}

impl Server {
    pub fn serve(&mut self, request: DetectRequest) -> Reply {
        let design = match &request.design {
            Some((spec, model)) => Some((
                Family::from_spec(spec.clone()).map_err(|e| e.to_string())?,
                model.clone(),
            )),
            None => None,
        };
        let key: DetectorKey = (
            request.families.clone(),
            design
                .as_ref()
                .map(|(f, m)| (f.spec().clone(), m.clone(), m.as_deref().and_then(written))),
        );
        if self.detector.as_ref().is_none_or(|(k, _)| *k != key) {
            self.detector = None;
            let detector = build_detector(
                &request.families,
                design.as_ref().map(|(f, m)| (f, m.as_deref())),
                &request.settings,
            )?;
            self.detector = Some((key, detector));
        }
        let (_, detector) = self.detector.as_mut().expect("built above");
        request.settings.apply(&mut detector.options);
        let expected = request.width as usize * request.height as usize;
        if request.pixels.len() != expected {
            return Err(format!(
                "{}: {} bytes for a {}×{} image",
                request.name,
                request.pixels.len(),
                request.width,
                request.height
            ));
        }
        let image = GrayImage::from_vec(request.width, request.height, request.pixels);
        let clock = tagsmith::io::Stopwatch::start();
        let (found, timings) = Detector::detect(detector, &image);
        let time_ms = clock.ms();
        let camera = detector.camera_for(&image);
        Ok(Detected {
            markers: shown(detector, &found, camera.as_ref()),
            timings,
            time_ms,
            detector: BenchDetector::name(detector),
        })
    }
}

/// When the model file at `path` was last written (`None` where it cannot be read): a model
/// trained again in place is another detector.
pub fn written(path: &Path) -> Option<SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

/// The shipped stage 1 with the shipped weights of `families` (built-ins) and the design's own
/// model (`None`: the shipped model of its layout), run as `settings` say.
pub fn build_detector(
    families: &[String],
    design: Option<(&Family, Option<&Path>)>,
    settings: &DetectorSettings,
) -> Result<Detector, String> {
    let mut readers = Vec::new();
    for name in families {
        let family = match tagsmith::builtin::get(name) {
            Some(Ok(f)) => f,
            Some(Err(e)) => return Err(e.to_string()),
            None => return Err(format!("{name} is not a built-in family")),
        };
        readers.push(FamilyReader::shipped(family).map_err(|e| e.to_string())?);
    }
    if let Some((family, model)) = design {
        let stage2 = match model {
            Some(model) => Stage2::load(model, family).map_err(|e| e.to_string())?,
            None => Stage2::shipped(family)
                .ok_or(format!(
                    "{}: no shipped model has its layout",
                    family.name()
                ))?
                .map_err(|e| e.to_string())?,
        };
        readers.push(FamilyReader::new(family.clone(), stage2));
    }
    if readers.is_empty() {
        return Err("choose at least one family to detect".into());
    }
    let stage1 = Stage1::shipped().map_err(|e| e.to_string())?;
    let mut detector = Detector::new(stage1, readers).map_err(|e| e.to_string())?;
    settings.apply(&mut detector.options);
    Ok(detector)
}

/// The markers as the panel draws them, with each pose's axes through `camera`.
pub fn shown(detector: &Detector, found: &[Found], camera: Option<&Camera>) -> Vec<Shown> {
    found
        .iter()
        .map(|f| Shown {
            detection: f.detection(),
            roi: f.proposal.corners,
            refined: f.marker.refinement.as_ref().is_some_and(|r| r.refined),
            axes: pose_axes(detector, f, camera),
        })
        .collect()
}

/// The marker's axes, as long as its side, as the pose puts them in the image.
fn pose_axes(detector: &Detector, f: &Found, camera: Option<&Camera>) -> Option<[[f64; 2]; 4]> {
    let pose = f.marker.pose.as_ref()?;
    let side = detector
        .readers
        .iter()
        .find(|r| r.family.name() == f.family)?
        .side_m;
    Some(tagsmith::pose::axes_in_image(&pose.pose, camera?, side))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> GrayImage {
        let (_, bytes) = crate::studio::detect::samples().next().unwrap();
        tagsmith::image::decode(bytes, &Default::default()).expect("the sample decodes")
    }

    fn request(image: &GrayImage, families: &[&str]) -> DetectRequest {
        DetectRequest {
            families: families.iter().map(|f| f.to_string()).collect(),
            design: None,
            settings: DetectorSettings::default(),
            name: "sample".into(),
            width: image.width,
            height: image.height,
            pixels: image.pixels.to_vec(),
        }
    }

    /// What the panel shows is what the detector finds, and a request that crossed as JSON
    /// (as it does to a browser's worker) reads the same.
    #[test]
    fn a_served_request_reads_what_the_detector_reads() {
        let image = sample();
        let families = ["aruco-6x6_250"];
        let detector = build_detector(
            &families.map(String::from),
            None,
            &DetectorSettings::default(),
        )
        .unwrap();
        let (found, _) = detector.detect(&image);
        assert!(!found.is_empty(), "the tutorial sample shows ArUco markers");

        let mut server = Server::default();
        let direct = server.serve(request(&image, &families)).unwrap();
        let wire = request(&image, &families);
        let mut crossed: DetectRequest =
            serde_json::from_str(&serde_json::to_string(&wire).unwrap()).unwrap();
        crossed.pixels = wire.pixels;
        let reply = server.serve(crossed).unwrap();
        let reply: Detected =
            serde_json::from_str(&serde_json::to_string(&reply).unwrap()).unwrap();
        for got in [&direct, &reply] {
            let ids: Vec<usize> = got.markers.iter().map(|m| m.detection.id).collect();
            let want: Vec<usize> = found.iter().map(|f| f.marker.id).collect();
            assert_eq!(ids, want);
            assert!(got.markers.iter().all(|m| m.axes.is_some()), "posed");
        }
        // serde_json parses floats to within an ulp, not exactly.
        let near = |a: &[[f64; 2]; 4], b: &[[f64; 2]; 4]| {
            a.iter()
                .zip(b)
                .all(|(p, q)| (p[0] - q[0]).abs() < 1e-9 && (p[1] - q[1]).abs() < 1e-9)
        };
        for (d, r) in direct.markers.iter().zip(&reply.markers) {
            assert_eq!(d.detection.family, r.detection.family);
            assert!(near(&d.detection.corners.0, &r.detection.corners.0));
            assert!(near(&d.roi.0, &r.roi.0));
            assert!(near(&d.axes.unwrap(), &r.axes.unwrap()));
            assert_eq!(d.detection.keypoints.len(), r.detection.keypoints.len());
        }
    }

    #[test]
    fn bad_requests_are_refused_with_a_reason() {
        let image = sample();
        let mut server = Server::default();
        let e = server.serve(request(&image, &[])).unwrap_err();
        assert!(e.contains("at least one family"), "{e}");
        let e = server
            .serve(request(&image, &["no-such-family"]))
            .unwrap_err();
        assert!(e.contains("no-such-family"), "{e}");
        let mut short = request(&image, &["aruco-6x6_250"]);
        short.pixels.truncate(10);
        let e = server.serve(short).unwrap_err();
        assert!(e.contains("10 bytes"), "{e}");
    }
}
