//! Designs compared under one scenario: every family sees the same scenes (same poses, light
//! and noise: [`crate::synth::SynthConfig::shared_scene`]), its detector reads them, and the
//! reads are scored per swept value and paired marker by marker across families, so that a
//! verdict ("X reads farthest") carries the 95 % interval of the paired difference and a gap
//! within noise is called one.
//!
//! The run goes one scene at a time ([`DesignRun::step`]) so that a panel can show the curves
//! filling in and cancel between scenes; the CLI steps it to the end.

use super::compare::{paired_difference, wilson};
use super::plot::{chart, Series};
use super::scenario::{BadField, Condition, Scenario, Scene};
use super::score::{judge, row, stats, Outcome, Stats};
use super::set::Group;
use crate::detect::BenchDetector;
use crate::family::Family;
use crate::geometry::{Camera, Quad};
use crate::image::GrayImage;
use crate::synth::{synthesize, SynthError};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Worst reads kept per family for the panel's thumbnails.
pub const WORST_KEPT: usize = 4;

/// A marker read badly or not at all, cut out of its scene.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct WorstCase {
    pub family: usize,
    pub scene: usize,
    pub group: Group,
    /// The scene around the marker, and the corners in its pixels.
    pub crop: GrayImage,
    pub truth: Quad,
    pub read: Option<Quad>,
    /// Rotation error of the read, degrees, when it has a pose.
    pub rotation_deg: Option<f64>,
}

impl WorstCase {
    /// How it ranks: infinite when missed, else the rotation error (0 without a pose). Derived,
    /// not stored: an infinite float has no JSON form, and the case crosses to the page as JSON.
    pub fn badness(&self) -> f64 {
        badness(self.read.is_some(), self.rotation_deg)
    }
}

fn badness(read: bool, rotation_deg: Option<f64>) -> f64 {
    if read {
        rotation_deg.unwrap_or(0.0)
    } else {
        f64::INFINITY
    }
}

/// A scenario's scenes, read by each family's detector as far as the run has got.
pub struct DesignRun {
    scenario: Scenario,
    families: Vec<Family>,
    scenes: Vec<Scene>,
    camera: Camera,
    /// Per family, per scene read so far.
    outcomes: Vec<Vec<Outcome>>,
    worst: Vec<WorstCase>,
}

impl DesignRun {
    /// A run of `families` (2 or more, named apart) under a checked `scenario`.
    pub fn new(scenario: Scenario, families: Vec<Family>) -> Result<Self, BadField> {
        scenario.validate()?;
        if families.len() < 2 {
            return Err(BadField {
                field: "families".into(),
                message: format!("{} given; compare at least 2", families.len()),
            });
        }
        for (i, f) in families.iter().enumerate() {
            if families[..i].iter().any(|g| g.name() == f.name()) {
                return Err(BadField {
                    field: "families".into(),
                    message: format!("{} is given twice", f.name()),
                });
            }
        }
        let scenes = scenario.scenes();
        Ok(Self {
            camera: scenario.camera(),
            outcomes: families.iter().map(|_| Vec::new()).collect(),
            scenario,
            families,
            scenes,
            worst: Vec::new(),
        })
    }

    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    pub fn families(&self) -> &[Family] {
        &self.families
    }

    /// Scenes in the run, and scenes read so far.
    pub fn len(&self) -> usize {
        self.scenes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.scenes.is_empty()
    }

    pub fn done(&self) -> usize {
        self.outcomes[0].len()
    }

    pub fn finished(&self) -> bool {
        self.done() == self.len()
    }

