//! Ring markers' proposals (docs/ARCHITECTURE.md §9.8, "ring markers"): the ellipse round a
//! ring of dark dots with a light centre.
//!
//! A RuneTag-style marker has no frame and no corners for stage 1 to find: its ROI is the
//! bounding square of its outer ring. But its dots, whether seen one by one or blurred into
//! arcs and a whole annulus, are dark blobs close to one another on a light quiet zone, and
//! the convex hull of that cluster is the image of a circle (the outer dots' outer edge): an
//! ellipse. The ellipse fixes the marker's plane up to a turn about its centre (exactly under
//! an affine view; under perspective stage 2's own fit and its retry from the keypoints close
//! the rest). A turn does not matter to a family whose slots repeat all the way round: stage 2
//! reads the dots wherever they are and the codebook tries every slot shift. A family with
//! orientation marks on the ROI's corners (RuneTag+) is turned onto its marks here; which mark
//! is which, stage 2's sort decides ([`crate::detect::stage2`]'s corner turns).

use super::stage1::group::Proposal;
use super::stage1::outline::contrast_range;
use super::stage1::traced::{blobs, convex_hull, dark_runs, Run, MIN_OFFSET};
use crate::family::spec::Layout;
use crate::family::Family;
use crate::geometry::Quad;
use crate::image::GrayImage;
use nalgebra::{Matrix2, Matrix6, SymmetricEigen, Vector2};

/// Thresholds of the ring search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RingParams {
    /// Side of the box whose mean a pixel is compared with, in pixels: wider than a close
    /// marker's dots (a dot's middle compared with a box it fills is not dark, but its rim is,
    /// and the hull only needs the rim).
    pub window: u32,
    /// How much darker than that mean a pixel must be, as a share of the image's 2–98 % range.
    pub offset: f32,
    /// The smallest light centre looked at, as its distance to the nearest dark pixel in
    /// pixels (a ring's hollow is 0.63 of its radius: RuneTag at 0.63 · 12 px).
    pub min_hollow: f64,
    /// The fewest dark pixels round a light centre for a ring.
    pub min_pixels: usize,
    /// The shortest minor axis of the ring's ellipse, in pixels: smaller rings have dots under
    /// a pixel that stage 2 cannot read.
    pub min_axis: f64,
    /// The most the hull may stray from its ellipse, as the mean of |radius − 1| over points
    /// spaced evenly along the hull (a ring is an ellipse to a few hundredths; text, tiles and
    /// blots are not).
    pub max_residual: f64,
    /// The most of the light centre (inside the innermost dots) that may be dark.
    pub max_hollow_dark: f64,
    /// The least of the dotted band that is dark (RuneTag: about a fifth).
    pub min_band_dark: f64,
    /// How light the quiet zone round the ring must be, as a share of the way from its dots'
    /// gray to its centre's: a marker's paper is as light outside the ring as inside, while
    /// the halo that a threshold draws round a light object is the ground's own gray.
    pub min_quiet_light: f64,
    /// The fewest blobs whose centres lie on the rings (see the concentric fit), ...
    pub min_on_levels: usize,
    /// ... and their least share of the blobs round the centre.
    pub min_share_on_levels: f64,
    /// How well those dots must keep to one grid of slots round the rings when no affine
    /// model holds them and only the perspective fit does (see `slot_coherence`: 1 when each
    /// dot is on a slot, near nought for blobs at random angles). Seven free parameters pass
    /// concentric ellipses through more clutter than the affine fit's five; the slots do not.
    pub min_slot_coherence: f64,
    /// The same when the affine model holds them: small rings' dot centres are a pixel or two
    /// off a slot a few pixels wide, so only blobs at random angles are turned away.
    pub min_affine_slot_coherence: f64,
    /// Ring proposals per image at most, largest first (each costs a large stage-2 patch).
    pub budget: usize,
}

impl Default for RingParams {
    fn default() -> Self {
        Self {
            window: 41,
            offset: 0.15,
            min_hollow: 5.0,
            min_pixels: 40,
            min_axis: 12.0,
            max_residual: 0.03,
            max_hollow_dark: 0.1,
            min_band_dark: 0.06,
            min_quiet_light: 0.6,
            min_on_levels: 12,
            min_share_on_levels: 0.6,
            min_slot_coherence: 0.5,
            min_affine_slot_coherence: 0.1,
            budget: 16,
        }
    }
}

impl RingParams {
    /// Whether `on_levels` of a ring's `blobs` lying on its rings are enough for a ring.
    fn enough_on_levels(&self, on_levels: usize, blobs: usize) -> bool {
        on_levels >= self.min_on_levels
            && on_levels as f64 >= self.min_share_on_levels * blobs.max(1) as f64
    }
}

/// What the search looks for, from a ring family's layout (in outer-ring radii).
#[derive(Debug, Clone, PartialEq)]
pub struct RingShape {
    /// The rings' radii, in outer-ring radii: every dot's centre lies on one.
    levels: Vec<f64>,
    /// The outermost dots' outer edge: the hull's radius.
    outer: f64,
    /// The innermost dots' inner edge: inside it the marker is light.
    hollow: f64,
    /// Where the orientation marks' centres are, and their size, when the family has four on
    /// the ROI's corners.
    marks: Option<(f64, f64)>,
    /// Dot slots round each ring.
    slots: usize,
}

impl RingShape {
    /// The shape of a rings layout (`None` for a grid family).
    pub fn of(family: &Family) -> Option<Self> {
        let Layout::Rings(rings) = &family.spec().layout else {
            return None;
        };
        let outer_radius = rings.radii.iter().cloned().fold(0.0, f64::max);
        let inner_radius = rings.radii.iter().cloned().fold(f64::INFINITY, f64::min);
        if outer_radius <= 0.0 || !inner_radius.is_finite() {
            return None;
        }
        let ratio = rings.dot_radius_ratio;
        let extra = &family.spec().extra;
        let on_corners = extra.len() == 4
            && extra.iter().all(|e| {
                (e.x.abs() - outer_radius).abs() < 1e-6 && (e.y.abs() - outer_radius).abs() < 1e-6
            });
        let marks = on_corners.then(|| {
            let size = extra.iter().map(|e| e.size).fold(0.0, f64::max);
            (std::f64::consts::SQRT_2, size / outer_radius)
        });
        Some(Self {
            levels: rings.radii.iter().map(|r| r / outer_radius).collect(),
            outer: 1.0 + ratio,
            hollow: inner_radius * (1.0 - ratio) / outer_radius,
            marks,
            slots: rings.slots as usize,
        })
    }
}

