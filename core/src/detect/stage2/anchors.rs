//! The stage-2 output grid: where anchors sit in the patch, how ground truth becomes per-anchor
//! training targets, and how per-anchor outputs become keypoint candidates. Pure geometry, no
//! network: the encode → decode round trip is testable on its own.
//!
//! **Patch geometry.** The patch is `size`² pixels (pixel centres at integer coordinates); the ROI
//! maps to the template square with corners at `margin · size` and `(1 − margin) · size`
//! (docs/ARCHITECTURE.md §9.1: a = 0.15). The default is 128 px at stride 4 (a 32 × 32 anchor
//! grid): the densest built-in grid, 10 × 10 cells with its border, then has a cell pitch of 0.7 ·
//! 128 / 10 = 8.96 px = 2.24 anchors on the template square, and 36h11's 8 × 8 grid 11.2 px = 2.8
//! anchors. The paper's 256 px at stride 8 gives the same 2.2–2.8 anchors per pitch at four times
//! the pixels; halving both keeps the anchor spacing and cuts the compute by four, which is what
//! lets the model train on two CPU cores. (Training quads with a_i near 0.25 on both sides shrink the
//! marker to 0.5 of the patch: 1.6 anchors per pitch for 10 × 10, 2.0 for 8 × 8.)

use crate::geometry::{distance, inside_polygon, length, squared_distance, Quad};
use crate::synth::KeypointTruth;

/// Anchor class of background; category `c` is class `c + 1`.
pub const BACKGROUND: usize = 0;
/// A target class that neither rewards nor penalises the anchor (between positive and negative).
pub const IGNORE: i32 = -1;
/// Offsets of the template head are encoded relative to the quadrant centre in units of this
/// fraction of the patch (the reference's "variance").
pub const TEMPLATE_SCALE: f64 = 0.1;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PatchSpec {
    pub size: u32,
    pub stride: u32,
    pub margin: f64,
}

impl Default for PatchSpec {
    fn default() -> Self {
        Self {
            size: 128,
            stride: 4,
            margin: 0.15,
        }
    }
}

impl PatchSpec {
    /// The smallest patch (128, 256 or 512 px at stride 4) on which the family's closest two
    /// keypoints are at least two anchors apart on the template square: 128 for every built-in
    /// grid, 256 for RuneTag's inner ring (the reference uses 512 at stride 8, the same ratio).
    /// The ROI sits at the family's template margin.
    pub fn for_family(family: &crate::Family) -> Self {
        let closest = family.keypoint_pitch();
        let mut spec = Self {
            margin: family.spec().roi.margin,
            ..Self::default()
        };
        let square = 1.0 - 2.0 * spec.margin;
        while spec.size < 512
            && closest / family.roi_side() * square * (spec.size as f64) < 2.0 * spec.stride as f64
        {
            spec.size *= 2;
        }
        spec
    }

    /// Anchors per side.
    pub fn cells(&self) -> usize {
        (self.size / self.stride) as usize
    }
    pub fn anchors(&self) -> usize {
        self.cells() * self.cells()
    }
    /// Centre of anchor `i` (row-major) in patch pixels: the middle of its `stride`² pixel block.
    pub fn anchor(&self, i: usize) -> [f64; 2] {
        let s = self.stride as f64;
        let (row, col) = (i / self.cells(), i % self.cells());
        [(col as f64 + 0.5) * s - 0.5, (row as f64 + 0.5) * s - 0.5]
    }
    /// Where the ROI points go in the patch: TL, TR, BR, BL of the template square.
    pub fn template_corners(&self) -> Quad {
        let (lo, hi) = (
            self.margin * self.size as f64,
            (1.0 - self.margin) * self.size as f64,
        );
        Quad([[lo, lo], [hi, lo], [hi, hi], [lo, hi]])
    }
    /// Centres of the template head's 2 × 2 anchors, in the order TL, TR, BR, BL.
    fn quadrant_centres(&self) -> [[f64; 2]; 4] {
        let (lo, hi) = (0.25 * self.size as f64, 0.75 * self.size as f64);
        [[lo, lo], [hi, lo], [hi, hi], [lo, hi]]
    }
    /// An anchor is positive within this distance of a keypoint (it covers the nearest anchor,
    /// which is at most stride·√2/2 away, and keeps keypoints two anchors apart from sharing one).
    pub fn positive_radius(&self) -> f64 {
        self.stride as f64
    }
    /// Anchors between the positive and this radius are ignored: their class is ambiguous.
    pub fn ignore_radius(&self) -> f64 {
        1.5 * self.stride as f64
    }
    /// Candidates closer than this belong to one keypoint.
    pub fn cluster_radius(&self) -> f64 {
        0.75 * self.stride as f64
    }
}

