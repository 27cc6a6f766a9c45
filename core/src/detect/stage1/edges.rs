//! Quads moved onto the image's edges: each side refitted to where the gray level steps up from
//! the marker's dark border to its light quiet zone, and the corners put where those lines meet.
//!
//! Stage 1's corners sit on a 4-px grid, a traced blob's hull on whole pixels, and a far steep
//! sliver is 8–12 px across: a corner 2–4 px off is a third of its width, and stage 2 reads it
//! from nothing further than about a pixel (dev ArUco seed 40 #480, 10 px across: from its
//! traced quad, 2–3 px off at two corners, nothing; from the same quad fitted here, a read). A
//! side's 50–70 px of edge pin its line down far better than any corner detector can place its
//! ends. Dev seed 42's 325 Difficult markers, every true ROI corner moved by a normal error of
//! σ = 2 px: the worst corner's median error 3.4 px → 0.07 px; of the 13 thinner than 16 px,
//! 8 end within a pixel (with the traced quads' single pass over a 2-px step, 2: that coarser
//! fit stays theirs, as it read two more of 1300 dev markers than this one there).

use crate::geometry::{distance, Quad};
use crate::image::GrayImage;

/// A line: a point on it and its unit direction.
pub(super) type Line = ([f64; 2], [f64; 2]);

/// How far either side of each side its edge is looked for in the first pass, and in the
/// second (from the first's lines), in pixels.
const REACH_PX: [f64; 2] = [3.0, 1.5];

/// Spacing of the gray-level profile across a side, in pixels: a sliver's quiet zone is a pixel
/// or so wide, and a step measured over 2 px blurs it into the dark ground beyond.
const PROFILE_STEP_PX: f64 = 0.25;

/// The weakest step counted as an edge, in gray levels per pixel.
const MIN_STEP: f64 = 5.0;

/// The most samples along one side.
const MAX_SAMPLES: usize = 64;

/// The quad with all four sides on the image's edges (two passes), or `None` where a side
/// shows no clear edge or the fit would move a corner by more than 15 % of the longest side.
pub fn on_edges(image: &GrayImage, quad: Quad) -> Option<Quad> {
    REACH_PX.iter().try_fold(quad, |q, &reach| {
        let lines = side_lines(image, &q, reach);
        let lines: [Line; 4] = [lines[0]?, lines[1]?, lines[2]?, lines[3]?];
        corners_of(&q, &lines)
    })
}

/// Each side's edge line, where it shows one within `reach` px.
fn side_lines(image: &GrayImage, quad: &Quad, reach: f64) -> [Option<Line>; 4] {
    let centre = quad.centre();
    std::array::from_fn(|i| side_line(image, quad[i], quad[(i + 1) % 4], centre, reach))
}

/// The quad's corners where neighbouring lines meet, or `None` when they move too far or turn
/// the quad inside out.
fn corners_of(quad: &Quad, lines: &[Line; 4]) -> Option<Quad> {
    let mut out = *quad;
    for (i, corner) in out.iter_mut().enumerate() {
        *corner = intersection(lines[(i + 3) % 4], lines[i])?;
    }
    let longest = quad.longest_side();
    let same_turn = out.signed_area() * quad.signed_area() > 0.0;
    (out.largest_corner_move(quad) <= 0.15 * longest && same_turn).then_some(out)
}

/// The edge along the side `a`–`b`: at up to [`MAX_SAMPLES`] points of its middle 70 %, the
/// strongest dark-to-light step outwards within `reach` px (to a quarter pixel, then by a
/// parabola through its neighbours), and a line fitted through them, weighted by the steps,
/// without the points off it (a data cell's edge beside the border's). `None` when fewer than
/// half the points show a step.
fn side_line(
    image: &GrayImage,
    a: [f64; 2],
    b: [f64; 2],
    centre: [f64; 2],
    reach: f64,
) -> Option<Line> {
    let length = distance(a, b);
    if length < 4.0 {
        return None;
    }
    let u = [(b[0] - a[0]) / length, (b[1] - a[1]) / length];
    let mut out = [-u[1], u[0]];
    let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
    if out[0] * (mid[0] - centre[0]) + out[1] * (mid[1] - centre[1]) < 0.0 {
        out = [-out[0], -out[1]];
    }
    let samples = ((0.7 * length / 0.5) as usize).clamp(3, MAX_SAMPLES);
    let steps = (2.0 * reach / PROFILE_STEP_PX).round() as usize;
    let mut points: Vec<([f64; 2], f64)> = Vec::with_capacity(samples);
    let mut profile = vec![0.0; steps + 3];
    for k in 0..samples {
        let t = length * (0.15 + 0.7 * (k as f64 + 0.5) / samples as f64);
        let base = [a[0] + t * u[0], a[1] + t * u[1]];
        // profile[j] at -reach - step + j·step outwards.
        for (j, v) in profile.iter_mut().enumerate() {
            let o = -reach + (j as f64 - 1.0) * PROFILE_STEP_PX;
            *v = image.sample((base[0] + o * out[0]) as f32, (base[1] + o * out[1]) as f32) as f64;
        }
        let slope = |j: usize| (profile[j + 1] - profile[j - 1]) / (2.0 * PROFILE_STEP_PX);
        let (best, strongest) = (1..=steps + 1)
            .map(|j| (j, slope(j)))
            .fold((0, f64::MIN), |m, s| if s.1 > m.1 { s } else { m });
        if strongest < MIN_STEP || best == 1 || best == steps + 1 {
            continue;
        }
        let (before, after) = (slope(best - 1), slope(best + 1));
        let curvature = before - 2.0 * strongest + after;
        let shift = if curvature < 0.0 {
            0.5 * (before - after) / curvature
        } else {
            0.0
        };
        let o = -reach + (best as f64 - 1.0 + shift) * PROFILE_STEP_PX;
        points.push(([base[0] + o * out[0], base[1] + o * out[1]], strongest));
    }
    if points.len() < 3 || 2 * points.len() < samples {
        return None;
    }
    robust_line(points)
}

