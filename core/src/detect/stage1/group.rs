//! From stage 1's maps to marker ROIs (docs/ARCHITECTURE.md §9.8), plain Rust.
//!
//! Corners are the heat map's local maxima, placed by their offsets. Each carries the direction
//! to its marker's centre, and the centre is where the diagonals cross, so two corners that
//! point at each other along the line joining them are the two ends of a diagonal. Two
//! diagonals whose segments cross make a quad; the marker mask has to cover its inside. Quads are
//! taken best first, each corner used once — clustering by geometry rather than NMS over boxes,
//! in the spirit of the paper's corner assignment. The candidates are kept ([`candidates`]) so
//! that the detector can select again without quads stage 2 could not read ([`select`]).

use super::STRIDE;
use crate::geometry::{distance, length, Quad};

/// A corner found on the heat map, in image pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Corner {
    pub at: [f64; 2],
    /// Unit direction to the marker centre.
    pub direction: [f64; 2],
    pub score: f64,
}

/// A marker ROI: four corners clockwise in the image (x right, y down), the same turning sense
/// as the families' ROI order; which corner comes first is left to stage 2, which reads markers
/// turned by any quarter.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Proposal {
    pub corners: Quad,
    /// Mean corner confidence × how well the mask marks the quad out (inside minus around) ×
    /// how well the corners' directions point at its centre.
    pub score: f64,
}

/// Stage 1's maps for one image, after the sigmoid on heat and mask.
#[derive(Debug, Clone, PartialEq)]
pub struct Maps {
    pub columns: usize,
    pub rows: usize,
    pub heat: Vec<f32>,
    pub offset: Vec<[f32; 2]>,
    pub direction: Vec<[f32; 2]>,
    pub mask: Vec<f32>,
}

/// Thresholds of the grouping.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupOptions {
    /// Corner confidence.
    pub corner: f32,
    /// Cosine between a corner's direction and the line to the other end of its diagonal.
    pub aligned: f64,
    /// Mean mask over the quad's inside.
    pub mask: f64,
    /// Shortest diagonal, in image pixels.
    pub min_diagonal: f64,
}

impl Default for GroupOptions {
    fn default() -> Self {
        Self {
            corner: 0.3,
            aligned: 0.8,
            mask: 0.5,
            min_diagonal: 8.0,
        }
    }
}

/// More corners than this in one image is clutter; the best are kept.
const MAX_CORNERS: usize = 400;

impl Maps {
    fn at(&self, cx: usize, cy: usize) -> f32 {
        self.heat[cy * self.columns + cx]
    }

    /// The mask at an image point (`scale` image pixels per network input pixel), bilinear.
    pub fn mask_at(&self, p: [f64; 2], scale: f64) -> f64 {
        let [x, y] = [level_from_image(p[0], scale), level_from_image(p[1], scale)];
        let s = STRIDE as f64;
        let (gx, gy) = (x / s - 0.5, y / s - 0.5);
        let (x0, y0) = (gx.floor(), gy.floor());
        let (fx, fy) = (gx - x0, gy - y0);
        let get = |x: f64, y: f64| {
            let x = x.clamp(0.0, self.columns as f64 - 1.0) as usize;
            let y = y.clamp(0.0, self.rows as f64 - 1.0) as usize;
            self.mask[y * self.columns + x] as f64
        };
        get(x0, y0) * (1.0 - fx) * (1.0 - fy)
            + get(x0 + 1.0, y0) * fx * (1.0 - fy)
            + get(x0, y0 + 1.0) * (1.0 - fx) * fy
            + get(x0 + 1.0, y0 + 1.0) * fx * fy
    }

