//! Quads traced around the image's dark blobs (docs/ARCHITECTURE.md §9.8, "traced quads").
//!
//! The last Difficult misses of the network and the outline search are steep views whose corners
//! stage 1 does not find at all (a side 20–90 px long, 6–20 px across), yet stage 2 reads most of
//! them from a ROI within 2 px. A marker's dark border, with the data cells that touch it, is one
//! dark blob on its light quiet zone however steep the view, and the convex hull of that blob is
//! the marker's outline: the four hull points that span the largest quadrilateral are its
//! corners. Pixels are called dark against their neighbourhood's mean (a box of
//! [`TraceOptions::window`] px), so shading across the image does not matter. Like every ROI,
//! a traced quad is only a proposal: stage 2 decides, so a blob of clutter costs one read.

use super::edges::{intersection, weighted_line};
use super::group::same_corners;
use super::outline::{contrast_range, cross, noise_sigma};
use crate::geometry::{distance, polygon_area, Quad};
use crate::image::GrayImage;

/// The noisiest image traced, as σ in gray levels: beyond it the dark pixels of noise join into
/// blobs across the image (the network's own grouping still runs).
const MAX_NOISE: f32 = 20.0;

/// Limits of the traced-quad search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TraceOptions {
    /// Side of the box whose mean a pixel is compared with, in pixels (odd): wide enough to
    /// hold a steep marker's dark border and some of its quiet zone.
    pub window: u32,
    /// How much darker than that mean a pixel must be, as a share of the image's range of gray
    /// levels (its 2–98 % spread): a border against its quiet zone spans most of the range, while
    /// texture and shading step by a fraction of it. The image is traced at each: the first
    /// keeps a close marker's border whole; the second, stricter, parts a steep marker from
    /// the darker ground around it, which its bright quiet zone lifts the box's mean above
    /// (a sliver 7 px across on gray ground joined its neighbours' texture at the first).
    pub offsets: [f32; 2],
    /// The shortest side of a quad, in pixels.
    pub min_side: f64,
    /// The smallest quad, in square pixels.
    pub min_area: f64,
    /// The least share of the blob's convex hull its quad covers: a quadrilateral blob is
    /// covered almost whole, a disc by 64 %, a triangle by at most 75 %. A sliver's blob,
    /// blurred at its tips, is covered by 0.75–0.85 (dev seed 12 #78, a rhombus 10 px across),
    /// so triangles of clutter pass too: the reads reject them.
    pub fit: f64,
    /// The mask's value that marks a spot to trace around. Below one half: a sliver a few
    /// pixels across 60–90 cm away lights the mask to 0.3–0.5 only (development sets 10–13:
    /// three of 260 Difficult markers had no spot at 0.5, and are read from one at 0.3).
    pub mask: f64,
    /// The stage-1 corner score that marks a spot as well: some slivers light no mask cell
    /// at all while the network still finds their corners (dev seeds 12 #78, 16 #78, 19 #76).
    pub corner: f64,
    /// The least mean of the network's marker mask inside a quad, at the level where it is
    /// highest: dark rectangles of clutter trace as well as markers do. Low, because the quad
    /// is only traced near a spot already: a marker seen steep from 10 cm is long, and the
    /// network's mask covers a fifth of it (development sets: 0.18–0.19 on both such misses);
    /// slivers far away cover a few of its cells, which the mask only partly lights.
    pub support: f64,
}

impl Default for TraceOptions {
    fn default() -> Self {
        Self {
            window: 15,
            offsets: [0.1, 0.3],
            min_side: 4.0,
            min_area: 150.0,
            fit: 0.7,
            mask: 0.3,
            corner: 0.3,
            support: 0.1,
        }
    }
}

/// The least offset, in gray levels, however flat the image: below it sensor noise alone makes
/// pixels dark.
pub(crate) const MIN_OFFSET: f32 = 4.0;

/// The most one side of a quad may exceed its opposite side, as a ratio. Opposite sides of a
/// square in perspective differ as the depths of their ends do, so only a marker close to the
/// camera, large in the image, shows a large ratio: a 5 cm marker 10 cm away at 75° on the
/// optical axis reaches 1.6, and off the axis, towards the image's edge, the near side comes
/// closer still — the 6710 markers of the development sets reach 3.9 (10 cm at 60°, 527 px
/// long), five beyond 2.5 (which dropped dev ArUco seed 20 #7, 2.8), none beyond 1.9 under
/// 380 px (at a focal length of 695 px). So a quad may reach 4.5 only where its longest side
/// spans [`CLOSE_LENGTH`] px — a lens of half that focal length included — and 2.5 elsewhere:
/// a far sliver's blob joined to its neighbours at the lenient offset traces a skewed quad (4.0
/// on dev seed 16 #78) over the sliver's own, and the larger of two nested quads is read first.
const MAX_OPPOSITE_RATIO: f64 = 2.5;
const MAX_OPPOSITE_RATIO_CLOSE: f64 = 4.5;
const CLOSE_LENGTH: f64 = 150.0;

