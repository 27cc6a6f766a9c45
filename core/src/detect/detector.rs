//! The full detector (docs/ARCHITECTURE.md §9.8): stage 1 proposes ROIs in the whole image,
//! stage 2 of every requested family reads each ROI, and a ROI that no family decodes is
//! dropped — a false ROI costs stage-2 passes, never a wrong ID. The CLI, the harness and the
//! studio all detect through [`Detector::detect`].

use super::cells::{CellOutcome, CellRead, CellReader};
use super::precheck::{PreCheck, QuadSample};
use super::stage1::edges::on_edges;
use super::stage1::group::{nested, same_quad, Proposal};
use super::stage1::pipeline::Outlined;
use super::stage1::{ProposeOptions, Stage1};
use super::stage2::model_file::ModelError;
use super::stage2::{shipped_model, ReadOptions, Stage2, Stage2Result};
use super::{BenchDetector, DetectedKeypoint, Detection};
use crate::family::{Assignment, Family};
use crate::geometry::{largest_corner_move, Homography};
use crate::geometry::{Camera, PoseJson};
use crate::image::GrayImage;
use crate::io::Stopwatch;
use serde::Serialize;

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
}

impl Default for DetectorOptions {
    fn default() -> Self {
        Self {
            propose: ProposeOptions::default(),
            read: ReadOptions::default(),
            cell_reads: true,
            edge_fits: true,
        }
    }
}

/// Where an image's time went.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Timings {
    pub stage1_ms: f64,
    /// Stage 2 on every proposal for every family, refinement and pose included (and stage 1's
    /// selections after the first round).
    pub stage2_ms: f64,
    /// Stage-1 ROIs read, over every round.
    pub proposals: usize,
    /// Stage-2 reads started (proposals × families, less the quads the pre-read check turned
    /// away).
    pub reads: usize,
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
        Self {
            family,
            stage2,
            side_m,
            cells,
            precheck,
        }
    }

    /// Whether the detector keeps a read of a proposal with this trust and ROI score.
    ///
    /// A read needing more than half the corrections must decode alike in every pass: a
    /// misread of a marker under heavy noise lands on some code within the limit, and the next
    /// pass, from a ROI that moved, on another or on none, where a right read decodes again
    /// (dev: 4 wrong IDs in 1170 noise images gone, for 46 of 968 reads).
    ///
    /// A read from the keypoints of a first pass that decoded nothing (stage 2 keeps it only
    /// where the alignment with the rendering accepted its frame) must, with more than half
    /// the corrections, also fit a pose closely: keypoints sorted a cell off place a frame that
    /// reads another code, and both passes from it may agree (dev seed 45 #48, a marker at 10 cm and 75°: another ID
    /// with 4 corrections, 11 px RMS, about 0.3 of a cell pitch; right reads of that kind under
    /// noise at most 0.43 px, a few hundredths of a pitch).
    fn accepts(&self, m: &Stage2Result, trust: Trust, roi_score: f64) -> bool {
        let limit = self.family.codebook().max_correction();
        m.corrected_errors <= trust.allowed(limit, roi_score)
            && (m.corrected_errors <= limit || self.rigid(m))
            && (m.corrected_errors <= limit / 2
                || (m.passes_agree
                    && (!m.from_keypoints
                        || self.fits_a_pose_within(m, MAX_KEYPOINT_READ_RMS_PITCH))))
    }

    /// Whether a rigid pose explains the read's keypoints: their reprojection RMS is at most
    /// [`MAX_RIGID_RMS_PITCH`] of a cell pitch in the image (a read without a pose passes).
    /// Asked only of reads that needed more corrections than the family's limit for errors
    /// alone, which erasures allow: a code read out of noise then lands on keypoints no camera
    /// sees a flat marker through (development sets: the one such wrong ID, 0.42 pitch; right
    /// reads at most 0.16).
    fn rigid(&self, marker: &Stage2Result) -> bool {
        self.fits_a_pose_within(marker, MAX_RIGID_RMS_PITCH)
    }

    /// Whether the read's keypoints reproject from its pose with an RMS of at most
    /// `max_rms_pitch` cell pitches in the image (a read without a pose passes).
    fn fits_a_pose_within(&self, marker: &Stage2Result, max_rms_pitch: f64) -> bool {
        let Some(pose) = &marker.pose else {
            return true;
        };
        let pitch = self.family.keypoint_pitch() / self.family.roi_side();
        let c = &marker.corners;
        let side = (0..4)
            .map(|i| (c[i][0] - c[(i + 1) % 4][0]).hypot(c[i][1] - c[(i + 1) % 4][1]))
            .sum::<f64>()
            / 4.0;
        pose.rms_px <= max_rms_pitch * pitch * side
    }

    /// The family with its shipped stage-2 weights.
    pub fn shipped(family: Family) -> Result<Self, DetectorError> {
        let bytes =
            shipped_model(family.name()).ok_or(DetectorError::NoWeights(family.name().into()))?;
        let name = format!("shipped model of {}", family.name());
        let stage2 = Stage2::from_bytes(bytes, &name, &family)?;
        Ok(Self::new(family, stage2))
    }
}

