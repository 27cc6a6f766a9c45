//! The proposal sources as one table (docs/ARCHITECTURE.md §9.8): each source proposes quads,
//! the detector verifies and reads them in selections of a bounded size, and the sources run in
//! the table's order, each seeing the markers the ones before it read. What a source proposes,
//! how far its reads are trusted and how much of stage 2 it may spend are all here.

use serde::Serialize;

/// Where a candidate quad came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Source {
    /// Stage 1's grouping of its corners on every pyramid level.
    Stage1,
    /// The ellipses round rings of dark dots with a light centre (ring families).
    Rings,
    /// Quads outlined between stage 1's weaker corners where the image shows their sides.
    Outline,
    /// Quads traced around dark blobs the network's mask or corners mark.
    Traced,
    /// Stage 1 again on boxes of the image enlarged twice, around strong corners no read
    /// explains (far slivers).
    CloseLook,
    /// Stage 1 again on views stretched across the directions of strong corners no read
    /// explains (needles 5–20 px across).
    StretchedLook,
    /// Quads of four of stage 1's corners whose sides the image's edges confirm.
    CornerQuads,
    /// The quads no network read, moved onto the image's edges.
    EdgeRefits,
    /// The cells of the quads no network read, read straight off the image, and the marker
    /// frame those cells fit read again by the network.
    CellReads,
}

impl Source {
    pub const ALL: [Source; SOURCES] = [
        Source::Stage1,
        Source::Rings,
        Source::Outline,
        Source::Traced,
        Source::CloseLook,
        Source::StretchedLook,
        Source::CornerQuads,
        Source::EdgeRefits,
        Source::CellReads,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Source::Stage1 => "stage1",
            Source::Rings => "rings",
            Source::Outline => "outline",
            Source::Traced => "traced",
            Source::CloseLook => "close-look",
            Source::StretchedLook => "stretched-look",
            Source::CornerQuads => "corner-quads",
            Source::EdgeRefits => "edge-refits",
            Source::CellReads => "cell-reads",
        }
    }

    pub(crate) fn index(self) -> usize {
        Source::ALL.iter().position(|&s| s == self).unwrap_or(0)
    }
}

/// Number of proposal sources.
pub const SOURCES: usize = 9;

/// What a source assumes of a family's markers: a family without it never reads the source's
/// quads, and the source does not run when no family has it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Capability {
    /// Any family.
    Any,
    /// The ROI is a quadrilateral whose corners or sides the image shows (every grid family):
    /// stage 1 and the searches built on its corners and edges.
    Quadrilateral,
    /// Rings of dots round a light centre (a rings layout): the ring search.
    RingsOfDots,
    /// The ROI sits on a dark frame on lighter surroundings (the family has a pre-read check).
    DarkFrame,
    /// Flat black/white cells that can be read straight off the image.
    FlatCells,
    /// The ROI is a light square inside a dark frame, with cells outside the frame (AprilTag 3's
    /// standard41h12 and circle21h7): stage 1 finds it on the inverted image, where it is a dark
    /// square on a light ring.
    LightInsideFrame,
}

/// How far a proposal's source is trusted: how many of the family's corrections its code may
/// need. Clutter decodes as some code at the edge of the correction limit (a 36-symbol read at
/// random lies within 5 symbols of one of 36h11's 587 codes in four turns once in 66 reads,
/// within 2 once in 44 000, within 3 once in about 2 500), so the sources that bring more
/// clutter are held to fewer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Trust {
    /// Stage 1's first selection: whatever the decoder accepts (with erasures it may correct
    /// more than the family's limit for errors alone), but for ROIs stage 1 scores below
    /// [`AcceptParams::weak_roi_score`], which are held like traced quads. Its later selections,
    /// which stage 1 ranked below ROIs no family could read, are held like [`Trust::Later`].
    First,
    /// Half the limit: quads ranked below ones no family read, or outlined between weaker
    /// corners.
    Later,
    /// One more than half: quads traced around a dark blob or fitted to edges. A steep view
    /// traced 2 px off needs 3 of 36h11's 5; a blob of clutter must be convex, quadrilateral,
    /// dark on light and under the mask to be read at all.
    Traced,
}

impl Trust {
    /// The trust of a source's `selection`-th selection (0 first).
    pub(crate) fn in_selection(self, selection: usize) -> Trust {
        match self {
            Trust::First if selection > 0 => Trust::Later,
            t => t,
        }
    }

    /// The corrections a read of a ROI with stage-1 score `score` may need.
    pub(crate) fn allowed(self, limit: usize, score: f64, weak_roi_score: f64) -> usize {
        match self {
            Trust::First if score >= weak_roi_score => usize::MAX,
            Trust::First | Trust::Traced => (limit / 2 + 1).min(limit),
            Trust::Later => limit / 2,
        }
    }
}

/// One row of the sources table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SourceParams {
    pub source: Source,
    pub trust: Trust,
    pub needs: Capability,
    /// Selections of the source's quads at most: each selects again without the quads that read
    /// nothing (a quad across two markers side by side takes a corner of each).
    pub selections: usize,
    /// Quads sent to stage 2 per selection at most (`None`: all of them).
    pub budget: Option<usize>,
    /// Whether its quads pass the families' pre-read check before stage 2 (verify phase).
    pub precheck: bool,
    /// Quads of each selection that decode nothing read again from where their keypoints place
    /// the marker, at most (see [`crate::detect::stage2::ReadOptions::retried_rois`]).
    pub retried_rois: usize,
}