    /// The camera the detectors should assume (the scenario's): poses are judged with it.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn worst_cases(&self) -> &[WorstCase] {
        &self.worst
    }

    /// Renders the next scene for every family (in parallel), and reads each with that family's
    /// detector (`detectors[i]` reads `families[i]`). Nothing is left to do once finished.
    pub fn step(&mut self, detectors: &mut [&mut dyn BenchDetector]) -> Result<(), SynthError> {
        assert_eq!(
            detectors.len(),
            self.families.len(),
            "one detector per family"
        );
        let index = self.done();
        let Some(scene) = self.scenes.get(index) else {
            return Ok(());
        };
        let samples = (self.families.par_iter())
            .map(|f| synthesize(f, &scene.config, scene.seed))
            .collect::<Result<Vec<_>, _>>()?;
        let group = scene.group;
        let side_m = self.scenario.side_mm / 1000.0;
        for (k, (sample, detector)) in samples.iter().zip(detectors.iter_mut()).enumerate() {
            detector.observe_truth(&sample.truth);
            let started = web_time::Instant::now();
            let detections = detector.detect(&sample.image);
            let time_ms = started.elapsed().as_secs_f64() * 1e3;
            let outcome = judge(
                &self.camera,
                side_m,
                Some(&self.families[k]),
                &sample.truth.markers,
                &detections,
                time_ms,
            );
            self.keep_worst(k, index, group, sample, &outcome);
            self.outcomes[k].push(outcome);
        }
        Ok(())
    }

    fn keep_worst(
        &mut self,
        family: usize,
        scene: usize,
        group: Group,
        sample: &crate::synth::Sample,
        outcome: &Outcome,
    ) {
        for (truth, read) in sample.truth.markers.iter().zip(&outcome.read) {
            let rotation_deg = read.map(|r| r.rotation_deg).filter(|d| d.is_finite());
            let badness = badness(read.is_some(), rotation_deg);
            let mine = self.worst.iter().filter(|w| w.family == family);
            let (count, least) = mine.fold((0, f64::INFINITY), |(n, least), w| {
                (n + 1, least.min(w.badness()))
            });
            if count >= WORST_KEPT && badness <= least {
                continue;
            }
            let truth_corners = Quad([truth.roi[0], truth.roi[1], truth.roi[2], truth.roi[3]]);
            let (crop, origin) = crop_around(&sample.image, &truth_corners);
            let shift = |q: Quad| q.map(|p| [p[0] - origin[0], p[1] - origin[1]]);
            if count >= WORST_KEPT {
                let (at, _) = (self.worst.iter().enumerate())
                    .filter(|(_, w)| w.family == family)
                    .min_by(|a, b| a.1.badness().total_cmp(&b.1.badness()))
                    .expect("the family has cases");
                self.worst.remove(at);
            }
            self.worst.push(WorstCase {
                family,
                scene,
                group,
                crop,
                truth: shift(truth_corners),
                read: read.map(|r| shift(r.corners)),
                rotation_deg,
            });
        }
    }

    /// The scores so far: one row per family and swept value, and the verdict.
    pub fn report(&self) -> DesignReport {
        let mut groups: Vec<Group> = Vec::new();
        for s in &self.scenes[..self.done()] {
            if !groups.contains(&s.group) {
                groups.push(s.group);
            }
        }
        let mut rows = Vec::new();
        for (k, family) in self.families.iter().enumerate() {
            for g in &groups {
                let selected: Vec<&Outcome> = (self.scenes.iter().zip(&self.outcomes[k]))
                    .filter(|(s, _)| s.group == *g)
                    .map(|(_, o)| o)
                    .collect();
                let r = row("", &selected);
                let Group::Scenario { condition, value } = *g else {
                    unreachable!("a scenario's scenes are scenario groups")
                };
                rows.push(DesignRow {
                    family: family.name().to_string(),
                    condition,
                    value,
                    scenes: r.images,
                    markers: r.markers,
                    read: r.correct,
                    recall: r.recall,
                    position_mm: r.position_error_mm,
                    rotation_deg: r.rotation_error_deg,
                    flips: r.flips,
                    time_ms: r.time_ms,
                });
            }
        }
        DesignReport {
            scenario: self.scenario.name.clone(),
            families: self.families.iter().map(|f| f.name().to_string()).collect(),
            scenes_done: self.done(),
            scenes: self.len(),
            rows,
            verdict: self.verdict(),
        }
    }

    /// Each family's reads of the scenes `holds` accepts, marker by marker, in one order: the
    /// same markers for every family. A scene whose families hold different marker counts (designs
    /// whose outlines let a different number fit) is left out rather than paired wrongly.
    fn reads(&self, holds: impl Fn(&Group) -> bool) -> Vec<Vec<Option<super::score::MarkerRead>>> {
        let mut out = vec![Vec::new(); self.families.len()];
        for (i, scene) in self.scenes[..self.done()].iter().enumerate() {
            let counts = self.outcomes.iter().map(|o| o[i].read.len());
            if !holds(&scene.group) || counts.clone().min() != counts.max() {
                continue;
            }
            for (k, outcomes) in self.outcomes.iter().enumerate() {
                out[k].extend(outcomes[i].read.iter().copied());
            }
        }
        out
    }

    fn verdict(&self) -> Vec<Verdict> {
        let mut out = Vec::new();
        for sweep in &self.scenario.sweeps {
            let c = sweep.condition;
            let reads =
                self.reads(|g| matches!(g, Group::Scenario { condition: Some(x), .. } if *x == c));
            if let Some(v) = self.recall_verdict(question(c), Some(c), &reads) {
                out.push(v);
            }
        }
        let all = self.reads(|_| true);
        if self.scenario.sweeps.is_empty() {
            if let Some(v) = self.recall_verdict("reads most", None, &all) {
                out.push(v);
            }
        }
        if let Some(v) = self.pose_verdict(&all) {
            out.push(v);
        }
        out
    }

    fn names(&self) -> Vec<String> {
        self.families.iter().map(|f| f.name().to_string()).collect()
    }

    fn recall_verdict(
        &self,
        question: &str,
        condition: Option<Condition>,
        reads: &[Vec<Option<super::score::MarkerRead>>],
    ) -> Option<Verdict> {
        let markers = reads.iter().map(Vec::len).min()?;
        if markers == 0 {
            return None;
        }
        let read_by = |k: usize| reads[k][..markers].iter().flatten().count();
        let best = (0..reads.len()).max_by_key(|&k| read_by(k))?;
        let names = self.names();
        let gaps: Vec<Gap> = (0..reads.len())
            .filter(|&k| k != best)
            .map(|k| {
                let (mut both, mut only_best, mut only_other, mut neither) = (0, 0, 0, 0);
                for (a, b) in reads[best][..markers].iter().zip(&reads[k][..markers]) {
                    match (a.is_some(), b.is_some()) {
                        (true, true) => both += 1,
                        (true, false) => only_best += 1,
                        (false, true) => only_other += 1,
                        (false, false) => neither += 1,
                    }
                }
                let (d, lo, hi) = paired_difference(both, only_best, only_other, neither);
                Gap {
                    other: names[k].clone(),
                    difference: 100.0 * d,
                    interval: (100.0 * lo, 100.0 * hi),
                }
            })
            .collect();
        let measurable = gaps.iter().all(|g| g.interval.0 > 0.0);
        let recall = 100.0 * read_by(best) as f64 / markers as f64;
        let detail: Vec<String> = gaps
            .iter()
            .map(|g| {
                format!(
                    "{:+.1} points over {} (95 % interval {:+.1} … {:+.1})",
                    g.difference, g.other, g.interval.0, g.interval.1
                )
            })
            .collect();
        // Pooled over the sweep: the values share their scenes, so the pairs are not independent
        // and the interval is a little narrower than it should be (ARCHITECTURE §11).
        let over = condition.map_or("every scene".to_string(), |c| {
            format!("recall over the whole {} sweep", c.name())
        });
        let sentence = if measurable {
            format!(
                "{} ({over}): {} ({recall:.1} % of {markers} markers), {}.",
                capitalised(question),
                names[best],
                detail.join("; ")
            )
        } else {
            format!(
                "{} ({over}): no design measurably; {} reads {recall:.1} % of {markers} markers, {}.",
                capitalised(question),
                names[best],
                detail.join("; ")
            )
        };
        Some(Verdict {
            question: question.to_string(),
            condition,
            best: measurable.then(|| names[best].clone()),
            leader: names[best].clone(),
            markers,
            gaps,
            sentence,
        })
    }

    /// Which design's rotation error is lower, marker by marker over the markers every design
    /// read: a sign test (ties left out) with Wilson's interval of the share, and the medians
    /// and p99 beside it.
    fn pose_verdict(&self, reads: &[Vec<Option<super::score::MarkerRead>>]) -> Option<Verdict> {
        let markers = reads.iter().map(Vec::len).min()?;
        let common: Vec<usize> = (0..markers)
            .filter(|&i| {
                reads
                    .iter()
                    .all(|r| r[i].is_some_and(|m| m.rotation_deg.is_finite()))
            })
            .collect();
        if common.is_empty() {
            return None;
        }
        let errors: Vec<Vec<f64>> = (reads.iter())
            .map(|r| {
                (common.iter())
                    .map(|&i| r[i].expect("read by every design").rotation_deg)
                    .collect()
            })
            .collect();
        let summaries: Vec<Stats> = (errors.iter())
            .map(|e| stats(e.clone()).expect("not empty"))
            .collect();
        let best = (0..reads.len())
            .min_by(|&a, &b| summaries[a].median.total_cmp(&summaries[b].median))?;
        let names = self.names();
        let gaps: Vec<Gap> = (0..reads.len())
            .filter(|&k| k != best)
            .map(|k| {
                let lower = (errors[best].iter().zip(&errors[k]))
                    .filter(|(a, b)| a < b)
                    .count();
                let higher = (errors[best].iter().zip(&errors[k]))
                    .filter(|(a, b)| a > b)
                    .count();
                let n = lower + higher;
                let share = 100.0 * lower as f64 / n.max(1) as f64;
                let (lo, hi) = if n > 0 { wilson(lower, n) } else { (0.0, 1.0) };
                Gap {
                    other: names[k].clone(),
                    difference: share,
                    interval: (100.0 * lo, 100.0 * hi),
                }
            })
            .collect();
        let measurable = gaps.iter().all(|g| g.interval.0 > 50.0);
        let detail: Vec<String> = (0..reads.len())
            .filter(|&k| k != best)
            .zip(&gaps)
            .map(|(k, g)| {
                format!(
                    "lower than {}'s on {:.0} % of them (95 % interval {:.0} … {:.0} %; median {:.2}° vs {:.2}°, p99 {:.2}° vs {:.2}°)",
                    g.other,
                    g.difference,
                    g.interval.0,
                    g.interval.1,
                    summaries[best].median,
                    summaries[k].median,
                    summaries[best].p99,
                    summaries[k].p99
                )
            })
            .collect();
        let sentence = format!(
            "Poses best: {}; on the {} markers every design read, {}'s rotation error is {}.",
            if measurable {
                names[best].as_str()
            } else {
                "no design measurably"
            },
            common.len(),
            names[best],
            detail.join("; ")
        );
        Some(Verdict {
            question: "poses best".into(),
            condition: None,
            best: measurable.then(|| names[best].clone()),
            leader: names[best].clone(),
            markers: common.len(),
            gaps,
            sentence,
        })
    }
}

