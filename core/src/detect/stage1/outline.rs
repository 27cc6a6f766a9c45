//! Quads whose four sides are edges in the image, from stage 1's corners (docs/ARCHITECTURE.md
//! §9.8, "outline quads").
//!
//! Stage 1 finds the corners of steep views (a marker seen at 65–75°, a side 6–40 px across) far
//! more often than it gets their directions and mask right: on the development sets the heat map
//! had all four corners of most Difficult misses within 3 px (at a lower confidence), but a
//! corner's direction to the centre was off by 45–80° or the mask covered half the marker, so
//! [`super::group`] never paired them. Here corners are joined by what the image shows instead:
//! two corners are a side when the image steps from light to dark across the segment between them
//! along most of its length, and four sides that close clockwise with the dark side inside (or
//! anticlockwise with the light side inside) are a quad. Stage 2 then reads it like any ROI, so a
//! quad of clutter costs one read, not a wrong ID.

use super::group::{Candidate, Corner, Proposal};
use crate::geometry::{distance, Quad};
use crate::image::GrayImage;

/// Limits of the outline search.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutlineOptions {
    /// Heat-map confidence of the corners it joins: lower than the grouping's, since the image,
    /// not the network, vouches for the quad.
    pub corner: f32,
    /// Corners considered at most, the most confident first (every two of them are tested for a
    /// side).
    pub max_corners: usize,
    /// Sides followed from one corner at most, the strongest first.
    pub max_sides: usize,
    /// The smallest step across a side, in gray levels (mean over a third of the side, 3 px
    /// apart); raised to [`NOISE_STEPS`] times the image's noise where that is more.
    pub contrast: f32,
    /// The shortest side, in pixels.
    pub min_side: f64,
    /// The least mean of the network's marker mask inside a quad, at the level where it is
    /// highest (the grouping asks 0.5 at one level).
    pub mask: f64,
}

impl Default for OutlineOptions {
    fn default() -> Self {
        Self {
            corner: 0.1,
            max_corners: 120,
            max_sides: 8,
            contrast: 12.0,
            min_side: 4.0,
            mask: 0.3,
        }
    }
}

/// How far apart the two samples of one step are, across the side, in pixels.
const STEP: f32 = 3.0;

/// The step a side needs, in units of the image's noise σ: the difference of two noisy samples
/// has σ√2, and the test keeps the best of up to 11 offsets, whose maximum lies near 1.6 of
/// those σ√2 — so 3σ lets noise alone pass about one test in a hundred instead of most of them.
const NOISE_STEPS: f32 = 3.0;

/// The steepest the side test gets, in gray levels: a marker's border steps by 100 or more in
/// usable light; an image noisier than a third of this is not searched.
const MAX_CONTRAST: f32 = 60.0;

/// The step a side needs as a share of the image's range of gray levels ([`contrast_range`]): a
/// marker's border spans most of it, while in a photograph of high contrast almost any two
/// corners have some weaker step between them that the offset search lines up with.
const RANGE_SHARE: f32 = 0.25;

/// The spread of the image's gray levels: the 98th percentile minus the 2nd, over every other
/// pixel of every other row.
pub(crate) fn contrast_range(image: &GrayImage) -> f32 {
    let w = image.width as usize;
    let mut histogram = [0usize; 256];
    let mut count = 0;
    for row in image.pixels.chunks(w.max(1)).step_by(2) {
        for &v in row.iter().step_by(2) {
            histogram[v as usize] += 1;
            count += 1;
        }
    }
    let level = |share: f64| {
        let target = (share * count as f64) as usize;
        let mut seen = 0;
        histogram
            .iter()
            .position(|&n| {
                seen += n;
                seen > target
            })
            .unwrap_or(255) as f32
    };
    level(0.98) - level(0.02)
}

