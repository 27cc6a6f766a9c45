//! The full detector (docs/ARCHITECTURE.md §9.8) in four phases, each timed:
//!
//! 1. *propose*: the sources of [`sources::DEFAULT_SOURCES`] (stage 1 first, then the image
//!    searches for what its grouping misses) give candidate quads, each with its score;
//! 2. *verify*: each source's quads pass the families' cheap checks before stage 2 sees them;
//! 3. *read*: stage 2 of every family reads them, decodes, aligns and poses, and a read is kept
//!    only with the evidence its source's trust asks for ([`read`]);
//! 4. *reconcile*: one read per marker, by evidence ([`reconcile`]).
//!
//! A quad no family decodes is dropped: a false ROI costs stage-2 passes, never a wrong ID. The
//! CLI, the harness and the studio all detect through [`Detector::detect`].

mod read;
mod reconcile;
pub mod sources;
mod track;

pub use track::{Frame, TrackParams, Tracker};

use super::cells::CellReader;
use super::outline::Outline;
use super::precheck::PreCheck;
use super::rings::{ring_quads, RingParams, RingShape};
use super::stage1::edges::on_edges;
use super::stage1::group::{nested, same_quad, Proposal};
use super::stage1::pipeline::Search;
use super::stage1::{ProposeOptions, Stage1};
use super::stage2::model_file::ModelError;
use super::stage2::{ReadOptions, Stage2, Stage2Result};
use super::verifier::{Verifier, VerifierParams};
use super::{BenchDetector, Detection};
use crate::family::Family;
use crate::geometry::{Camera, PoseJson, Quad};
use crate::image::GrayImage;
use crate::io::Stopwatch;
use read::Batch;
use reconcile::{reconcile, Evidence, Rounds};
use serde::{Deserialize, Serialize};
use sources::{
    AcceptParams, Capability, RefitParams, Source, SourceParams, DEFAULT_SOURCES, SOURCES,
};

/// One family's stage 2 and the marker size its poses assume.
pub struct FamilyReader {
    pub family: Family,
    pub stage2: Stage2,
    /// ROI side in metres.
    pub side_m: f64,
    /// Reads cells straight off the image where stage 2 reads nothing (flat-celled families).
    pub cells: Option<CellReader>,
    /// Turns away the traced searches' quads that cannot frame one of the family's markers
    /// before they cost a stage-2 pass or a frame fit (families whose ROI sits on a dark frame
    /// on lighter surroundings).
    pub precheck: Option<PreCheck>,
    /// The dark frame proposals outline, where the family's ROI lies inside it.
    pub(super) outline: Option<Outline>,
    /// What the ring search looks for (ring families).
    pub(super) rings: Option<RingShape>,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DetectorOptions {
    pub propose: ProposeOptions,
    pub read: ReadOptions,
    /// Read the cells of ROIs stage 2 reads nothing from straight off the image (flat-celled
    /// families only).
    pub cell_reads: bool,
    /// Read the quads of four corners that the image's edges confirm, and the ROIs no network
    /// read again once their sides are fitted to those edges.
    pub edge_fits: bool,
    /// The proposal sources, run in this order (see [`sources`]).
    pub sources: [SourceParams; SOURCES],
    pub accept: AcceptParams,
    pub refit: RefitParams,
    /// The learned verifier's threshold (the verify phase).
    pub verifier: VerifierParams,
    /// The ring search's thresholds (ring families).
    pub rings: RingParams,
}

impl Default for DetectorOptions {
    fn default() -> Self {
        Self {
            propose: ProposeOptions::default(),
            read: ReadOptions::default(),
            cell_reads: true,
            edge_fits: true,
            sources: DEFAULT_SOURCES,
            accept: AcceptParams::default(),
            refit: RefitParams::default(),
            verifier: VerifierParams::default(),
            rings: RingParams::default(),
        }
    }
}

/// Where an image's time went, by phase and by proposal source.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Timings {
    /// Stage 1 on the image and every image search.
    pub propose_ms: f64,
    /// The pre-read checks.
    pub verify_ms: f64,
    /// Stage 2, decoding, the alignment with the rendering and the pose (and the cell reads).
    pub read_ms: f64,
    /// Overlapping reads resolved.
    pub reconcile_ms: f64,
    /// Quads sent to the verify phase, over every source.
    pub proposals: usize,
    /// Stage-2 reads started (quads × families that verified them).
    pub reads: usize,
    /// Stage-2 network passes run (first passes, their retries from keypoints, later passes). A
    /// quad read by several families that share weights costs one pass, so there can be fewer
    /// passes than reads.
    pub passes: usize,
    /// Quads the learned verifier turned away before any stage-2 pass.
    #[serde(default)]
    pub turned_away: usize,
    /// Per source, in [`Source::ALL`]'s order.
    pub sources: [SourceTally; SOURCES],
}