    /// The highest mask value in the 3 × 3 cells around an image point.
    pub fn mask_near(&self, p: [f64; 2], scale: f64) -> f64 {
        let s = STRIDE as f64;
        let cell = |v: f64, n: usize| {
            ((level_from_image(v, scale) / s).floor().max(0.0) as usize).min(n - 1)
        };
        let (cx, cy) = (cell(p[0], self.columns), cell(p[1], self.rows));
        let mut most = 0.0f32;
        for y in cy.saturating_sub(1)..=(cy + 1).min(self.rows - 1) {
            for x in cx.saturating_sub(1)..=(cx + 1).min(self.columns - 1) {
                most = most.max(self.mask[y * self.columns + x]);
            }
        }
        most as f64
    }

    /// Local maxima of the heat map above `threshold`, in image pixels (`scale` image pixels per
    /// network input pixel).
    pub fn corners(&self, threshold: f32, scale: f64) -> Vec<Corner> {
        let mut out = Vec::new();
        for cy in 0..self.rows {
            for cx in 0..self.columns {
                let v = self.at(cx, cy);
                if v < threshold {
                    continue;
                }
                let mut peak = true;
                for ny in cy.saturating_sub(1)..=(cy + 1).min(self.rows - 1) {
                    for nx in cx.saturating_sub(1)..=(cx + 1).min(self.columns - 1) {
                        let w = self.at(nx, ny);
                        // Ties go to the first in raster order.
                        if w > v || (w == v && (ny, nx) < (cy, cx)) {
                            peak = false;
                        }
                    }
                }
                if !peak {
                    continue;
                }
                let i = cy * self.columns + cx;
                let s = STRIDE as f64;
                let [ox, oy] = self.offset[i];
                let [dx, dy] = self.direction[i];
                let len = length([dx as f64, dy as f64]).max(1e-9);
                out.push(Corner {
                    at: [
                        image_from_level((cx as f64 + 0.5 + ox as f64) * s, scale),
                        image_from_level((cy as f64 + 0.5 + oy as f64) * s, scale),
                    ],
                    direction: [dx as f64 / len, dy as f64 / len],
                    score: v as f64,
                });
            }
        }
        out.sort_by(|a, b| b.score.total_cmp(&a.score));
        out.truncate(MAX_CORNERS);
        out
    }
}

/// A pyramid level's coordinate in the image. Pixel centres sit at whole coordinates and a level
/// pixel averages `scale` × `scale` image pixels, so its centre lies (scale − 1)/2 further on.
pub fn image_from_level(x: f64, scale: f64) -> f64 {
    x * scale + (scale - 1.0) / 2.0
}

fn level_from_image(x: f64, scale: f64) -> f64 {
    (x - (scale - 1.0) / 2.0) / scale
}

fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Where the segments a→b and c→d cross, as fractions along each.
fn crossing(a: [f64; 2], b: [f64; 2], c: [f64; 2], d: [f64; 2]) -> Option<(f64, f64)> {
    let (r, s) = (sub(b, a), sub(d, c));
    let den = cross(r, s);
    if den.abs() < 1e-9 {
        return None;
    }
    let ac = sub(c, a);
    Some((cross(ac, s) / den, cross(ac, r) / den))
}

/// The mean and the lowest of `mask` at nine points spread over the quad's inside.
pub fn mask_inside(q: &Quad, mask: &dyn Fn([f64; 2]) -> f64) -> (f64, f64) {
    let (mut sum, mut lowest) = (0.0, f64::MAX);
    for v in [0.25, 0.5, 0.75] {
        for u in [0.25, 0.5, 0.75] {
            let top = [
                q[0][0] + u * (q[1][0] - q[0][0]),
                q[0][1] + u * (q[1][1] - q[0][1]),
            ];
            let bottom = [
                q[3][0] + u * (q[2][0] - q[3][0]),
                q[3][1] + u * (q[2][1] - q[3][1]),
            ];
            let m = mask([
                top[0] + v * (bottom[0] - top[0]),
                top[1] + v * (bottom[1] - top[1]),
            ]);
            sum += m;
            lowest = lowest.min(m);
        }
    }
    (sum / 9.0, lowest)
}