impl Detector {
    pub fn new(stage1: Stage1, readers: Vec<FamilyReader>) -> Result<Self, DetectorError> {
        if readers.is_empty() {
            return Err(DetectorError::NoFamilies);
        }
        Ok(Self {
            stage1,
            readers,
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
        let clock = Stopwatch::start();
        let search = self.stage1.search(image, &self.options.propose);
        let mut timings = Timings {
            stage1_ms: clock.ms(),
            ..Timings::default()
        };
        let clock = Stopwatch::start();
        let guessed;
        let camera = match camera {
            Some(c) => Some(c),
            None => {
                guessed = guess_camera(image);
                guessed.as_ref()
            }
        };
        // Rounds: a ROI no family reads may have taken corners of real markers (a quad across
        // two markers side by side), so stage 1 selects again without the ROIs that failed, and
        // only the ROIs not read yet go to stage 2.
        let mut rounds = Rounds::default();
        for round in 0..ROUNDS {
            let batch: Vec<Proposal> = search
                .proposals(&rounds.kept(), &rounds.failed)
                .into_iter()
                .filter(|p| rounds.is_new(p))
                .collect();
            if batch.is_empty() {
                break;
            }
            let trust = if round == 0 {
                Trust::First
            } else {
                Trust::Later
            };
            let reads = self.read_all(image, &batch, camera, trust, &mut timings);
            rounds.record(batch, reads);
        }
        // Then the quads the image shows away from the markers read, in rounds the same way:
        // first those outlined between stage 1's weaker corners, then those traced around dark
        // blobs (which needs no corner at all). Both searches are stage 1's work, and their
        // time is counted there.
        let search_clock = Stopwatch::start();
        let outlined = search.outline(image, &rounds.covered());
        let mut search_ms = search_clock.ms();
        self.read_rounds(
            image,
            &outlined,
            Trust::Later,
            camera,
            &mut rounds,
            &mut timings,
        );
        let search_clock = Stopwatch::start();
        let traced = search.traced(image, &rounds.covered());
        search_ms += search_clock.ms();
        self.read_rounds(
            image,
            &traced,
            Trust::Traced,
            camera,
            &mut rounds,
            &mut timings,
        );
        // Then the network's closer look, on the image doubled, around its strong corners that no
        // read accounts for (far slivers).
        let search_clock = Stopwatch::start();
        let looked =
            self.stage1
                .close_look(&search, image, &rounds.covered(), &self.options.propose);
        search_ms += search_clock.ms();
        self.read_rounds(
            image,
            &looked,
            Trust::Later,
            camera,
            &mut rounds,
            &mut timings,
        );
        // Then its stretched look across the directions of the strong corners still unexplained
        // (needles 5–20 px across).
        let search_clock = Stopwatch::start();
        let stretched =
            self.stage1
                .stretched_look(&search, image, &rounds.covered(), &self.options.propose);
        search_ms += search_clock.ms();
        self.read_rounds(
            image,
            &stretched,
            Trust::Later,
            camera,
            &mut rounds,
            &mut timings,
        );
        // Then quads of four of stage 1's corners that the image's edges confirm: a sliver's
        // corners all point along its length, so the grouping cannot pair them (dev: 3 of 1950
        // 36h11 and 1 of 1300 ArUco Difficult markers, none of them read otherwise).
        if self.options.edge_fits {
            let search_clock = Stopwatch::start();
            let cornered = search.corner_quads(image, &rounds.covered());
            search_ms += search_clock.ms();
            self.read_rounds(
                image,
                &cornered,
                Trust::Traced,
                camera,
                &mut rounds,
                &mut timings,
            );
        }
        // Then the quads no network read, moved onto the image's edges: a far sliver 8–12 px
        // across reads from corners within about a pixel, and stage 1's grid, a traced hull or
        // a closer look leave them 2–4 px off; its long sides' edges place them to a fraction
        // of a pixel (`stage1::edges`). Held like traced quads, since clutter fits too.
        if self.options.edge_fits {
            let mut refits: Vec<Proposal> = Vec::new();
            for p in rounds.failed.iter().chain(&rounds.unread) {
                if refits.len() == MAX_EDGE_REFITS {
                    break;
                }
                if rounds.over_a_marker_read(p) {
                    continue;
                }
                let Some(corners) = on_edges(image, p.corners) else {
                    continue;
                };
                let refit = Proposal { corners, ..*p };
                let tried =
                    |q: &Proposal| largest_corner_move(&q.corners, &corners) < MIN_REFIT_MOVE_PX;
                if !rounds.read.iter().chain(&refits).any(tried) {
                    refits.push(refit);
                }
            }
            let reads = self.read_all(image, &refits, camera, Trust::Traced, &mut timings);
            rounds.record(refits, reads);
        }
        // Last, the cells of the ROIs no network read (and of the image searches' quads left
        // unread), away from every marker read: after every round, so that a cell read of a
        // poor ROI never takes a marker's place from a network read of a better one (dev seed
        // 16 #6, 10 cm away: a cell read of a stage-1 ROI with its corners 80 px off covered
        // the ROI stage 2 read right a round later).
        if self.options.cell_reads {
            let mut left: Vec<Proposal> = Vec::new();
            let mut tried = 0;
            for (k, p) in rounds.failed.iter().chain(&rounds.unread).enumerate() {
                if !rounds.over_a_marker_read(p) && !left.iter().any(|q| same_quad(q, p)) {
                    left.push(*p);
                    if k < rounds.failed.len() {
                        tried = left.len();
                    }
                }
            }
            let reads = self.cell_reads(image, &left, tried, camera, &mut timings);
            rounds.found.extend(reads.into_iter().flatten());
        }
        timings.proposals = rounds.read.len();
        // Markers do not overlap: of two reads where either's centre lies inside the other (the
        // same marker read twice, or a quad over part of a marker and its surroundings read as
        // another code) the one whose code needed fewer corrections stays, the first on a tie.
        let mut kept: Vec<Found> = Vec::new();
        for f in rounds.found {
            let overlapping = kept
                .iter()
                .position(|g| nested(&g.marker.corners, &f.marker.corners));
            match overlapping {
                None => kept.push(f),
                Some(k) if f.marker.corrected_errors < kept[k].marker.corrected_errors => {
                    kept[k] = f
                }
                Some(_) => {}
            }
        }
        timings.stage1_ms += search_ms;
        timings.stage2_ms = clock.ms() - search_ms;
        (kept, timings)
    }

    /// Up to [`IMAGE_SEARCH_ROUNDS`] selections of the quads an image search found, at most
    /// [`MAX_IMAGE_SEARCH_READS`] new ones each, none over a marker already read; the quads left
    /// over are filed for cell reads.
    fn read_rounds(
        &self,
        image: &GrayImage,
        quads: &Outlined,
        trust: Trust,
        camera: Option<&Camera>,
        rounds: &mut Rounds,
        timings: &mut Timings,
    ) {
        for _ in 0..IMAGE_SEARCH_ROUNDS {
            let batch: Vec<Proposal> = rounds
                .fresh(quads)
                .into_iter()
                .take(MAX_IMAGE_SEARCH_READS)
                .collect();
            if batch.is_empty() {
                break;
            }
            let reads = self.read_all(image, &batch, camera, trust, timings);
            rounds.record(batch, reads);
        }
        // A cluttered image traces dozens of quads, largest first, and a far sliver comes
        // last: past the network's reads, it still gets a cell read.
        let unread = rounds.fresh(quads);
        rounds.unread.extend(unread);
    }

    /// Stage 2 of every family on every proposal: for each, the family that reads it, if any,
    /// with no more corrections than the proposals' [`Trust`] allows.
    fn read_all(
        &self,
        image: &GrayImage,
        proposals: &[Proposal],
        camera: Option<&Camera>,
        trust: Trust,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        // The first stage-2 pass of each family over every proposal in one batch (and one more
        // batch for the ROIs it decodes nothing from, from where their keypoints place them);
        // only the ROIs decoded get the second pass, the alignment and the pose.
        let rois: Vec<[[f64; 2]; 4]> = proposals.iter().map(|p| p.corners).collect();
        let mut best: Vec<Option<Found>> = vec![None; proposals.len()];
        // The traced searches' quads (blobs, corner quads, edge refits, fitted frames) go to
        // stage 2 only where they may frame a marker; the rest fail as stage 2 would have
        // failed them, and stay for the later searches and the cell reads.
        let sampled = (trust == Trust::Traced)
            .then(|| self.sample_for_prechecks(image, &rois))
            .flatten();
        for reader in &self.readers {
            let checked: Vec<usize> = match (&reader.precheck, &sampled) {
                (Some(check), Some(sampled)) => (0..rois.len())
                    .filter(|&i| check.passes(sampled[i].as_ref()))
                    .collect(),
                _ => (0..rois.len()).collect(),
            };
            let checked_rois: Vec<[[f64; 2]; 4]> = checked.iter().map(|&i| rois[i]).collect();
            timings.reads += checked_rois.len();
            let mut firsts = vec![None; rois.len()];
            for (i, first) in checked.iter().zip(reader.stage2.first_passes(
                image,
                &checked_rois,
                &self.options.read,
            )) {
                firsts[*i] = first;
            }
            // The rest of each read (second pass, alignment, pose) on both cores.
            use rayon::prelude::*;
            let read: Vec<(usize, Stage2Result)> = firsts
                .into_par_iter()
                .enumerate()
                .with_max_len(1)
                .filter_map(|(i, first)| {
                    let marker = reader.stage2.continue_from(
                        image,
                        first?,
                        &self.options.read,
                        camera.map(|c| (c, reader.side_m)),
                    )?;
                    Some((i, marker))
                })
                .collect();
            let read = read
                .into_iter()
                .filter(|(i, m)| reader.accepts(m, trust, proposals[*i].score));
            keep_fewest_corrections(&mut best, reader, proposals, read, false);
        }
        best
    }

    /// Each quad's samples for the families' pre-read checks, taken once whatever the number of
    /// families; `None` when no family has a check.
    fn sample_for_prechecks(
        &self,
        image: &GrayImage,
        quads: &[[[f64; 2]; 4]],
    ) -> Option<Vec<Option<QuadSample>>> {
        self.readers
            .iter()
            .any(|r| r.precheck.is_some())
            .then(|| quads.iter().map(|q| QuadSample::of(image, q)).collect())
    }

    /// Cell reads of the ROIs no family's network read (§9.8 "Cell reads"), once each is
    /// fitted to the marker's frame: held to half the family's limit in the code and in the
    /// frame. The alignment with the rendering still runs, but a sliver's is refused (its
    /// residual does not drop on 1-px cells), so it is not asked for.
    /// The first `tried` proposals failed in the network already.
    fn cell_reads(
        &self,
        image: &GrayImage,
        proposals: &[Proposal],
        tried: usize,
        camera: Option<&Camera>,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        let mut best: Vec<Option<Found>> = vec![None; proposals.len()];
        let rois: Vec<[[f64; 2]; 4]> = proposals.iter().map(|p| p.corners).collect();
        let sampled = self.sample_for_prechecks(image, &rois);
        // ROIs whose frame fitted but whose cells did not decode, with the fitted corners.
        let mut framed: Vec<(usize, Proposal)> = Vec::new();
        for reader in &self.readers {
            let Some(cells) = &reader.cells else {
                continue;
            };
            let limit = reader.family.codebook().max_correction() / 2;
            let single = ReadOptions {
                iterations: 1,
                ..self.options.read
            };
            use rayon::prelude::*;
            // Per ROI: the marker its cells read, or the corners its frame fitted.
            let outcomes: Vec<(usize, Result<Stage2Result, FittedCorners>)> = proposals
                .par_iter()
                .enumerate()
                .with_max_len(1)
                .filter_map(|(i, proposal)| {
                    // The frame fit scores hundreds of quads per ROI; one with no light inside
                    // has no cells to read.
                    if let (Some(check), Some(sampled)) = (&reader.precheck, &sampled) {
                        if !check.has_light_inside(sampled[i].as_ref()) {
                            return None;
                        }
                    }
                    let cell_read = match cells.read_or_frame(
                        &reader.family,
                        image,
                        &proposal.corners,
                        limit,
                    ) {
                        CellOutcome::Read(read) => read,
                        CellOutcome::Framed(corners) => return Some((i, Err(corners))),
                        CellOutcome::Unfit => return None,
                    };
                    let first = cell_result(&reader.family, &cell_read)?;
                    let marker = reader.stage2.continue_from(
                        image,
                        first,
                        &single,
                        camera.map(|c| (c, reader.side_m)),
                    )?;
                    (marker.fixed_mismatches <= limit).then_some((i, Ok(marker)))
                })
                .collect();
            let mut read = Vec::new();
            for (i, outcome) in outcomes {
                match outcome {
                    Ok(marker) => read.push((i, marker)),
                    Err(corners) => framed.push((
                        i,
                        Proposal {
                            corners,
                            ..proposals[i]
                        },
                    )),
                }
            }
            keep_fewest_corrections(&mut best, reader, proposals, read, true);
        }
        // The network reads a sliver from a ROI a pixel or two off that its cells, a pixel
        // wide, cannot: the fitted frame's corners go to stage 2, held like a traced quad.
        // A frame within a pixel of a ROI the network failed on is not worth its pass (the
        // speed sets: 2–3 ms a 640×480 image without this).
        framed.retain(|(i, p)| {
            best[*i].is_none()
                && (*i >= tried || largest_corner_move(&proposals[*i].corners, &p.corners) >= 1.0)
        });
        let mut fitted: Vec<(usize, Proposal)> = Vec::new();
        for (i, p) in framed {
            if !fitted.iter().any(|(_, q)| same_quad(q, &p)) {
                fitted.push((i, p));
            }
        }
        let rois: Vec<Proposal> = fitted.iter().map(|(_, p)| *p).collect();
        let reads = self.read_all(image, &rois, camera, Trust::Traced, timings);
        for ((i, _), read) in fitted.into_iter().zip(reads) {
            if best[i].is_none() {
                best[i] = read;
            }
        }
        best
    }
}

/// The corners of a ROI fitted to a marker's frame.
type FittedCorners = [[f64; 2]; 4];

/// Files one family's reads (proposal index, marker) into `best`: where two families read one
/// ROI, the one whose code needed fewer corrections stays.
fn keep_fewest_corrections(
    best: &mut [Option<Found>],
    reader: &FamilyReader,
    proposals: &[Proposal],
    reads: impl IntoIterator<Item = (usize, Stage2Result)>,
    cell_read: bool,
) {
    for (i, marker) in reads {
        if best[i]
            .as_ref()
            .is_none_or(|b| marker.corrected_errors < b.marker.corrected_errors)
        {
            best[i] = Some(Found {
                family: reader.family.name().into(),
                marker,
                proposal: proposals[i],
                cell_read,
            });
        }
    }
}

/// A cell read as stage 2's first pass would give it: every keypoint where the ROI's homography
/// puts it, in the family's canonical order.
fn cell_result(family: &Family, read: &CellRead) -> Option<Stage2Result> {
    let rotation = &family.rotations()[read.decoded.rotation];
    let kps = family.keypoints();
    let keypoints: Vec<DetectedKeypoint> = (0..kps.len())
        .map(|i| {
            let slot = rotation.keypoint_perm[i];
            let [x, y] = read.centres[slot];
            let category = read.observed[slot];
            DetectedKeypoint {
                index: i,
                x,
                y,
                category,
                symbol: matches!(kps[i].assignment, Assignment::Symbol(_))
                    .then(|| family.category_symbol(category))
                    .flatten(),
                confidence: read.margins[slot],
            }
        })
        .collect();
    let canonical: Vec<[f64; 2]> = kps.iter().map(|k| k.pos).collect();
    let pixels: Vec<[f64; 2]> = keypoints.iter().map(|k| [k.x, k.y]).collect();
    let to_pixels = Homography::from_points(&canonical, &pixels).ok()?;
    let roi = family.roi_points();
    Some(Stage2Result {
        id: read.decoded.id,
        rotation_deg: rotation.angle_deg,
        corrected_errors: read.decoded.corrected_errors,
        fixed_mismatches: read.decoded.fixed_mismatches,
        corners: std::array::from_fn(|j| to_pixels.apply(roi[j])),
        missing: 0,
        keypoints,
        iterations: 1,
        passes_agree: true,
        from_keypoints: false,
        refinement: None,
        pose: None,
    })
}

/// The largest keypoint reprojection RMS, in cell pitches, of a read that needed more than the
/// family's hard-decision corrections ([`FamilyReader::rigid`]).
const MAX_RIGID_RMS_PITCH: f64 = 0.25;

/// The most a read from a failed first pass's keypoints may reproject, in cell pitches, when it
/// needs more than half the family's corrections (see [`FamilyReader::accepts`]).
const MAX_KEYPOINT_READ_RMS_PITCH: f64 = 0.1;

/// Stage-1 selections per image at most: the first, and two more without the ROIs no family
/// read.
const ROUNDS: usize = 3;

/// Selections of each image search's quads per image at most, and reads in each.
const IMAGE_SEARCH_ROUNDS: usize = 3;
const MAX_IMAGE_SEARCH_READS: usize = 4;

/// Quads refitted to the image's edges and read again, per image at most.
const MAX_EDGE_REFITS: usize = 8;

/// A refitted quad whose corners all lie this close to a quad read already is not read again
/// (pixels): the read would be the same.
const MIN_REFIT_MOVE_PX: f64 = 0.5;

/// How far a proposal's source is trusted: how many of the family's corrections its code may
/// need. Clutter decodes as some code at the edge of the correction limit (a 36-symbol read at
/// random lies within 5 symbols of one of 36h11's 587 codes in four turns once in 66 reads,
/// within 2 once in 44 000, within 3 once in about 2 500), so the sources that bring more
/// clutter are held to fewer.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Trust {
    /// Stage 1's first selection: whatever the decoder accepts (with erasures it may correct
    /// more than the family's limit for errors alone: 7 on a σ 125 read of 36h11), but for ROIs
    /// stage 1 scores below [`WEAK_ROI_SCORE`], which are held like traced quads.
    First,
    /// A later selection, which stage 1 ranked below ROIs no family could read, or a quad
    /// outlined between weaker corners: half the limit.
    Later,
    /// A quad traced around a dark blob the network's mask calls marker: one more than half.
    /// A steep view traced 2 px off needs 3 of 36h11's 5 (dev set: one marker); a blob of
    /// clutter must be convex, quadrilateral, dark on light and under the mask to be read at all.
    Traced,
}

impl Trust {
    /// The corrections a read of a ROI with stage-1 score `score` may need.
    fn allowed(self, limit: usize, score: f64) -> usize {
        match self {
            Trust::First if score >= WEAK_ROI_SCORE => usize::MAX,
            Trust::First | Trust::Traced => (limit / 2 + 1).min(limit),
            Trust::Later => limit / 2,
        }
    }
}

/// Below this stage-1 score a first-selection ROI is held to the traced quads' limit. A
/// cluttered photograph sends dozens of such ROIs to stage 2 (70 per swarmathon photograph), and
/// a read at the correction limit then comes out of clutter about once per photograph; within 3
/// corrections, once in ~40.
const WEAK_ROI_SCORE: f64 = 0.3;

/// What the rounds of one image have sent to stage 2 so far.
#[derive(Default)]
struct Rounds {
    read: Vec<Proposal>,
    failed: Vec<Proposal>,
    found: Vec<Found>,
    /// Image-search quads left over when the rounds' reads ran out: cell reads only.
    unread: Vec<Proposal>,
}

impl Rounds {
    /// The markers read so far, by their corners.
    fn covered(&self) -> Vec<[[f64; 2]; 4]> {
        self.found.iter().map(|f| f.marker.corners).collect()
    }