/// A dark blob: its pixel count and the sums of their coordinates.
#[derive(Debug, Clone, Default)]
struct Blob {
    pixels: usize,
    sum: [f64; 2],
}

impl Blob {
    fn centroid(&self) -> [f64; 2] {
        let n = self.pixels.max(1) as f64;
        [self.sum[0] / n, self.sum[1] / n]
    }
}

/// An ellipse {p : (p − centre)ᵀ Q (p − centre) = 1}.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Ellipse {
    centre: Vector2<f64>,
    q: Matrix2<f64>,
}

impl Ellipse {
    fn radius(&self, p: [f64; 2]) -> f64 {
        let d = Vector2::new(p[0], p[1]) - self.centre;
        (d.transpose() * self.q * d)[(0, 0)].max(0.0).sqrt()
    }

    /// Pixels inside the ellipse scaled by `r`.
    fn area(&self, r: f64) -> f64 {
        std::f64::consts::PI * r * r / self.q.determinant().max(f64::MIN_POSITIVE).sqrt()
    }

    fn minor_axis(&self) -> f64 {
        let largest = SymmetricEigen::new(self.q).eigenvalues.max();
        2.0 / largest.max(f64::MIN_POSITIVE).sqrt()
    }

    /// The symmetric map M with M Mᵀ = Q⁻¹ (the unit circle onto the ellipse, turning nothing).
    fn unit_map(&self) -> Option<Matrix2<f64>> {
        let eigen = SymmetricEigen::new(self.q);
        if eigen.eigenvalues.iter().any(|&v| v <= 0.0) {
            return None;
        }
        let inverse_root = Matrix2::from_diagonal(&eigen.eigenvalues.map(|v| 1.0 / v.sqrt()));
        Some(eigen.eigenvectors * inverse_root * eigen.eigenvectors.transpose())
    }
}

/// Least-squares conic through `points` (normalised first, so the fit is well conditioned),
/// kept only when it is an ellipse.
fn fit_ellipse(points: &[[f64; 2]]) -> Option<Ellipse> {
    if points.len() < 6 {
        return None;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold([0.0; 2], |a, p| [a[0] + p[0], a[1] + p[1]]);
    let mean = [mean[0] / n, mean[1] / n];
    let spread = (points
        .iter()
        .map(|p| (p[0] - mean[0]).powi(2) + (p[1] - mean[1]).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    if spread <= 0.0 {
        return None;
    }
    let mut scatter = Matrix6::<f64>::zeros();
    for p in points {
        let (x, y) = ((p[0] - mean[0]) / spread, (p[1] - mean[1]) / spread);
        let row = nalgebra::Vector6::new(x * x, x * y, y * y, x, y, 1.0);
        scatter += row * row.transpose();
    }
    let eigen = SymmetricEigen::new(scatter);
    let smallest = eigen.eigenvalues.imin();
    let c = eigen.eigenvectors.column(smallest);
    let (a, b, cc, d, e, f) = (c[0], c[1], c[2], c[3], c[4], c[5]);
    let quadratic = Matrix2::new(a, b / 2.0, b / 2.0, cc);
    let centre = quadratic.try_inverse()? * Vector2::new(-d / 2.0, -e / 2.0);
    let at_centre =
        (centre.transpose() * quadratic * centre)[(0, 0)] + d * centre[0] + e * centre[1] + f;
    if at_centre == 0.0 {
        return None;
    }
    let q = quadratic / -at_centre;
    let eigenvalues = SymmetricEigen::new(q).eigenvalues;
    if eigenvalues.iter().any(|&v| v <= 0.0 || !v.is_finite()) {
        return None;
    }
    Some(Ellipse {
        centre: Vector2::new(mean[0], mean[1]) + centre * spread,
        q: q / (spread * spread),
    })
}

/// The share of pixels of a ring with orientation marks (RuneTag+: about a sixth) or a speck
/// of clutter beside it, that lie in blobs beyond the ring, at most.
const MAX_SET_ASIDE: f64 = 0.4;

/// `count` points spaced evenly along the closed polygon `hull`.
fn along(hull: &[[f64; 2]], count: usize) -> Vec<[f64; 2]> {
    let edges: Vec<([f64; 2], [f64; 2], f64)> = (0..hull.len())
        .map(|i| {
            let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
            (a, b, ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2)).sqrt())
        })
        .collect();
    let perimeter: f64 = edges.iter().map(|e| e.2).sum();
    if perimeter <= 0.0 {
        return Vec::new();
    }
    let step = perimeter / count as f64;
    let mut points = Vec::with_capacity(count);
    let mut walked = 0.0;
    let mut next = 0.0;
    for (a, b, length) in edges {
        while next < walked + length && points.len() < count {
            let t = (next - walked) / length.max(f64::MIN_POSITIVE);
            points.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            next += step;
        }
        walked += length;
    }
    points
}

/// Every ring marker's ROI in `image` for the shapes asked, largest first: the bounding square of
/// the outer ring (TL, TR, BR, BL as the marker is turned by its marks, or at any turn).
pub fn ring_quads(image: &GrayImage, shapes: &[RingShape], params: &RingParams) -> Vec<Proposal> {
    if shapes.is_empty() || image.width < 8 || image.height < 8 {
        return Vec::new();
    }
    let offset = (params.offset * contrast_range(image)).max(MIN_OFFSET);
    let runs = dark_runs(image, offset, params.window);
    let labels = blobs(&runs);
    let blob_count = labels.iter().map(|&l| l + 1).max().unwrap_or(0);
    let mut blob_list = vec![Blob::default(); blob_count];
    for (run, &l) in runs.iter().zip(&labels) {
        let b = &mut blob_list[l];
        let length = run.len() as f64;
        b.pixels += run.len();
        b.sum[0] += length * (run.x0 + run.x1) as f64 / 2.0;
        b.sum[1] += length * run.y as f64;
    }
    let (w, h) = (image.width as usize, image.height as usize);
    let mut dark = vec![false; w * h];
    let mut runs_by_blob: Vec<Vec<usize>> = vec![Vec::new(); blob_count];
    for (k, (run, &l)) in runs.iter().zip(&labels).enumerate() {
        let row = run.y as usize * w;
        dark[row + run.x0 as usize..=row + run.x1 as usize].fill(true);
        runs_by_blob[l].push(k);
    }
    let distance = distance_to_dark(&dark, w, h);
    let mut rings: Vec<(f64, Quad, Ellipse)> = Vec::new();
    for (centre, hollow) in light_centres(&distance, w, h, params.min_hollow) {
        if rings.iter().any(|(_, _, e)| e.radius(centre) < 1.0)
            || !surrounded_by_a_thin_ring(&dark, w, h, centre, hollow)
        {
            continue;
        }
        let gather = |ellipse: &Ellipse, within: f64| -> Vec<(&Run, usize)> {
            let mut members = Vec::new();
            for (l, blob) in blob_list.iter().enumerate() {
                if blob.pixels as f64 > MAX_DOT_AREA * hollow * hollow {
                    continue;
                }
                let r = ellipse.radius(blob.centroid());
                if r <= within && r >= 0.3 {
                    members.extend(runs_by_blob[l].iter().map(|&k| (&runs[k], l)));
                }
            }
            members
        };
        // A circle the light centre's distance to the dark wide first: the ring's near side
        // (all of it, seen face on); then each fit's own ellipse, a little beyond it, takes in
        // more of a steep ring's far sides.
        let mut ellipse = Ellipse {
            centre: Vector2::new(centre[0], centre[1]),
            q: Matrix2::identity() / (FIRST_REACH * hollow).powi(2),
        };
        let mut found = None;
        for round in 0..GROW_ROUNDS {
            let last = round + 1 == GROW_ROUNDS;
            let within = match round {
                0 => 1.0,
                _ if last => GATHER_LAST,
                _ => GATHER_GROWING,
            };
            let members = gather(&ellipse, within);
            let pixels: usize = members.iter().map(|(r, _)| r.len()).sum();
            if pixels < params.min_pixels {
                break;
            }
            let tolerance = if last {
                params.max_residual
            } else {
                2.0 * params.max_residual
            };
            let Some(fitted) = hull_ellipse(&members, tolerance, params) else {
                break;
            };
            ellipse = fitted;
            if last {
                found = Some((fitted, members));
            }
        }
        let Some((ellipse, members)) = found else {
            continue;
        };
        for shape in shapes {
            if let Some(quad) = ring_roi(image, &ellipse, shape, &members, &blob_list, params) {
                if !rings.iter().any(|(_, q, _)| same_centre(q, &quad)) {
                    rings.push((ellipse.area(1.0), quad, ellipse));
                }
            }
        }
    }
    rings.sort_by(|a, b| b.0.total_cmp(&a.0));
    rings.truncate(params.budget);
    rings
        .into_iter()
        .map(|(_, corners, _)| Proposal {
            corners,
            score: 1.0,
        })
        .collect()
}

fn same_centre(a: &Quad, b: &Quad) -> bool {
    let (ca, cb) = (a.centre(), b.centre());
    let side = a.shortest_side().min(b.shortest_side());
    ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2)).sqrt() < 0.1 * side
}

