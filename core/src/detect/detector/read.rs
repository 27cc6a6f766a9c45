//! The verify and read phases: which families' stage 2 each candidate quad goes to, then the
//! reads themselves (stage 2, decoding, the alignment with the rendering, the pose), each kept
//! only where its evidence is what its source's trust asks for.

use super::reconcile::Evidence;
use super::sources::{AcceptParams, Capability, SourceParams, Trust};
use super::{Detector, FamilyReader, Found, Timings};
use crate::detect::cells::{CellOutcome, CellRead, CellReader, Fitted};
use crate::detect::precheck::QuadSample;
use crate::detect::stage1::group::{same_quad, Proposal};
use crate::detect::stage2::{PassMemo, ReadOptions, RetryGate, Stage2Result};
use crate::detect::verifier::Verifier;
use crate::detect::DetectedKeypoint;
use crate::family::{Assignment, Family};
use crate::geometry::{Camera, Homography, Quad};
use crate::image::GrayImage;
use crate::io::Stopwatch;
use rayon::prelude::*;

/// One selection of a source's quads, as the read phase sees it.
#[derive(Clone, Copy)]
pub(super) struct Batch<'a> {
    pub params: &'a SourceParams,
    pub trust: Trust,
    /// Whether the quads are the ROIs themselves (stage 1 on the inverted image), not the dark
    /// outlines around them.
    pub rois_inside: bool,
}

impl FamilyReader {
    /// Whether the family has what a source assumes of its markers.
    pub(super) fn has(&self, capability: Capability) -> bool {
        match capability {
            Capability::Any => true,
            Capability::Quadrilateral => self.rings.is_none(),
            Capability::RingsOfDots => self.rings.is_some(),
            Capability::DarkFrame => self.precheck.is_some(),
            Capability::FlatCells => self.cells.is_some(),
            Capability::LightInsideFrame => self.outline.is_some(),
        }
    }

    /// Whether the detector keeps a read of a proposal with this trust and ROI score.
    ///
    /// A uniform code is not kept unless [`AcceptParams::read_uniform_codes`] says so. A read
    /// needing more than half the corrections must decode alike in every pass and fit a rigid
    /// pose closely ([`AcceptParams::max_weak_read_rms_pitch`]): a misread of a marker
    /// under heavy noise lands on some code within the limit, and the next pass, from a ROI that
    /// moved, on another or on none, where a right read decodes again; a quad across a row of
    /// markers read as one code reprojects by a large part of a cell. A read from the keypoints
    /// of a first pass that decoded nothing must, with more than half the corrections, fit its
    /// pose more closely still ([`AcceptParams::max_keypoint_read_rms_pitch`]), and so must any
    /// read of a code too short to correct ([`AcceptParams::max_short_code_rms_pitch`]).
    pub(super) fn accepts(
        &self,
        m: &Stage2Result,
        trust: Trust,
        roi_score: f64,
        params: &AcceptParams,
    ) -> bool {
        let limit = self.correction_limit(params);
        let fits = |max: f64| self.rms_pitch(m).is_none_or(|rms| rms <= max);
        let uniform = (self.family.codebook().code(m.id))
            .is_some_and(|code| code.windows(2).all(|pair| pair[0] == pair[1]));
        (params.read_uniform_codes || !uniform)
            && (!self.too_short_to_correct(params) || fits(params.max_short_code_rms_pitch))
            && m.corrected_errors <= limit
            && m.corrected_errors <= trust.allowed(limit, roi_score, params.weak_roi_score)
            && (m.corrected_errors <= limit / 2
                || (m.passes_agree
                    && fits(params.max_weak_read_rms_pitch)
                    && (!m.from_keypoints || fits(params.max_keypoint_read_rms_pitch))))
    }

    /// The most corrected symbols a read of the family may need: the codebook's limit, or none
    /// for a code too short to correct ([`AcceptParams::min_symbols_to_correct`]).
    pub(super) fn correction_limit(&self, params: &AcceptParams) -> usize {
        if self.too_short_to_correct(params) {
            0
        } else {
            self.family.codebook().max_correction()
        }
    }