    /// The ROIs read as markers: their corners are spoken for in the next selection.
    fn kept(&self) -> Vec<Proposal> {
        self.found.iter().map(|f| f.proposal).collect()
    }

    /// The quads an image search found that are not sent to stage 2 yet nor over a marker read,
    /// selected as [`Outlined::proposals`] does.
    fn fresh(&self, quads: &Outlined) -> Vec<Proposal> {
        quads
            .proposals(&self.kept(), &self.failed)
            .into_iter()
            .filter(|p| self.is_new(p) && !self.over_a_marker_read(p))
            .collect()
    }

    fn over_a_marker_read(&self, p: &Proposal) -> bool {
        self.found
            .iter()
            .any(|f| nested(&f.marker.corners, &p.corners))
    }

    fn is_new(&self, p: &Proposal) -> bool {
        !self.read.iter().any(|r| same_quad(p, r))
    }

    /// Files each proposal of a batch as found or failed by its read.
    fn record(&mut self, batch: Vec<Proposal>, reads: Vec<Option<Found>>) {
        for (proposal, read_as) in batch.iter().zip(reads) {
            match read_as {
                Some(f) => self.found.push(f),
                None => self.failed.push(*proposal),
            }
        }
        self.read.extend(batch);
    }
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
        Detector::detect(self, image)
            .0
            .iter()
            .map(Found::detection)
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_family_without_weights_is_named_with_the_command_that_trains_them() {
        let family = crate::builtin::get("aruco-4x4_50").unwrap().unwrap();
        let e = Detector::shipped(vec![family]).err().unwrap().to_string();
        assert!(e.contains("aruco-4x4_50"), "{e}");
        assert!(
            e.contains("tagsmith train aruco-4x4_50 --stage keypoints"),
            "{e}"
        );
        let stage1 = Stage1::shipped().unwrap();
        assert!(matches!(
            Detector::new(stage1, Vec::new()),
            Err(DetectorError::NoFamilies)
        ));
    }