/// How far round a light centre the first fit looks, in its distance to the dark: a ring's
/// outer dots are 1.68 times as far out as its hollow's edge, its quiet zone ends at 1.9.
const FIRST_REACH: f64 = 1.8;

/// The largest blob a ring is gathered from, in squared distances from its light centre to the
/// dark: a dot of the outer ring covers a fortieth of that face on; a blob of many times that
/// is the ground past the quiet zone, a shadow or print, not a dot or an arc of blurred dots.
const MAX_DOT_AREA: f64 = 0.25;

/// Fits of a ring's ellipse, each from the blobs within the last.
const GROW_ROUNDS: usize = 4;

/// The blobs each fit after the first takes in, by their centres' radius on the last fit: a
/// fifth beyond it while the ring grows along a steep view's far sides, then to just past the
/// outer dots' centres (0.95 of the hull's radius) and short of the quiet zone's edge.
const GATHER_GROWING: f64 = 1.2;
const GATHER_LAST: f64 = 1.05;

/// Rays cast from a light centre, and the share of them that must find the ring: a sparse code
/// leaves whole sectors of all its rings empty.
const RAYS: usize = 32;
const MIN_RAYS_ON_A_RING: f64 = 0.4;

/// Whether most rays from `centre` meet dark within [`RAY_REACH`] times its distance to the dark
/// and, a ring's width further out (its quiet zone: 1.75 times as far as that first dark, the
/// outer dots' 1.68 less a margin), light again: a ring of dots round a light centre does; a
/// light patch in dark ground does not.
fn surrounded_by_a_thin_ring(
    dark: &[bool],
    w: usize,
    h: usize,
    centre: [f64; 2],
    hollow: f64,
) -> bool {
    let at = |x: f64, y: f64| -> Option<bool> {
        let (xi, yi) = (x.round(), y.round());
        (xi >= 0.0 && yi >= 0.0 && (xi as usize) < w && (yi as usize) < h)
            .then(|| dark[yi as usize * w + xi as usize])
    };
    let mut ringed = 0;
    for k in 0..RAYS {
        let t = k as f64 * std::f64::consts::TAU / RAYS as f64;
        let (dx, dy) = (t.cos(), t.sin());
        let mut step = hollow * 0.9;
        let first = loop {
            if step > RAY_REACH * hollow {
                break None;
            }
            match at(centre[0] + step * dx, centre[1] + step * dy) {
                Some(true) => break Some(step),
                Some(false) => step += 0.5,
                None => break None,
            }
        };
        let Some(first) = first else { continue };
        let quiet = 1.75 * first;
        if at(centre[0] + quiet * dx, centre[1] + quiet * dy) == Some(false) {
            ringed += 1;
        }
    }
    ringed as f64 >= MIN_RAYS_ON_A_RING * RAYS as f64
}

/// How far a ray looks for the ring, in the centre's distance to the dark: a steep ring's far
/// sides are further than its near ones.
const RAY_REACH: f64 = 2.5;

/// Each pixel's distance to the nearest dark pixel, in pixels (the 3-4 chamfer, within 8 %
/// of the Euclidean distance).
fn distance_to_dark(dark: &[bool], w: usize, h: usize) -> Vec<f32> {
    const FAR: u32 = u32::MAX / 2;
    let mut d: Vec<u32> = dark.iter().map(|&k| if k { 0 } else { FAR }).collect();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let mut v = d[i];
            if x > 0 {
                v = v.min(d[i - 1] + 3);
            }
            if y > 0 {
                v = v.min(d[i - w] + 3);
                if x > 0 {
                    v = v.min(d[i - w - 1] + 4);
                }
                if x + 1 < w {
                    v = v.min(d[i - w + 1] + 4);
                }
            }
            d[i] = v;
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            let i = y * w + x;
            let mut v = d[i];
            if x + 1 < w {
                v = v.min(d[i + 1] + 3);
            }
            if y + 1 < h {
                v = v.min(d[i + w] + 3);
                if x + 1 < w {
                    v = v.min(d[i + w + 1] + 4);
                }
                if x > 0 {
                    v = v.min(d[i + w - 1] + 4);
                }
            }
            d[i] = v;
        }
    }
    d.into_iter().map(|v| v as f32 / 3.0).collect()
}

