//! What the sources have read so far, and the reconcile phase: one read per marker, chosen by
//! evidence (fewest corrections, then the closest pose fit), never by the order the reads came
//! in.

use super::Found;
use crate::detect::stage1::group::{nested, same_quad, Proposal};
use crate::detect::stage1::pipeline::Outlined;
use crate::geometry::Quad;
use std::cmp::Ordering;

/// How strongly a read is supported.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Evidence {
    pub corrections: usize,
    /// Keypoint reprojection RMS from the read's pose, in cell pitches in the image (`None`
    /// without a pose).
    pub rms_pitch: Option<f64>,
    /// At most half the family's corrections: such a read claims the image around it, and the
    /// sources after it do not look there again.
    pub strong: bool,
}

impl Evidence {
    /// Better evidence first.
    pub fn compare(&self, other: &Evidence) -> Ordering {
        let fit = |e: &Evidence| e.rms_pitch.unwrap_or(f64::INFINITY);
        self.corrections
            .cmp(&other.corrections)
            .then(fit(self).total_cmp(&fit(other)))
    }
}

/// The proposals read so far, by outcome.
#[derive(Default)]
pub(super) struct Rounds {
    /// Every proposal sent to stage 2.
    pub read: Vec<Proposal>,
    /// Those no family read.
    pub failed: Vec<Proposal>,
    /// The markers read.
    pub found: Vec<Found>,
    /// The image searches' quads past their budget, left for the cell reads.
    pub unread: Vec<Proposal>,
}

impl Rounds {
    /// The strong reads' corners: the image searches skip what lies inside them.
    pub fn covered(&self) -> Vec<Quad> {
        (self.found.iter())
            .filter(|f| f.evidence.strong)
            .map(|f| f.marker.corners)
            .collect()
    }

    /// The ROIs read as markers: their corners are spoken for in the next selection.
    pub fn kept(&self) -> Vec<Proposal> {
        self.found.iter().map(|f| f.proposal).collect()
    }

    /// The quads from `selection` (the source's quads in its order given what was kept and what
    /// failed) not sent to stage 2 yet nor over a marker read.
    pub fn fresh(&self, selection: Vec<Proposal>) -> Vec<Proposal> {
        selection
            .into_iter()
            .filter(|p| self.is_new(p) && !self.over_a_marker_read(p))
            .collect()
    }

    /// [`Rounds::fresh`] for an image search's quads.
    pub fn fresh_outlined(&self, quads: &Outlined) -> Vec<Proposal> {
        self.fresh(quads.proposals(&self.kept(), &self.failed))
    }

    /// Whether `p` lies over a marker read already. A weak read (more than half the
    /// corrections) only shadows quads of about its own size: a quad across a row of markers
    /// read as one code must not keep the markers inside it from being read.
    pub fn over_a_marker_read(&self, p: &Proposal) -> bool {
        self.found.iter().any(|f| {
            nested(&f.marker.corners, &p.corners)
                && (f.evidence.strong || 2.0 * p.corners.area() >= f.marker.corners.area())
        })
    }

    pub fn is_new(&self, p: &Proposal) -> bool {
        !self.read.iter().any(|r| same_quad(p, r))
    }

    /// Files each proposal of a batch as found or failed by its read.
    pub fn record(&mut self, batch: Vec<Proposal>, reads: Vec<Option<Found>>) -> usize {
        let mut found = 0;
        for (proposal, read_as) in batch.iter().zip(reads) {
            match read_as {
                Some(f) => {
                    self.found.push(f);
                    found += 1;
                }
                None => self.failed.push(*proposal),
            }
        }
        self.read.extend(batch);
        found
    }
}

/// Markers do not overlap: of reads where either's centre lies inside the other (one marker
/// read twice, a quad over part of a marker and its surroundings, or over several markers,
/// read as another code), the one with the best [`Evidence`] stays, then the next best that
/// overlaps none kept, and so on. The reads keep the order they were found in.
pub(super) fn reconcile(found: Vec<Found>) -> Vec<Found> {
    let mut order: Vec<usize> = (0..found.len()).collect();
    order.sort_by(|&a, &b| {
        (found[a].evidence)
            .compare(&found[b].evidence)
            .then(a.cmp(&b))
    });
    let mut kept: Vec<usize> = Vec::new();
    for i in order {
        let corners = &found[i].marker.corners;
        if !kept
            .iter()
            .any(|&k| nested(&found[k].marker.corners, corners))
        {
            kept.push(i);
        }
    }
    kept.sort_unstable();
    let mut kept = kept.into_iter().peekable();
    found
        .into_iter()
        .enumerate()
        .filter_map(|(i, f)| (kept.next_if_eq(&i).is_some()).then_some(f))
        .collect()
}