/// How many times a region is traced again, grown, when a blob over its middle runs out of it.
/// Each growth adds the region's size on each side the blob leaves by: a spot covers only the
/// middle of a marker seen steep from 10 cm (dev ArUco seed 20 #7: 520 × 60 px, the region
/// first 180 px wide), and a blob the region cuts is not a whole outline.
const MAX_REGROWS: usize = 2;

/// Side of the tiles that [`traced_quads_near`] marks, in pixels.
const TILE: u32 = 16;

/// [`traced_quads`] in the parts of `image` around the `spots` (x0, y0, x1, y1 in pixels:
/// where the network's mask sees a marker no read accounts for), in image coordinates. The
/// spots are gathered into boxes half again their size (a steep marker's mask may cover half of
/// it), and only those are traced: on most images little or nothing is left to trace once the
/// network's markers are read.
pub fn traced_quads_near(
    image: &GrayImage,
    spots: &[[f64; 4]],
    options: &TraceOptions,
) -> Vec<Quad> {
    if spots.is_empty() || noise_sigma(image) > MAX_NOISE {
        // Noise this strong makes half the pixels dark and one blob of the whole image.
        return Vec::new();
    }
    let mut quads: Vec<(Quad, f64)> = Vec::new();
    // Darker by a share of the whole image's range, not the crop's.
    let range = contrast_range(image);
    for mut region in regions(image.width, image.height, spots) {
        for _ in 0..=MAX_REGROWS {
            let [x0, y0, x1, y1] = region;
            let crop = image.crop(x0, y0, x1 - x0, y1 - y0);
            let mut cut = [false; 4];
            for share in options.offsets {
                let offset = (share * range).max(MIN_OFFSET);
                let traced = traced_quads(&crop, offset, options);
                for q in traced.quads {
                    let q = fitted_to_edges(&crop, q).map(|p| [p[0] + x0 as f64, p[1] + y0 as f64]);
                    if !quads.iter().any(|(seen, _)| same_corners(seen, &q)) {
                        quads.push((q, q.signed_area()));
                    }
                }
                for (side, cut_here) in cut.iter_mut().zip(traced.centre_cut) {
                    *side |= cut_here;
                }
            }
            let grown = grown(region, cut, image.width, image.height);
            if grown == region {
                break;
            }
            region = grown;
        }
    }
    quads.sort_by(|a, b| b.1.total_cmp(&a.1));
    quads.into_iter().map(|(q, _)| q).collect()
}