    /// Whether the family's codes are read only as they are
    /// ([`AcceptParams::min_symbols_to_correct`]).
    fn too_short_to_correct(&self, params: &AcceptParams) -> bool {
        self.family.codebook().code_len() < params.min_symbols_to_correct
    }

    /// The read's keypoint reprojection RMS from its pose, in cell pitches in the image (`None`
    /// for a read without a pose).
    pub(super) fn rms_pitch(&self, marker: &Stage2Result) -> Option<f64> {
        let pose = marker.pose.as_ref()?;
        let pitch = self.family.keypoint_pitch() / self.family.roi_side();
        let side = marker.corners.sides().iter().sum::<f64>() / 4.0;
        Some(pose.rms_px / (pitch * side).max(f64::MIN_POSITIVE))
    }

    fn evidence(&self, marker: &Stage2Result) -> Evidence {
        Evidence {
            corrections: marker.corrected_errors,
            rms_pitch: self.rms_pitch(marker),
            strong: marker.corrected_errors <= self.family.codebook().max_correction() / 2,
        }
    }
}

impl Detector {
    /// The verify phase: for each family that may read the batch's quads, the quads it reads.
    /// A source whose quads are mostly clutter has them pass each family's pre-read check first;
    /// the rest fail as stage 2 would have failed them.
    ///
    /// A quad its source trusts whatever the corrections (stage 1's first selection, scored at
    /// least [`AcceptParams::weak_roi_score`]) is not checked: such a ROI a few pixels off
    /// samples the quiet zone as rim, and a marker read from it at the correction limit would
    /// be lost.
    fn verify(
        &self,
        image: &GrayImage,
        proposals: &[Proposal],
        batch: Batch,
        timings: &mut Timings,
    ) -> Vec<Vec<usize>> {
        let clock = Stopwatch::start();
        let rois: Vec<Quad> = proposals.iter().map(|p| p.corners).collect();
        let weak = self.options.accept.weak_roi_score;
        let trusted = |i: usize| batch.trust == Trust::First && proposals[i].score >= weak;
        let sampled = batch
            .params
            .precheck
            .then(|| self.sample_for_prechecks(image, &rois))
            .flatten();
        let framed = self.framing_markers(image, &rois, timings);
        let verified = (self.readers.iter())
            .map(|reader| {
                if !reader.has(batch.params.needs) {
                    return Vec::new();
                }
                let judged = reader.has(Capability::DarkFrame);
                let candidates = (0..rois.len()).filter(|&i| !judged || framed[i]);
                match (&reader.precheck, &sampled) {
                    (Some(check), Some(sampled)) => candidates
                        .filter(|&i| trusted(i) || check.passes(sampled[i].as_ref()))
                        .collect(),
                    _ => candidates.collect(),
                }
            })
            .collect();
        timings.verify_ms += clock.ms();
        verified
    }

    /// Whether the learned verifier lets each quad on to stage 2 (every quad, without one).
    ///
    /// Its verdict counts for the families whose markers sit on a dark frame (those with a
    /// pre-read check): it keeps fewer of the others' markers (a TopoTag's dark square with its
    /// blobs), and a fresh seed lost some of them to it (BENCHMARKS.md, "A learned verifier").
    fn framing_markers(
        &self,
        image: &GrayImage,
        rois: &[Quad],
        timings: &mut Timings,
    ) -> Vec<bool> {
        let judged = self.readers.iter().any(|r| r.has(Capability::DarkFrame));
        match self.verifier_on().filter(|_| judged && !rois.is_empty()) {
            Some(verifier) => {
                let framed = self.verified_by(verifier, image, rois);
                timings.turned_away += framed.iter().filter(|&&f| !f).count();
                framed
            }
            None => vec![true; rois.len()],
        }
    }

    /// The verifier, unless there is none or its threshold turns it off.
    fn verifier_on(&self) -> Option<&Verifier> {
        (self.verifier.as_ref()).filter(|_| self.options.verifier.min_score > 0.0)
    }