fn question(c: Condition) -> &'static str {
    match c {
        Condition::Distance => "reads farthest",
        Condition::Angle => "reads steepest",
        Condition::Blur => "reads under most blur",
        Condition::Motion => "reads under most motion",
        Condition::Noise => "reads under most noise",
        Condition::Light => "reads in least light",
    }
}

fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// The scene around a marker (its box grown by half its size on each side), and where the cut
/// starts in the scene.
fn crop_around(image: &GrayImage, corners: &Quad) -> (GrayImage, [f64; 2]) {
    let b = corners.bounding_box();
    let margin = 0.5 * (b[2] - b[0]).max(b[3] - b[1]).max(8.0);
    let clamp = |v: f64, hi: u32| v.clamp(0.0, hi as f64) as u32;
    let (x0, y0) = (
        clamp(b[0] - margin, image.width - 1),
        clamp(b[1] - margin, image.height - 1),
    );
    let (x1, y1) = (
        clamp(b[2] + margin, image.width).max(x0 + 1),
        clamp(b[3] + margin, image.height).max(y0 + 1),
    );
    (image.crop(x0, y0, x1 - x0, y1 - y0), [x0 as f64, y0 as f64])
}

/// One family's scores at one swept value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DesignRow {
    pub family: String,
    /// The swept condition (none without sweeps) and its value.
    pub condition: Option<Condition>,
    pub value: f64,
    pub scenes: usize,
    pub markers: usize,
    pub read: usize,
    pub recall: f64,
    pub position_mm: Option<Stats>,
    pub rotation_deg: Option<Stats>,
    pub flips: usize,
    pub time_ms: f64,
}

