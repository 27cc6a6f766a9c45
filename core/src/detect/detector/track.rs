//! Video: each marker of the last frame read again from where its motion puts it, by its family's
//! stage 2 alone; the whole detector (stage 1 and every source) runs on the first frame, every
//! [`TrackParams::redetect_every`] frames, and whenever a marker is lost.

use super::read::Batch;
use super::reconcile::reconcile;
use super::sources::{Capability, SourceParams, Trust, DEFAULT_SOURCES};
use super::{Detector, Found, Timings};
use crate::detect::stage1::group::Proposal;
use crate::detect::stage2::ReadOptions;
use crate::geometry::{Camera, Quad};
use crate::image::GrayImage;
use crate::io::Stopwatch;

/// How a [`Tracker`] follows markers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrackParams {
    /// Frames between two runs of the whole detector at most: markers that came into view are
    /// found no later than this.
    pub redetect_every: usize,
    /// Stage-2 passes per followed marker: its predicted corners are as close as a first
    /// pass's keypoints make them, so one pass reads it as the whole detector's two do.
    pub passes: usize,
}

impl Default for TrackParams {
    fn default() -> Self {
        Self {
            redetect_every: 10,
            passes: 1,
        }
    }
}

/// What one frame of a sequence gave.
#[derive(Debug, Clone)]
pub struct Frame {
    pub found: Vec<Found>,
    pub timings: Timings,
    /// The whole detector ran on this frame (the first, a scheduled one, or after a loss).
    pub full: bool,
}

/// Follows the markers of an image sequence (frames in order, one camera).
#[derive(Debug, Clone, Default)]
pub struct Tracker {
    pub params: TrackParams,
    /// The last frame's markers, and the frame before's corners of each where it was read there
    /// too (for the motion).
    last: Vec<(Found, Option<Quad>)>,
    since_full: usize,
}

impl Tracker {
    pub fn new(params: TrackParams) -> Self {
        Self {
            params,
            ..Self::default()
        }
    }

    /// The markers of the next frame.
    pub fn next(
        &mut self,
        detector: &Detector,
        image: &GrayImage,
        camera: Option<&Camera>,
    ) -> Frame {
        let due = self.last.is_empty() || self.since_full + 1 >= self.params.redetect_every;
        if !due {
            let predicted: Vec<(Found, Quad)> = self
                .last
                .iter()
                .map(|(f, before)| (f.clone(), predict(&f.marker.corners, before.as_ref())))
                .collect();
            let (found, timings) = detector.reread(image, &predicted, camera, self.params.passes);
            // Every marker read again, as itself: the frame is done without stage 1.
            let kept_all = found.len() == predicted.len()
                && predicted.iter().all(|(p, _)| {
                    found
                        .iter()
                        .any(|f| f.family == p.family && f.marker.id == p.marker.id)
                });
            if kept_all {
                self.since_full += 1;
                self.remember(&found);
                return Frame {
                    found,
                    timings,
                    full: false,
                };
            }
        }
        let (found, timings) = detector.detect_with(image, camera.or(detector.camera.as_ref()));
        self.since_full = 0;
        self.remember(&found);
        Frame {
            found,
            timings,
            full: true,
        }
    }

    fn remember(&mut self, found: &[Found]) {
        let before = std::mem::take(&mut self.last);
        self.last = found
            .iter()
            .map(|f| {
                let previous = before
                    .iter()
                    .find(|(b, _)| b.family == f.family && b.marker.id == f.marker.id)
                    .map(|(b, _)| b.marker.corners);
                (f.clone(), previous)
            })
            .collect();
    }
}

/// Where a marker's corners will be in the next frame: moved as they moved from the frame
/// before (constant velocity), or where they were.
fn predict(now: &Quad, before: Option<&Quad>) -> Quad {
    let Some(before) = before else {
        return *now;
    };
    let moved: Quad = Quad(std::array::from_fn(|i| {
        [
            2.0 * now[i][0] - before[i][0],
            2.0 * now[i][1] - before[i][1],
        ]
    }));
    if moved.check().is_ok() {
        moved
    } else {
        *now
    }
}

/// Reads of a tracked marker are held like stage 1's later selections: half the family's
/// corrections, no retries from keypoints.
const TRACKED: SourceParams = SourceParams {
    trust: Trust::Later,
    precheck: false,
    retried_rois: 0,
    needs: Capability::Any,
    ..DEFAULT_SOURCES[0]
};

impl Detector {
    /// Each of the `previous` markers read again from its `predicted` corners by its own family's
    /// stage 2 with `passes` passes (no stage 1, no image search); the reads that decode,
    /// reconciled.
    pub fn reread(
        &self,
        image: &GrayImage,
        predicted: &[(Found, Quad)],
        camera: Option<&Camera>,
        passes: usize,
    ) -> (Vec<Found>, Timings) {
        let read = ReadOptions {
            iterations: passes.max(1),
            ..self.options.read
        };
        let mut timings = Timings::default();
        let guessed;
        let camera = match camera.or(self.camera.as_ref()) {
            Some(c) => Some(c),
            None => {
                guessed = super::guess_camera(image);
                guessed.as_ref()
            }
        };
        let mut found = Vec::new();
        for (r, reader) in self.readers.iter().enumerate() {
            let proposals: Vec<Proposal> = predicted
                .iter()
                .filter(|(f, _)| f.family == reader.family.name())
                .map(|(f, corners)| Proposal {
                    corners: *corners,
                    score: f.proposal.score,
                })
                .collect();
            if proposals.is_empty() {
                continue;
            }
            timings.proposals += proposals.len();
            // The quads are last frame's ROIs, wherever the family's frame lies.
            let batch = Batch {
                params: &TRACKED,
                trust: Trust::Later,
                rois_inside: true,
            };
            let reads =
                self.read_one_family(r, &read, image, &proposals, camera, batch, &mut timings);
            found.extend(reads.into_iter().flatten());
        }
        let clock = Stopwatch::start();
        let kept = reconcile(found);
        timings.reconcile_ms = clock.ms();
        (kept, timings)
    }
}