impl Timings {
    pub fn total_ms(&self) -> f64 {
        self.propose_ms + self.verify_ms + self.read_ms + self.reconcile_ms
    }

    /// The tally of one source.
    pub fn source(&self, source: Source) -> &SourceTally {
        &self.sources[source.index()]
    }
}

/// One line: each phase's time, then the ROIs and stage-2 passes they cost.
impl std::fmt::Display for Timings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let plural =
            |n: usize, one: &'static str, many: &'static str| if n == 1 { one } else { many };
        write!(
            f,
            "propose {:.1} ms, verify {:.1} ms, read {:.1} ms, reconcile {:.1} ms; {} ROI{} ({} turned away), {} stage-2 pass{}",
            self.propose_ms,
            self.verify_ms,
            self.read_ms,
            self.reconcile_ms,
            self.proposals,
            plural(self.proposals, "", "s"),
            self.turned_away,
            self.passes,
            plural(self.passes, "", "es"),
        )
    }
}

/// What one proposal source cost and gave in an image.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct SourceTally {
    /// Its own search's time (stage 1 on the whole image for [`Source::Stage1`]).
    pub propose_ms: f64,
    /// Verify and read time spent on its quads.
    pub read_ms: f64,
    /// Quads it sent to the verify phase.
    pub proposals: usize,
    /// Stage-2 reads of them started.
    pub reads: usize,
    /// Markers read from them that no source before it had read (one marker read from two of
    /// its quads counts once).
    pub found: usize,
}

/// A marker found in an image.
#[derive(Debug, Clone)]
pub struct Found {
    pub family: String,
    pub marker: Stage2Result,
    /// Stage 1's ROI for it.
    pub proposal: Proposal,
    /// Read from its cells straight off the image, not by stage 2's network.
    pub cell_read: bool,
    /// What the reconcile phase weighs it by.
    pub(crate) evidence: Evidence,
}

#[derive(Debug, thiserror::Error)]
pub enum DetectorError {
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(
        "family {0:?} has no shipped stage-2 weights; train them with `tagsmith train {0} --stage \
         keypoints` and pass the model file"
    )]
    NoWeights(String),
    #[error("no family to detect")]
    NoFamilies,
}

/// The intrinsics poses assume when none are given: the image's size and a 70° diagonal field of
/// view (a typical webcam or phone); `None` for an image too small to have one.
pub fn guess_camera(image: &GrayImage) -> Option<Camera> {
    Camera::from_diagonal_fov(image.width, image.height, 70.0).ok()
}

pub struct Detector {
    pub stage1: Stage1,
    pub readers: Vec<FamilyReader>,
    /// Says which candidate quads frame a marker at all before stage 2 reads them (the shipped
    /// one where this build ships one; `None` sends every quad that passes the families' checks
    /// to stage 2).
    pub verifier: Option<Verifier>,
    /// Intrinsics for the poses; without them each image's are guessed from its size and a 70°
    /// diagonal field of view.
    pub camera: Option<Camera>,
    pub options: DetectorOptions,
}

impl FamilyReader {
    pub fn new(family: Family, stage2: Stage2) -> Self {
        let side_m = family.spec().print.marker_side_mm / 1000.0;
        let cells = CellReader::new(&family);
        let precheck = PreCheck::new(&family);
        let outline = Outline::new(&family);
        let rings = RingShape::of(&family);
        Self {
            family,
            stage2,
            side_m,
            cells,
            precheck,
            outline,
            rings,
        }
    }