    /// Whether `verifier` scores each quad at least the threshold.
    fn verified_by(&self, verifier: &Verifier, image: &GrayImage, quads: &[Quad]) -> Vec<bool> {
        let min_score = self.options.verifier.min_score;
        (verifier.scores(image, quads).iter())
            .map(|&s| s >= min_score)
            .collect()
    }

    /// Verify, then read: stage 2 of every family on every proposal it verified; for each
    /// proposal, the family that reads it, if any, with no more corrections than the batch's
    /// trust allows.
    pub(super) fn read_all(
        &self,
        image: &GrayImage,
        proposals: &[Proposal],
        camera: Option<&Camera>,
        batch: Batch,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        self.read_by(
            None,
            &self.options.read,
            image,
            proposals,
            camera,
            batch,
            timings,
        )
    }

    /// [`Detector::read_all`] with the family of `self.readers[reader]` alone, read as `read`
    /// says.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn read_one_family(
        &self,
        reader: usize,
        read: &ReadOptions,
        image: &GrayImage,
        proposals: &[Proposal],
        camera: Option<&Camera>,
        batch: Batch,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        self.read_by(Some(reader), read, image, proposals, camera, batch, timings)
    }

    #[allow(clippy::too_many_arguments)]
    fn read_by(
        &self,
        only: Option<usize>,
        read_options: &ReadOptions,
        image: &GrayImage,
        proposals: &[Proposal],
        camera: Option<&Camera>,
        batch: Batch,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        let rois: Vec<Quad> = proposals.iter().map(|p| p.corners).collect();
        let verified = self.verify(image, proposals, batch, timings);
        let clock = Stopwatch::start();
        let mut best: Vec<Option<Found>> = vec![None; proposals.len()];
        // Families sharing weights read each quad with one pass between them; a family sharing
        // with none keeps its outputs only while it reads.
        let mut memo = PassMemo::default();
        let mut verified: Vec<Option<Vec<usize>>> = verified.into_iter().map(Some).collect();
        for r in self.reading_order() {
            let reader = &self.readers[r];
            let checked = verified[r].take().unwrap_or_default();
            // A quad read without a correction keeps that read: another family's of it could at
            // best tie, and a marker is one family's (on the Detect panel's three families an
            // ArUco tag read exactly costs XO's model no pass).
            let checked: Vec<usize> = (checked.into_iter())
                .filter(|&i| {
                    best[i]
                        .as_ref()
                        .is_none_or(|b| b.marker.corrected_errors > 0)
                })
                .collect();
            if checked.is_empty() || only.is_some_and(|o| o != r) {
                continue;
            }
            // The first stage-2 pass over every verified quad in one batch (and the retries from
            // their keypoints); only the ROIs decoded get the second pass, the alignment and the
            // pose.
            let roi_of = |quad: &Quad| match batch.rois_inside {
                true => *quad,
                false => reader.roi_of(quad),
            };
            let checked_rois: Vec<Quad> = checked.iter().map(|&i| roi_of(&rois[i])).collect();
            timings.reads += checked_rois.len();
            let options = ReadOptions {
                retried_rois: batch.params.retried_rois,
                ..*read_options
            };
            let shares = (self.readers.iter().enumerate())
                .any(|(o, other)| o != r && other.stage2.shares_passes_with(&reader.stage2));
            // A retry from a failed pass's keypoints is a fresh quad: the verifier judges it too.
            let verifier = self
                .verifier_on()
                .filter(|_| reader.has(Capability::DarkFrame));
            let gate = verifier.map(|v| move |quads: &[Quad]| self.verified_by(v, image, quads));
            let retry_gate = gate.as_ref().map(|g| g as RetryGate);
            let mut own = PassMemo::default();
            let memo = if shares { &mut memo } else { &mut own };
            let (first_reads, passes) = (reader.stage2).first_passes_shared(
                image,
                &checked_rois,
                &options,
                memo,
                retry_gate,
            );
            timings.passes += passes;
            let mut firsts = vec![None; rois.len()];
            for (i, first) in checked.iter().zip(first_reads) {
                firsts[*i] = first;
            }
            let read: Vec<(usize, Stage2Result, usize)> = firsts
                .into_par_iter()
                .enumerate()
                .with_max_len(1)
                .filter_map(|(i, first)| {
                    let first = first?;
                    let passes = read_options.iterations.saturating_sub(1);
                    let marker = reader.stage2.continue_from(
                        image,
                        first,
                        read_options,
                        camera.map(|c| (c, reader.side_m)),
                    )?;
                    Some((i, marker, passes))
                })
                .collect();
            timings.passes += read.iter().map(|(_, _, passes)| passes).sum::<usize>();
            let read = read.into_iter().map(|(i, m, _)| (i, m));
            let accept = &self.options.accept;
            let read =
                read.filter(|(i, m)| reader.accepts(m, batch.trust, proposals[*i].score, accept));
            keep_fewest_corrections(&mut best, &self.readers, r, proposals, read, false);
        }
        timings.read_ms += clock.ms();
        best
    }

    /// The readers' indices, those that share a network's passes next to each other, the
    /// networks most families share first (then in the order named): a family's exact reads
    /// spare the families after it, and a shared network reads the most families' markers.
    fn reading_order(&self) -> Vec<usize> {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for r in 0..self.readers.len() {
            let stage2 = &self.readers[r].stage2;
            match (groups.iter_mut()).find(|g| self.readers[g[0]].stage2.shares_passes_with(stage2))
            {
                Some(group) => group.push(r),
                None => groups.push(vec![r]),
            }
        }
        // Stable: groups of one size keep the order their first family was named in.
        groups.sort_by_key(|g| std::cmp::Reverse(g.len()));
        groups.concat()
    }

    /// Each quad's samples for the families' pre-read checks, taken once whatever the number of
    /// families; `None` when no family has a check.
    fn sample_for_prechecks(
        &self,
        image: &GrayImage,
        quads: &[Quad],
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
    pub(super) fn cell_reads(
        &self,
        image: &GrayImage,
        proposals: &[Proposal],
        tried: usize,
        camera: Option<&Camera>,
        batch: Batch,
        timings: &mut Timings,
    ) -> Vec<Option<Found>> {
        let mut best: Vec<Option<Found>> = vec![None; proposals.len()];
        let rois: Vec<Quad> = proposals.iter().map(|p| p.corners).collect();
        let clock = Stopwatch::start();
        let sampled = self.sample_for_prechecks(image, &rois);
        timings.verify_ms += clock.ms();
        let clock = Stopwatch::start();
        // ROIs whose frame fitted but whose cells did not decode, with the fitted corners.
        let mut framed: Vec<(usize, Proposal)> = Vec::new();
        let single = ReadOptions {
            iterations: 1,
            ..self.options.read
        };
        // The readers' frame fits: families of one layout share one (the fit scores hundreds
        // of quads per ROI; reading the cells against a codebook is cheap).
        let cell_readers: Vec<(usize, &CellReader)> = (self.readers.iter().enumerate())
            .filter_map(|(r, reader)| reader.cells.as_ref().map(|cells| (r, cells)))
            .collect();
        let frame_of: Vec<usize> = (cell_readers.iter())
            .map(|(_, cells)| {
                (cell_readers.iter())
                    .position(|(_, other)| other.same_frame(cells))
                    .unwrap_or_default()
            })
            .collect();
        // Per ROI, per reader with cells: the marker its cells read, or the corners its frame
        // fitted.
        type Outcome = Option<Result<Stage2Result, FittedCorners>>;
        let outcomes: Vec<Vec<Outcome>> = proposals
            .par_iter()
            .enumerate()
            .with_max_len(1)
            .map(|(i, proposal)| {
                let mut frames: Vec<Option<Option<Fitted>>> = vec![None; cell_readers.len()];
                (cell_readers.iter().enumerate())
                    .map(|(k, &(r, cells))| {
                        let reader = &self.readers[r];
                        // One with no light inside has no cells to read.
                        if let (Some(check), Some(sampled)) = (&reader.precheck, &sampled) {
                            if !check.has_light_inside(sampled[i].as_ref()) {
                                return None;
                            }
                        }
                        let frame = *frames[frame_of[k]].get_or_insert_with(|| {
                            cells.frame(image, &reader.roi_of(&proposal.corners))
                        });
                        let limit = reader.correction_limit(&self.options.accept) / 2;
                        let cell_read =
                            match cells.read_fitted(&reader.family, image, frame.as_ref(), limit) {
                                CellOutcome::Read(read) => read,
                                CellOutcome::Framed(corners) => return Some(Err(corners)),
                                CellOutcome::Unfit => return None,
                            };
                        let first = cell_result(&reader.family, &cell_read)?;
                        let marker = reader.stage2.continue_from(
                            image,
                            first,
                            &single,
                            camera.map(|c| (c, reader.side_m)),
                        )?;
                        (marker.fixed_mismatches <= limit).then_some(Ok(marker))
                    })
                    .collect()
            })
            .collect();
        for (k, &(r, _)) in cell_readers.iter().enumerate() {
            let mut read = Vec::new();
            for (i, per_reader) in outcomes.iter().enumerate() {
                match &per_reader[k] {
                    Some(Ok(marker)) => read.push((i, marker.clone())),
                    Some(Err(corners)) => framed.push((
                        i,
                        Proposal {
                            corners: self.readers[r].proposal_of(corners),
                            ..proposals[i]
                        },
                    )),
                    None => {}
                }
            }
            keep_fewest_corrections(&mut best, &self.readers, r, proposals, read, true);
        }
        // The network reads a sliver from a ROI a pixel or two off that its cells, a pixel
        // wide, cannot: the fitted frame's corners go to stage 2, held like a traced quad.
        // A frame close to a ROI the network failed on is not worth its pass.
        let min_move = self.options.refit.min_frame_move_px;
        framed.retain(|(i, p)| {
            best[*i].is_none()
                && (*i >= tried
                    || proposals[*i].corners.largest_corner_move(&p.corners) >= min_move)
        });
        let mut fitted: Vec<(usize, Proposal)> = Vec::new();
        for (i, p) in framed {
            if !fitted.iter().any(|(_, q)| same_quad(q, &p)) {
                fitted.push((i, p));
            }
        }
        timings.read_ms += clock.ms();
        let rois: Vec<Proposal> = fitted.iter().map(|(_, p)| *p).collect();
        let reads = self.read_all(image, &rois, camera, batch, timings);
        for ((i, _), read) in fitted.into_iter().zip(reads) {
            if best[i].is_none() {
                best[i] = read;
            }
        }
        best
    }
}

