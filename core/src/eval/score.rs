//! Scoring detections against a benchmark set: a detection is correct when its box overlaps the
//! true marker's ROI box with IoU ≥ 0.5 and its ID is right; everything else is a false positive.
//! Poses are compared in OpenCV ArUco's marker frame; a detection without a pose gets one from its
//! four corners through the set's camera (the same PnP for every detector).

use super::scenario::Condition;
use super::set::{normalise_path, BenchmarkSet, Group};
use super::EvalError;
use crate::detect::{Detection, DetectionsFile};
use crate::family::Family;
use crate::geometry::{bounding_box, Quad};
use crate::pose::{marker_plane_points, solve_planar, Pose};
use crate::synth::MarkerTruth;
use nalgebra::{Matrix3, Rotation3, Vector3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::Path;

/// An error's distribution: its centre and its tail (a user who steers by the pose cares about
/// the worst reads in a hundred, not the typical one).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    pub mean: f64,
    pub median: f64,
    /// 95th and 99th percentiles (nearest rank). Reports written before they existed read as NaN.
    #[serde(default = "not_reported")]
    pub p95: f64,
    #[serde(default = "not_reported")]
    pub p99: f64,
}

fn not_reported() -> f64 {
    f64::NAN
}

pub(super) fn stats(mut v: Vec<f64>) -> Option<Stats> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let median = if v.len() % 2 == 1 {
        v[v.len() / 2]
    } else {
        (v[v.len() / 2 - 1] + v[v.len() / 2]) / 2.0
    };
    let rank = |p: f64| v[((p * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
    Some(Stats {
        mean: v.iter().sum::<f64>() / v.len() as f64,
        median,
        p95: rank(0.95),
        p99: rank(0.99),
    })
}

impl Stats {
    /// "mean / median / p95 / p99", as the reports' tables print it.
    pub fn columns(&self) -> String {
        format!(
            "{:.3} / {:.3} / {:.3} / {:.3}",
            self.mean, self.median, self.p95, self.p99
        )
    }
}

/// A pose is flipped when its rotation is this far off (degrees) although the marker's corners
/// were found where they are: the planar pose ambiguity chose the wrong solution, which a robot
/// steering by the pose feels as a jump, not as noise.
pub const FLIP_ROTATION_DEG: f64 = 10.0;
/// Corners count as found where they are within this share of the true marker's mean side.
pub const FLIP_CORNER_SHARE: f64 = 0.1;

/// Scores of one subset of images.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub subset: String,
    pub images: usize,
    pub markers: usize,
    pub detections: usize,
    pub correct: usize,
    pub recall: f64,
    pub precision: f64,
    pub position_error_mm: Option<Stats>,
    pub rotation_error_deg: Option<Stats>,
    /// Correct reads with a pose whose rotation is flipped (see [`FLIP_ROTATION_DEG`]), and
    /// their share of the correct reads with a pose.
    #[serde(default)]
    pub flips: usize,
    #[serde(default)]
    pub flip_rate: f64,
    pub time_ms: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurvePoint {
    pub x: f64,
    pub recall: f64,
    pub position_error_mm: Option<f64>,
    pub rotation_error_deg: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Curve {
    pub name: String,
    pub x_label: String,
    pub points: Vec<CurvePoint>,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Jitter {
    /// Poses with at least two detections.
    pub poses: usize,
    /// Mean over poses of the standard deviation of the position (mm) and rotation (deg).
    pub position_std_mm: f64,
    pub rotation_std_deg: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub detector: String,
    pub family: String,
    pub rows: Vec<Row>,
    pub curves: Vec<Curve>,
    pub jitter: Option<Jitter>,
}

/// One image's outcome.
pub(super) struct Outcome {
    pub(super) detections: usize,
    /// Each truth marker, in the set's order: its correct detection, if any.
    pub(super) read: Vec<Option<MarkerRead>>,
    pub(super) time_ms: f64,
}

/// A truth marker's correct detection.
#[derive(Clone, Copy)]
pub(super) struct MarkerRead {
    /// Position (m) and rotation (deg) error of its pose; NaN without one.
    pub(super) position_m: f64,
    pub(super) rotation_deg: f64,
    /// The rotation is flipped though the corners are right.
    pub(super) flipped: bool,
    pub(super) pose: Option<Pose>,
    /// Where the detector put the marker's corners.
    pub(super) corners: Quad,
}

fn iou(a: [f64; 4], b: [f64; 4]) -> f64 {
    let w = (a[2].min(b[2]) - a[0].max(b[0])).max(0.0);
    let h = (a[3].min(b[3]) - a[1].max(b[1])).max(0.0);
    let inter = w * h;
    let area = |r: [f64; 4]| (r[2] - r[0]) * (r[3] - r[1]);
    let union = area(a) + area(b) - inter;
    if union > 0.0 {
        inter / union
    } else {
        0.0
    }
}

/// One image's truth against its detections; poses solved from corners use `camera` and a
/// marker of side `side_m`.
pub(super) fn judge(
    camera: &crate::geometry::Camera,
    side_m: f64,
    family: Option<&Family>,
    truth: &[MarkerTruth],
    detections: &[Detection],
    time_ms: f64,
) -> Outcome {
    let mut read: Vec<Option<MarkerRead>> = vec![None; truth.len()];
    for d in detections {
        if !d.corners.iter().flatten().all(|v| v.is_finite()) {
            continue;
        }
        let boxed = d.corners.bounding_box();
        let hit = truth.iter().enumerate().find(|(i, t)| {
            read[*i].is_none() && t.id == d.id && iou(boxed, bounding_box(&t.roi[..4])) >= 0.5
        });
        let Some((i, t)) = hit else { continue };
        let detected = d.pose.as_ref().map(Pose::from).or_else(|| {
            let f = family?;
            let object = marker_plane_points(f, side_m, &f.roi_points()[..4]);
            solve_planar(camera, &object, &d.corners[..])
                .ok()
                .map(|s| s.pose)
        });
        let (position_m, rotation_deg) = match (detected, &t.pose) {
            (Some(p), Some(tp)) => {
                let truth_pose = Pose::from(&tp.pose);
                (
                    p.position_error(&truth_pose),
                    p.rotation_error_deg(&truth_pose),
                )
            }
            _ => (f64::NAN, f64::NAN),
        };
        let truth_corners = &t.roi[..4];
        let side = (0..4)
            .map(|k| crate::geometry::distance(truth_corners[k], truth_corners[(k + 1) % 4]))
            .sum::<f64>()
            / 4.0;
        let corners_right = (d.corners.iter().zip(truth_corners))
            .all(|(&p, &q)| crate::geometry::distance(p, q) <= FLIP_CORNER_SHARE * side);
        read[i] = Some(MarkerRead {
            position_m,
            rotation_deg,
            flipped: corners_right && rotation_deg > FLIP_ROTATION_DEG,
            pose: detected,
            corners: d.corners,
        });
    }
    Outcome {
        detections: detections.len(),
        read,
        time_ms,
    }
}

pub(super) fn row(subset: &str, outcomes: &[&Outcome]) -> Row {
    let markers: usize = outcomes.iter().map(|o| o.read.len()).sum();
    let detections: usize = outcomes.iter().map(|o| o.detections).sum();
    let correct: usize = outcomes
        .iter()
        .map(|o| o.read.iter().flatten().count())
        .sum();
    let finite = |f: fn(&MarkerRead) -> f64| -> Vec<f64> {
        outcomes
            .iter()
            .flat_map(|o| o.read.iter().flatten().map(f))
            .filter(|v| v.is_finite())
            .collect()
    };
    let rotations = finite(|r| r.rotation_deg);
    let flips = (outcomes.iter())
        .flat_map(|o| o.read.iter().flatten())
        .filter(|r| r.flipped)
        .count();
    Row {
        subset: subset.to_string(),
        images: outcomes.len(),
        markers,
        detections,
        correct,
        recall: if markers > 0 {
            correct as f64 / markers as f64
        } else {
            0.0
        },
        precision: if detections > 0 {
            correct as f64 / detections as f64
        } else {
            1.0
        },
        position_error_mm: stats(finite(|r| r.position_m * 1000.0)),
        flips,
        flip_rate: flips as f64 / rotations.len().max(1) as f64,
        rotation_error_deg: stats(rotations),
        time_ms: outcomes.iter().map(|o| o.time_ms).sum::<f64>() / outcomes.len().max(1) as f64,
    }
}

fn curve(name: &str, x_label: &str, groups: Vec<(f64, Vec<&Outcome>)>) -> Curve {
    Curve {
        name: name.into(),
        x_label: x_label.into(),
        points: groups
            .into_iter()
            .map(|(x, o)| {
                let r = row("", &o);
                CurvePoint {
                    x,
                    recall: r.recall,
                    position_error_mm: r.position_error_mm.map(|s| s.mean),
                    rotation_error_deg: r.rotation_error_deg.map(|s| s.mean),
                }
            })
            .collect(),
    }
}

/// Groups outcomes by a key, in ascending key order.
fn by<K: Copy + PartialOrd + Into<f64>>(
    items: &[(Group, Outcome)],
    key: impl Fn(&Group) -> Option<K>,
) -> Vec<(f64, Vec<&Outcome>)> {
    let mut out: Vec<(f64, Vec<&Outcome>)> = Vec::new();
    for (g, o) in items {
        if let Some(k) = key(g) {
            let k: f64 = k.into();
            match out.iter_mut().find(|(x, _)| *x == k) {
                Some((_, v)) => v.push(o),
                None => out.push((k, vec![o])),
            }
        }
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// Two entries of a detections file for one image: the later one would silently replace the
/// earlier.
fn listed_twice(detections: &DetectionsFile, first: usize, second: usize) -> EvalError {
    let (a, b) = (
        &detections.images[first].file,
        &detections.images[second].file,
    );
    let message = if a == b {
        format!("{b:?} is listed twice")
    } else {
        format!("{b:?} is listed twice: images[{first}].file {a:?} is the same image")
    };
    EvalError::BadDetections {
        field: format!("images[{second}].file"),
        message,
    }
}

/// What scoring relies on in a detections file: each image listed once, under any spelling of
/// its path (a second list for the same image was silently dropped), and each pose's rotation a
/// rotation (a zero matrix scored as a finite error).
fn check_detections(detections: &DetectionsFile) -> Result<(), EvalError> {
    let bad = |field: String, message: String| EvalError::BadDetections { field, message };
    let mut seen = HashMap::new();
    for (i, img) in detections.images.iter().enumerate() {
        if let Some(first) = seen.insert(normalise_path(&img.file), i) {
            return Err(listed_twice(detections, first, i));
        }
        for (j, d) in img.detections.iter().enumerate() {
            let Some(pose) = &d.pose else { continue };
            let field = format!("images[{i}].detections[{j}].pose");
            let r = Matrix3::from_fn(|row, col| pose.rotation[row][col]);
            // Loose enough for rotations written with a few decimals.
            let orthonormal = (r.transpose() * r - Matrix3::identity()).amax() < 1e-3;
            if !(orthonormal && (r.determinant() - 1.0).abs() < 1e-3) {
                return Err(bad(
                    format!("{field}.rotation"),
                    "is not a rotation matrix (orthonormal, determinant 1)".into(),
                ));
            }
            if !pose.translation_m.iter().all(|v| v.is_finite()) {
                return Err(bad(
                    format!("{field}.translation_m"),
                    "must be finite numbers".into(),
                ));
            }
        }
    }
    Ok(())
}

/// A report row: its name and which images it holds.
pub(super) type Subset = (&'static str, fn(&Group) -> bool);

/// The rows every report (and every comparison) has, in order.
pub(super) const SUBSETS: [Subset; 7] = [
    ("normal (≤ 50 cm, ≤ 60°)", |g| {
        matches!(g, Group::Protocol { normal: true, .. })
    }),
    ("difficult", |g| {
        matches!(g, Group::Protocol { normal: false, .. })
    }),
    ("protocol, all", |g| matches!(g, Group::Protocol { .. })),
    ("jitter", |g| matches!(g, Group::Jitter { .. })),
    ("noise sweep", |g| matches!(g, Group::Noise { .. })),
    ("motion-blur sweep", |g| {
        matches!(g, Group::MotionBlur { .. })
    }),
    ("scenario", |g| matches!(g, Group::Scenario { .. })),
];

/// Each set image's group and what the detections file found in it, in the set's order.
pub(super) fn outcomes(
    set: &BenchmarkSet,
    family: Option<&Family>,
    detections: &DetectionsFile,
) -> Result<Vec<(Group, Outcome)>, EvalError> {
    check_detections(detections)?;
    // `tagsmith detect SET/images/*.png --json` names images by the path it was given; an entry
    // counts for the set image whose path (relative to the set) it ends with.
    let mut by_name: HashMap<&str, Vec<&str>> = HashMap::new();
    for img in &set.images {
        let name = Path::new(&img.file)
            .file_name()
            .and_then(|n| n.to_str())
            .unwrap_or(&img.file);
        by_name.entry(name).or_default().push(img.file.as_str());
    }
    // Compared as spelled one way (`./images//000001.png` is `images/000001.png`).
    let resolve = |file: &str| -> Option<&str> {
        let normal = normalise_path(file);
        let path = Path::new(&normal);
        let name = path.file_name()?.to_str()?;
        by_name
            .get(name)?
            .iter()
            .copied()
            .find(|s| *s == file || path.ends_with(normalise_path(s)))
    };
    let mut by_file: HashMap<&str, (usize, &crate::detect::ImageDetections)> = HashMap::new();
    for (k, i) in detections.images.iter().enumerate() {
        let file = resolve(&i.file).ok_or_else(|| EvalError::UnknownImage {
            file: i.file.clone(),
        })?;
        // Two spellings that name one set image (a relative path and one through the set's
        // folder): the later would silently win.
        if let Some((first, _)) = by_file.insert(file, (k, i)) {
            return Err(listed_twice(detections, first, k));
        }
    }
    Ok(set
        .images
        .iter()
        .map(|img| {
            let found = by_file.get(img.file.as_str()).map(|(_, f)| *f);
            let dets = found.map_or(&[][..], |f| &f.detections[..]);
            (
                img.group,
                judge(
                    &set.camera,
                    set.side_m,
                    family,
                    &img.truth.markers,
                    dets,
                    found.map_or(0.0, |f| f.time_ms),
                ),
            )
        })
        .collect())
}

pub fn score(
    set: &BenchmarkSet,
    family: Option<&Family>,
    detections: &DetectionsFile,
) -> Result<Report, EvalError> {
    let items = outcomes(set, family, detections)?;
    let rows = SUBSETS
        .iter()
        .map(|(name, holds)| {
            let selected: Vec<&Outcome> = items
                .iter()
                .filter(|(g, _)| holds(g))
                .map(|(_, o)| o)
                .collect();
            row(name, &selected)
        })
        .collect();
    let mut curves = vec![
        curve(
            "recall and error vs distance",
            "distance (cm)",
            by(&items, |g| match g {
                Group::Protocol { distance_cm, .. } => Some(*distance_cm),
                _ => None,
            }),
        ),
        curve(
            "recall and error vs view angle",
            "view angle (deg)",
            by(&items, |g| match g {
                Group::Protocol { angle_deg, .. } => Some(*angle_deg),
                _ => None,
            }),
        ),
        curve(
            "recall vs Gaussian noise",
            "noise sigma (gray levels)",
            by(&items, |g| match g {
                Group::Noise { sigma } => Some(*sigma),
                _ => None,
            }),
        ),
        curve(
            "recall vs motion blur",
            "kernel length (px)",
            by(&items, |g| match g {
                Group::MotionBlur { length, .. } => Some(*length),
                _ => None,
            }),
        ),
    ];
    for condition in Condition::ALL {
        let points = by(&items, |g| match g {
            Group::Scenario {
                condition: Some(c),
                value,
            } if *c == condition => Some(*value),
            _ => None,
        });
        if !points.is_empty() {
            let name = format!("recall and error vs {}", condition.name());
            curves.push(curve(&name, condition.label(), points));
        }
    }
    Ok(Report {
        detector: detections.detector.clone(),
        family: set.family.clone(),
        rows,
        curves,
        jitter: jitter(&items),
    })
}

fn jitter(items: &[(Group, Outcome)]) -> Option<Jitter> {
    let mut groups: HashMap<u32, Vec<Pose>> = HashMap::new();
    for (g, o) in items {
        if let Group::Jitter { pose } = g {
            groups
                .entry(*pose)
                .or_default()
                .extend(o.read.iter().flatten().filter_map(|r| r.pose));
        }
    }
    let (mut pos, mut rot, mut n) = (0.0, 0.0, 0);
    for poses in groups.values().filter(|p| p.len() >= 2) {
        let k = poses.len() as f64;
        let mean_t = poses.iter().map(|p| p.translation).sum::<Vector3<f64>>() / k;
        // The rotation nearest to the mean matrix (chordal mean).
        let sum: Matrix3<f64> = poses.iter().map(|p| *p.rotation.matrix()).sum();
        // Capped, as every SVD here: a group whose mean does not decompose is left out.
        let Ok(svd) = crate::geometry::svd_capped(sum, true, true, "mean rotation (SVD)") else {
            continue;
        };
        let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
            continue;
        };
        let mut r = u * v_t;
        if r.determinant() < 0.0 {
            r = -r;
        }
        let mean_r = Pose {
            rotation: Rotation3::from_matrix_unchecked(r),
            translation: mean_t,
        };
        pos += (poses
            .iter()
            .map(|p| (p.translation - mean_t).norm_squared())
            .sum::<f64>()
            / k)
            .sqrt()
            * 1000.0;
        rot += (poses
            .iter()
            .map(|p| p.rotation_error_deg(&mean_r).powi(2))
            .sum::<f64>()
            / k)
            .sqrt();
        n += 1;
    }
    (n > 0).then(|| Jitter {
        poses: n,
        position_std_mm: pos / n as f64,
        rotation_std_deg: rot / n as f64,
    })
}

impl Report {
    pub fn markdown(&self) -> String {
        let mut s = format!("# {} on {}\n\n", self.detector, self.family);
        s += "| subset | images | markers | recall | precision | position error mm (mean / median / p95 / p99) | rotation error ° (mean / median / p95 / p99) | flipped poses | time/image ms |\n";
        s += "|---|---|---|---|---|---|---|---|---|\n";
        let fmt = |st: &Option<Stats>| st.map_or("–".to_string(), |st| st.columns());
        for r in &self.rows {
            if r.images == 0 {
                continue;
            }
            s += &format!(
                "| {} | {} | {} | {:.1} % | {:.1} % | {} | {} | {} ({:.2} %) | {:.1} |\n",
                r.subset,
                r.images,
                r.markers,
                100.0 * r.recall,
                100.0 * r.precision,
                fmt(&r.position_error_mm),
                fmt(&r.rotation_error_deg),
                r.flips,
                100.0 * r.flip_rate,
                r.time_ms
            );
        }
        s += &format!(
            "\nA flipped pose: rotation off by more than {FLIP_ROTATION_DEG}° with every corner \
             within {:.0} % of the marker's side of where it is.\n",
            100.0 * FLIP_CORNER_SHARE
        );
        if let Some(j) = &self.jitter {
            s += &format!(
                "\nJitter over {} poses: position STD {:.4} mm, rotation STD {:.4}°.\n",
                j.poses, j.position_std_mm, j.rotation_std_deg
            );
        }
        for c in &self.curves {
            if c.points.is_empty() {
                continue;
            }
            s += &format!("\n**{}** — {}: ", c.name, c.x_label);
            let parts: Vec<String> = c
                .points
                .iter()
                .map(|p| format!("{}: {:.0} %", p.x, 100.0 * p.recall))
                .collect();
            s += &parts.join(", ");
            s += "\n";
        }
        s
    }

    /// One SVG line chart per curve (recall, 0–100 %).
    pub fn plots(&self) -> Vec<(String, String)> {
        self.curves
            .iter()
            .filter(|c| !c.points.is_empty())
            .map(|c| {
                let name = c
                    .name
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .join("-")
                    .replace(['(', ')'], "");
                let points: Vec<(f64, f64)> =
                    c.points.iter().map(|p| (p.x, 100.0 * p.recall)).collect();
                (
                    format!("{name}.svg"),
                    super::plot::line_chart(&c.name, &c.x_label, "recall (%)", &points, 100.0),
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests;