    /// The ROI stage 2 reads from a proposal's quad: the quad itself, or the ROI inside the
    /// frame it outlines.
    pub(super) fn roi_of(&self, quad: &Quad) -> Quad {
        (self.outline.as_ref())
            .and_then(|o| o.roi_in(quad))
            .unwrap_or(*quad)
    }

    /// The proposal's quad for a ROI of the family: the inverse of [`FamilyReader::roi_of`].
    pub(super) fn proposal_of(&self, roi: &Quad) -> Quad {
        (self.outline.as_ref())
            .and_then(|o| o.around(roi))
            .unwrap_or(*roi)
    }

    /// The family with its shipped stage-2 weights.
    pub fn shipped(family: Family) -> Result<Self, DetectorError> {
        let stage2 = Stage2::shipped(&family)
            .ok_or_else(|| DetectorError::NoWeights(family.name().into()))??;
        Ok(Self::new(family, stage2))
    }
}

impl Detector {
    pub fn new(stage1: Stage1, readers: Vec<FamilyReader>) -> Result<Self, DetectorError> {
        if readers.is_empty() {
            return Err(DetectorError::NoFamilies);
        }
        let verifier = Verifier::shipped().transpose()?;
        Ok(Self {
            stage1,
            readers,
            verifier,
            camera: None,
            options: DetectorOptions::default(),
        })
    }

    /// The shipped stage 1 with the shipped stage 2 of each family.
    pub fn shipped(families: Vec<Family>) -> Result<Self, DetectorError> {
        let stage1 = Stage1::shipped()?;
        let readers = families
            .into_iter()
            .map(FamilyReader::shipped)
            .collect::<Result<Vec<_>, _>>()?;
        Self::new(stage1, readers)
    }

    /// Every marker in `image`, best ROI first, and the time each stage took.
    pub fn detect(&self, image: &GrayImage) -> (Vec<Found>, Timings) {
        self.detect_with(image, self.camera.as_ref())
    }

    /// The camera [`Detector::detect`] poses `image`'s markers with: the detector's own, or the
    /// guess from the image's size.
    pub fn camera_for(&self, image: &GrayImage) -> Option<Camera> {
        self.camera.or_else(|| guess_camera(image))
    }

    /// [`Detector::detect`] with this image's camera (several images of different cameras or
    /// sizes on one detector, in parallel).
    pub fn detect_with(&self, image: &GrayImage, camera: Option<&Camera>) -> (Vec<Found>, Timings) {
        let mut timings = Timings::default();
        let clock = Stopwatch::start();
        // Ring families alone need none of stage 1's corners.
        let search = match self
            .readers
            .iter()
            .any(|r| r.has(Capability::Quadrilateral))
        {
            true => self.stage1.search(image, &self.options.propose),
            false => Search::none(image),
        };
        let stage1_ms = clock.ms();
        timings.propose_ms += stage1_ms;
        timings.sources[Source::Stage1.index()].propose_ms += stage1_ms;
        let guessed;
        let camera = match camera {
            Some(c) => Some(c),
            None => {
                guessed = guess_camera(image);
                guessed.as_ref()
            }
        };
        let scene = Scene {
            image,
            camera,
            search: &search,
        };
        let mut rounds = Rounds::default();
        for params in &self.options.sources {
            if self.runs(params) {
                self.run_source(params, &scene, &mut rounds, &mut timings);
            }
        }
        self.read_light_insides(&scene, &mut rounds, &mut timings);
        timings.proposals = rounds.read.len();
        let clock = Stopwatch::start();
        let kept = reconcile(rounds.found);
        timings.reconcile_ms = clock.ms();
        (kept, timings)
    }

