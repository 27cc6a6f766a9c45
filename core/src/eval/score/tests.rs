use super::super::set::{generate, load, run_detector, BenchImage, SetParams};
use super::*;
use crate::detect::{BenchDetector, ImageDetections};
use crate::image::GrayImage;
use crate::synth::Truth;

fn family() -> Family {
    crate::builtin::get("apriltag-16h5").unwrap().unwrap()
}

/// A small set on disk: 2 jitter poses × 3 renders and one image per noise level.
fn small_set(dir: &std::path::Path) -> BenchmarkSet {
    let params = SetParams {
        per_cell: 0,
        jitter_poses: 2,
        jitter_renders: 3,
        per_noise_level: 1,
        blur_directions: 0,
        ..SetParams::default()
    };
    generate(&family(), &params, dir).unwrap()
}

/// Reports the truth: the perfect detector.
fn oracle(img: &BenchImage, with_pose: bool) -> Vec<Detection> {
    img.truth_detections(with_pose)
}

fn detections(
    set: &BenchmarkSet,
    f: impl Fn(usize, &BenchImage) -> Vec<Detection>,
) -> DetectionsFile {
    DetectionsFile {
        detector: "fake".into(),
        images: set
            .images
            .iter()
            .enumerate()
            .map(|(i, img)| ImageDetections {
                file: img.file.clone(),
                time_ms: 1.0,
                detections: f(i, img),
                timings: None,
            })
            .collect(),
    }
}

fn all_rows(r: &Report) -> Row {
    let used: Vec<&Row> = r
        .rows
        .iter()
        .filter(|r| r.images > 0 && r.subset != "protocol, all")
        .collect();
    let sum = |f: fn(&Row) -> usize| used.iter().map(|r| f(r)).sum::<usize>();
    let (markers, dets, correct) = (
        sum(|r| r.markers),
        sum(|r| r.detections),
        sum(|r| r.correct),
    );
    Row {
        subset: "sum".into(),
        images: 0,
        markers,
        detections: dets,
        correct,
        recall: correct as f64 / markers as f64,
        precision: correct as f64 / dets.max(1) as f64,
        position_error_mm: None,
        rotation_error_deg: None,
        flips: 0,
        flip_rate: 0.0,
        time_ms: 0.0,
    }
}

#[test]
fn the_ground_truth_scores_full_recall_and_no_error() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    assert_eq!(set.images.len(), 6 + 13);
    let loaded = load(dir.path()).unwrap();
    assert_eq!(loaded.images.len(), set.images.len());
    for (a, b) in loaded.images.iter().zip(&set.images) {
        assert_eq!(
            (&a.file, a.group, a.truth.markers[0].id),
            (&b.file, b.group, b.truth.markers[0].id)
        );
        let (pa, pb) = (
            a.truth.markers[0].pose.as_ref().unwrap(),
            b.truth.markers[0].pose.as_ref().unwrap(),
        );
        assert!((0..3).all(|i| (pa.pose.translation_m[i] - pb.pose.translation_m[i]).abs() < 1e-12));
    }
    let f = family();
    for with_pose in [true, false] {
        let report = score(
            &set,
            Some(&f),
            &detections(&set, |_, img| oracle(img, with_pose)),
        )
        .unwrap();
        let sum = all_rows(&report);
        assert_eq!((sum.recall, sum.precision), (1.0, 1.0));
        for r in report.rows.iter().filter(|r| r.images > 0) {
            // From exact corners the PnP pose is exact too.
            assert!(r.position_error_mm.unwrap().mean < 1e-6, "{r:?}");
            assert!(r.rotation_error_deg.unwrap().mean < 1e-6, "{r:?}");
        }
        let j = report.jitter.unwrap();
        assert_eq!(j.poses, 2);
        assert!(j.position_std_mm < 1e-9 && j.rotation_std_deg < 1e-6);
    }
    let md = report_markdown(&set, &f);
    assert!(
        md.contains("| jitter | 6 | 6 | 100.0 % | 100.0 % |"),
        "{md}"
    );
}

fn report_markdown(set: &BenchmarkSet, f: &Family) -> String {
    score(set, Some(f), &detections(set, |_, img| oracle(img, true)))
        .unwrap()
        .markdown()
}

#[test]
fn dropping_half_the_markers_scores_half_recall() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let total: usize = set.images.iter().map(|i| i.truth.markers.len()).sum();
    let report = score(
        &set,
        Some(&family()),
        &detections(&set, |i, img| {
            if i % 2 == 0 {
                oracle(img, true)
            } else {
                vec![]
            }
        }),
    )
    .unwrap();
    let sum = all_rows(&report);
    let expected: usize = set
        .images
        .iter()
        .step_by(2)
        .map(|i| i.truth.markers.len())
        .sum();
    assert_eq!(sum.correct, expected);
    assert!((sum.recall - expected as f64 / total as f64).abs() < 1e-12);
    assert!((sum.recall - 0.5).abs() < 0.05, "{}", sum.recall);
    assert_eq!(sum.precision, 1.0);
}