/// The best design's lead over another: recall points for a reading question, the share of
/// markers with the lower rotation error (%) for the pose question; with its 95 % interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Gap {
    pub other: String,
    pub difference: f64,
    pub interval: (f64, f64),
}

/// One question's answer.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Verdict {
    pub question: String,
    pub condition: Option<Condition>,
    /// The design that answers it, when its lead over every other is beyond noise.
    pub best: Option<String>,
    /// The design ahead, measurably or not.
    pub leader: String,
    pub markers: usize,
    pub gaps: Vec<Gap>,
    pub sentence: String,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DesignReport {
    pub scenario: String,
    pub families: Vec<String>,
    pub scenes_done: usize,
    pub scenes: usize,
    pub rows: Vec<DesignRow>,
    pub verdict: Vec<Verdict>,
}

/// The CSV's columns, in order.
pub const CSV_HEADER: &str = "family,condition,value,scenes,markers,read,recall,\
position_mm_median,position_mm_p95,position_mm_p99,\
rotation_deg_median,rotation_deg_p95,rotation_deg_p99,flips,time_ms";

impl DesignRow {
    /// The row as the CSV writes it (empty cells where nothing was read).
    pub fn csv(&self) -> String {
        let tail = |s: &Option<Stats>| match s {
            Some(s) => format!("{:.4},{:.4},{:.4}", s.median, s.p95, s.p99),
            None => ",,".into(),
        };
        format!(
            "{},{},{},{},{},{},{:.4},{},{},{},{:.1}",
            self.family,
            self.condition.map_or("", Condition::name),
            self.value,
            self.scenes,
            self.markers,
            self.read,
            self.recall,
            tail(&self.position_mm),
            tail(&self.rotation_deg),
            self.flips,
            self.time_ms
        )
    }
}