/// The corners of a ROI fitted to a marker's frame.
type FittedCorners = Quad;

/// Files one family's reads (proposal index, marker) into `best`: where two families read one
/// ROI, the one whose code needed fewer corrections stays.
fn keep_fewest_corrections(
    best: &mut [Option<Found>],
    readers: &[FamilyReader],
    r: usize,
    proposals: &[Proposal],
    reads: impl IntoIterator<Item = (usize, Stage2Result)>,
    cell_read: bool,
) {
    let reader = &readers[r];
    let index = |name: &str| readers.iter().position(|o| o.family.name() == name);
    for (i, marker) in reads {
        // Fewer corrections win; of equal ones, the family named first.
        if best[i].as_ref().is_none_or(|b| {
            (marker.corrected_errors, r)
                < (b.marker.corrected_errors, index(&b.family).unwrap_or(0))
        }) {
            best[i] = Some(Found {
                family: reader.family.name().into(),
                evidence: reader.evidence(&marker),
                marker,
                proposal: proposals[i],
                cell_read,
            });
        }
    }
}

/// A cell read as a first stage-2 result: keypoints at the cell centres in the image, in the
/// family's order for the rotation decoded.
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
        corners: Quad(std::array::from_fn(|j| to_pixels.apply(roi[j]))),
        missing: 0,
        keypoints,
        iterations: 1,
        passes_agree: true,
        from_keypoints: false,
        refinement: None,
        pose: None,
    })
}