    /// Stage 1 and the traced search on the inverted image for the families whose ROI is a light
    /// square inside a dark frame ([`Capability::LightInsideFrame`]), read as the table's rows
    /// of those sources are: there the ROI is a dark square on a light ring.
    fn read_light_insides(&self, scene: &Scene, rounds: &mut Rounds, timings: &mut Timings) {
        if !(self.readers.iter()).any(|r| r.has(Capability::LightInsideFrame)) {
            return;
        }
        let row = |source: Source| {
            (self.options.sources.iter())
                .find(|p| p.source == source && p.selections > 0)
                .map(|p| SourceParams {
                    needs: Capability::LightInsideFrame,
                    precheck: false,
                    ..*p
                })
        };
        let stage1_row = row(Source::Stage1);
        let traced_row = row(Source::Traced).filter(|_| self.options.propose.trace.is_some());
        if stage1_row.is_none() && traced_row.is_none() {
            return;
        }
        let clock = Stopwatch::start();
        let inverted = scene.image.inverted();
        let search = self.stage1.search(&inverted, &self.options.propose);
        let stage1_ms = clock.ms();
        // The table's quads were outlines to these families: one that failed as an outline
        // (the ROI's own edge, which stage 1 also sees) may still be their ROI.
        let mut own = Rounds {
            found: std::mem::take(&mut rounds.found),
            ..Rounds::default()
        };
        let (before, found_before) = (*timings, own.found.len());
        if let Some(params) = stage1_row {
            self.read_selections(&params, scene, &mut own, timings, true, |r| {
                stage1_selection(&search, r)
            });
        }
        file_tally(
            Source::Stage1,
            stage1_ms,
            &before,
            found_before,
            &own,
            timings,
        );
        if let Some(params) = traced_row {
            let (before, found_before) = (*timings, own.found.len());
            let clock = Stopwatch::start();
            let quads = search.traced(&inverted, &own.covered());
            let traced_ms = clock.ms();
            self.read_selections(&params, scene, &mut own, timings, true, |r| {
                r.fresh_outlined(&quads)
            });
            file_tally(
                Source::Traced,
                traced_ms,
                &before,
                found_before,
                &own,
                timings,
            );
        }
        rounds.found = own.found;
        rounds.read.extend(own.read);
        rounds.failed.extend(own.failed);
    }

    /// Whether a source runs: switched on, and some family has what it assumes.
    fn runs(&self, params: &SourceParams) -> bool {
        let propose = &self.options.propose;
        let on = match params.source {
            Source::Stage1 | Source::Rings => true,
            Source::Outline => propose.outline.is_some(),
            Source::Traced => propose.trace.is_some(),
            Source::CloseLook => propose.close_look,
            Source::StretchedLook => propose.stretched_look,
            Source::CornerQuads | Source::EdgeRefits => self.options.edge_fits,
            Source::CellReads => self.options.cell_reads,
        };
        on && params.selections > 0 && self.readers.iter().any(|r| r.has(params.needs))
    }