/// The mean of `mask` around the quad: its corners and edge midpoints pushed out from the centre
/// by half again (past a one-cell white border, which the mask counts as marker).
fn mask_outside(q: &Quad, mask: &dyn Fn([f64; 2]) -> f64) -> f64 {
    let c = q.centre();
    let out = |p: [f64; 2]| mask([c[0] + 1.5 * (p[0] - c[0]), c[1] + 1.5 * (p[1] - c[1])]);
    (0..4)
        .map(|i| {
            let (a, b) = (q[i], q[(i + 1) % 4]);
            out(a) + out([(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0])
        })
        .sum::<f64>()
        / 8.0
}

/// How well the mask marks out the quad — inside minus around, 0 to 1 — or `None` when its
/// inside is not marker (a quad spanning two markers and the gap between them).
fn mask_fit(q: &Quad, mask: &dyn Fn([f64; 2]) -> f64, threshold: f64) -> Option<f64> {
    let (mean, lowest) = mask_inside(q, mask);
    if mean < threshold || lowest < threshold / 2.0 {
        return None;
    }
    let contrast = mean - mask_outside(q, mask);
    (contrast > 0.2).then_some(contrast)
}

/// The mean cosine between each corner's direction and the way to where the quad's diagonals
/// cross: 1 when every corner points at the centre of this quad rather than another's.
fn alignment(q: &Quad, directions: [[f64; 2]; 4]) -> f64 {
    let Some(x) = q.diagonal_crossing() else {
        return 0.0;
    };
    (0..4)
        .map(|i| {
            let to = sub(x, q[i]);
            let len = length(to).max(1e-9);
            dot(directions[i], [to[0] / len, to[1] / len])
        })
        .sum::<f64>()
        / 4.0
}

/// A quad that four corners (or three and a completion) make, before the selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    /// Indices of its corners in the level's list (a completed quad repeats its third).
    pub corners: [usize; 4],
    pub proposal: Proposal,
}