/// The image's noise σ in gray levels (Immerkær 1996: the mean absolute response to a mask that
/// cancels every plane and the 3 × 3 Laplacian of smooth shading), over every other pixel.
pub(super) fn noise_sigma(image: &GrayImage) -> f32 {
    let (w, h) = (image.width as usize, image.height as usize);
    if w < 3 || h < 3 {
        return 0.0;
    }
    let p = |x: usize, y: usize| image.pixels[y * w + x] as i32;
    let (mut sum, mut count) = (0u64, 0u64);
    for y in (1..h - 1).step_by(2) {
        for x in (1..w - 1).step_by(2) {
            let v = p(x - 1, y - 1) + p(x + 1, y - 1) + p(x - 1, y + 1) + p(x + 1, y + 1)
                - 2 * (p(x, y - 1) + p(x - 1, y) + p(x + 1, y) + p(x, y + 1))
                + 4 * p(x, y);
            sum += v.unsigned_abs() as u64;
            count += 1;
        }
    }
    (std::f64::consts::FRAC_PI_2.sqrt() * sum as f64 / (6.0 * count as f64)) as f32
}

/// The steps across the segment `a`→`b` in gray levels: with the dark side on its right (the
/// inside of a clockwise quad, y down), and with the dark side on its left. A corner from stage 1
/// is a few pixels off, so the segment may cross the true side at a slant: each third of it
/// finds its own offset (up to a tenth of the side, at least 2 px) and the weakest third counts.
fn side_steps(image: &GrayImage, a: [f64; 2], b: [f64; 2], contrast: f32) -> (f32, f32) {
    let (dx, dy) = ((b[0] - a[0]) as f32, (b[1] - a[1]) as f32);
    let len = (dx * dx + dy * dy).sqrt();
    let (ux, uy) = (dx / len, dy / len);
    // Right-hand normal in image coordinates (y down): the inside of a clockwise quad.
    let (nx, ny) = (-uy, ux);
    // Offsets 1.5 px apart: a step measured 3 px across still sees a sharp edge at full height
    // half that far off.
    let reach = ((0.1 * len).clamp(2.0, 8.0) / 1.5).round() as i32;
    let per_third = ((len / 6.0).round() as usize).clamp(2, 4);
    let h = STEP / 2.0;
    let step_at = |t: f32, offset: i32| {
        let (px, py) = (
            a[0] as f32 + t * dx + 1.5 * offset as f32 * nx,
            a[1] as f32 + t * dy + 1.5 * offset as f32 * ny,
        );
        image.sample(px - h * nx, py - h * ny) - image.sample(px + h * nx, py + h * ny)
    };
    // One point first: most pairs of corners are not a side, and the middle of the segment says
    // so at a sixteenth of the cost of the whole test.
    let (most, least) = (-reach..=reach)
        .map(|offset| step_at(0.5, offset))
        .fold((f32::MIN, f32::MAX), |(m, l), v| (m.max(v), l.min(v)));
    if most < contrast && -least < contrast {
        return (0.0, 0.0);
    }
    let (mut right, mut left) = (f32::MAX, f32::MAX);
    // The middle third first, then stop as soon as neither side can pass.
    for third in [1, 0, 2] {
        let (mut most, mut least) = (f32::MIN, f32::MAX);
        for offset in -reach..=reach {
            let mut sum = 0.0;
            for k in 0..per_third {
                // Clear of the corners, where the neighbouring sides begin.
                let t = 0.12 + 0.76 * (third as f32 + (k as f32 + 0.5) / per_third as f32) / 3.0;
                sum += step_at(t, offset);
            }
            let mean = sum / per_third as f32;
            most = most.max(mean);
            least = least.min(mean);
        }
        right = right.min(most);
        left = left.min(-least);
        if right < contrast && left < contrast {
            break;
        }
    }
    (right, left)
}

pub(super) fn cross(o: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
}

/// Convex with every corner's turn the same way and no corner flatter than ~170°: the signed
/// turning sense (+1 clockwise in image coordinates) or `None`.
fn convex_turn(q: &Quad) -> Option<f64> {
    let mut sense = 0.0;
    for i in 0..4 {
        let (p, c, n) = (q[(i + 3) % 4], q[i], q[(i + 1) % 4]);
        let turn = cross(p, c, n);
        let (l1, l2) = (distance(p, c), distance(c, n));
        // |sin| of the turn: a corner under ~10° off straight is not a corner.
        if (turn / (l1 * l2)).abs() < 0.17 {
            return None;
        }
        if sense == 0.0 {
            sense = turn.signum();
        } else if turn.signum() != sense {
            return None;
        }
    }
    Some(sense)
}