/// The centres of light regions at least `min` px from the dark, each with that distance, the
/// farthest first: pixels farther from the dark than their 8 neighbours, less those within
/// half its distance of a farther one.
fn light_centres(distance: &[f32], w: usize, h: usize, min: f64) -> Vec<([f64; 2], f64)> {
    let mut peaks: Vec<(usize, f32)> = Vec::new();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w - 1 {
            let i = y * w + x;
            let v = distance[i];
            if (v as f64) < min {
                continue;
            }
            // Ties along a ridge: only the first in scan order is a peak.
            let before = [i - w - 1, i - w, i - w + 1, i - 1];
            let after = [i + 1, i + w - 1, i + w, i + w + 1];
            if before.iter().all(|&j| distance[j] < v) && after.iter().all(|&j| distance[j] <= v) {
                peaks.push((i, v));
            }
        }
    }
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut kept: Vec<([f64; 2], f64)> = Vec::new();
    for (i, v) in peaks {
        let p = [(i % w) as f64, (i / w) as f64];
        let near = |(q, d): &([f64; 2], f64)| {
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt() < 0.5 * d
        };
        if !kept.iter().any(near) {
            kept.push((p, v as f64));
        }
    }
    kept
}

/// The ellipse through the hull of a cluster's blobs, less the blobs that bend the hull off
/// it: while the hull is not an ellipse closely enough, the blob whose part of the hull strays
/// furthest is set aside (orientation marks; the ground's edge beyond the quiet zone, which the
/// ring's outer dots reach). `None` when no ellipse is left, too much of the cluster was set
/// aside, or the ring is too small.
fn hull_ellipse(runs: &[(&Run, usize)], max_residual: f64, params: &RingParams) -> Option<Ellipse> {
    // Each blob's own hull: a cluster's hull is the hull of its blobs' hulls.
    let mut corners: std::collections::HashMap<usize, Vec<[f64; 2]>> = Default::default();
    let mut pixels: std::collections::HashMap<usize, usize> = Default::default();
    for (run, label) in runs {
        (corners.entry(*label).or_default()).extend(run.corners());
        *pixels.entry(*label).or_default() += run.len();
    }
    let total: usize = pixels.values().sum();
    let mut owner: std::collections::HashMap<[i64; 2], usize> = Default::default();
    let mut hulls: Vec<(usize, Vec<[f64; 2]>)> = Vec::new();
    for (label, points) in corners {
        let hull = convex_hull(points);
        for p in &hull {
            owner.insert(key(*p), label);
        }
        hulls.push((label, hull));
    }
    let mut aside = 0usize;
    for _ in 0..=MAX_PEELED {
        let hull = convex_hull(hulls.iter().flat_map(|(_, h)| h.iter().copied()).collect());
        if hull.len() < 6 {
            return None;
        }
        let samples = along(&hull, HULL_SAMPLES);
        let ellipse = fit_ellipse(&samples)?;
        let residuals: Vec<f64> = samples
            .iter()
            .map(|&p| (ellipse.radius(p) - 1.0).abs())
            .collect();
        let residual = residuals.iter().sum::<f64>() / samples.len() as f64;
        if residual <= max_residual {
            let kept = (ellipse.minor_axis() >= params.min_axis
                && aside as f64 <= MAX_SET_ASIDE * total as f64)
                .then_some(ellipse);
            return kept;
        }
        // Each hull sample belongs to the blobs at the ends of its hull edge.
        let mut stray: std::collections::HashMap<usize, f64> = Default::default();
        for (sample, r) in samples.iter().zip(&residuals) {
            let edge = edge_of(&hull, *sample);
            for end in [hull[edge], hull[(edge + 1) % hull.len()]] {
                if let Some(&label) = owner.get(&key(end)) {
                    *stray.entry(label).or_default() += r;
                }
            }
        }
        let worst = stray.into_iter().max_by(|a, b| a.1.total_cmp(&b.1))?.0;
        aside += pixels.get(&worst).copied().unwrap_or(0);
        hulls.retain(|(label, _)| *label != worst);
        if aside as f64 > MAX_SET_ASIDE * total as f64 {
            return None;
        }
    }
    None
}

/// Blobs set aside from a cluster's hull at most.
const MAX_PEELED: usize = 16;

/// Points sampled along a hull for its ellipse.
const HULL_SAMPLES: usize = 64;

/// A hull vertex's key (its coordinates are half-pixels).
fn key(p: [f64; 2]) -> [i64; 2] {
    [(p[0] * 2.0).round() as i64, (p[1] * 2.0).round() as i64]
}

/// The edge of the closed polygon `hull` that `p` lies on (the nearest).
fn edge_of(hull: &[[f64; 2]], p: [f64; 2]) -> usize {
    let distance = |i: usize| {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let length = (dx * dx + dy * dy).max(f64::MIN_POSITIVE);
        let t = (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length).clamp(0.0, 1.0);
        (a[0] + t * dx - p[0]).powi(2) + (a[1] + t * dy - p[1]).powi(2)
    };
    (0..hull.len())
        .min_by(|&a, &b| distance(a).total_cmp(&distance(b)))
        .unwrap_or(0)
}