    /// A weak first-selection ROI is held like a traced quad; a strong one takes whatever the
    /// decoder accepts; later selections half the limit.
    #[test]
    fn weak_rois_are_trusted_with_fewer_corrections() {
        assert_eq!(Trust::First.allowed(5, 0.8), usize::MAX);
        assert_eq!(Trust::First.allowed(5, 0.12), 3);
        assert_eq!(Trust::Traced.allowed(5, 0.9), 3);
        assert_eq!(Trust::Later.allowed(5, 0.9), 2);
    }

    /// A read with 4 of 36h11's 5 corrections from a 100 px marker: kept from a first pass
    /// over its ROI; from the keypoints of one that decoded nothing, only where its pose
    /// reprojects within a tenth of a cell pitch (12.5 px: 1.25 px).
    #[test]
    fn a_read_from_a_failed_passs_keypoints_needing_many_corrections_must_fit_its_pose() {
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let reader = FamilyReader::shipped(family).unwrap();
        let read = |from_keypoints: bool, rms_px: f64| Stage2Result {
            id: 7,
            rotation_deg: 0.0,
            corrected_errors: 4,
            fixed_mismatches: 0,
            corners: [[0.0, 0.0], [100.0, 0.0], [100.0, 100.0], [0.0, 100.0]],
            keypoints: Vec::new(),
            missing: 0,
            iterations: 2,
            passes_agree: true,
            from_keypoints,
            refinement: None,
            pose: Some(crate::pose::PnpSolution {
                pose: crate::pose::Pose {
                    rotation: nalgebra::Rotation3::identity(),
                    translation: nalgebra::Vector3::new(0.0, 0.0, 0.5),
                },
                rms_px,
                iterations: 1,
                ambiguity_ratio: None,
                covariance: None,
            }),
        };
        assert!(reader.accepts(&read(false, 3.0), Trust::First, 0.9));
        assert!(reader.accepts(&read(true, 0.4), Trust::First, 0.9));
        assert!(!reader.accepts(&read(true, 3.0), Trust::First, 0.9));
        // Within half the corrections the pose is not asked for.
        let few = Stage2Result {
            corrected_errors: 2,
            ..read(true, 3.0)
        };
        assert!(reader.accepts(&few, Trust::First, 0.9));
        // Passes that disagree still refuse it, as any read with many corrections.
        let disagreeing = Stage2Result {
            passes_agree: false,
            ..read(true, 0.4)
        };
        assert!(!reader.accepts(&disagreeing, Trust::First, 0.9));
    }