/// Training targets of one patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Targets {
    /// Per anchor: [`BACKGROUND`], category + 1, or [`IGNORE`].
    pub classes: Vec<i32>,
    /// Per anchor: (keypoint − anchor) / stride; zero where the anchor is not positive.
    pub offsets: Vec<[f32; 2]>,
    /// Per anchor: 1 inside the marker's outline, else 0.
    pub mask: Vec<f32>,
    /// Template head targets, TL, TR, BR, BL quadrant: (corner / size − quadrant centre) / scale.
    pub template: [[f32; 2]; 4],
}

impl Targets {
    pub fn positives(&self) -> usize {
        self.classes.iter().filter(|&&c| c > 0).count()
    }
}

/// Targets for a patch with these keypoints (patch pixels; the invisible ones are skipped), ROI
/// points (4, any cyclic order) and marker outline.
pub fn encode(
    spec: &PatchSpec,
    keypoints: &[KeypointTruth],
    roi: &[[f64; 2]],
    outline: &[[f64; 2]],
) -> Targets {
    let n = spec.anchors();
    let mut classes = vec![BACKGROUND as i32; n];
    let mut offsets = vec![[0.0f32; 2]; n];
    let s = spec.stride as f64;
    let (pos_r, ign_r) = (spec.positive_radius(), spec.ignore_radius());
    let visible: Vec<&KeypointTruth> = keypoints.iter().filter(|k| k.visible).collect();
    for (i, (class, offset)) in classes.iter_mut().zip(&mut offsets).enumerate() {
        let a = spec.anchor(i);
        let nearest = visible
            .iter()
            .map(|k| (k, length([k.x - a[0], k.y - a[1]])))
            .min_by(|x, y| x.1.total_cmp(&y.1));
        if let Some((k, d)) = nearest {
            if d < pos_r {
                *class = k.category as i32 + 1;
                *offset = [((k.x - a[0]) / s) as f32, ((k.y - a[1]) / s) as f32];
            } else if d < ign_r {
                *class = IGNORE;
            }
        }
    }
    let mask = (0..n)
        .map(|i| f32::from(u8::from(inside_polygon(outline, spec.anchor(i)))))
        .collect();
    let corners = patch_order(spec, roi);
    let q = spec.quadrant_centres();
    let size = spec.size as f64;
    let template = std::array::from_fn(|j| {
        [
            ((corners[j][0] / size - q[j][0] / size) / TEMPLATE_SCALE) as f32,
            ((corners[j][1] / size - q[j][1] / size) / TEMPLATE_SCALE) as f32,
        ]
    });
    Targets {
        classes,
        offsets,
        mask,
        template,
    }
}

/// The 4 ROI points reordered by the patch quadrant they lie in (TL, TR, BR, BL): the cyclic
/// shift closest to the template square, so a marker turned by 90° in the patch still gives each
/// template anchor its own corner.
pub fn patch_order(spec: &PatchSpec, roi: &[[f64; 2]]) -> Quad {
    let t = spec.template_corners();
    let cost = |shift: usize| -> f64 { (0..4).map(|j| distance(roi[(j + shift) % 4], t[j])).sum() };
    let best = (0..4)
        .min_by(|&a, &b| cost(a).total_cmp(&cost(b)))
        .unwrap_or(0);
    Quad(std::array::from_fn(|j| roi[(j + best) % 4]))
}