/// Boxes around the spots (x0, y0, x1, y1, exclusive ends, inside the image), none overlapping:
/// the spots' tiles joined where they touch, each group's bounds grown by half their size and
/// 16 px on every side, and boxes that then overlap merged.
fn regions(width: u32, height: u32, spots: &[[f64; 4]]) -> Vec<[u32; 4]> {
    let (columns, rows) = (
        width.div_ceil(TILE) as usize,
        height.div_ceil(TILE) as usize,
    );
    if columns == 0 || rows == 0 {
        return Vec::new();
    }
    let mut marked = vec![false; columns * rows];
    let tile = |v: f64, n: usize| ((v / TILE as f64).floor().max(0.0) as usize).min(n - 1);
    for &[x0, y0, x1, y1] in spots {
        for ty in tile(y0, rows)..=tile(y1, rows) {
            for tx in tile(x0, columns)..=tile(x1, columns) {
                marked[ty * columns + tx] = true;
            }
        }
    }
    // Bounds of each 8-connected group of marked tiles, by flood fill.
    let mut boxes: Vec<[f64; 4]> = Vec::new();
    let mut seen = vec![false; columns * rows];
    for start in 0..marked.len() {
        if !marked[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let mut stack = vec![start];
        let mut bounds = [usize::MAX, usize::MAX, 0, 0];
        while let Some(i) = stack.pop() {
            let (tx, ty) = (i % columns, i / columns);
            bounds = [
                bounds[0].min(tx),
                bounds[1].min(ty),
                bounds[2].max(tx),
                bounds[3].max(ty),
            ];
            for ny in ty.saturating_sub(1)..=(ty + 1).min(rows - 1) {
                for nx in tx.saturating_sub(1)..=(tx + 1).min(columns - 1) {
                    let j = ny * columns + nx;
                    if marked[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        let t = TILE as f64;
        let (x0, y0) = (bounds[0] as f64 * t, bounds[1] as f64 * t);
        let (x1, y1) = ((bounds[2] + 1) as f64 * t, (bounds[3] + 1) as f64 * t);
        let (gx, gy) = (16.0 + 0.5 * (x1 - x0), 16.0 + 0.5 * (y1 - y0));
        boxes.push([x0 - gx, y0 - gy, x1 + gx, y1 + gy]);
    }
    // Merge overlapping boxes until none overlap.
    let mut merged = true;
    while merged {
        merged = false;
        'outer: for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                let (a, b) = (boxes[i], boxes[j]);
                if a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3] {
                    boxes[i] = [
                        a[0].min(b[0]),
                        a[1].min(b[1]),
                        a[2].max(b[2]),
                        a[3].max(b[3]),
                    ];
                    boxes.swap_remove(j);
                    merged = true;
                    break 'outer;
                }
            }
        }
    }
    boxes
        .into_iter()
        .map(|[x0, y0, x1, y1]| {
            let clamp = |v: f64, n: u32| v.clamp(0.0, n as f64) as u32;
            [
                clamp(x0, width),
                clamp(y0, height),
                clamp(x1, width),
                clamp(y1, height),
            ]
        })
        .filter(|[x0, y0, x1, y1]| x1 > x0 && y1 > y0)
        .collect()
}

/// `region` (x0, y0, x1, y1, exclusive ends) grown by its own width or height on each `cut` side
/// (left, top, right, bottom), inside the image.
fn grown(region: [u32; 4], cut: [bool; 4], width: u32, height: u32) -> [u32; 4] {
    let [x0, y0, x1, y1] = region;
    let (w, h) = (x1 - x0, y1 - y0);
    [
        if cut[0] { x0.saturating_sub(w) } else { x0 },
        if cut[1] { y0.saturating_sub(h) } else { y0 },
        if cut[2] { (x1 + w).min(width) } else { x1 },
        if cut[3] { (y1 + h).min(height) } else { y1 },
    ]
}

/// What one trace of an image found.
struct Traced {
    /// Every whole dark blob's quad, largest first.
    quads: Vec<Quad>,
    /// The sides (left, top, right, bottom) where a blob over the image's middle runs out of
    /// it: the marker a crop was centred on may lie partly beyond it.
    centre_cut: [bool; 4],
}

/// A horizontal run of dark pixels `x0..=x1` on row `y`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Run {
    pub(crate) y: u32,
    pub(crate) x0: u32,
    pub(crate) x1: u32,
}

impl Run {
    /// Its pixels.
    pub(crate) fn len(&self) -> usize {
        (self.x1 - self.x0 + 1) as usize
    }

    /// The corners of its pixels' squares, x0 − ½ … x1 + ½ by y − ½ … y + ½ (the only points
    /// of the run a convex hull can pass through).
    pub(crate) fn corners(&self) -> [[f64; 2]; 4] {
        let (left, right) = (self.x0 as f64 - 0.5, self.x1 as f64 + 0.5);
        let (top, bottom) = (self.y as f64 - 0.5, self.y as f64 + 0.5);
        [[left, top], [right, top], [right, bottom], [left, bottom]]
    }
}

/// Every dark blob's quad in `image`, clockwise in the image (y down, the order stage 2 takes),
/// largest first, and where a blob over the middle runs out of the image. Image coordinates put
/// pixel centres on integers. `offset`: how much darker than its box's mean a dark pixel is, in
/// gray levels.
fn traced_quads(image: &GrayImage, offset: f32, options: &TraceOptions) -> Traced {
    let runs = dark_runs(image, offset, options.window);
    let labels = blobs(&runs);
    // Each blob's bounds first: most blobs (texture, text) are too small to gather points for.
    let blob_count = labels.iter().map(|&l| l + 1).max().unwrap_or(0);
    let mut rows = vec![(u32::MAX, 0u32); blob_count];
    let mut columns = vec![(u32::MAX, 0u32); blob_count];
    for (run, &l) in runs.iter().zip(&labels) {
        rows[l] = (rows[l].0.min(run.y), rows[l].1.max(run.y));
        columns[l] = (columns[l].0.min(run.x0), columns[l].1.max(run.x1));
    }
    let min_extent = options.min_side.max(2.0) as u32;
    let (last_column, last_row) = (
        image.width.saturating_sub(1),
        image.height.saturating_sub(1),
    );
    let cut_sides = |l: usize| {
        [
            columns[l].0 == 0,
            rows[l].0 == 0,
            columns[l].1 == last_column,
            rows[l].1 == last_row,
        ]
    };
    let big_enough = |l: usize| {
        let (h, w) = (rows[l].1 - rows[l].0 + 1, columns[l].1 - columns[l].0 + 1);
        h >= min_extent && w >= min_extent && (w as f64) * (h as f64) >= options.min_area
    };
    // A blob the border cuts is not a whole outline (and a marker cut by it cannot be read).
    let large = |l: usize| big_enough(l) && !cut_sides(l).contains(&true);
    // The middle half of the image in each direction: a marker's dark border, seen through a
    // crop that cuts it, falls apart into strips that each miss the centre point itself.
    let (middle_x, middle_y) = (
        image.width / 4..=image.width * 3 / 4,
        image.height / 4..=image.height * 3 / 4,
    );
    let overlaps = |(a, b): (u32, u32), middle: &std::ops::RangeInclusive<u32>| {
        a <= *middle.end() && b >= *middle.start()
    };
    let mut centre_cut = [false; 4];
    for l in (0..blob_count).filter(|&l| big_enough(l)) {
        if overlaps(columns[l], &middle_x) && overlaps(rows[l], &middle_y) {
            for (side, cut) in centre_cut.iter_mut().zip(cut_sides(l)) {
                *side |= cut;
            }
        }
    }
    let mut index = vec![usize::MAX; blob_count];
    let mut outlines: Vec<Vec<[f64; 2]>> = Vec::new();
    for l in (0..blob_count).filter(|&l| large(l)) {
        index[l] = outlines.len();
        outlines.push(Vec::new());
    }
    // Only a row's leftmost and rightmost dark pixels can be on the hull: each blob's row
    // extremes, flushed as its next row starts (runs come row by row).
    let mut row_span: Vec<Option<(u32, u32, u32)>> = vec![None; outlines.len()];
    let flush = |outline: &mut Vec<[f64; 2]>, (y, x0, x1): (u32, u32, u32)| {
        outline.extend(Run { y, x0, x1 }.corners());
    };
    for (run, &l) in runs.iter().zip(&labels) {
        let b = index[l];
        if b == usize::MAX {
            continue;
        }
        row_span[b] = match row_span[b] {
            Some((y, x0, x1)) if y == run.y => Some((y, x0.min(run.x0), x1.max(run.x1))),
            Some(span) => {
                flush(&mut outlines[b], span);
                Some((run.y, run.x0, run.x1))
            }
            None => Some((run.y, run.x0, run.x1)),
        };
    }
    for (outline, span) in outlines.iter_mut().zip(row_span) {
        if let Some(span) = span {
            flush(outline, span);
        }
    }
    let mut quads: Vec<(Quad, f64)> = outlines
        .into_iter()
        .filter_map(|points| {
            let hull = convex_hull(points);
            let hull_area = polygon_area(&hull);
            let hull = straightened(hull);
            let (quad, area) = largest_quad(&hull)?;
            let short = quad.shortest_side();
            (area >= options.min_area
                && area >= options.fit * hull_area
                && short >= options.min_side
                && seen_by_a_camera(&quad))
            .then_some((quad, area))
        })
        .collect();
    quads.sort_by(|a, b| b.1.total_cmp(&a.1));
    Traced {
        quads: quads.into_iter().map(|(q, _)| q).collect(),
        centre_cut,
    }
}

/// The runs of pixels darker than their box's mean by the offset, row by row. The box sums come
/// from running sums (each row's column sums updated by the row entering and the row leaving the
/// box, then slid along the row), a few operations per pixel.
pub(crate) fn dark_runs(image: &GrayImage, offset: f32, window: u32) -> Vec<Run> {
    let (w, h) = (image.width as usize, image.height as usize);
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let r = (window / 2) as usize;
    let offset = offset.round() as u32;
    let row = |y: usize| &image.pixels[y * w..(y + 1) * w];
    // Column sums over rows y − r … y + r (clipped to the image).
    let mut columns = vec![0u32; w];
    for y in 0..r.min(h) {
        for (c, &p) in columns.iter_mut().zip(row(y)) {
            *c += p as u32;
        }
    }
    let mut runs = Vec::new();
    for y in 0..h {
        if y + r < h {
            for (c, &p) in columns.iter_mut().zip(row(y + r)) {
                *c += p as u32;
            }
        }
        if y > r {
            for (c, &p) in columns.iter_mut().zip(row(y - r - 1)) {
                *c -= p as u32;
            }
        }
        let box_rows = ((y + r + 1).min(h) - y.saturating_sub(r)) as u32;
        // The box's sum slides along the row: columns x − r … x + r.
        let mut total: u32 = columns[..r.min(w)].iter().sum();
        let mut open: Option<u32> = None;
        for (x, &p) in row(y).iter().enumerate() {
            if x + r < w {
                total += columns[x + r];
            }
            if x > r {
                total -= columns[x - r - 1];
            }
            let box_columns = ((x + r + 1).min(w) - x.saturating_sub(r)) as u32;
            let area = box_rows * box_columns;
            // p < mean − offset, in integers: (p + offset) · area < total.
            let dark = (p as u32 + offset) * area < total;
            match (dark, open) {
                (true, None) => open = Some(x as u32),
                (false, Some(x0)) => {
                    runs.push(Run {
                        y: y as u32,
                        x0,
                        x1: x as u32 - 1,
                    });
                    open = None;
                }
                _ => {}
            }
        }
        if let Some(x0) = open {
            runs.push(Run {
                y: y as u32,
                x0,
                x1: w as u32 - 1,
            });
        }
    }
    runs
}

/// Each run's blob (8-connected: a steep border's pixels often touch only at corners), as
/// labels 0, 1, … in order of first appearance.
pub(crate) fn blobs(runs: &[Run]) -> Vec<usize> {
    let mut parent: Vec<usize> = (0..runs.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    // Runs come row by row; `previous` is the last row's span of `runs`.
    let mut previous = 0..0;
    let mut start = 0;
    while start < runs.len() {
        let y = runs[start].y;
        let end = start + runs[start..].iter().take_while(|r| r.y == y).count();
        if previous.end > previous.start && runs[previous.start].y + 1 == y {
            let mut j = previous.start;
            for i in start..end {
                // Skip the last row's runs that end left of this one's reach.
                while j < previous.end && runs[j].x1 + 1 < runs[i].x0 {
                    j += 1;
                }
                let mut k = j;
                while k < previous.end && runs[k].x0 <= runs[i].x1 + 1 {
                    let (a, b) = (root(&mut parent, i), root(&mut parent, k));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                    k += 1;
                }
            }
        }
        previous = start..end;
        start = end;
    }
    let mut label = vec![usize::MAX; runs.len()];
    let mut next = 0;
    (0..runs.len())
        .map(|i| {
            let r = root(&mut parent, i);
            if label[r] == usize::MAX {
                label[r] = next;
                next += 1;
            }
            label[r]
        })
        .collect()
}

/// Whether a square seen by a camera can have `quad`'s opposite sides (see
/// [`MAX_OPPOSITE_RATIO`]).
fn seen_by_a_camera(quad: &Quad) -> bool {
    let longest = quad.longest_side();
    let bound = if longest >= CLOSE_LENGTH {
        MAX_OPPOSITE_RATIO_CLOSE
    } else {
        MAX_OPPOSITE_RATIO
    };
    quad.opposite_sides_ratio() <= bound
}

/// The convex hull, clockwise in the image (y down), without collinear points (Andrew's
/// monotone chain).
pub(crate) fn convex_hull(mut points: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    points.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    points.dedup();
    if points.len() < 3 {
        return points;
    }
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(points.len() + 1);
    for pass in 0..2 {
        let floor = hull.len();
        let ordered: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(points.iter())
        } else {
            Box::new(points.iter().rev())
        };
        for &p in ordered {
            while hull.len() >= floor + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0.0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// The quad with each side moved onto the image's edge and the corners where those lines meet.
/// A hull vertex sits on a dark pixel's square, and at a steep view's acute corner blur leaves the
/// last pixels of the tip lighter than the threshold: that corner is then several pixels short,
/// while the long sides themselves are traced along their whole length. Each side's edge is
/// found at up to 32 points of its middle 70 %, as the strongest light-to-dark step into the quad
/// within 3 px, and a line fitted through them; a side with too few clear steps stays as it is,
/// and so does a quad whose corners would move by more than 15 % of its longest side.
fn fitted_to_edges(image: &GrayImage, quad: Quad) -> Quad {
    let mut lines: [Option<([f64; 2], [f64; 2])>; 4] = [None; 4];
    for (i, line) in lines.iter_mut().enumerate() {
        let (p, q) = (quad[i], quad[(i + 1) % 4]);
        let len = distance(p, q);
        if len < 4.0 {
            continue;
        }
        let u = [(q[0] - p[0]) / len, (q[1] - p[1]) / len];
        // Into the quad: the right-hand normal of a clockwise quad (y down).
        let n = [-u[1], u[0]];
        let samples = (len * 0.7).clamp(2.0, 32.0) as usize;
        let mut points = Vec::with_capacity(samples);
        for k in 0..samples {
            let t = len * (0.15 + 0.7 * (k as f64 + 0.5) / samples as f64);
            let base = [p[0] + t * u[0], p[1] + t * u[1]];
            let at = |d: f64| {
                image.sample((base[0] + d * n[0]) as f32, (base[1] + d * n[1]) as f32) as f64
            };
            let mut best = (0.0, 0.0);
            let mut d = -3.0;
            while d <= 3.0 {
                let step = at(d - 1.0) - at(d + 1.0);
                if step > best.0 {
                    best = (step, d);
                }
                d += 0.25;
            }
            if best.0 >= 10.0 {
                points.push([base[0] + best.1 * n[0], base[1] + best.1 * n[1]]);
            }
        }
        if points.len() * 2 >= samples && points.len() >= 3 {
            let weighted: Vec<([f64; 2], f64)> = points.iter().map(|&p| (p, 1.0)).collect();
            *line = weighted_line(&weighted);
        }
    }
    let mut out = quad;
    for i in 0..4 {
        let (before, after) = (lines[(i + 3) % 4], lines[i]);
        if let (Some(a), Some(b)) = (before, after) {
            if let Some(corner) = intersection(a, b) {
                out[i] = corner;
            }
        }
    }
    let longest = quad.longest_side();
    let moved = out.largest_corner_move(&quad);
    if moved > 0.15 * longest || out.signed_area() <= 0.0 {
        return quad;
    }
    out
}

/// The convex polygon without the vertices where it turns by less than about 6°: the pixel
/// staircase along a straight side leaves dozens of them, and each costs the quad search O(n).
/// Dropping one loses a sliver of at most a few square pixels, so the search stays exact where it
/// matters — at the corners.
fn straightened(mut hull: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    loop {
        let n = hull.len();
        if n <= 4 {
            return hull;
        }
        let flat = (0..n).find(|&i| {
            let (p, c, q) = (hull[(i + n - 1) % n], hull[i], hull[(i + 1) % n]);
            cross(p, c, q).abs() < 0.1 * distance(p, c) * distance(c, q)
        });
        match flat {
            Some(i) => {
                hull.remove(i);
            }
            None => return hull,
        }
    }
}

/// The four vertices of a convex polygon (in its order) that span the largest quadrilateral, and
/// its area. For each diagonal i–k the best third vertex on either side maximises a triangle,
/// and along a convex chain that maximum moves forward as k does, so each side is a pointer that
/// only advances: O(n²) rather than O(n⁴).
fn largest_quad(hull: &[[f64; 2]]) -> Option<(Quad, f64)> {
    let n = hull.len();
    if n < 4 {
        return None;
    }
    let at = |i: usize| hull[i % n];
    let triangle = |a: usize, b: usize, c: usize| cross(at(a), at(b), at(c)).abs() / 2.0;
    let mut best = (0.0, [0usize; 4]);
    for i in 0..n {
        let (mut j, mut l) = (i + 1, i + 3);
        for k in i + 2..i + n - 1 {
            while j + 1 < k && triangle(i, j + 1, k) >= triangle(i, j, k) {
                j += 1;
            }
            l = l.max(k + 1);
            while l + 1 < i + n && triangle(k, l + 1, i) >= triangle(k, l, i) {
                l += 1;
            }
            let area = triangle(i, j, k) + triangle(k, l, i);
            if area > best.0 {
                best = (area, [i, j, k, l]);
            }
        }
    }
    let [a, b, c, d] = best.1;
    Some((Quad([at(a), at(b), at(c), at(d)]), best.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `fill` inside the quad (sampled 4 × 4 per pixel), `ground` elsewhere.
    fn draw(quads: &[[[f64; 2]; 4]], ground: u8, fill: u8) -> GrayImage {
        let mut image = GrayImage::new(200, 150, ground);
        for y in 0..150u32 {
            for x in 0..200u32 {
                let mut hits = 0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        let p = [
                            x as f64 - 0.375 + 0.25 * sx as f64,
                            y as f64 - 0.375 + 0.25 * sy as f64,
                        ];
                        hits += quads.iter().any(|&q| Quad(q).encloses(p)) as i32;
                    }
                }
                let v = ground as f64 + (fill as f64 - ground as f64) * hits as f64 / 16.0;
                image.pixels[(y * 200 + x) as usize] = v.round() as u8;
            }
        }
        image
    }

    fn matches(found: &Quad, truth: &[[f64; 2]; 4], tolerance: f64) -> bool {
        (0..4).any(|k| (0..4).all(|i| distance(found[(i + k) % 4], truth[i]) < tolerance))
    }

    /// A steep view: 100 × 12 px, clockwise.
    const SLIVER: [[f64; 2]; 4] = [[30.0, 50.0], [130.0, 40.0], [131.5, 52.0], [31.5, 62.0]];

    #[test]
    fn a_dark_sliver_is_traced_to_its_corners_clockwise() {
        let image = draw(&[SLIVER], 210, 30);
        let quads = traced_quads(&image, 20.0, &TraceOptions::default()).quads;
        let best = quads.first().expect("the sliver is traced");
        assert!(matches(best, &SLIVER, 1.5), "{best:?}");
        assert!(best.signed_area() > 0.0, "clockwise in the image");
    }

    #[test]
    fn a_steep_marker_on_textured_ground_is_parted_from_it_by_the_stricter_offset() {
        // A 36h11 marker 90 cm away at 60°, 7 px across (`tagsmith eval generate apriltag-36h11
        // --seed 9`, image 86, cut at x 372–492, y 262–352): its quiet zone lifts the box means
        // over the gray ground beside it, which joins its blob at the lenient offset.
        let bytes = include_bytes!("testdata/steep-marker-on-texture.png");
        let image = crate::image::decode(bytes, &Default::default()).expect("the fixture decodes");
        let truth = [[80.0, 33.7], [45.9, 59.3], [40.6, 54.3], [73.0, 30.0]];
        let options = TraceOptions::default();
        let lenient = traced_quads(
            &image,
            options.offsets[0] * contrast_range(&image),
            &options,
        )
        .quads;
        assert!(
            !lenient.iter().any(|q| matches(q, &truth, 2.5)),
            "the lenient offset alone already parts it, so the fixture no longer shows the case: {lenient:?}"
        );
        let everywhere = [[0.0, 0.0, 119.0, 89.0]];
        let both = traced_quads_near(&image, &everywhere, &options);
        assert!(both.iter().any(|q| matches(q, &truth, 2.5)), "{both:?}");
    }

    #[test]
    fn a_flat_blob_running_out_of_its_spots_region_is_traced_whole() {
        // A close steep view: 180 × 20 px, the spot (the network's mask) over its middle only,
        // whose region is 96 px wide at first.
        let flat = [[10.0, 58.0], [190.0, 62.0], [186.0, 82.0], [14.0, 78.0]];
        let image = draw(&[flat], 210, 30);
        let spot = [[95.0, 66.0, 105.0, 74.0]];
        let quads = traced_quads_near(&image, &spot, &TraceOptions::default());
        assert!(quads.iter().any(|q| matches(q, &flat, 1.5)), "{quads:?}");
    }

    #[test]
    fn a_ring_with_holes_is_one_blob_and_its_outer_quad() {
        // A marker-like ring: dark square with a light inner square, on light ground.
        let outer = [[40.0, 30.0], [140.0, 40.0], [130.0, 130.0], [35.0, 120.0]];
        let mut image = draw(&[outer], 220, 20);
        let inner = draw(
            &[[[65.0, 55.0], [115.0, 60.0], [110.0, 105.0], [60.0, 100.0]]],
            0,
            200,
        );
        for (p, q) in image.pixels.iter_mut().zip(&inner.pixels) {
            *p = p.saturating_add(*q);
        }
        let quads = traced_quads(&image, 20.0, &TraceOptions::default()).quads;
        assert!(matches(&quads[0], &outer, 1.5), "{:?}", quads[0]);
    }

    #[test]
    fn discs_triangles_flat_images_and_specks_trace_nothing() {
        let mut image = GrayImage::new(200, 150, 200);
        for y in 0..150i32 {
            for x in 0..200i32 {
                let disc = (x - 60).pow(2) + (y - 70).pow(2) < 35 * 35;
                let triangle = x > 120 && y > 40 && (x - 120) > (y - 40) / 2 && y < 120;
                let speck = (x - 170).abs() < 2 && (y - 20).abs() < 2;
                if disc || triangle || speck {
                    image.pixels[(y * 200 + x) as usize] = 30;
                }
            }
        }
        assert!(traced_quads(&image, 20.0, &TraceOptions::default())
            .quads
            .is_empty());
        assert!(
            traced_quads(&GrayImage::new(64, 48, 90), 20.0, &TraceOptions::default())
                .quads
                .is_empty()
        );
        // A trapezoid whose parallel sides differ threefold is no square a camera sees this
        // small.
        let wedge = draw(
            &[[[20.0, 40.0], [110.0, 40.0], [80.0, 80.0], [50.0, 80.0]]],
            210,
            30,
        );
        assert!(traced_quads(&wedge, 20.0, &TraceOptions::default())
            .quads
            .is_empty());
        // Close up, 180 px long, it may be one (a marker 10 cm away near the image's edge).
        let close = [[10.0, 40.0], [190.0, 40.0], [130.0, 80.0], [70.0, 80.0]];
        let quads = traced_quads(&draw(&[close], 210, 30), 20.0, &TraceOptions::default()).quads;
        assert!(quads.iter().any(|q| matches(q, &close, 2.0)), "{quads:?}");
        // A dark blob the image's border cuts is not traced.
        let cut = draw(
            &[[[-10.0, 40.0], [60.0, 40.0], [60.0, 90.0], [-10.0, 90.0]]],
            210,
            30,
        );
        assert!(traced_quads(&cut, 20.0, &TraceOptions::default())
            .quads
            .is_empty());
    }

    #[test]
    fn fitting_the_sides_to_the_edges_restores_a_blunted_tip() {
        let image = draw(&[SLIVER], 210, 30);
        // The tip at (30, 50) traced 5 px short, as blur leaves it on a steep view, and the
        // other corners half a pixel off.
        let traced = Quad([[35.0, 49.9], [130.4, 40.3], [131.2, 51.6], [31.8, 61.5]]);
        let fitted = fitted_to_edges(&image, traced);
        assert!(matches(&fitted, &SLIVER, 1.5), "{fitted:?}");
        // With nothing to fit to, a quad stays as it is.
        let flat = GrayImage::new(200, 150, 128);
        assert_eq!(fitted_to_edges(&flat, traced), traced);
    }

    #[test]
    fn only_the_parts_around_the_spots_are_traced() {
        let image = draw(
            &[
                SLIVER,
                [
                    [150.0, 100.0],
                    [190.0, 100.0],
                    [190.0, 140.0],
                    [150.0, 140.0],
                ],
            ],
            210,
            30,
        );
        let options = TraceOptions::default();
        // Spots over the middle of the sliver, as the network's mask marks a steep view: the
        // square beyond it is not looked at.
        let near = traced_quads_near(&image, &[[50.0, 40.0, 110.0, 60.0]], &options);
        assert_eq!(near.len(), 1, "{near:?}");
        assert!(matches(&near[0], &SLIVER, 1.0), "{near:?}");
        // Spots on both: both, in image coordinates.
        let both = traced_quads_near(
            &image,
            &[[50.0, 40.0, 110.0, 60.0], [165.0, 115.0, 175.0, 125.0]],
            &options,
        );
        assert_eq!(both.len(), 2, "{both:?}");
        assert!(traced_quads_near(&image, &[], &options).is_empty());
    }

    #[test]
    fn an_image_too_noisy_to_threshold_is_not_traced() {
        let mut image = draw(&[SLIVER], 210, 30);
        let mut state = 12345u32;
        for p in &mut image.pixels {
            // ±60 gray levels of uniform noise (σ ≈ 35).
            state = state.wrapping_mul(1_103_515_245).wrapping_add(12345);
            let n = (state >> 16) as i32 % 121 - 60;
            *p = (*p as i32 + n).clamp(0, 255) as u8;
        }
        assert!(noise_sigma(&image) > MAX_NOISE);
        let everywhere = [[0.0, 0.0, 199.0, 149.0]];
        assert!(traced_quads_near(&image, &everywhere, &TraceOptions::default()).is_empty());
    }

    #[test]
    fn the_largest_quad_of_a_square_hull_is_the_square() {
        let hull = convex_hull(vec![
            [0.0, 0.0],
            [5.0, 0.0],
            [10.0, 0.0],
            [10.0, 10.0],
            [0.0, 10.0],
            [5.0, 5.0],
            [10.0, 4.0],
        ]);
        assert_eq!(hull.len(), 4, "{hull:?}");
        let (quad, area) = largest_quad(&hull).unwrap();
        assert!((area - 100.0).abs() < 1e-9);
        assert!(quad.signed_area() > 0.0);
    }
}