impl DesignReport {
    pub fn csv(&self) -> String {
        let mut s = format!("{CSV_HEADER}\n");
        for r in &self.rows {
            s += &r.csv();
            s.push('\n');
        }
        s
    }

    pub fn markdown(&self) -> String {
        let mut s = format!(
            "# {} under \"{}\" ({} of {} scenes per design)\n\n",
            self.families.join(" vs "),
            self.scenario,
            self.scenes_done,
            self.scenes
        );
        s += "## Verdict\n\n";
        for v in &self.verdict {
            s += &format!("- {}\n", v.sentence);
        }
        s += "\n| design | condition | value | markers | recall | position mm (median / p95 / p99) | rotation ° (median / p95 / p99) | flips | ms/image |\n";
        s += "|---|---|---|---|---|---|---|---|---|\n";
        let tail = |st: &Option<Stats>| {
            st.map_or("–".to_string(), |st| {
                format!("{:.2} / {:.2} / {:.2}", st.median, st.p95, st.p99)
            })
        };
        for r in &self.rows {
            s += &format!(
                "| {} | {} | {} | {} | {:.1} % | {} | {} | {} | {:.0} |\n",
                r.family,
                r.condition.map_or("all", Condition::name),
                r.value,
                r.markers,
                100.0 * r.recall,
                tail(&r.position_mm),
                tail(&r.rotation_deg),
                r.flips,
                r.time_ms
            );
        }
        s
    }