/// Every quad the `corners` (image pixels, any levels) outline in `image`, best first: each a
/// [`Candidate`] over indices into `corners`, for [`super::group::select`]. The score is the
/// weakest side's step (in units of 255 gray levels) times the mean corner confidence, so a
/// network quad of the same corners (scored by mask and directions) ranks apart from these.
pub fn outline_candidates(
    image: &GrayImage,
    corners: &[Corner],
    options: &OutlineOptions,
) -> Vec<Candidate> {
    let contrast = options
        .contrast
        .max(NOISE_STEPS * noise_sigma(image))
        .max(RANGE_SHARE * contrast_range(image));
    if contrast > MAX_CONTRAST {
        // Noise this strong passes the test anywhere a border would: it cannot tell sides from
        // clutter, and only costs time (the network's own grouping still runs).
        return Vec::new();
    }
    let n = corners.len().min(options.max_corners);
    let corners = &corners[..n];
    // sides[i]: (j, step) with the dark side on the right of i→j.
    let mut sides: Vec<Vec<(usize, f32)>> = vec![Vec::new(); n];
    for i in 0..n {
        for j in i + 1..n {
            let (a, b) = (corners[i].at, corners[j].at);
            if distance(a, b) < options.min_side {
                continue;
            }
            let (right, left) = side_steps(image, a, b, contrast);
            if right >= contrast {
                sides[i].push((j, right));
            }
            if left >= contrast {
                sides[j].push((i, left));
            }
        }
    }
    for s in &mut sides {
        s.sort_by(|x, y| y.1.total_cmp(&x.1));
        s.truncate(options.max_sides);
    }
    let step_of = |i: usize, j: usize| sides[i].iter().find(|s| s.0 == j).map(|s| s.1);
    let mut out = Vec::new();
    for a in 0..n {
        for &(b, ab) in &sides[a] {
            // Each cycle once: from its lowest corner.
            if b < a {
                continue;
            }
            for &(c, bc) in &sides[b] {
                if c <= a || c == b {
                    continue;
                }
                for &(d, cd) in &sides[c] {
                    if d <= a || d == b || d == c {
                        continue;
                    }
                    let Some(da) = step_of(d, a) else {
                        continue;
                    };
                    let q = Quad([corners[a].at, corners[b].at, corners[c].at, corners[d].at]);
                    // Dark on the right all round: clockwise is a dark-inside quad, anticlockwise
                    // a light-inside one (its inside is then on the left).
                    let Some(sense) = convex_turn(&q) else {
                        continue;
                    };
                    let (q, idx) = if sense > 0.0 {
                        (q, [a, b, c, d])
                    } else {
                        (Quad([q[0], q[3], q[2], q[1]]), [a, d, c, b])
                    };
                    let (short, long) = (q.shortest_side(), q.longest_side());
                    if short < options.min_side || short < 0.04 * long {
                        continue;
                    }
                    let weakest = ab.min(bc).min(cd).min(da) as f64 / 255.0;
                    let confidence = idx.iter().map(|&i| corners[i].score).sum::<f64>() / 4.0;
                    out.push(Candidate {
                        corners: idx,
                        proposal: Proposal {
                            corners: q,
                            score: weakest * confidence,
                        },
                    });
                }
            }
        }
    }
    out.sort_by(|x, y| y.proposal.score.total_cmp(&x.proposal.score));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// `fill` inside the quad, `ground` elsewhere, with sensor noise of `sigma`.
    fn draw(q: &Quad, ground: u8, fill: u8, sigma: f64) -> GrayImage {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut image = GrayImage::new(160, 120, ground);
        for y in 0..120u32 {
            for x in 0..160u32 {
                let base = if q.encloses([x as f64, y as f64]) {
                    fill
                } else {
                    ground
                };
                // Box–Muller from two uniforms.
                let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random::<f64>());
                let n = sigma * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
                image.pixels[(y * 160 + x) as usize] =
                    (base as f64 + n).round().clamp(0.0, 255.0) as u8;
            }
        }
        image
    }

    fn corner(at: [f64; 2], score: f64) -> Corner {
        Corner {
            at,
            direction: [1.0, 0.0],
            score,
        }
    }

    /// A steep view: 90 × 14 px, clockwise, with stage 1's corners a pixel or two off.
    const SLIVER: Quad = Quad([[30.0, 50.0], [120.0, 42.0], [122.0, 58.0], [32.0, 66.0]]);

    fn sliver_corners() -> Vec<Corner> {
        let off = [[1.5, -1.0], [-1.0, 1.5], [1.0, 1.0], [-1.5, -0.5]];
        let mut corners: Vec<Corner> = SLIVER
            .iter()
            .zip(off)
            .map(|(p, o)| corner([p[0] + o[0], p[1] + o[1]], 0.2))
            .collect();
        // Two of the background's, more confident than the marker's.
        corners.insert(1, corner([140.0, 100.0], 0.6));
        corners.insert(0, corner([10.0, 10.0], 0.5));
        corners
    }

    fn matches(found: &Quad, truth: &Quad) -> bool {
        (0..4).any(|k| {
            (0..4).all(|i| {
                let (p, q) = (found[(i + k) % 4], truth[i]);
                (p[0] - q[0]).hypot(p[1] - q[1]) < 3.0
            })
        })
    }

    #[test]
    fn a_dark_sliver_on_light_ground_is_outlined_clockwise() {
        let image = draw(&SLIVER, 210, 30, 2.0);
        let found = outline_candidates(&image, &sliver_corners(), &OutlineOptions::default());
        let best = found
            .first()
            .expect("the sliver is outlined")
            .proposal
            .corners;
        assert!(matches(&best, &SLIVER), "{best:?}");
        // Stage 2 takes ROIs clockwise in the image (y down): positive shoelace sum.
        let area: f64 = (0..4)
            .map(|i| best[i][0] * best[(i + 1) % 4][1] - best[(i + 1) % 4][0] * best[i][1])
            .sum();
        assert!(area > 0.0);
    }

    #[test]
    fn a_light_quad_on_dark_ground_is_outlined_too() {
        let image = draw(&SLIVER, 30, 210, 2.0);
        let found = outline_candidates(&image, &sliver_corners(), &OutlineOptions::default());
        assert!(found.iter().any(|c| matches(&c.proposal.corners, &SLIVER)));
    }

    #[test]
    fn corners_with_no_edges_between_them_outline_nothing() {
        let flat = draw(&SLIVER, 120, 120, 2.0);
        assert!(
            outline_candidates(&flat, &sliver_corners(), &OutlineOptions::default()).is_empty()
        );
        // Edges of the wrong shape: the same corners over a square elsewhere.
        let elsewhere = draw(
            &Quad([[60.0, 80.0], [100.0, 80.0], [100.0, 115.0], [60.0, 115.0]]),
            210,
            30,
            2.0,
        );
        assert!(
            outline_candidates(&elsewhere, &sliver_corners(), &OutlineOptions::default())
                .is_empty()
        );
    }

    #[test]
    fn the_noise_estimate_follows_the_sensor_noise() {
        for sigma in [0.0, 4.0, 12.0] {
            let got = noise_sigma(&draw(&SLIVER, 150, 150, sigma)) as f64;
            assert!(
                (got - sigma).abs() <= 0.15 * sigma + 0.3,
                "σ {sigma}: {got}"
            );
        }
    }

    #[test]
    fn the_gray_range_ignores_the_extreme_two_percent() {
        let mut image = draw(&SLIVER, 200, 40, 0.0);
        // A few glints and shadows (under 2 % of the pixels each) do not widen the range.
        for i in 0..100 {
            image.pixels[i * 7] = 255;
            image.pixels[i * 7 + 3] = 0;
        }
        assert_eq!(contrast_range(&image), 160.0);
        assert_eq!(contrast_range(&draw(&SLIVER, 90, 90, 0.0)), 0.0);
    }

    #[test]
    fn an_image_too_noisy_for_the_side_test_is_not_searched() {
        // σ 25: a 180-level border would still pass, but so would noise anywhere.
        let noisy = draw(&SLIVER, 210, 30, 25.0);
        assert!(noise_sigma(&noisy) * NOISE_STEPS > MAX_CONTRAST);
        assert!(
            outline_candidates(&noisy, &sliver_corners(), &OutlineOptions::default()).is_empty()
        );
    }
}