/// The ROI of a ring of `shape` whose hull is `hull`: `None` when the cluster's pixels do not
/// leave the centre light and the dotted band dark enough.
fn ring_roi(
    image: &GrayImage,
    hull: &Ellipse,
    shape: &RingShape,
    runs: &[(&Run, usize)],
    blob_list: &[Blob],
    params: &RingParams,
) -> Option<Quad> {
    let hollow = shape.hollow / shape.outer;
    let (mut in_hollow, mut in_band, mut band_gray) = (0usize, 0usize, 0.0);
    for (run, _) in runs {
        for x in run.x0..=run.x1 {
            let r = hull.radius([x as f64, run.y as f64]);
            if r < HOLLOW_CORE * hollow {
                in_hollow += 1;
            } else if r <= 1.0 {
                in_band += 1;
                band_gray += image.get(x, run.y) as f64;
            }
        }
    }
    let hollow_area = hull.area(HOLLOW_CORE * hollow);
    let band_area = hull.area(1.0) - hull.area(hollow);
    if in_hollow as f64 > params.max_hollow_dark * hollow_area
        || (in_band as f64) < params.min_band_dark * band_area
    {
        return None;
    }
    let hull_map = hull.unit_map()?;
    let dots = band_gray / in_band.max(1) as f64;
    let centre = median_on_circles(image, hull, &hull_map, &[0.3 * hollow, 0.6 * hollow]);
    // The quiet zone: past the dots' outer edge, short of the paper's.
    let quiet = median_on_circles(image, hull, &hull_map, &QUIET_ZONE);
    let (Some(centre), Some(quiet)) = (centre, quiet) else {
        return None;
    };
    if centre - dots < MIN_OFFSET as f64 || quiet < dots + params.min_quiet_light * (centre - dots)
    {
        return None;
    }
    // The outer ring's ellipse: the hull's, scaled in from the dots' outer edge, then fitted
    // to every dot's centre on its own ring.
    let start = Ellipse {
        centre: hull.centre,
        q: hull.q * (shape.outer * shape.outer),
    };
    let mut labels: Vec<usize> = runs.iter().map(|(_, l)| *l).collect();
    labels.sort_unstable();
    labels.dedup();
    let centres: Vec<[f64; 2]> = labels.iter().map(|&l| blob_list[l].centroid()).collect();
    // The affine fit where it holds (it is the better start); a close steep view fits none,
    // and the perspective fit starts from the hull's ellipse.
    let affine = concentric_fit(&centres, &start, &shape.levels, params);
    let from = RingPlane::affine(affine.as_ref().unwrap_or(&start))?;
    let plane = match from.refined(&centres, &shape.levels) {
        Some((plane, on_levels)) if params.enough_on_levels(on_levels, centres.len()) => plane,
        _ if affine.is_some() => from,
        _ => return None,
    };
    let coherence = slot_coherence(&plane, &centres, shape);
    let least = if affine.is_some() {
        params.min_affine_slot_coherence
    } else {
        params.min_slot_coherence
    };
    if coherence < least {
        return None;
    }
    let turn = shape
        .marks
        .and_then(|(at, size)| marks_turn(&plane, at, size, blob_list))
        .unwrap_or(0.0);
    let (s, c) = turn.sin_cos();
    let corner = |u: f64, v: f64| plane.image_point(Vector2::new(c * u - s * v, s * u + c * v));
    Some(Quad([
        corner(-1.0, -1.0)?,
        corner(1.0, -1.0)?,
        corner(1.0, 1.0)?,
        corner(-1.0, 1.0)?,
    ]))
}

/// The part of a ring's hollow that must be light, as a share of its radius: the dots' inner
/// edge is blurred and thresholded a little inwards.
const HOLLOW_CORE: f64 = 0.85;

/// Where the quiet zone is sampled, in radii of the hull's ellipse: past the dots' outer edge
/// (1), short of the paper's edge (RuneTag: 1.2 outer radii, 1.14 of the hull's).
const QUIET_ZONE: [f64; 2] = [1.06, 1.1];

/// The ellipse of the outer ring (radius 1) whose concentric copies at `levels` pass through the
/// most of `centres` (the dots'), from `start`: each centre is given the level nearest its radius
/// on the last fit, and the ellipses (p − c)ᵀ Q (p − c) = level² fitted to all of them at once,
/// a linear least-squares problem in Q, Qc and cᵀQc. A ring of dots fits it to a few hundredths
/// of its radius, wherever its code leaves slots empty; clutter does not. `None` when fewer than
/// [`RingParams::min_on_levels`] of the centres end within [`LEVEL_TOLERANCE`] of a level.
fn concentric_fit(
    centres: &[[f64; 2]],
    start: &Ellipse,
    levels: &[f64],
    params: &RingParams,
) -> Option<Ellipse> {
    let scale = start.q.determinant().max(f64::MIN_POSITIVE).powf(-0.25);
    let origin = start.centre;
    let local = |p: [f64; 2]| (Vector2::new(p[0], p[1]) - origin) / scale;
    let mut ellipse = Ellipse {
        centre: Vector2::zeros(),
        q: start.q * scale * scale,
    };
    let mut on_levels = 0;
    for round in 0..LEVEL_ROUNDS {
        let tolerance = if round == 0 {
            FIRST_LEVEL_TOLERANCE
        } else {
            LEVEL_TOLERANCE
        };
        let (mut normal, mut rhs) = (Matrix6::<f64>::zeros(), nalgebra::Vector6::zeros());
        on_levels = 0;
        for &p in centres {
            let x = local(p);
            let r = ellipse.radius([x[0], x[1]]);
            let level = nearest_level(levels, r);
            if (r - level).abs() > tolerance {
                continue;
            }
            on_levels += 1;
            let row = nalgebra::Vector6::new(
                x[0] * x[0],
                2.0 * x[0] * x[1],
                x[1] * x[1],
                -2.0 * x[0],
                -2.0 * x[1],
                1.0,
            );
            normal += row * row.transpose();
            rhs += row * (level * level);
        }
        if on_levels < 6 {
            return None;
        }
        let theta = normal.try_inverse()? * rhs;
        let q = Matrix2::new(theta[0], theta[1], theta[1], theta[2]);
        let centre = q.try_inverse()? * Vector2::new(theta[3], theta[4]);
        // The fit's constant may differ from cᵀQc: the ellipses are then those of level² plus
        // that difference, which a ring of dots keeps near nought.
        let offset = (centre.transpose() * q * centre)[(0, 0)] - theta[5];
        if SymmetricEigen::new(q).eigenvalues.iter().any(|&v| v <= 0.0) || offset.abs() > 0.1 {
            return None;
        }
        ellipse = Ellipse { centre, q };
    }
    params
        .enough_on_levels(on_levels, centres.len())
        .then(|| Ellipse {
            centre: origin + ellipse.centre * scale,
            q: ellipse.q / (scale * scale),
        })
}

/// A ring marker's plane as the image shows it: a marker point u (in outer-ring radii, about
/// its centre) is seen at p where u = S (p − c) / (1 + vᵀ(p − c)). `c` is the image of the
/// marker's centre, S (symmetric) its affine view, v the perspective's tilt. A turn about the
/// centre is left out: it does not move a dot off its ring.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RingPlane {
    centre: Vector2<f64>,
    s: Matrix2<f64>,
    tilt: Vector2<f64>,
}

impl RingPlane {
    /// The affine view of `ring` (the outer ring's ellipse): no tilt.
    fn affine(ring: &Ellipse) -> Option<Self> {
        let s = ring.unit_map()?.try_inverse()?;
        Some(Self {
            centre: ring.centre,
            s,
            tilt: Vector2::zeros(),
        })
    }

    fn marker_point(&self, p: [f64; 2]) -> Vector2<f64> {
        let d = Vector2::new(p[0], p[1]) - self.centre;
        self.s * d / (1.0 + self.tilt.dot(&d))
    }

    fn image_point(&self, u: Vector2<f64>) -> Option<[f64; 2]> {
        let d = (self.s - u * self.tilt.transpose()).try_inverse()? * u;
        let p = self.centre + d;
        Some([p[0], p[1]])
    }