    /// Per swept condition: recall, position error and rotation error against its values, one
    /// line per design (medians solid, p99 dashed), as SVG files named `CONDITION-WHAT.svg`.
    pub fn plots(&self) -> Vec<(String, String)> {
        let mut out = Vec::new();
        let mut conditions: Vec<Option<Condition>> = Vec::new();
        for r in &self.rows {
            if !conditions.contains(&r.condition) {
                conditions.push(r.condition);
            }
        }
        // A scenario without sweeps has one value per design: a table row, not a curve.
        for condition in conditions.into_iter().flatten() {
            let (slug, label) = (condition.name(), condition.label());
            let c = Some(condition);
            let line = |family: usize, name: &str, dashed: bool, y: &dyn Fn(&DesignRow) -> f64| {
                let points = (self.rows.iter())
                    .filter(|r| r.condition == c && r.family == self.families[family])
                    .map(|r| (r.value, y(r)))
                    .collect();
                (name.to_string(), points, family, dashed)
            };
            let mut recall = Vec::new();
            let mut position = Vec::new();
            let mut rotation = Vec::new();
            for (k, name) in self.families.iter().enumerate() {
                recall.push(line(k, name, false, &|r| 100.0 * r.recall));
                for (dashed, what) in [(false, "median"), (true, "p99")] {
                    let pick = move |s: &Option<Stats>| {
                        s.map_or(f64::NAN, |s| if dashed { s.p99 } else { s.median })
                    };
                    let series = format!("{name} {what}");
                    position.push(line(k, &series, dashed, &|r| pick(&r.position_mm)));
                    rotation.push(line(k, &series, dashed, &|r| pick(&r.rotation_deg)));
                }
            }
            for (what, y_label, y_max, lines) in [
                ("recall", "recall (%)", 100.0, recall),
                ("position", "position error (mm)", 0.0, position),
                ("rotation", "rotation error (°)", 0.0, rotation),
            ] {
                let series: Vec<Series> = (lines.iter())
                    .map(|(name, points, colour, dashed)| Series {
                        name,
                        points: Vec::clone(points),
                        colour: *colour,
                        dashed: *dashed,
                    })
                    .collect();
                let title = format!("{what} vs {slug}: {}", self.scenario);
                out.push((
                    format!("{slug}-{what}.svg"),
                    chart(&title, label, y_label, &series, y_max),
                ));
            }
        }
        out
    }
}

/// A detector for one design under a scenario: the shipped stage 1 with `stage2`, told the
/// scenario's camera and print size so that its poses are in the scene's metres.
#[cfg(feature = "detect")]
pub fn detector_for(
    family: Family,
    stage2: crate::detect::stage2::Stage2,
    scenario: &Scenario,
) -> Result<crate::detect::Detector, crate::detect::detector::DetectorError> {
    use crate::detect::detector::FamilyReader;
    let mut reader = FamilyReader::new(family, stage2);
    reader.side_m = scenario.side_mm / 1000.0;
    let stage1 = crate::detect::stage1::Stage1::shipped()?;
    let mut detector = crate::detect::Detector::new(stage1, vec![reader])?;
    detector.camera = Some(scenario.camera());
    Ok(detector)
}

#[cfg(test)]
mod tests;