    /// One row of the sources table: its quads proposed, then verified and read in selections,
    /// its tally kept.
    fn run_source(
        &self,
        params: &SourceParams,
        scene: &Scene,
        rounds: &mut Rounds,
        timings: &mut Timings,
    ) {
        let before = *timings;
        let found_before = rounds.found.len();
        let (image, search) = (scene.image, scene.search);
        let covered = rounds.covered();
        let propose = &self.options.propose;
        let clock = Stopwatch::start();
        // The image searches look once, away from the strong reads so far; the quads they found
        // are then read in selections.
        let outlined = match params.source {
            Source::Outline => Some(search.outline(image, &covered)),
            Source::Traced => Some(search.traced(image, &covered)),
            Source::CloseLook => Some(self.stage1.close_look(search, image, &covered, propose)),
            Source::StretchedLook => {
                Some(self.stage1.stretched_look(search, image, &covered, propose))
            }
            Source::CornerQuads => Some(search.corner_quads(image, &covered)),
            Source::Stage1 | Source::Rings | Source::EdgeRefits | Source::CellReads => None,
        };
        let mut propose_ms = clock.ms();
        match (params.source, outlined) {
            (_, Some(quads)) => {
                self.read_selections(params, scene, rounds, timings, false, |r| {
                    r.fresh_outlined(&quads)
                });
                // A cluttered image traces dozens of quads, largest first, and a far sliver
                // comes last: past the network's budget, it still gets a cell read.
                let unread = rounds.fresh_outlined(&quads);
                rounds.unread.extend(unread);
            }
            (Source::Rings, None) => {
                let clock = Stopwatch::start();
                let shapes: Vec<RingShape> = self
                    .readers
                    .iter()
                    .filter_map(|r| r.rings.clone())
                    .collect();
                let rings = ring_quads(image, &shapes, &self.options.rings);
                propose_ms += clock.ms();
                self.read_selections(params, scene, rounds, timings, true, |r| {
                    (rings.iter())
                        .filter(|p| r.is_new(p) && !r.over_a_marker_read(p))
                        .copied()
                        .collect()
                });
            }
            (Source::Stage1, None) => {
                self.read_selections(params, scene, rounds, timings, false, |r| {
                    stage1_selection(search, r)
                });
            }
            (Source::EdgeRefits, None) => {
                let min_move = self.options.refit.min_move_px;
                let budget = params.budget.unwrap_or(usize::MAX);
                self.read_selections(params, scene, rounds, timings, false, |r| {
                    edge_refits(image, r, budget, min_move)
                });
            }
            (_, None) => {
                let clock = Stopwatch::start();
                let (left, tried) = left_unread(rounds, params.budget);
                propose_ms += clock.ms();
                let batch = Batch {
                    params,
                    trust: params.trust,
                    rois_inside: false,
                };
                let reads = self.cell_reads(image, &left, tried, scene.camera, batch, timings);
                rounds.found.extend(reads.into_iter().flatten());
            }
        }
        file_tally(
            params.source,
            propose_ms,
            &before,
            found_before,
            rounds,
            timings,
        );
    }

    /// Up to `params.selections` selections of a source's quads (`select` picks them given what
    /// was read so far), at most `params.budget` each, verified and read. `rois_inside`: the
    /// quads are ROIs inside dark frames ([`Batch::rois_inside`]).
    fn read_selections(
        &self,
        params: &SourceParams,
        scene: &Scene,
        rounds: &mut Rounds,
        timings: &mut Timings,
        rois_inside: bool,
        mut select: impl FnMut(&Rounds) -> Vec<Proposal>,
    ) {
        for selection in 0..params.selections {
            let clock = Stopwatch::start();
            let mut batch = select(rounds);
            let select_ms = clock.ms();
            timings.propose_ms += select_ms;
            timings.sources[params.source.index()].propose_ms += select_ms;
            if let Some(budget) = params.budget {
                batch.truncate(budget);
            }
            if batch.is_empty() {
                break;
            }
            timings.sources[params.source.index()].proposals += batch.len();
            let trust = params.trust.in_selection(selection);
            let reads = self.read_all(
                scene.image,
                &batch,
                scene.camera,
                Batch {
                    params,
                    trust,
                    rois_inside,
                },
                timings,
            );
            rounds.record(batch, reads);
        }
    }
}

/// Stage 1's next selection: its proposals away from the markers read, less those read already.
fn stage1_selection(search: &Search, rounds: &Rounds) -> Vec<Proposal> {
    let selected = search.proposals(&rounds.kept(), &rounds.failed);
    selected.into_iter().filter(|p| rounds.is_new(p)).collect()
}

/// Files under `source` what its quads cost and found since `before` (the timings, and the
/// number of markers found, when it started), with `propose_ms` of its own search.
fn file_tally(
    source: Source,
    propose_ms: f64,
    before: &Timings,
    found_before: usize,
    rounds: &Rounds,
    timings: &mut Timings,
) {
    timings.propose_ms += propose_ms;
    let tally = &mut timings.sources[source.index()];
    tally.propose_ms += propose_ms;
    tally.read_ms += (timings.read_ms + timings.verify_ms) - (before.read_ms + before.verify_ms);
    tally.reads += timings.reads - before.reads;
    tally.found += new_markers(&rounds.found, found_before);
}