    /// The plane whose concentric circles at `levels` pass through the most of `centres` (the
    /// dots'), fitted from `self`: each dot is given the level nearest its radius, then damped
    /// Gauss–Newton moves the plane to shorten every dot's distance to its ring, over
    /// [`LEVEL_ROUNDS`] rounds. Under perspective the rings' ellipses are neither concentric nor
    /// scaled copies: an affine fit leaves the ROI's far side short and its centre off the
    /// marker's, and close steep views fit no affine model at all. Returns the plane and how
    /// many dots lie on its rings; `None` when too few do or the plane turns away from the
    /// camera across the ROI.
    fn refined(&self, centres: &[[f64; 2]], levels: &[f64]) -> Option<(Self, usize)> {
        let scale = self.s.determinant().abs().max(f64::MIN_POSITIVE).powf(-0.5);
        // In units of the outer ring's radius about the start's centre, so that the steps
        // of all seven parameters are of one size.
        let origin = self.centre;
        let local: Vec<Vector2<f64>> = centres
            .iter()
            .map(|p| (Vector2::new(p[0], p[1]) - origin) / scale)
            .collect();
        let on_rings = |plane: &Self, tolerance: f64| -> Vec<(Vector2<f64>, f64)> {
            local
                .iter()
                .filter_map(|&x| {
                    let r = plane.marker_point([x[0], x[1]]).norm();
                    let level = nearest_level(levels, r);
                    ((r - level).abs() <= tolerance).then_some((x, level))
                })
                .collect()
        };
        let mut plane = Self {
            centre: Vector2::zeros(),
            s: self.s * scale,
            tilt: self.tilt * scale,
        };
        for round in 0..LEVEL_ROUNDS {
            let tolerance = if round == 0 {
                FIRST_LEVEL_TOLERANCE
            } else {
                LEVEL_TOLERANCE
            };
            let dots = on_rings(&plane, tolerance);
            if dots.len() < 2 * TILT_PARAMETERS {
                return None;
            }
            plane = plane.descended(&dots);
            if !plane.in_front() {
                return None;
            }
        }
        let on_levels = on_rings(&plane, LEVEL_TOLERANCE).len();
        Some((
            Self {
                centre: origin + plane.centre * scale,
                s: plane.s / scale,
                tilt: plane.tilt / scale,
            },
            on_levels,
        ))
    }

    /// Damped Gauss–Newton from `self` on the dots' distances to their rings ((dot, level)
    /// pairs).
    fn descended(&self, dots: &[(Vector2<f64>, f64)]) -> Self {
        let cost = |plane: &Self| -> f64 {
            dots.iter()
                .map(|(x, level)| (plane.marker_point([x[0], x[1]]).norm() - level).powi(2))
                .sum()
        };
        let mut plane = *self;
        let mut damping = 1e-3;
        for _ in 0..TILT_ITERATIONS {
            let (mut normal, mut gradient) = (
                nalgebra::SMatrix::<f64, TILT_PARAMETERS, TILT_PARAMETERS>::zeros(),
                nalgebra::SVector::<f64, TILT_PARAMETERS>::zeros(),
            );
            for (x, level) in dots {
                let d = x - plane.centre;
                let w = 1.0 + plane.tilt.dot(&d);
                let u = plane.s * d / w;
                let r = u.norm().max(1e-12);
                let along = u / r;
                // ∂u/∂S for S = [a b; b e], ∂u/∂v and ∂u/∂c, each projected on u's direction.
                let toward_centre = -(plane.s - u * plane.tilt.transpose()) / w;
                let row = nalgebra::SVector::<f64, TILT_PARAMETERS>::from_column_slice(&[
                    along[0] * d[0] / w,
                    (along[0] * d[1] + along[1] * d[0]) / w,
                    along[1] * d[1] / w,
                    -r * d[0] / w,
                    -r * d[1] / w,
                    (along.transpose() * toward_centre)[0],
                    (along.transpose() * toward_centre)[1],
                ]);
                normal += row * row.transpose();
                gradient += row * (r - level);
            }
            let now = cost(&plane);
            let mut improved = false;
            while damping < 1e6 {
                let mut damped = normal;
                for k in 0..TILT_PARAMETERS {
                    damped[(k, k)] *= 1.0 + damping;
                }
                let Some(step) = damped.try_inverse().map(|m| -(m * gradient)) else {
                    break;
                };
                let trial = Self {
                    s: plane.s + Matrix2::new(step[0], step[1], step[1], step[2]),
                    tilt: plane.tilt + Vector2::new(step[3], step[4]),
                    centre: plane.centre + Vector2::new(step[5], step[6]),
                };
                if cost(&trial) < now {
                    plane = trial;
                    damping = (damping / 10.0).max(1e-9);
                    improved = true;
                    break;
                }
                damping *= 10.0;
            }
            if !improved {
                break;
            }
        }
        plane
    }

    /// Whether the plane stays in front of the camera over the whole ROI: 1 + vᵀd stays well
    /// above nought at its corners.
    fn in_front(&self) -> bool {
        [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]]
            .iter()
            .all(|&[a, b]| {
                self.image_point(Vector2::new(a, b)).is_some_and(|p| {
                    1.0 + self.tilt.dot(&(Vector2::new(p[0], p[1]) - self.centre)) > MIN_DEPTH_RATIO
                })
            })
    }
}

/// S's three entries, the tilt's two and the centre's two.
const TILT_PARAMETERS: usize = 7;

/// Gauss–Newton steps of the perspective fit at most.
const TILT_ITERATIONS: usize = 20;

/// The least ratio of a ROI corner's depth to the centre's the perspective fit may leave: a
/// ring seen so steeply that its far corner is three times as far is past what stage 2 reads.
const MIN_DEPTH_RATIO: f64 = 0.33;

/// How well the dots on `plane`'s rings keep to one grid of slots: the length of the mean of
/// e^(i·slots·θ) over their angles θ about the centre, 1 when every dot sits on a slot and
/// about 1/√n for n dots at random angles. Clutter that some ellipses happen to pass through
/// does not keep to the slots; a ring seen in perspective does, once the plane is right.
fn slot_coherence(plane: &RingPlane, centres: &[[f64; 2]], shape: &RingShape) -> f64 {
    let (mut sum, mut count) = (Vector2::zeros(), 0usize);
    for &p in centres {
        let u = plane.marker_point(p);
        let r = u.norm();
        if (r - nearest_level(&shape.levels, r)).abs() > LEVEL_TOLERANCE {
            continue;
        }
        let phase = shape.slots as f64 * u[1].atan2(u[0]);
        sum += Vector2::new(phase.cos(), phase.sin());
        count += 1;
    }
    sum.norm() / count.max(1) as f64
}