/// Every quad that `corners` make, best first.
pub fn candidates(
    corners: &[Corner],
    mask: &dyn Fn([f64; 2]) -> f64,
    options: &GroupOptions,
) -> Vec<Candidate> {
    let mut diagonals = Vec::new();
    for (i, a) in corners.iter().enumerate() {
        for (j, b) in corners.iter().enumerate().skip(i + 1) {
            let ab = sub(b.at, a.at);
            // Squares and a root, not `hypot`: this runs for every pair of corners, and libm's
            // hypot (exact where this needs none) was a few per cent of a photograph's time.
            let len_sq = ab[0] * ab[0] + ab[1] * ab[1];
            if len_sq < options.min_diagonal * options.min_diagonal {
                continue;
            }
            let len = len_sq.sqrt();
            let u = [ab[0] / len, ab[1] / len];
            let (ca, cb) = (dot(a.direction, u), -dot(b.direction, u));
            if ca > options.aligned && cb > options.aligned {
                diagonals.push((i, j));
            }
        }
    }
    let mut candidates = Vec::new();
    for (k, &(a, b)) in diagonals.iter().enumerate() {
        for &(c, d) in &diagonals[k + 1..] {
            if a == c || a == d || b == c || b == d {
                continue;
            }
            let (pa, pb, pc, pd) = (corners[a].at, corners[b].at, corners[c].at, corners[d].at);
            let Some((t, s)) = crossing(pa, pb, pc, pd) else {
                continue;
            };
            if !(0.15..=0.85).contains(&t) || !(0.15..=0.85).contains(&s) {
                continue;
            }
            let mut q = Quad([pa, pc, pb, pd]);
            if q.signed_area() < 0.0 {
                q = Quad([pa, pd, pb, pc]);
            }
            if !sides_balanced(&q) {
                continue;
            }
            let Some(fit) = mask_fit(&q, mask, options.mask) else {
                continue;
            };
            let direction_of = |p: [f64; 2]| {
                [a, b, c, d]
                    .iter()
                    .find(|&&i| corners[i].at == p)
                    .map_or([0.0, 0.0], |&i| corners[i].direction)
            };
            let aligned = alignment(&q, q.0.map(direction_of));
            let confidence = [a, b, c, d].iter().map(|&i| corners[i].score).sum::<f64>() / 4.0;
            candidates.push((
                [a, b, c, d],
                Proposal {
                    corners: q,
                    score: confidence * fit * aligned.max(0.0),
                },
            ));
        }
    }
    // A corner lost to blur, glare or occlusion: a diagonal and a third corner pointing at its
    // middle give the fourth by completing the parallelogram — a few pixels off under
    // perspective, which stage 2's second pass corrects. Scored as if the fourth corner had
    // confidence 0, so any complete quad over the same corners wins.
    for &(a, b) in &diagonals {
        let (pa, pb) = (corners[a].at, corners[b].at);
        let middle = [(pa[0] + pb[0]) / 2.0, (pa[1] + pb[1]) / 2.0];
        for (c, corner) in corners.iter().enumerate() {
            if c == a || c == b {
                continue;
            }
            let to_middle = sub(middle, corner.at);
            let len = (to_middle[0] * to_middle[0] + to_middle[1] * to_middle[1]).sqrt();
            if len < options.min_diagonal / 2.0
                || dot(corner.direction, [to_middle[0] / len, to_middle[1] / len])
                    <= options.aligned
            {
                continue;
            }
            let pd = [pa[0] + pb[0] - corner.at[0], pa[1] + pb[1] - corner.at[1]];
            let mut q = Quad([pa, corner.at, pb, pd]);
            if q.signed_area() < 0.0 {
                q = Quad([pa, pd, pb, corner.at]);
            }
            if !sides_balanced(&q) {
                continue;
            }
            let Some(fit) = mask_fit(&q, mask, options.mask) else {
                continue;
            };
            let confidence = (corners[a].score + corners[b].score + corner.score) / 4.0;
            candidates.push((
                [a, b, c, c],
                Proposal {
                    corners: q,
                    score: confidence * fit,
                },
            ));
        }
    }
    candidates.sort_by(|x, y| y.1.score.total_cmp(&x.1.score));
    candidates
        .into_iter()
        .map(|(corners, proposal)| Candidate { corners, proposal })
        .collect()
}

/// The candidates taken best first, each corner in at most one quad and no quad's centre inside
/// another's — clustering by geometry, not box NMS. Those `kept` says yes to are taken before
/// any other (quads stage 2 read: their corners are spoken for), those `rejected` says no to are
/// skipped (quads stage 2 could not read: their corners may belong to other quads).
pub fn select(
    candidates: &[Candidate],
    kept: &dyn Fn(&Proposal) -> bool,
    rejected: &dyn Fn(&Proposal) -> bool,
) -> Vec<Candidate> {
    let used_len = candidates
        .iter()
        .flat_map(|c| c.corners)
        .max()
        .map_or(0, |m| m + 1);
    let mut used = vec![false; used_len];
    let mut taken: Vec<Candidate> = Vec::new();
    let (firsts, rest): (Vec<&Candidate>, Vec<&Candidate>) =
        candidates.iter().partition(|c| kept(&c.proposal));
    for c in firsts.into_iter().chain(rest) {
        let p = &c.proposal;
        if c.corners.iter().any(|&i| used[i]) || rejected(p) {
            continue;
        }
        if taken
            .iter()
            .any(|t| nested(&t.proposal.corners, &p.corners))
        {
            continue;
        }
        c.corners.iter().for_each(|&i| used[i] = true);
        taken.push(*c);
    }
    taken
}

/// Whether either quad's centre lies inside the other: the same marker twice, or a quad over
/// part of one — markers do not overlap.
pub fn nested(a: &Quad, b: &Quad) -> bool {
    a.encloses(b.centre()) || b.encloses(a.centre())
}