/// The table the detector runs, in order. Budgets bound what clutter can cost; the figures that
/// chose them are in BENCHMARKS.md ("Real photographs": each proposal source).
pub const DEFAULT_SOURCES: [SourceParams; SOURCES] = [
    SourceParams {
        source: Source::Stage1,
        trust: Trust::First,
        needs: Capability::Quadrilateral,
        selections: 3,
        budget: None,
        precheck: true,
        retried_rois: 2,
    },
    SourceParams {
        source: Source::Rings,
        trust: Trust::First,
        needs: Capability::RingsOfDots,
        selections: 1,
        budget: Some(16),
        precheck: false,
        retried_rois: 2,
    },
    SourceParams {
        source: Source::Outline,
        trust: Trust::Later,
        needs: Capability::Quadrilateral,
        selections: 3,
        budget: Some(4),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::Traced,
        trust: Trust::Traced,
        needs: Capability::DarkFrame,
        selections: 3,
        budget: Some(4),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::CloseLook,
        trust: Trust::Later,
        needs: Capability::Quadrilateral,
        selections: 3,
        budget: Some(4),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::StretchedLook,
        trust: Trust::Later,
        needs: Capability::Quadrilateral,
        selections: 3,
        budget: Some(4),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::CornerQuads,
        trust: Trust::Traced,
        needs: Capability::Quadrilateral,
        selections: 3,
        budget: Some(4),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::EdgeRefits,
        trust: Trust::Traced,
        needs: Capability::Quadrilateral,
        selections: 1,
        budget: Some(8),
        precheck: true,
        retried_rois: 0,
    },
    SourceParams {
        source: Source::CellReads,
        trust: Trust::Traced,
        needs: Capability::FlatCells,
        selections: 1,
        budget: None,
        precheck: true,
        retried_rois: 0,
    },
];

/// When a family's read of a quad is kept ([`super::FamilyReader::accepts`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AcceptParams {
    /// Below this stage-1 score a first-selection ROI is held to the traced quads' limit: a
    /// cluttered photograph sends dozens of such ROIs to stage 2, and a read at the correction
    /// limit then comes out of clutter about once per photograph.
    pub weak_roi_score: f64,
    /// The largest keypoint reprojection RMS, in cell pitches in the image, of a read that needed
    /// more than half the family's corrections: a code read out of clutter, or from a quad
    /// across several markers, lands on keypoints no camera sees a flat marker through.
    pub max_weak_read_rms_pitch: f64,
    /// The same for a read from a failed first pass's keypoints that needed more than half the
    /// corrections: keypoints sorted a cell off place a frame that reads another code, and both
    /// passes from it may agree.
    pub max_keypoint_read_rms_pitch: f64,
    /// A code of fewer symbols than this is read only as it is, without corrections: with 16
    /// bits and 30 to 50 codes (AprilTag 16h5, ArUco 4x4_50) a quad of clutter decodes within a
    /// correction or two often enough to matter, where codes of 25 bits and more do not
    /// (BENCHMARKS.md, "Every family detecting").
    pub min_symbols_to_correct: usize,
    /// The largest keypoint reprojection RMS, in cell pitches in the image, of a read of such a
    /// short code: a quad of clutter that is one of the codes as it stands needs no correction,
    /// but its keypoints fit no flat marker's pose as a marker's do (BENCHMARKS.md, "Every
    /// family detecting").
    pub max_short_code_rms_pitch: f64,
    /// Whether a code whose every symbol is the same is read. Quaternary 6×6's ID 0 (every cell
    /// solid) is a black square with its orientation mark; a dark square of clutter reads as it,
    /// and the network is no surer of the marker's keypoints than of the clutter's, so neither is
    /// read (BENCHMARKS.md, "Every family detecting"). No built-in code of two symbols is uniform.
    pub read_uniform_codes: bool,
}

impl Default for AcceptParams {
    fn default() -> Self {
        Self {
            weak_roi_score: 0.3,
            max_weak_read_rms_pitch: 0.25,
            max_keypoint_read_rms_pitch: 0.1,
            min_symbols_to_correct: 20,
            max_short_code_rms_pitch: 0.1,
            read_uniform_codes: false,
        }
    }
}

/// How much a quad must move to be read again.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RefitParams {
    /// A quad refitted to the image's edges whose corners all lie this close (pixels) to a quad
    /// read already is not read again: the read would be the same.
    pub min_move_px: f64,
    /// A cell-fitted frame within this many pixels of a ROI the network failed on is not read
    /// again by the network.
    pub min_frame_move_px: f64,
}

impl Default for RefitParams {
    fn default() -> Self {
        Self {
            min_move_px: 0.5,
            min_frame_move_px: 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weak_rois_and_later_selections_are_trusted_with_fewer_corrections() {
        let weak = AcceptParams::default().weak_roi_score;
        assert_eq!(Trust::First.allowed(5, 0.8, weak), usize::MAX);
        assert_eq!(Trust::First.allowed(5, 0.12, weak), 3);
        assert_eq!(Trust::Traced.allowed(5, 0.9, weak), 3);
        assert_eq!(Trust::Later.allowed(5, 0.9, weak), 2);
        assert_eq!(Trust::First.in_selection(1), Trust::Later);
        assert_eq!(Trust::Traced.in_selection(2), Trust::Traced);
    }

    #[test]
    fn the_table_names_every_source_once_in_order() {
        let listed: Vec<Source> = DEFAULT_SOURCES.iter().map(|p| p.source).collect();
        assert_eq!(listed, Source::ALL);
        for (i, s) in Source::ALL.iter().enumerate() {
            assert_eq!(s.index(), i);
        }
    }
}