/// The weighted total-least-squares line through the points, refitted up to three times without
/// those further from it than 2.5 × the median distance (and 0.75 px).
fn robust_line(mut points: Vec<([f64; 2], f64)>) -> Option<Line> {
    for _ in 0..3 {
        let line = weighted_line(&points)?;
        let off = |p: [f64; 2]| {
            let [dx, dy] = [p[0] - line.0[0], p[1] - line.0[1]];
            (dx * line.1[1] - dy * line.1[0]).abs()
        };
        let mut distances: Vec<f64> = points.iter().map(|(p, _)| off(*p)).collect();
        distances.sort_by(f64::total_cmp);
        let bound = (2.5 * distances[distances.len() / 2]).max(0.75);
        let before = points.len();
        points.retain(|(p, _)| off(*p) <= bound);
        if points.len() == before {
            return Some(line);
        }
        if points.len() < 3 {
            return None;
        }
    }
    weighted_line(&points)
}

/// The principal axis of the weighted points: a point on the line and its direction.
pub(super) fn weighted_line(points: &[([f64; 2], f64)]) -> Option<Line> {
    let total: f64 = points.iter().map(|(_, w)| w).sum();
    if total <= 0.0 {
        return None;
    }
    let mean = [
        points.iter().map(|(p, w)| w * p[0]).sum::<f64>() / total,
        points.iter().map(|(p, w)| w * p[1]).sum::<f64>() / total,
    ];
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    for (p, w) in points {
        let (dx, dy) = (p[0] - mean[0], p[1] - mean[1]);
        xx += w * dx * dx;
        xy += w * dx * dy;
        yy += w * dy * dy;
    }
    let angle = 0.5 * (2.0 * xy).atan2(xx - yy);
    Some((mean, [angle.cos(), angle.sin()]))
}

/// Where two lines meet (`None` for parallel lines).
pub(super) fn intersection(a: Line, b: Line) -> Option<[f64; 2]> {
    let ((p, u), (q, v)) = (a, b);
    let det = u[0] * v[1] - u[1] * v[0];
    if det.abs() < 1e-6 {
        return None;
    }
    let t = ((q[0] - p[0]) * v[1] - (q[1] - p[1]) * v[0]) / det;
    Some([p[0] + t * u[0], p[1] + t * u[1]])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A dark quad on a light quiet zone 1.2 px wide, on dark ground: a far steep marker on a
    /// dark table. Supersampled 4 × 4 per pixel so its edges fall between pixels.
    fn sliver_on_dark_ground(quad: &Quad) -> GrayImage {
        let centre = quad.centre();
        // The quiet zone's outline: every side moved out by 1.2 px.
        let grown = {
            let lines: Vec<Line> = (0..4)
                .map(|i| {
                    let (a, b) = (quad[i], quad[(i + 1) % 4]);
                    let l = distance(a, b);
                    let u = [(b[0] - a[0]) / l, (b[1] - a[1]) / l];
                    let mut n = [-u[1], u[0]];
                    let mid = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
                    if n[0] * (mid[0] - centre[0]) + n[1] * (mid[1] - centre[1]) < 0.0 {
                        n = [-n[0], -n[1]];
                    }
                    ([a[0] + 1.2 * n[0], a[1] + 1.2 * n[1]], u)
                })
                .collect();
            Quad(std::array::from_fn(|i| {
                intersection(lines[(i + 3) % 4], lines[i]).unwrap()
            }))
        };
        let (w, h) = (120u32, 100u32);
        let mut pixels = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            for x in 0..w {
                let mut sum: f64 = 0.0;
                for sy in 0..4 {
                    for sx in 0..4 {
                        // Pixel (x, y) is centred on (x, y), as the image's sampling has it.
                        let p = [
                            x as f64 - 0.5 + (sx as f64 + 0.5) / 4.0,
                            y as f64 - 0.5 + (sy as f64 + 0.5) / 4.0,
                        ];
                        sum += if quad.encloses(p) {
                            30.0
                        } else if grown.encloses(p) {
                            220.0
                        } else {
                            40.0
                        };
                    }
                }
                pixels.push((sum / 16.0).round() as u8);
            }
        }
        GrayImage::from_vec(w, h, pixels)
    }

    const SLIVER: Quad = Quad([[50.3, 20.6], [61.8, 24.1], [58.4, 80.2], [47.1, 76.9]]);

    #[test]
    fn a_sliver_a_few_pixels_off_is_moved_onto_its_edges() {
        let image = sliver_on_dark_ground(&SLIVER);
        // Off as stage 1's grid or a traced hull leaves a sliver 11 px across: 2–4 px.
        let rough = Quad([[52.0, 18.5], [59.0, 24.0], [61.0, 77.0], [45.0, 79.0]]);
        let fitted = on_edges(&image, rough).expect("four clear sides");
        let error = fitted.largest_corner_move(&SLIVER);
        assert!(error < 0.5, "{fitted:?} is {error:.2} px off");
        assert!(rough.largest_corner_move(&SLIVER) > 2.0);
    }

    #[test]
    fn a_quad_with_no_edges_is_left_alone() {
        let flat = GrayImage::new(120, 100, 128);
        let rough = Quad([[52.0, 18.5], [59.0, 24.0], [61.0, 77.0], [45.0, 79.0]]);
        assert_eq!(on_edges(&flat, rough), None);
    }
}
