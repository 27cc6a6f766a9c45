use super::*;
use crate::detect::Detection;
use crate::eval::scenario::{ScenarioCamera, Sweep};
use crate::synth::{BackgroundKind, Truth};

fn family(name: &str) -> Family {
    crate::builtin::get(name).unwrap().unwrap()
}

/// Reads what the scene holds, as a perfect detector would, except the markers `misses`
/// rejects; its poses are turned `turn_deg` about the marker's normal.
struct Oracle {
    truth: Option<Truth>,
    misses: fn(f64) -> bool,
    turn_deg: f64,
}

impl Oracle {
    fn perfect() -> Self {
        Self {
            truth: None,
            misses: |_| false,
            turn_deg: 0.0,
        }
    }
}

impl BenchDetector for Oracle {
    fn name(&self) -> String {
        "oracle".into()
    }
    fn observe_truth(&mut self, truth: &Truth) {
        self.truth = Some(truth.clone());
    }
    fn detect(&mut self, _image: &GrayImage) -> Vec<Detection> {
        let truth = self.truth.as_ref().expect("shown the truth first");
        (truth.markers.iter())
            .filter(|m| {
                let distance = m.pose.as_ref().map_or(0.0, |p| {
                    let t = p.pose.translation_m;
                    (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt()
                });
                !(self.misses)(distance)
            })
            .map(|m| {
                let pose = m.pose.as_ref().map(|p| {
                    let mut pose = p.pose;
                    let turn = nalgebra::Rotation3::from_axis_angle(
                        &nalgebra::Vector3::z_axis(),
                        self.turn_deg.to_radians(),
                    );
                    let r = nalgebra::Matrix3::from_fn(|i, j| pose.rotation[i][j]) * turn.matrix();
                    pose.rotation = std::array::from_fn(|i| std::array::from_fn(|j| r[(i, j)]));
                    pose
                });
                Detection::plain(m.id, Quad([m.roi[0], m.roi[1], m.roi[2], m.roi[3]]), pose)
            })
            .collect()
    }
}

/// A small, quick scene: 320×240 at 70°, one marker, swept over distance.
fn scenario(scenes: u32) -> Scenario {
    let mut s = Scenario::example(0.3);
    s.camera = ScenarioCamera {
        width: 320,
        height: 240,
        focal_px: None,
        fov_deg: Some(70.0),
    };
    s.background = BackgroundKind::Plain;
    s.sweeps = vec![Sweep {
        condition: Condition::Distance,
        values: vec![0.2, 0.4, 0.8],
    }];
    s.scenes = scenes;
    s
}

fn run(scenario: Scenario, a: &mut Oracle, b: &mut Oracle) -> DesignRun {
    let families = vec![family("apriltag-36h11"), family("apriltag-xo-36h11")];
    let mut run = DesignRun::new(scenario, families).unwrap();
    while !run.finished() {
        run.step(&mut [a, b]).unwrap();
    }
    run
}

#[test]
fn a_design_that_loses_far_markers_loses_the_distance_verdict() {
    let mut far_blind = Oracle::perfect();
    far_blind.misses = |d| d > 0.6;
    let report = run(scenario(40), &mut Oracle::perfect(), &mut far_blind).report();
    let verdict = &report.verdict[0];
    assert_eq!(verdict.question, "reads farthest");
    assert_eq!(
        verdict.best.as_deref(),
        Some("apriltag-36h11"),
        "{}",
        verdict.sentence
    );
    let gap = &verdict.gaps[0];
    assert!((gap.difference - 100.0 / 3.0).abs() < 1e-9, "{gap:?}");
    assert!(gap.interval.0 > 20.0 && gap.interval.1 < 45.0, "{gap:?}");
    let far = |family: &str| {
        (report.rows.iter())
            .find(|r| r.family == family && r.value == 0.8)
            .unwrap()
            .recall
    };
    assert_eq!(
        (far("apriltag-36h11"), far("apriltag-xo-36h11")),
        (1.0, 0.0)
    );
}

#[test]
fn designs_that_read_alike_get_no_winner() {
    let report = run(scenario(10), &mut Oracle::perfect(), &mut Oracle::perfect()).report();
    let verdict = &report.verdict[0];
    assert_eq!(verdict.best, None);
    assert!(
        verdict.sentence.contains("no design measurably"),
        "{}",
        verdict.sentence
    );
}

#[test]
fn the_design_with_the_lower_rotation_error_poses_best() {
    let mut turned = Oracle::perfect();
    turned.turn_deg = 3.0;
    let report = run(scenario(10), &mut turned, &mut Oracle::perfect()).report();
    let pose = report
        .verdict
        .iter()
        .find(|v| v.question == "poses best")
        .unwrap();
    assert_eq!(
        pose.best.as_deref(),
        Some("apriltag-xo-36h11"),
        "{}",
        pose.sentence
    );
    assert_eq!(pose.markers, 30);
    assert_eq!(pose.gaps[0].difference, 100.0);
}

#[test]
fn the_csv_has_a_row_per_design_and_value_and_the_plots_a_line_per_design() {
    let report = run(scenario(4), &mut Oracle::perfect(), &mut Oracle::perfect()).report();
    let csv = report.csv();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], CSV_HEADER);
    assert_eq!(lines.len(), 1 + 2 * 3);
    assert!(
        lines[1].starts_with("apriltag-36h11,distance,0.2,4,4,4,1.0000,"),
        "{}",
        lines[1]
    );
    let plots = report.plots();
    let names: Vec<&str> = plots.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        names,
        [
            "distance-recall.svg",
            "distance-position.svg",
            "distance-rotation.svg"
        ]
    );
    assert!(plots[0].1.contains("apriltag-xo-36h11"));
}

#[test]
fn worst_cases_keep_the_misses_cut_out_around_the_marker() {
    let mut far_blind = Oracle::perfect();
    far_blind.misses = |d| d > 0.6;
    let run = run(scenario(10), &mut Oracle::perfect(), &mut far_blind);
    let misses: Vec<&WorstCase> = (run.worst_cases().iter())
        .filter(|w| w.family == 1)
        .collect();
    assert_eq!(misses.len(), WORST_KEPT);
    for w in misses {
        assert!(w.read.is_none() && w.badness().is_infinite());
        assert!(w.crop.width < 320 && w.crop.height < 240);
        assert!(w
            .truth
            .iter()
            .all(|p| p[0] >= 0.0 && p[0] < w.crop.width as f64));
    }
}

/// The browser's compare worker sends its report and worst cases to the page as JSON: a missed
/// marker (the worst kind of case) must survive the trip.
#[test]
fn a_run_with_misses_crosses_to_the_page_as_json() {
    let mut far_blind = Oracle::perfect();
    far_blind.misses = |d| d > 0.6;
    let run = run(scenario(4), &mut Oracle::perfect(), &mut far_blind);
    let sent = serde_json::to_string(&(run.report(), run.worst_cases())).unwrap();
    let (report, worst): (DesignReport, Vec<WorstCase>) = serde_json::from_str(&sent).unwrap();
    // Floats come back within a unit in the last place (serde_json's fast parsing).
    let expected = run.report();
    assert_eq!(report.verdict, expected.verdict);
    assert_eq!(report.rows.len(), expected.rows.len());
    for (got, sent) in report.rows.iter().zip(&expected.rows) {
        assert_eq!(
            (got.read, got.markers, got.recall),
            (sent.read, sent.markers, sent.recall)
        );
    }
    assert!(worst
        .iter()
        .any(|w| w.read.is_none() && w.badness().is_infinite()));
    assert_eq!(worst.len(), run.worst_cases().len());
}