/// The level (ring radius) nearest `r`.
fn nearest_level(levels: &[f64], r: f64) -> f64 {
    (levels.iter().copied())
        .min_by(|a, b| (a - r).abs().total_cmp(&(b - r).abs()))
        .unwrap_or(1.0)
}

/// Rounds of giving each dot its level and fitting the rings again.
const LEVEL_ROUNDS: usize = 4;

/// How far from its ring a dot's centre may lie, in outer-ring radii: under a tenth of the
/// rings' spacing (RuneTag: a sixth).
const LEVEL_TOLERANCE: f64 = 0.06;

/// The same for the first round, from the hull's ellipse: half RuneTag's ring spacing.
const FIRST_LEVEL_TOLERANCE: f64 = 0.08;

/// The median gray on circles of the given radii (in `ellipse`'s units, through `map`), or
/// `None` when most of them lie outside the image.
fn median_on_circles(
    image: &GrayImage,
    ellipse: &Ellipse,
    map: &Matrix2<f64>,
    radii: &[f64],
) -> Option<f64> {
    const POINTS: usize = 48;
    let mut grays: Vec<u8> = Vec::with_capacity(POINTS * radii.len());
    for &r in radii {
        for k in 0..POINTS {
            let t = k as f64 * std::f64::consts::TAU / POINTS as f64;
            let p = ellipse.centre + map * Vector2::new(r * t.cos(), r * t.sin());
            let (x, y) = (p[0].round(), p[1].round());
            if x >= 0.0 && y >= 0.0 && x < image.width as f64 && y < image.height as f64 {
                grays.push(image.get(x as u32, y as u32));
            }
        }
    }
    if grays.len() * 2 < POINTS * radii.len() {
        return None;
    }
    let middle = grays.len() / 2;
    Some(*grays.select_nth_unstable(middle).1 as f64)
}