/// Whether two proposals mark the same quad: every corner within a fifth of the thinner quad's
/// width ([`Quad::width`]) of the other's, and within [`MAX_SAME_OFFSET`], from any starting corner.
pub fn same_quad(a: &Proposal, b: &Proposal) -> bool {
    same_corners(&a.corners, &b.corners)
}

/// [`same_quad`] for bare corners.
pub fn same_corners(a: &Quad, b: &Quad) -> bool {
    let tolerance = (0.2 * a.width().min(b.width())).min(MAX_SAME_OFFSET);
    (0..4).any(|shift| (0..4).all(|i| distance(a[(i + shift) % 4], b[i]) < tolerance))
}

/// The farthest apart, in pixels, two quads' corners may be and still mark the same quad,
/// however large: a close marker 270 px across had a stage-1 quad 43 px off that stage 2 could
/// not read, and its traced quad, 0.3 px off and read with 0 corrections, counted as "the
/// same" within a fifth of the width and was never read (dev seed 21 #8, 10 cm at 70°).
const MAX_SAME_OFFSET: f64 = 8.0;

/// No side under 15 % of the longest: flatter quads are slivers of clutter, not markers.
fn sides_balanced(q: &Quad) -> bool {
    q.shortest_side() >= 0.15 * q.longest_side()
}