/// Per-anchor network outputs of one patch, as plain numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct RawOutputs {
    /// Per anchor, class probabilities (background first), `classes` values each.
    pub probs: Vec<f32>,
    pub classes: usize,
    /// Per anchor, offset in strides.
    pub offsets: Vec<[f32; 2]>,
    /// Template head, TL, TR, BR, BL, encoded as in [`Targets::template`].
    pub template: [[f32; 2]; 4],
}

impl RawOutputs {
    /// What a perfect network would output for `targets` (ignored anchors read as background).
    pub fn from_targets(targets: &Targets, classes: usize) -> Self {
        let mut probs = vec![0.0; targets.classes.len() * classes];
        for (i, &c) in targets.classes.iter().enumerate() {
            probs[i * classes + c.max(0) as usize] = 1.0;
        }
        Self {
            probs,
            classes,
            offsets: targets.offsets.clone(),
            template: targets.template,
        }
    }

    /// The template head's corners in patch pixels, TL, TR, BR, BL.
    pub fn template_corners(&self, spec: &PatchSpec) -> Quad {
        let q = spec.quadrant_centres();
        let size = spec.size as f64;
        Quad(std::array::from_fn(|j| {
            [
                q[j][0] + self.template[j][0] as f64 * TEMPLATE_SCALE * size,
                q[j][1] + self.template[j][1] as f64 * TEMPLATE_SCALE * size,
            ]
        }))
    }
}

/// A keypoint found in the patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Found {
    /// Patch pixels.
    pub pos: [f64; 2],
    /// The category with the largest probability summed over the cluster's anchors.
    pub category: usize,
    /// The most confident anchor's largest non-background probability.
    pub confidence: f64,
    /// Per category, its probability summed over the cluster's anchors.
    pub votes: Vec<f64>,
}

/// Confidence filter, then greedy clustering in order of decreasing confidence: each cluster is
/// the anchors within the cluster radius of its most confident member; its position is their
/// confidence-weighted mean and its category the largest summed probability.
pub fn extract(spec: &PatchSpec, raw: &RawOutputs, min_confidence: f64) -> Vec<Found> {
    let c = raw.classes;
    let s = spec.stride as f64;
    let mut candidates: Vec<([f64; 2], f64, usize)> = (0..spec.anchors())
        .filter_map(|i| {
            let p = &raw.probs[i * c..(i + 1) * c];
            let conf = p[1..].iter().copied().fold(0.0f32, f32::max) as f64;
            (conf > min_confidence).then(|| {
                let (a, o) = (spec.anchor(i), raw.offsets[i]);
                ([a[0] + o[0] as f64 * s, a[1] + o[1] as f64 * s], conf, i)
            })
        })
        .collect();
    candidates.sort_by(|a, b| b.1.total_cmp(&a.1));
    // Squared, because this pairwise test runs for every pair of candidates of every read.
    let r_squared = spec.cluster_radius().powi(2);
    let mut used = vec![false; candidates.len()];
    let mut found = Vec::new();
    for k in 0..candidates.len() {
        if used[k] {
            continue;
        }
        let centre = candidates[k].0;
        let mut sum = [0.0; 2];
        let mut weight = 0.0;
        let mut votes = vec![0.0f64; c];
        for j in k..candidates.len() {
            let (pos, conf, anchor) = candidates[j];
            if used[j] || squared_distance(pos, centre) >= r_squared {
                continue;
            }
            used[j] = true;
            sum = [sum[0] + pos[0] * conf, sum[1] + pos[1] * conf];
            weight += conf;
            for (v, &p) in votes
                .iter_mut()
                .zip(&raw.probs[anchor * c..(anchor + 1) * c])
            {
                *v += p as f64;
            }
        }
        let category = (1..c)
            .max_by(|&a, &b| votes[a].total_cmp(&votes[b]))
            .unwrap_or(1)
            - 1;
        found.push(Found {
            pos: [sum[0] / weight, sum[1] / weight],
            category,
            confidence: candidates[k].1,
            votes: votes[1..].to_vec(),
        });
    }
    found
}