/// The turn (radians, in marker units as `plane` leaves them) that puts the ROI's corners on the
/// orientation marks round the ring: blobs of about the marks' size whose centres lie about `at`
/// outer radii from the centre, at least three of them a quarter turn apart.
fn marks_turn(plane: &RingPlane, at: f64, size: f64, blob_list: &[Blob]) -> Option<f64> {
    let unit_pixels = 1.0 / plane.s.determinant().abs().max(f64::MIN_POSITIVE);
    // A mark is at most a disc of `size` across (a cross covers less of its square).
    let most = std::f64::consts::PI * (size / 2.0).powi(2) * unit_pixels * 2.0;
    let least = 0.1 * most;
    let (mut sum, mut count) = (Vector2::zeros(), 0usize);
    for blob in blob_list {
        let pixels = blob.pixels as f64;
        if pixels < least.max(2.0) || pixels > most {
            continue;
        }
        let u = plane.marker_point(blob.centroid());
        let r = u.norm();
        if (r - at).abs() > 0.2 * at {
            continue;
        }
        // Marks sit at 45° + k · 90°: four times their angle less 180° is the same for all.
        let angle = 4.0 * u[1].atan2(u[0]) - std::f64::consts::PI;
        sum += Vector2::new(angle.cos(), angle.sin());
        count += 1;
    }
    (count >= 3 && sum.norm() >= 0.8 * count as f64 && count <= 6)
        .then(|| sum[1].atan2(sum[0]) / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{synthesize, Mode, Sample, SynthConfig};

    fn family(name: &str) -> Family {
        crate::builtin::get(name).unwrap().unwrap()
    }

    fn scenes(family: &Family, seeds: std::ops::Range<u64>, view_deg: f64) -> Vec<Sample> {
        scenes_at(family, seeds, [0.25, 0.4], [0.0, view_deg])
    }

    fn scenes_at(
        family: &Family,
        seeds: std::ops::Range<u64>,
        distance_m: [f64; 2],
        view_deg: [f64; 2],
    ) -> Vec<Sample> {
        let mut config = SynthConfig::new(Mode::Camera);
        config.markers = [2, 2];
        config.side_m = [0.05, 0.05];
        config.distance_m = distance_m;
        config.view_angle_deg = view_deg;
        seeds
            .map(|seed| synthesize(family, &config, seed).unwrap())
            .collect()
    }

    fn truth_quad(roi: &[[f64; 2]]) -> Quad {
        Quad([roi[0], roi[1], roi[2], roi[3]])
    }

    fn mean_side(q: &Quad) -> f64 {
        q.sides().iter().sum::<f64>() / 4.0
    }

    /// The same ring: centres within 6 % of the side, areas within 15 %.
    fn same_ring(found: &Quad, truth: &Quad) -> bool {
        let (a, b) = (found.centre(), truth.centre());
        let apart = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
        apart < 0.06 * mean_side(truth) && (found.area() / truth.area() - 1.0).abs() < 0.15
    }

    /// The same corners in some quarter turn, each within 8 % of the side.
    fn same_corners_turned(found: &Quad, truth: &Quad) -> bool {
        (0..4).any(|turn| {
            (0..4).all(|k| {
                let (p, q) = (found[(k + turn) % 4], truth[k]);
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt() < 0.08 * mean_side(truth)
            })
        })
    }

    /// (markers whose ring was found, markers, proposals matching none) over `scenes`.
    fn tally(
        scenes: &[Sample],
        shape: &RingShape,
        matches: fn(&Quad, &Quad) -> bool,
    ) -> [usize; 3] {
        let mut counts = [0; 3];
        for sample in scenes {
            let found = ring_quads(
                &sample.image,
                std::slice::from_ref(shape),
                &RingParams::default(),
            );
            let truths: Vec<Quad> = sample
                .truth
                .markers
                .iter()
                .map(|m| truth_quad(&m.roi))
                .collect();
            counts[0] += truths
                .iter()
                .filter(|t| found.iter().any(|p| matches(&p.corners, t)))
                .count();
            counts[1] += truths.len();
            counts[2] += (found.iter())
                .filter(|p| !truths.iter().any(|t| same_ring(&p.corners, t)))
                .count();
        }
        counts
    }

    #[test]
    fn most_runetags_seen_from_the_front_get_their_ring_roi() {
        let family = family("runetag");
        let shape = RingShape::of(&family).unwrap();
        let [found, markers, _] = tally(&scenes(&family, 0..10, 30.0), &shape, same_ring);
        assert!(found * 10 >= markers * 4, "{found} of {markers}");
    }

    /// A ring close and steep is far from an affine view (its near side up to half as large
    /// again as its far side): the perspective fit holds it where no affine model does.
    #[test]
    fn close_steep_runetags_get_their_ring_roi() {
        let family = family("runetag");
        let shape = RingShape::of(&family).unwrap();
        let samples = scenes_at(&family, 0..10, [0.15, 0.25], [35.0, 50.0]);
        let [found, markers, _] = tally(&samples, &shape, same_ring);
        assert!(found * 10 >= markers * 5, "{found} of {markers}");
    }

    #[test]
    fn runetag_plus_rois_are_turned_onto_the_orientation_marks() {
        let family = family("runetag-plus");
        let shape = RingShape::of(&family).unwrap();
        assert!(shape.marks.is_some());
        let samples = scenes(&family, 0..10, 30.0);
        let [rings, markers, _] = tally(&samples, &shape, same_ring);
        let [turned, _, _] = tally(&samples, &shape, same_corners_turned);
        assert!(rings * 10 >= markers * 4, "{rings} of {markers}");
        assert!(
            turned * 4 >= rings * 3,
            "{turned} of {rings} turned onto their marks"
        );
    }

    #[test]
    fn no_square_marker_is_taken_for_a_ring() {
        assert!(RingShape::of(&family("apriltag-36h11")).is_none());
        let shape = RingShape::of(&family("runetag")).unwrap();
        for name in ["apriltag-36h11", "topotag-like", "aruco-4x4_50"] {
            for sample in scenes(&family(name), 0..4, 50.0) {
                let found = ring_quads(
                    &sample.image,
                    std::slice::from_ref(&shape),
                    &RingParams::default(),
                );
                for m in &sample.truth.markers {
                    let truth = truth_quad(&m.roi);
                    let on_it = |p: &Proposal| truth.encloses(p.corners.centre());
                    assert!(
                        !found.iter().any(on_it),
                        "{name} seed {}: {found:?}",
                        sample.truth.seed
                    );
                }
            }
        }
    }

    #[test]
    fn an_ellipse_is_fitted_through_points_on_it() {
        let points: Vec<[f64; 2]> = (0..40)
            .map(|k| {
                let t = k as f64 * std::f64::consts::TAU / 40.0;
                let (x, y) = (30.0 * t.cos(), 12.0 * t.sin());
                // Turned 30°, centred at (100, 50).
                let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
                [100.0 + c * x - s * y, 50.0 + s * x + c * y]
            })
            .collect();
        let e = fit_ellipse(&points).unwrap();
        assert!((e.centre - Vector2::new(100.0, 50.0)).norm() < 1e-6);
        for p in &points {
            assert!((e.radius(*p) - 1.0).abs() < 1e-6);
        }
        assert!((e.minor_axis() - 24.0).abs() < 1e-6);
        let m = e.unit_map().unwrap();
        assert!((m * m.transpose() - e.q.try_inverse().unwrap()).norm() < 1e-9);
    }

    #[test]
    fn dots_seen_in_perspective_give_the_roi_corners_and_centre_of_the_marker_plane() {
        // A ring of 60 px radius tilted so that its far side is a third farther than its
        // near side: the rings' ellipses are no longer concentric.
        let truth = RingPlane {
            centre: Vector2::new(320.0, 240.0),
            s: Matrix2::new(1.0 / 60.0, 0.002, 0.002, 1.0 / 45.0),
            tilt: Vector2::new(0.001, -0.002),
        };
        let levels = [2.0 / 3.0, 5.0 / 6.0, 1.0];
        let centres: Vec<[f64; 2]> = (0..43 * 3)
            .filter(|k| k % 3 == 0 || k % 5 == 1)
            .filter_map(|k| {
                let t = (k / 3) as f64 * std::f64::consts::TAU / 43.0;
                truth.image_point(Vector2::new(t.cos(), t.sin()) * levels[k % 3])
            })
            .collect();
        let outer: Vec<[f64; 2]> = (0..40)
            .filter_map(|k| {
                let t = k as f64 * std::f64::consts::TAU / 40.0;
                truth.image_point(Vector2::new(t.cos(), t.sin()))
            })
            .collect();
        let start = fit_ellipse(&outer).unwrap();
        let ring = concentric_fit(&centres, &start, &levels, &RingParams::default()).unwrap();
        let affine = RingPlane::affine(&ring).unwrap();
        let (fitted, on_levels) = affine.refined(&centres, &levels).unwrap();
        assert_eq!(on_levels, centres.len());
        let miss = |plane: &RingPlane| {
            [
                [-1.0, -1.0],
                [1.0, -1.0],
                [1.0, 1.0],
                [-1.0, 1.0],
                [0.0, 0.0],
            ]
            .iter()
            .map(|&[a, b]| {
                let (p, q) = (
                    plane.image_point(Vector2::new(a, b)).unwrap(),
                    truth.image_point(Vector2::new(a, b)).unwrap(),
                );
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max)
        };
        assert!(
            miss(&affine) > 3.0,
            "the affine fit misses by {}",
            miss(&affine)
        );
        assert!(
            miss(&fitted) < 1e-3,
            "{fitted:?} misses by {}",
            miss(&fitted)
        );
    }

    #[test]
    fn dots_on_three_concentric_rings_give_the_outer_ring_wherever_slots_are_empty() {
        // An ellipse of axes 80 and 50 turned 20°, at (300, 200); dots on rings of 2/3, 5/6
        // and 1 of it in some of the slots, from a start 3 % too large and 2 px off (as the hull's ellipse leaves it).
        let (s, c) = (20f64.to_radians().sin(), 20f64.to_radians().cos());
        let at = |r: f64, t: f64| {
            let (x, y) = (80.0 * r * t.cos(), 50.0 * r * t.sin());
            [300.0 + c * x - s * y, 200.0 + s * x + c * y]
        };
        let levels = [2.0 / 3.0, 5.0 / 6.0, 1.0];
        let centres: Vec<[f64; 2]> = (0..43 * 3)
            .filter(|k| k % 3 == 0 || k % 7 == 1)
            .map(|k| at(levels[k % 3], (k / 3) as f64 * std::f64::consts::TAU / 43.0))
            .collect();
        let truth = fit_ellipse(
            &(0..40)
                .map(|k| at(1.0, k as f64 * 0.157))
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let start = Ellipse {
            centre: truth.centre + Vector2::new(2.0, 0.0),
            q: truth.q / 1.03f64.powi(2),
        };
        let fitted = concentric_fit(&centres, &start, &levels, &RingParams::default()).unwrap();
        assert!(
            (fitted.centre - truth.centre).norm() < 1e-6,
            "{fitted:?} {truth:?}"
        );
        assert!((fitted.q - truth.q).norm() < 1e-9 * truth.q.norm().max(1.0));
    }
}