#[test]
fn a_wrong_id_is_a_false_positive() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let wrong = detections(&set, |_, img| {
        oracle(img, true)
            .into_iter()
            .map(|mut d| {
                d.id = (d.id + 1) % 30;
                d
            })
            .collect()
    });
    let sum = all_rows(&score(&set, Some(&family()), &wrong).unwrap());
    assert_eq!((sum.correct, sum.recall, sum.precision), (0, 0.0, 0.0));
    assert!(sum.detections > 0);
    // A box elsewhere with the right ID is wrong too.
    let shifted = detections(&set, |_, img| {
        oracle(img, true)
            .into_iter()
            .map(|mut d| {
                d.corners.iter_mut().for_each(|c| c[0] += 400.0);
                d
            })
            .collect()
    });
    assert_eq!(
        all_rows(&score(&set, Some(&family()), &shifted).unwrap()).correct,
        0
    );
    // Detections for an image that is not in the set are refused.
    let mut stray = detections(&set, |_, _| vec![]);
    stray.images[0].file = "images/nope.png".into();
    assert!(matches!(
        score(&set, None, &stray),
        Err(EvalError::UnknownImage { file }) if file == "images/nope.png"
    ));
}

/// An in-process detector that reads the truth back from the manifest by image content.
struct Lookup(Vec<(GrayImage, Vec<Detection>)>);

impl BenchDetector for Lookup {
    fn name(&self) -> String {
        "lookup".into()
    }
    fn detect(&mut self, image: &GrayImage) -> Vec<Detection> {
        self.0
            .iter()
            .find(|(i, _)| i == image)
            .map(|(_, d)| d.clone())
            .unwrap_or_default()
    }
}

#[test]
fn in_process_detectors_run_over_the_images_on_disk() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let table = set
        .images
        .iter()
        .map(|img| {
            (
                crate::image::read(&dir.path().join(&img.file), &Default::default()).unwrap(),
                oracle(img, false),
            )
        })
        .collect();
    let file = run_detector(dir.path(), &set, &mut Lookup(table), &|_| true).unwrap();
    assert_eq!(file.images.len(), set.images.len());
    assert_eq!(
        all_rows(&score(&set, Some(&family()), &file).unwrap()).recall,
        1.0
    );
    let _: Option<Truth> = None;
}

#[test]
fn a_missing_or_broken_set_names_its_file_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("set.json");
    let e = load(dir.path()).unwrap_err();
    assert!(
        matches!(&e, EvalError::Read { path: p, .. } if *p == path),
        "{e}"
    );
    std::fs::write(&path, "{").unwrap();
    let e = load(dir.path()).unwrap_err();
    assert!(matches!(&e, EvalError::Json { .. }), "{e}");
    assert_eq!(e.to_string().matches("set.json").count(), 1, "{e}");
}

/// `pose` turned by `deg` about the marker's x axis: the other solution of a planar pose looks
/// like this, a tilt the wrong way.
fn tilted(pose: &crate::geometry::PoseJson, deg: f64) -> crate::geometry::PoseJson {
    let r = Matrix3::from_fn(|i, j| pose.rotation[i][j])
        * Rotation3::from_axis_angle(&Vector3::x_axis(), deg.to_radians()).matrix();
    crate::geometry::PoseJson {
        rotation: std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)])),
        translation_m: pose.translation_m,
    }
}

#[test]
fn a_planted_flipped_pose_shows_in_the_tail_and_the_flip_rate_not_the_median() {
    let dir = tempfile::tempdir().unwrap();
    let set = small_set(dir.path());
    let f = family();
    let file = detections(&set, |i, img| {
        let mut found = oracle(img, true);
        let d = &mut found[0];
        match i {
            // Right corners, a pose tilted the wrong way: a flip.
            0 => d.pose = Some(tilted(d.pose.as_ref().unwrap(), 30.0)),
            // The same tilt with a corner a third of the side off: a bad read, not a flip.
            1 => {
                d.pose = Some(tilted(d.pose.as_ref().unwrap(), 30.0));
                let side = crate::geometry::distance(d.corners[0], d.corners[1]);
                d.corners[2][0] += side / 3.0;
            }
            _ => {}
        }
        found
    });
    let report = score(&set, Some(&f), &file).unwrap();
    let jitter = report.rows.iter().find(|r| r.subset == "jitter").unwrap();
    assert_eq!(jitter.markers, 6);
    assert_eq!(jitter.correct, 6);
    assert_eq!(jitter.flips, 1);
    assert!((jitter.flip_rate - 1.0 / 6.0).abs() < 1e-12);
    let rotation = jitter.rotation_error_deg.unwrap();
    assert!(rotation.median < 1e-6, "{rotation:?}");
    assert!((rotation.p99 - 30.0).abs() < 1e-6, "{rotation:?}");
    let others: usize = (report.rows.iter())
        .filter(|r| r.subset != "jitter" && r.subset != "protocol, all")
        .map(|r| r.flips)
        .sum();
    assert_eq!(others, 0);
    assert!(report.markdown().contains("| 1 (16.67 %) |"));
}

#[test]
fn percentiles_are_nearest_rank() {
    let s = stats((1..=200).map(f64::from).collect()).unwrap();
    assert_eq!((s.median, s.p95, s.p99), (100.5, 190.0, 198.0));
    let one = stats(vec![7.0]).unwrap();
    assert_eq!((one.p95, one.p99), (7.0, 7.0));
}
