//! Two detectors' reads of one benchmark set, marker by marker.
//!
//! Recall figures of two detectors on the same images are paired: most markers are read by
//! both or by neither, and only the markers one reads and the other misses tell them apart.
//! On the harness's 65 Difficult markers one marker is 1.5 points, so a gap of "+3 points" is
//! two markers; this says, per subset, which markers each read alone and how far apart the two
//! recalls can plausibly be on that many markers (a 95 % interval for the paired difference).

use super::score::{outcomes, stats, MarkerRead, Outcome, Stats, SUBSETS};
use super::set::{BenchmarkSet, Group};
use super::EvalError;
use crate::detect::DetectionsFile;
use crate::family::Family;
use serde::{Deserialize, Serialize};

/// One subset's markers as two detectors read them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedRow {
    pub subset: String,
    pub markers: usize,
    pub both: usize,
    pub only_a: usize,
    pub only_b: usize,
    /// A's recall minus B's, in points.
    pub difference_points: f64,
    /// 95 % interval of that difference, in points.
    pub interval_points: (f64, f64),
    /// The markers only A read, as (image file, index in its truth).
    pub only_a_markers: Vec<(String, usize)>,
    /// The markers only B read.
    pub only_b_markers: Vec<(String, usize)>,
    /// Pose errors on the markers both read with a pose (A's, then B's): the same markers, so
    /// a detector that reads more hard ones is not charged for their poses.
    pub both_errors: Option<PairedErrors>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedErrors {
    pub markers: usize,
    pub position_mm: (Stats, Stats),
    pub rotation_deg: (Stats, Stats),
    /// Flipped poses among them (see `score::FLIP_ROTATION_DEG`), A's and B's.
    #[serde(default)]
    pub flips: (usize, usize),
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Comparison {
    pub a: String,
    pub b: String,
    pub family: String,
    /// The set's images, and how many of them A's and B's files list: an image a file leaves
    /// out counts as read by nothing.
    pub images: usize,
    pub listed: (usize, usize),
    pub rows: Vec<PairedRow>,
}

/// One detections file matched against a set's truth, marker by marker.
pub struct Reads {
    detector: String,
    listed: usize,
    outcomes: Vec<(Group, Outcome)>,
}

impl Reads {
    /// Fails as `eval score` would on this file, so a caller can name the file that failed.
    pub fn of(
        set: &BenchmarkSet,
        family: Option<&Family>,
        detections: &DetectionsFile,
    ) -> Result<Self, EvalError> {
        Ok(Reads {
            detector: detections.detector.clone(),
            listed: detections.images.len(),
            outcomes: outcomes(set, family, detections)?,
        })
    }
}

/// Two files' reads of `set` (each from [`Reads::of`] on it), subset by subset (those with
/// markers).
pub fn compare(set: &BenchmarkSet, a: &Reads, b: &Reads) -> Comparison {
    let rows = SUBSETS
        .iter()
        .filter_map(|&(name, holds)| paired_row(set, a, b, name, holds))
        .collect();
    Comparison {
        a: a.detector.clone(),
        b: b.detector.clone(),
        family: set.family.clone(),
        images: set.images.len(),
        listed: (a.listed, b.listed),
        rows,
    }
}

/// One subset's row, `None` when it holds no marker.
fn paired_row(
    set: &BenchmarkSet,
    a: &Reads,
    b: &Reads,
    name: &str,
    holds: fn(&Group) -> bool,
) -> Option<PairedRow> {
    let mut row = PairedRow {
        subset: name.to_string(),
        markers: 0,
        both: 0,
        only_a: 0,
        only_b: 0,
        difference_points: 0.0,
        interval_points: (0.0, 0.0),
        only_a_markers: Vec::new(),
        only_b_markers: Vec::new(),
        both_errors: None,
    };
    // A's and B's reads of each marker both read with a pose.
    let mut errors: Vec<[MarkerRead; 2]> = Vec::new();
    let images = set.images.iter().zip(&a.outcomes).zip(&b.outcomes);
    for ((image, (group, oa)), (_, ob)) in images {
        if !holds(group) {
            continue;
        }
        for (k, (&ra, &rb)) in oa.read.iter().zip(&ob.read).enumerate() {
            row.markers += 1;
            match (ra, rb) {
                (Some(ea), Some(eb)) => {
                    row.both += 1;
                    let finite =
                        |r: &MarkerRead| r.position_m.is_finite() && r.rotation_deg.is_finite();
                    if finite(&ea) && finite(&eb) {
                        errors.push([ea, eb]);
                    }
                }
                (Some(_), None) => row.only_a_markers.push((image.file.clone(), k)),
                (None, Some(_)) => row.only_b_markers.push((image.file.clone(), k)),
                (None, None) => {}
            }
        }
    }
    if row.markers == 0 {
        return None;
    }
    row.only_a = row.only_a_markers.len();
    row.only_b = row.only_b_markers.len();
    let neither = row.markers - row.both - row.only_a - row.only_b;
    let (difference, low, high) = paired_difference(row.both, row.only_a, row.only_b, neither);
    row.difference_points = 100.0 * difference;
    row.interval_points = (100.0 * low, 100.0 * high);
    row.both_errors = paired_errors(&errors);
    Some(row)
}

/// Both detectors' pose errors over the same markers; `None` without any.
fn paired_errors(errors: &[[MarkerRead; 2]]) -> Option<PairedErrors> {
    let of = |side: usize, mm: bool| {
        stats(
            errors
                .iter()
                .map(|e| {
                    let r = &e[side];
                    if mm {
                        1000.0 * r.position_m
                    } else {
                        r.rotation_deg
                    }
                })
                .collect(),
        )
    };
    let flips = |side: usize| errors.iter().filter(|e| e[side].flipped).count();
    Some(PairedErrors {
        markers: errors.len(),
        position_mm: (of(0, true)?, of(1, true)?),
        rotation_deg: (of(0, false)?, of(1, false)?),
        flips: (flips(0), flips(1)),
    })
}

/// The normal quantile of a two-sided 95 % interval.
const Z_95: f64 = 1.959_963_984_540_054;

/// Wilson's score interval of a proportion `k / n` (95 %).
pub(super) fn wilson(k: usize, n: usize) -> (f64, f64) {
    let (k, n) = (k as f64, n as f64);
    let p = k / n;
    let z2 = Z_95 * Z_95;
    let scale = 1.0 + z2 / n;
    let centre = (p + z2 / (2.0 * n)) / scale;
    let half = Z_95 * (p * (1.0 - p) / n + z2 / (4.0 * n * n)).sqrt() / scale;
    (centre - half, centre + half)
}

/// Paired recall difference A − B with its 95 % interval, from the counts of markers both,
/// only A, only B and neither read: Newcombe's (1998) hybrid score interval for paired
/// proportions (his method 10; Fagerland, Lydersen and Laake 2014 recommend it), which
/// combines the two recalls' Wilson intervals through their correlation. Unlike the Wald
/// interval it stays sensible with few discordant markers (the usual case here).
pub fn paired_difference(
    both: usize,
    only_a: usize,
    only_b: usize,
    neither: usize,
) -> (f64, f64, f64) {
    let n = both + only_a + only_b + neither;
    if n == 0 {
        return (0.0, 0.0, 0.0);
    }
    let (a_read, b_read) = (both + only_a, both + only_b);
    let (pa, pb) = (a_read as f64 / n as f64, b_read as f64 / n as f64);
    let ((la, ua), (lb, ub)) = (wilson(a_read, n), wilson(b_read, n));
    // The two recalls' correlation (phi of the 2×2 table), with Newcombe's continuity
    // correction of a positive association.
    let margins = [a_read, n - a_read, b_read, n - b_read];
    let phi = if margins.contains(&0) {
        0.0
    } else {
        let cross = both as f64 * neither as f64 - only_a as f64 * only_b as f64;
        let half_n = n as f64 / 2.0;
        let corrected = if cross > half_n {
            cross - half_n
        } else if cross >= 0.0 {
            0.0
        } else {
            cross
        };
        corrected / margins.iter().map(|&m| m as f64).product::<f64>().sqrt()
    };
    let spread = |x: f64, y: f64| (x * x - 2.0 * phi * x * y + y * y).max(0.0).sqrt();
    let d = pa - pb;
    (
        d,
        (d - spread(pa - la, ub - pb)).max(-1.0),
        (d + spread(ua - pa, pb - lb)).min(1.0),
    )
}

impl Comparison {
    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# A vs B on {}: the same markers\n\nA: {}. B: {}.\n\n",
            self.family, self.a, self.b
        );
        // A file of another set with the same image names, or of a run cut short, pairs
        // without an error; its missing images would read as the other detector's lead.
        for (who, listed) in [("A", self.listed.0), ("B", self.listed.1)] {
            if listed < self.images {
                s += &format!(
                    "**{who}'s file lists {listed} of the set's {} images**: the others count as \
                     read by nothing.\n\n",
                    self.images
                );
            }
        }
        s += "| subset | markers | A | B | only A | only B | A − B (points) | 95 % interval |\n";
        s += "|---|---|---|---|---|---|---|---|\n";
        for r in &self.rows {
            let recall = |only: usize| 100.0 * (r.both + only) as f64 / r.markers as f64;
            s += &format!(
                "| {} | {} | {:.1} % | {:.1} % | {} | {} | {:+.1} | {:+.1} to {:+.1} |\n",
                r.subset,
                r.markers,
                recall(r.only_a),
                recall(r.only_b),
                r.only_a,
                r.only_b,
                r.difference_points,
                r.interval_points.0,
                r.interval_points.1
            );
        }
        s += "\nThe interval (Newcombe's hybrid score interval for paired proportions) holds the \
              differences these markers cannot tell from the one measured; one marker is \
              100 / markers points.\n";
        if self.rows.iter().any(|r| r.both_errors.is_some()) {
            s += "\nPose errors on the markers both read, mean / median / p95 / p99, and flipped \
                  poses (A | B):\n\n";
            s += "| subset | markers | position mm A | position mm B | rotation ° A | rotation ° B | flips A | flips B |\n";
            s += "|---|---|---|---|---|---|---|---|\n";
            for r in &self.rows {
                if let Some(e) = &r.both_errors {
                    s += &format!(
                        "| {} | {} | {} | {} | {} | {} | {} | {} |\n",
                        r.subset,
                        e.markers,
                        e.position_mm.0.columns(),
                        e.position_mm.1.columns(),
                        e.rotation_deg.0.columns(),
                        e.rotation_deg.1.columns(),
                        e.flips.0,
                        e.flips.1
                    );
                }
            }
        }
        for r in &self.rows {
            if r.subset == "protocol, all" {
                continue;
            }
            for (who, list) in [("A", &r.only_a_markers), ("B", &r.only_b_markers)] {
                if !list.is_empty() {
                    let names: Vec<String> =
                        list.iter().map(|(f, k)| format!("{f} #{k}")).collect();
                    s += &format!("\n{}, read by {who} only: {}\n", r.subset, names.join(", "));
                }
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(x: (f64, f64, f64), want: (f64, f64, f64)) -> bool {
        (x.0 - want.0).abs() < 5e-4 && (x.1 - want.1).abs() < 5e-4 && (x.2 - want.2).abs() < 5e-4
    }

    #[test]
    fn markers_one_detector_misses_or_misreads_are_counted_against_it_alone() {
        use crate::detect::ImageDetections;
        use crate::eval::set::{generate, SetParams};
        let dir = tempfile::tempdir().unwrap();
        let family = crate::builtin::get("apriltag-16h5").unwrap().unwrap();
        let params = SetParams {
            per_cell: 0,
            jitter_poses: 0,
            per_noise_level: 1,
            blur_directions: 0,
            ..SetParams::default()
        };
        let set = generate(&family, &params, dir.path()).unwrap();
        let file = |name: &str, skip: usize, wrong_id_in: usize, shift_px: f64| DetectionsFile {
            detector: name.into(),
            images: set
                .images
                .iter()
                .enumerate()
                .map(|(i, img)| {
                    let mut detections = img.truth_detections(false);
                    if i == skip {
                        detections.clear();
                    }
                    if i == wrong_id_in {
                        detections[0].id += 1;
                    }
                    for d in &mut detections {
                        d.corners[0][0] += shift_px;
                    }
                    ImageDetections {
                        file: img.file.clone(),
                        time_ms: 1.0,
                        detections,
                        timings: None,
                    }
                })
                .collect(),
        };
        // B also places one corner of each marker 2 px off.
        let (a, b) = (file("A", usize::MAX, usize::MAX, 0.0), file("B", 0, 2, 2.0));
        let reads = |f: &DetectionsFile| Reads::of(&set, Some(&family), f).unwrap();
        let c = compare(&set, &reads(&a), &reads(&b));
        let noise = c.rows.iter().find(|r| r.subset == "noise sweep").unwrap();
        let markers: usize = set.images.iter().map(|i| i.truth.markers.len()).sum();
        let in_0 = set.images[0].truth.markers.len();
        assert_eq!(noise.markers, markers);
        assert_eq!((noise.only_a, noise.only_b), (in_0 + 1, 0));
        assert_eq!(noise.both, markers - in_0 - 1);
        assert_eq!(noise.only_a_markers[0], (set.images[0].file.clone(), 0));
        assert!(noise.difference_points > 0.0 && noise.interval_points.0 < 0.0);
        let poses = noise.both_errors.as_ref().unwrap();
        assert_eq!(poses.markers, noise.both);
        assert!(poses.position_mm.0.median < 0.05, "{poses:?}");
        assert!(poses.position_mm.1.median > 2.0 * poses.position_mm.0.median + 0.05);
        let md = c.markdown();
        assert!(
            md.contains("read by A only") && md.contains(&set.images[2].file),
            "{md}"
        );
        assert!(md.contains("Pose errors on the markers both read"), "{md}");
        assert!(!md.contains("file lists"), "{md}");
        let mut short = b.clone();
        short.images.pop();
        let md = compare(&set, &reads(&a), &reads(&short)).markdown();
        let listed = format!(
            "B's file lists {} of the set's {}",
            set.images.len() - 1,
            set.images.len()
        );
        assert!(md.contains(&listed), "{md}");
    }

    #[test]
    fn the_interval_matches_the_published_examples() {
        // Newcombe (1998), the paired example with 36 / 12 / 2 / 0: 0.2000 (0.0569, 0.3404).
        let got = paired_difference(36, 12, 2, 0);
        assert!(close(got, (0.2, 0.0569, 0.3404)), "{got:?}");
        // Fagerland et al. (2014), airway hyper-responsiveness (Bentur et al. 2009), 1 / 1 / 7
        // / 12: −0.2857 (−0.5069, −0.0256).
        let got = paired_difference(1, 1, 7, 12);
        assert!(close(got, (-0.2857, -0.5069, -0.0256)), "{got:?}");
    }

    #[test]
    fn one_marker_apart_in_65_cannot_show_3_points_but_16_to_2_in_325_can() {
        // The harness's Difficult row: 63 read by both, 1 by A alone, 1 by neither.
        // ad − bc = 63 > n / 2: the only case Newcombe's continuity correction of phi changes.
        let got = paired_difference(63, 1, 0, 1);
        assert!(close(got, (1.0 / 65.0, -0.0474, 0.0867)), "{got:?}");
        // Five times the markers and the same kind of lead.
        let (d, low, _) = paired_difference(305, 16, 2, 2);
        assert!(d > 0.04 && low > 0.0, "{d} from {low}");
    }

    #[test]
    fn equal_reads_give_an_interval_around_zero_within_the_range() {
        let (d, low, high) = paired_difference(10, 0, 0, 0);
        assert_eq!(d, 0.0);
        assert!(low < 0.0 && high > 0.0);
        let (d, low, high) = paired_difference(0, 5, 0, 0);
        assert_eq!(d, 1.0);
        // Each recall's Wilson interval on 5 markers reaches 0.43 from its end.
        assert!(
            (low - 0.3855).abs() < 1e-3 && high == 1.0,
            "({low}, {high})"
        );
    }
}