/// Keeps, of proposals that mark the same quad (every corner within a fifth of the shorter
/// side of the other's), the better one. Pyramid levels find mid-sized markers twice.
pub fn merge_duplicates(mut proposals: Vec<Proposal>) -> Vec<Proposal> {
    proposals.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut kept: Vec<Proposal> = Vec::new();
    for p in proposals {
        if !kept.iter().any(|k| same_quad(&p, k)) {
            kept.push(p);
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The marker ROIs that `corners` make in one selection, best first.
    fn group(
        corners: &[Corner],
        mask: &dyn Fn([f64; 2]) -> f64,
        options: &GroupOptions,
    ) -> Vec<Proposal> {
        select(&candidates(corners, mask, options), &|_| false, &|_| false)
            .into_iter()
            .map(|c| c.proposal)
            .collect()
    }

    fn corner(at: [f64; 2], centre: [f64; 2], score: f64) -> Corner {
        let d = sub(centre, at);
        let l = d[0].hypot(d[1]);
        Corner {
            at,
            direction: [d[0] / l, d[1] / l],
            score,
        }
    }

    /// A mask that is 1 on the given markers and 0 elsewhere.
    fn mask_of(quads: Vec<[[f64; 2]; 4]>) -> impl Fn([f64; 2]) -> f64 {
        move |p| f64::from(u8::from(quads.iter().any(|&q| Quad(q).encloses(p))))
    }

    fn marker(corners: [[f64; 2]; 4]) -> Vec<Corner> {
        let c = Quad(corners).diagonal_crossing().unwrap();
        corners.iter().map(|&p| corner(p, c, 0.9)).collect()
    }

    fn candidate(corners: [usize; 4], quad: [[f64; 2]; 4], score: f64) -> Candidate {
        Candidate {
            corners,
            proposal: Proposal {
                corners: Quad(quad),
                score,
            },
        }
    }

    /// Two markers side by side and a quad across them that takes a corner pair of each: the
    /// first selection gives only the quad across; without it, both markers.
    #[test]
    fn a_rejected_quad_frees_the_corners_of_the_markers_it_took_them_from() {
        let a = [[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [0.0, 30.0]];
        let b = [[40.0, 0.0], [70.0, 0.0], [70.0, 30.0], [40.0, 30.0]];
        let across = [[30.0, 0.0], [40.0, 0.0], [40.0, 30.0], [30.0, 30.0]];
        let list = [
            candidate([1, 4, 7, 2], across, 0.9),
            candidate([0, 1, 2, 3], a, 0.8),
            candidate([4, 5, 6, 7], b, 0.7),
        ];
        let first = select(&list, &|_| false, &|_| false);
        assert_eq!(first.len(), 1);
        assert_eq!(first[0].proposal.corners, across);
        let rejected = first[0].proposal;
        let second = select(&list, &|_| false, &|p| same_quad(p, &rejected));
        let quads: Vec<_> = second.iter().map(|c| c.proposal.corners).collect();
        assert_eq!(quads, vec![a, b]);
        // A marker already read keeps its corners even where a better quad wants them.
        let read = list[2].proposal;
        let third = select(&list, &|p| same_quad(p, &read), &|_| false);
        let quads: Vec<_> = third.iter().map(|c| c.proposal.corners).collect();
        assert_eq!(quads, vec![b, a]);
    }

    #[test]
    fn the_same_quad_from_another_starting_corner_is_the_same() {
        let q = [[0.0, 0.0], [30.0, 0.0], [30.0, 30.0], [0.0, 30.0]];
        let p = |corners| Proposal {
            corners: Quad(corners),
            score: 1.0,
        };
        let turned = [[30.5, 0.0], [30.0, 30.0], [0.0, 29.0], [1.0, 0.0]];
        assert!(same_quad(&p(q), &p(turned)));
        let moved = q.map(|[x, y]| [x + 8.0, y]);
        assert!(!same_quad(&p(q), &p(moved)));
    }

    #[test]
    fn a_sliver_is_the_same_quad_only_within_a_fifth_of_its_width() {
        // A rhombus 86 px a side and 10 px across its long diagonal (a marker turned about its
        // diagonal, seen nearly edge-on).
        let sliver = [[0.0, 0.0], [85.0, -5.0], [170.0, 0.0], [85.0, 5.0]];
        let p = |corners| Proposal {
            corners: Quad(corners),
            score: 1.0,
        };
        let nudged = sliver.map(|[x, y]| [x + 1.5, y]);
        assert!(same_quad(&p(sliver), &p(nudged)));
        let mut far_tip = sliver;
        far_tip[0][0] -= 16.0;
        assert!(!same_quad(&p(sliver), &p(far_tip)));
        // From another corner, still the same.
        let turned = [sliver[2], sliver[3], sliver[0], sliver[1]];
        assert!(same_quad(&p(sliver), &p(turned)));
    }

    #[test]
    fn a_large_quad_is_the_same_only_within_a_few_pixels() {
        // A close marker about 270 px across.
        let close = [
            [686.0, 588.0],
            [889.0, 382.0],
            [1073.0, 606.0],
            [726.0, 860.0],
        ];
        let p = |corners| Proposal {
            corners: Quad(corners),
            score: 1.0,
        };
        let nudged = close.map(|[x, y]| [x + 3.0, y - 3.0]);
        assert!(same_quad(&p(close), &p(nudged)));
        // Stage 1's quad of it 43 px off at one corner is another quad, though well within a
        // fifth of its width.
        let mut off = close;
        off[0] = [695.0, 630.0];
        assert!(!same_quad(&p(close), &p(off)));
    }

    #[test]
    fn two_markers_and_clutter_group_into_two_clockwise_quads() {
        let a = [[10.0, 10.0], [50.0, 12.0], [52.0, 48.0], [8.0, 50.0]];
        // Listed anticlockwise: the result must still turn clockwise.
        let b = [
            [100.0, 100.0],
            [100.0, 160.0],
            [170.0, 165.0],
            [165.0, 95.0],
        ];
        let mut corners = marker(a);
        corners.extend(marker(b));
        // Corners pointing nowhere useful.
        corners.push(corner([80.0, 20.0], [80.0, 0.0], 0.95));
        corners.push(corner([30.0, 120.0], [0.0, 120.0], 0.95));
        let mask = mask_of(vec![a, b]);
        let quads = group(&corners, &mask, &GroupOptions::default());
        assert_eq!(quads.len(), 2, "{quads:?}");
        for q in &quads {
            assert!(q.corners.signed_area() > 0.0);
            let expected = if q.corners.0.contains(&a[0]) { a } else { b };
            for p in expected {
                assert!(q.corners.0.contains(&p));
            }
        }
    }

    #[test]
    fn a_lost_corner_is_completed_from_the_other_three() {
        let q = [[10.0, 10.0], [50.0, 12.0], [52.0, 50.0], [8.0, 48.0]];
        let mut corners = marker(q);
        corners.remove(3);
        let mask = mask_of(vec![q]);
        let quads = group(&corners, &mask, &GroupOptions::default());
        assert_eq!(quads.len(), 1, "{quads:?}");
        let p = quads[0];
        assert!(p.corners.signed_area() > 0.0);
        // The fourth corner by parallelogram: (10,10) + (52,50) − (50,12).
        assert!(p.corners.0.contains(&[12.0, 48.0]), "{p:?}");
        // A complete marker outscores a completed one.
        assert!(p.score < 0.9 * 0.8);
    }

    #[test]
    fn corners_of_two_touching_markers_do_not_make_one_quad_across_them() {
        // Two markers side by side: the outer corners of the pair also make a big quad whose
        // diagonals cross, but its corners point at their own markers' centres, not its own.
        let a = [[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let b = [[54.0, 10.0], [94.0, 10.0], [94.0, 50.0], [54.0, 50.0]];
        let mut corners = marker(a);
        corners.extend(marker(b));
        let mask = mask_of(vec![a, b]);
        let quads = group(&corners, &mask, &GroupOptions::default());
        assert_eq!(quads.len(), 2, "{quads:?}");
        for q in quads {
            assert!(q.corners.0.contains(&a[0]) == q.corners.0.contains(&a[2]));
        }
    }

    #[test]
    fn a_quad_the_mask_does_not_cover_is_dropped() {
        let corners = marker([[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]]);
        let nowhere = |_: [f64; 2]| 0.1;
        assert!(group(&corners, &nowhere, &GroupOptions::default()).is_empty());
    }

    #[test]
    fn the_same_quad_from_two_levels_is_kept_once() {
        let q = [[10.0, 10.0], [50.0, 10.0], [50.0, 50.0], [10.0, 50.0]];
        let shifted = [q[1], q[2], q[3], [11.0, 9.0]];
        let other = [[60.0, 10.0], [90.0, 10.0], [90.0, 40.0], [60.0, 40.0]];
        let kept = merge_duplicates(vec![
            Proposal {
                corners: Quad(q),
                score: 0.5,
            },
            Proposal {
                corners: Quad(shifted),
                score: 0.8,
            },
            Proposal {
                corners: Quad(other),
                score: 0.4,
            },
        ]);
        assert_eq!(kept.len(), 2);
        assert_eq!(kept[0].corners, shifted);
    }

    #[test]
    fn peaks_are_placed_by_their_offsets() {
        let (columns, rows) = (8, 6);
        let mut maps = Maps {
            columns,
            rows,
            heat: vec![0.0; 48],
            offset: vec![[0.0; 2]; 48],
            direction: vec![[1.0, 0.0]; 48],
            mask: vec![0.0; 48],
        };
        maps.heat[2 * 8 + 3] = 0.9;
        maps.heat[2 * 8 + 4] = 0.5;
        maps.offset[2 * 8 + 3] = [0.25, -0.5];
        let found = maps.corners(0.3, 2.0);
        assert_eq!(found.len(), 1);
        // Level pixel centres at whole coordinates: a half-size level's x maps to 2x + 0.5.
        assert_eq!(found[0].at, [3.75 * 8.0 + 0.5, 2.0 * 8.0 + 0.5]);
    }
}