/// The markers among `found[before..]` that no read before them covers: what a source read that
/// the sources before it had not (one marker read from two of its quads counts once).
fn new_markers(found: &[Found], before: usize) -> usize {
    (before..found.len())
        .filter(|&i| {
            !found[..i]
                .iter()
                .any(|f| nested(&f.marker.corners, &found[i].marker.corners))
        })
        .count()
}

/// What every source of one image works on.
struct Scene<'a> {
    image: &'a GrayImage,
    camera: Option<&'a Camera>,
    search: &'a Search,
}

/// The quads no network read, moved onto the image's edges (at most `budget`): a far sliver
/// 8–12 px across reads from corners within about a pixel, and stage 1's grid, a traced hull or
/// a closer look leave them 2–4 px off; its long sides' edges place them to a fraction of a
/// pixel (`stage1::edges`). A refit that moves no corner `min_move` px from a quad read already
/// would read the same.
fn edge_refits(image: &GrayImage, rounds: &Rounds, budget: usize, min_move: f64) -> Vec<Proposal> {
    let mut refits: Vec<Proposal> = Vec::new();
    for p in rounds.failed.iter().chain(&rounds.unread) {
        if refits.len() == budget {
            break;
        }
        if rounds.over_a_marker_read(p) {
            continue;
        }
        let Some(corners) = on_edges(image, p.corners) else {
            continue;
        };
        let tried = |q: &Proposal| q.corners.largest_corner_move(&corners) < min_move;
        if !rounds.read.iter().chain(&refits).any(tried) {
            refits.push(Proposal { corners, ..*p });
        }
    }
    refits
}

/// The quads left for the cell reads: those no network read (the first `tried` of them) and the
/// image searches' quads past their budget, away from every marker read, at most `budget`.
/// They come after every network read, so that a cell read of a poor ROI never takes a marker's
/// place from a network read of a better one.
fn left_unread(rounds: &Rounds, budget: Option<usize>) -> (Vec<Proposal>, usize) {
    let mut left: Vec<Proposal> = Vec::new();
    let mut tried = 0;
    for (k, p) in rounds.failed.iter().chain(&rounds.unread).enumerate() {
        if budget.is_some_and(|b| left.len() == b) {
            break;
        }
        if !rounds.over_a_marker_read(p) && !left.iter().any(|q| same_quad(q, p)) {
            left.push(*p);
            if k < rounds.failed.len() {
                tried = left.len();
            }
        }
    }
    (left, tried)
}

impl Found {
    /// What `annotate` draws for it: the stage-1 ROI, the outline, the keypoints.
    pub fn overlay(&self) -> super::annotate::Overlay<'_> {
        super::annotate::Overlay {
            roi: &self.proposal.corners,
            corners: Some(&self.marker.corners),
            keypoints: self
                .marker
                .keypoints
                .iter()
                .map(|k| (k.x, k.y, k.category))
                .collect(),
        }
    }

    /// The marker in the detections file's format.
    pub fn detection(&self) -> Detection {
        let m = &self.marker;
        Detection {
            id: m.id,
            corners: m.corners,
            pose: m.pose.as_ref().map(|p| PoseJson::from(&p.pose)),
            family: Some(self.family.clone()),
            keypoints: m.keypoints.clone(),
            scores: Some(m.scores(self.proposal.score, self.cell_read)),
        }
    }
}

/// The harness runs the full detector like any other.
impl BenchDetector for Detector {
    fn name(&self) -> String {
        let families: Vec<&str> = self.readers.iter().map(|r| r.family.name()).collect();
        format!("Tagsmith ({})", families.join(", "))
    }

    fn detect(&mut self, image: &GrayImage) -> Vec<Detection> {
        self.detect_timed(image).0
    }

    fn detect_timed(&mut self, image: &GrayImage) -> (Vec<Detection>, Option<serde_json::Value>) {
        let (found, timings) = Detector::detect(self, image);
        let detections = found.iter().map(Found::detection).collect();
        (detections, serde_json::to_value(timings).ok())
    }
}

#[cfg(test)]
mod tests;