    /// A marker 60 cm away at 65°, 62 × 25 px (development seed 22 #57, cut at x 700–1100,
    /// y 330–630).
    const STEEP: &[u8] = include_bytes!("testdata/steep-60cm-65deg.png");
    const STEEP_TRUTH: [[f64; 2]; 4] = [
        [255.92, 194.07],
        [222.53, 141.59],
        [243.33, 159.47],
        [275.62, 209.46],
    ];

    /// A quad 6 px off fails in the network and in the cells, but its frame fits: the network
    /// reads the marker from the fitted corners. (Its quad fitted to the image's edges reads
    /// too; that read is off here, as it comes first.)
    #[test]
    fn the_network_reads_a_marker_from_the_frame_its_cells_fitted() {
        let image = crate::image::decode(STEEP, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = detector_for_search_tests(family);
        detector.options.edge_fits = false;
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(!found[0].cell_read);
        assert_eq!(found[0].marker.id, 547);
        assert_corners_within(&found[0], &STEEP_TRUTH, 1.5);
        detector.options.cell_reads = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// The shipped stage 2 behind the stage 1 these tests were built on
    /// ([`crate::detect::stage1::pipeline::stage1_for_search_tests`]).
    fn detector_for_search_tests(family: Family) -> Detector {
        let stage1 = crate::detect::stage1::pipeline::stage1_for_search_tests();
        Detector::new(stage1, vec![FamilyReader::shipped(family).unwrap()]).unwrap()
    }

    fn assert_corners_within(found: &Found, truth: &[[f64; 2]; 4], px: f64) {
        let worst = largest_corner_move(&found.marker.corners, truth);
        assert!(worst < px, "corners {worst:.2} px off");
    }

    /// The closer look is what reads a far sliver: without it nothing is found there. (The
    /// stretched look, which comes after it, reads this one too: off here.)
    #[test]
    fn a_far_sliver_is_read_after_a_closer_look() {
        use crate::detect::stage1::pipeline::{FAR_SLIVER, FAR_SLIVER_TRUTH};
        let image = crate::image::decode(FAR_SLIVER, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = detector_for_search_tests(family);
        detector.options.propose.stretched_look = false;
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].marker.id, 456);
        assert_corners_within(&found[0], &FAR_SLIVER_TRUTH, 1.5);
        detector.options.propose.close_look = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// `tagsmith eval generate apriltag-36h11 --seed 43 --per-cell 5`, image 498, cut at x
    /// 593–913, y 472–712: ID 158 100 cm away at 75°, a needle 45 px long and 6 px across.
    const THIN_NEEDLE: &[u8] = include_bytes!("testdata/needle-100cm-75deg.png");
    const THIN_NEEDLE_TRUTH: [[f64; 2]; 4] = [
        [149.39, 120.01],
        [139.42, 108.92],
        [171.99, 120.83],
        [180.9, 131.74],
    ];

    /// The shipped networks read this needle only through the stretched look: neither the
    /// network's grouping nor any other search finds it (the shipped stage 1, not the one the
    /// other search tests pin: the stretched look was built on it).
    #[test]
    fn a_thin_needle_is_read_after_a_stretched_look() {
        let image = crate::image::decode(THIN_NEEDLE, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = Detector::shipped(vec![family]).unwrap();
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].marker.id, 158);
        assert_corners_within(&found[0], &THIN_NEEDLE_TRUTH, 1.5);
        detector.options.propose.stretched_look = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// `tagsmith eval generate apriltag-36h11 --seed 40 --per-cell 5`, image 398, cut at x
    /// 714–1034, y 518–758: ID 388 80 cm away at 75°, turned so that it is a rhombus 70 px long
    /// and 6 px across, on flat background.
    const FAR_RHOMBUS: &[u8] = include_bytes!("testdata/far-rhombus-80cm-75deg.png");
    const FAR_RHOMBUS_TRUTH: [[f64; 2]; 4] = [
        [160.67, 124.61],
        [125.78, 110.33],
        [157.73, 113.76],
        [194.12, 128.86],
    ];

    /// The closer look's crop, normalised as the whole image is, shows the network the rhombus
    /// it finds in the image doubled; normalised by its own contrast, or centred on the
    /// rhombus's end, it showed nothing. (The stretched look, which comes after it, reads this
    /// one too: off here.)
    #[test]
    fn a_far_rhombus_is_read_after_a_closer_look_through_the_images_contrast() {
        let image = crate::image::decode(FAR_RHOMBUS, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = detector_for_search_tests(family);
        detector.options.propose.stretched_look = false;
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].marker.id, 388);
        assert_corners_within(&found[0], &FAR_RHOMBUS_TRUTH, 1.5);
        detector.options.propose.close_look = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// A cluttered scene (`tagsmith eval generate apriltag-36h11 --seed 16`, image 96, cut at x
    /// 0–640, y 150–630) with a marker 100 cm away at 60°, 10 px across (ID 483): its dark
    /// blobs trace more quads than the network reads, largest first, and the marker's comes
    /// after them.
    const CLUTTERED: &[u8] = include_bytes!("testdata/cluttered-100cm-60deg.png");
    const CLUTTERED_TRUTH: [[f64; 2]; 4] = [
        [317.47, 317.16],
        [306.80, 317.55],
        [281.22, 287.25],
        [291.01, 285.51],
    ];

    /// The traced quads the network's reads do not reach still get cell reads. (The stretched
    /// look and the edge fits read this one too, before the cells: off here.)
    #[test]
    fn a_sliver_traced_past_the_networks_reads_is_read_by_its_cells() {
        let image = crate::image::decode(CLUTTERED, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = detector_for_search_tests(family);
        detector.options.propose.stretched_look = false;
        detector.options.edge_fits = false;
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].cell_read);
        assert_eq!(found[0].marker.id, 483);
        assert_corners_within(&found[0], &CLUTTERED_TRUTH, 1.5);
        detector.options.cell_reads = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// An ArUco 6x6_250 marker 100 cm away at 60°, 10 px across (ID 181; `tagsmith eval
    /// generate aruco-6x6_250 --seed 40 --per-cell 5`, image 480, cut at x 600–1240, y
    /// 150–630): the one quad the searches propose for it, traced, is 2–3 px off at two
    /// corners, too far for stage 2 on a marker 10 px across.
    const EDGE_SLIVER: &[u8] = include_bytes!("testdata/aruco-sliver-100cm-60deg.png");
    const EDGE_SLIVER_TRUTH: [[f64; 2]; 4] = [
        [309.79, 220.48],
        [320.01, 251.80],
        [309.15, 237.93],
        [298.74, 205.61],
    ];

    /// Moved onto the image's edges, a quad stage 2 failed on is read. (The stretched look,
    /// which comes before the edge fits, reads this one too: off here.)
    #[test]
    fn a_sliver_is_read_once_its_quad_is_fitted_to_the_edges() {
        let image = crate::image::decode(EDGE_SLIVER, &Default::default()).unwrap();
        let family = crate::builtin::get("aruco-6x6_250").unwrap().unwrap();
        let mut detector = Detector::shipped(vec![family]).unwrap();
        detector.options.propose.stretched_look = false;
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].marker.id, 181);
        assert_corners_within(&found[0], &EDGE_SLIVER_TRUTH, 2.0);
        detector.options.edge_fits = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    /// A 36h11 marker 70 cm away at 75°, seen along its diagonal: a needle 87 px long and 17 px
    /// at its waist (ID 55; `tagsmith eval generate apriltag-36h11 --seed 41 --per-cell 5`,
    /// image 348, cut at x 640–1280, y 430–910). Stage 1 finds corners near all four of its
    /// corners, but each points along the needle, so the grouping pairs none of them.
    const NEEDLE: &[u8] = include_bytes!("testdata/needle-70cm-75deg.png");
    const NEEDLE_TRUTH: [[f64; 2]; 4] = [
        [318.78, 237.73],
        [353.10, 251.80],
        [302.52, 243.06],
        [268.69, 229.63],
    ];

    /// Four corners whose sides the image's edges confirm make the needle's quad.
    #[test]
    fn a_needle_is_read_from_four_corners_its_edges_confirm() {
        let image = crate::image::decode(NEEDLE, &Default::default()).unwrap();
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        let mut detector = Detector::shipped(vec![family]).unwrap();
        let (found, _) = detector.detect_with(&image, None);
        assert_eq!(found.len(), 1, "{found:?}");
        assert_eq!(found[0].marker.id, 55);
        // The tips, where two sides meet at 12°, move along the needle with the slightest turn
        // of either side.
        assert_corners_within(&found[0], &NEEDLE_TRUTH, 2.5);
        detector.options.edge_fits = false;
        assert!(detector.detect_with(&image, None).0.is_empty());
    }

    #[test]
    fn dark_blobs_cost_no_stage_2_pass_once_checked() {
        let family = crate::builtin::get("apriltag-36h11").unwrap().unwrap();
        // Dark squares on light ground: a marker's outline with nothing light inside.
        let mut image = GrayImage::new(320, 240, 200);
        for (x0, y0, side) in [(20, 30, 48), (120, 60, 64), (220, 120, 80)] {
            for y in y0..y0 + side {
                for x in x0..x0 + side {
                    image.pixels[(y * 320 + x) as usize] = 25;
                }
            }
        }
        let mut detector = Detector::shipped(vec![family]).unwrap();
        let (found, checked) = detector.detect(&image);
        assert!(found.is_empty());
        detector.readers[0].precheck = None;
        let (found, unchecked) = detector.detect(&image);
        assert!(found.is_empty());
        // One pass saved per blob at least.
        assert!(
            checked.reads + 3 <= unchecked.reads,
            "{} stage-2 passes with the check, {} without",
            checked.reads,
            unchecked.reads
        );
    }

    #[test]
    fn a_marker_free_image_gives_no_detection() {
        let families = ["apriltag-36h11", "aruco-6x6_250"]
            .iter()
            .map(|n| crate::builtin::get(n).unwrap().unwrap())
            .collect();
        let detector = Detector::shipped(families).unwrap();
        let flat = GrayImage::new(320, 240, 128);
        let (found, timings) = detector.detect(&flat);
        assert!(found.is_empty());
        assert_eq!(timings.reads, 2 * timings.proposals);
    }
}
