//! The network's stretched look at far steep slivers. A marker seen at 60–75° from 60–100 cm is
//! a needle: 30–110 px long and 4–20 px across. Doubling it (the closer look) leaves it thinner
//! than any view the network was trained on; stretching it across its length four times (and
//! along it twice) undoes most of the foreshortening, and the network sees an ordinary steep
//! marker. A sliver's end corners point along its length to its centre, so the network's own
//! corner directions tell which way to stretch.

use super::group::Corner;
use crate::image::GrayImage;

/// Crop pixels per image pixel along the sliver (at most; a long one is scaled to fit) and how
/// many times more across it.
const ALONG_SCALE: f64 = 2.0;
const ACROSS_RATIO: f64 = 2.0;

/// The share of the crop's length a sliver between two corners fills.
const PAIR_FILL: f64 = 0.6;

/// The crop's size in its own pixels: 128 image pixels along the axis (a sliver up to about
/// 100 px long, with the corner a quarter in) and 40 across (a sliver up to 20 px across, with
/// its quiet zone). Multiples of the network's stride, so the crops need no padding.
pub const CROP_WIDTH: u32 = 256;
pub const CROP_HEIGHT: u32 = 160;

/// How far along its direction from the corner the crop's centre lies, in image pixels: the
/// corner a quarter of the crop's length in from its end.
const LEAD: f64 = 0.25 * CROP_WIDTH as f64 / ALONG_SCALE;

/// An affine view of the image: crop pixel (u, v) shows image point
/// `centre + (u − u₀) / ALONG_SCALE · along + (v − v₀) / ACROSS_SCALE · across`, with (u₀, v₀)
/// the crop's centre and `across` the `along` direction turned a quarter clockwise, so that the
/// map keeps the image's turning sense (ROIs stay clockwise).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stretch {
    pub centre: [f64; 2],
    /// Unit vector along the sliver's length.
    pub along: [f64; 2],
    /// Crop pixels per image pixel along it (across: [`ACROSS_RATIO`] times more).
    pub scale: f64,
}

impl Stretch {
    /// The view of the sliver whose end corner is `corner`.
    pub fn from_corner(corner: &Corner) -> Self {
        let [dx, dy] = corner.direction;
        let norm = dx.hypot(dy).max(1e-9);
        let along = [dx / norm, dy / norm];
        Self {
            centre: [
                corner.at[0] + LEAD * along[0],
                corner.at[1] + LEAD * along[1],
            ],
            along,
            scale: ALONG_SCALE,
        }
    }

    /// The view of the sliver between two corners that point at each other.
    pub fn between(a: [f64; 2], b: [f64; 2]) -> Self {
        let length = (b[0] - a[0]).hypot(b[1] - a[1]).max(1e-9);
        Self {
            centre: [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0],
            along: [(b[0] - a[0]) / length, (b[1] - a[1]) / length],
            scale: (PAIR_FILL * CROP_WIDTH as f64 / length).min(ALONG_SCALE),
        }
    }

    fn across(&self) -> [f64; 2] {
        [-self.along[1], self.along[0]]
    }

    /// The image point crop pixel `p` shows.
    pub fn to_image(&self, [u, v]: [f64; 2]) -> [f64; 2] {
        let a = (u - (CROP_WIDTH as f64 - 1.0) / 2.0) / self.scale;
        let b = (v - (CROP_HEIGHT as f64 - 1.0) / 2.0) / (ACROSS_RATIO * self.scale);
        let across = self.across();
        [
            self.centre[0] + a * self.along[0] + b * across[0],
            self.centre[1] + a * self.along[1] + b * across[1],
        ]
    }

    /// Whether `other` views about the same place in about the same direction (either way
    /// along: a sliver's two end corners point at each other).
    pub fn overlaps(&self, other: &Stretch) -> bool {
        let near = (self.centre[0] - other.centre[0]).hypot(self.centre[1] - other.centre[1])
            < SAME_VIEW_PX;
        let cos = (self.along[0] * other.along[0] + self.along[1] * other.along[1]).abs();
        near && cos > SAME_VIEW_COS
    }

    /// The crop, sampled bilinearly (points outside the image take its nearest edge).
    pub fn crop(&self, image: &GrayImage) -> GrayImage {
        let mut out = GrayImage::new(CROP_WIDTH, CROP_HEIGHT, 0);
        for v in 0..CROP_HEIGHT {
            for u in 0..CROP_WIDTH {
                let [x, y] = self.to_image([u as f64, v as f64]);
                let value = image.sample(x as f32, y as f32);
                out.pixels[(v * CROP_WIDTH + u) as usize] = value.round().clamp(0.0, 255.0) as u8;
            }
        }
        out
    }
}

/// Two views closer than this (image px) and within about 25° of each other see the same sliver.
const SAME_VIEW_PX: f64 = 24.0;
const SAME_VIEW_COS: f64 = 0.9;

/// A sliver's end corners point at each other within this (cos 30°).
const PAIR_COS: f64 = 0.866;

/// How far apart (image px) two corners of one sliver may be.
const PAIR_SPAN: [f64; 2] = [12.0, 200.0];

/// The corners of [`views`]' pairs: the strongest this many.
const PAIR_CORNERS: usize = 40;

/// Up to `most` views: first between pairs of `weak` corners that point at each other (the two
/// ends of one sliver fix its axis better than either's direction), strongest pair first; then
/// one per `strong` corner in the order given (strongest first). Corners that `explained` says a
/// read accounts for are skipped, and so are views that overlap an earlier one.
pub fn views(
    weak: &[Corner],
    strong: &[Corner],
    explained: &dyn Fn([f64; 2]) -> bool,
    most: usize,
) -> Vec<Stretch> {
    let free: Vec<&Corner> = weak
        .iter()
        .filter(|c| !explained(c.at))
        .take(PAIR_CORNERS)
        .collect();
    let mut pairs: Vec<(f64, Stretch)> = Vec::new();
    for (i, a) in free.iter().enumerate() {
        for b in &free[i + 1..] {
            let (dx, dy) = (b.at[0] - a.at[0], b.at[1] - a.at[1]);
            let length = dx.hypot(dy);
            if !(PAIR_SPAN[0]..=PAIR_SPAN[1]).contains(&length) {
                continue;
            }
            let toward_b = (a.direction[0] * dx + a.direction[1] * dy) / length;
            let toward_a = -(b.direction[0] * dx + b.direction[1] * dy) / length;
            if toward_b > PAIR_COS && toward_a > PAIR_COS {
                pairs.push((a.score + b.score, Stretch::between(a.at, b.at)));
            }
        }
    }
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let singles = (strong.iter())
        .filter(|c| !explained(c.at))
        .map(Stretch::from_corner);
    // A single corner's view is skipped only where another single corner's overlaps it, not
    // where a pair's does: the two frame the same needle differently, and each read needles
    // the other missed (dev 36h11 misses: pairs' views with singles' over them read 9 of 30,
    // either's alone 7).
    let mut out = distinct(pairs.into_iter().map(|(_, v)| v), most);
    let left = most - out.len();
    out.extend(distinct(singles, left));
    out
}

/// Up to `most` of `views` in order, each not overlapping an earlier one.
fn distinct(views: impl Iterator<Item = Stretch>, most: usize) -> Vec<Stretch> {
    let mut out: Vec<Stretch> = Vec::new();
    for view in views {
        if out.len() == most {
            break;
        }
        if !out.iter().any(|v| v.overlaps(&view)) {
            out.push(view);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corner(at: [f64; 2], direction: [f64; 2]) -> Corner {
        Corner {
            at,
            direction,
            score: 0.9,
        }
    }

    #[test]
    fn a_views_crop_centre_lies_along_the_corners_direction_and_keeps_clockwise_order() {
        let view = Stretch::from_corner(&corner([100.0, 50.0], [0.0, 1.0]));
        let middle = view.to_image([
            (CROP_WIDTH as f64 - 1.0) / 2.0,
            (CROP_HEIGHT as f64 - 1.0) / 2.0,
        ]);
        assert!((middle[0] - 100.0).abs() < 1e-9 && (middle[1] - (50.0 + LEAD)).abs() < 1e-9);
        // A clockwise square in the crop (x right, y down) maps to a clockwise quad in the image:
        // positive signed area in image coordinates (y down).
        let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]].map(|p| view.to_image(p));
        let area: f64 = (0..4)
            .map(|i| {
                let (a, b) = (square[i], square[(i + 1) % 4]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        assert!(area > 0.0, "{square:?}");
        // Ten crop pixels along are five image pixels, ten across two and a half.
        let d = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]);
        assert!((d(square[0], square[1]) - 10.0 / ALONG_SCALE).abs() < 1e-9);
        assert!((d(square[1], square[2]) - 10.0 / (ACROSS_RATIO * ALONG_SCALE)).abs() < 1e-9);
    }

    #[test]
    fn a_thin_bar_looks_four_times_thicker_in_its_view() {
        // A dark bar 40 px long and 4 px thick along the diagonal of a light image.
        let mut image = GrayImage::new(120, 120, 220);
        let along = [1.0 / 2f64.sqrt(), 1.0 / 2f64.sqrt()];
        for y in 0..120 {
            for x in 0..120 {
                let (dx, dy) = (x as f64 - 60.0, y as f64 - 60.0);
                let t = dx * along[0] + dy * along[1];
                let s = -dx * along[1] + dy * along[0];
                if t.abs() <= 20.0 && s.abs() <= 2.0 {
                    image.pixels[y * 120 + x] = 20;
                }
            }
        }
        let view = Stretch::from_corner(&corner(
            [60.0 - 20.0 * along[0], 60.0 - 20.0 * along[1]],
            along,
        ));
        let crop = view.crop(&image);
        let dark_rows = |u: u32| {
            (0..CROP_HEIGHT)
                .filter(|&v| crop.pixels[(v * CROP_WIDTH + u) as usize] < 120)
                .count()
        };
        // Through the bar's middle (40 crop px past the corner's 32 image px = 64 crop px in).
        let u = (CROP_WIDTH as f64 / 4.0 + 20.0 * ALONG_SCALE) as u32;
        let thickness = dark_rows(u);
        assert!((14..=18).contains(&thickness), "{thickness} crop rows dark");
        // Past the bar's far end nothing is dark.
        assert_eq!(dark_rows(u + 60), 0);
    }

    #[test]
    fn the_two_end_corners_of_one_sliver_give_one_view_along_the_line_between_them_first() {
        let a = corner([0.0, 0.0], [1.0, 0.1]);
        let b = corner([60.0, 2.0], [-1.0, -0.1]);
        let c = corner([30.0, 200.0], [1.0, 0.0]);
        let seen = views(&[a, b, c], &[a, b, c], &|_| false, 6);
        // The pair's view, then one per single corner's (the two ends' views overlap).
        let expected = vec![
            Stretch::between(a.at, b.at),
            Stretch::from_corner(&a),
            Stretch::from_corner(&c),
        ];
        assert_eq!(seen, expected);
        let first = views(&[a, b, c], &[a, b, c], &|p| p[1] > 100.0, 1);
        assert_eq!(first, vec![Stretch::between(a.at, b.at)]);
        // Corners that point past each other are no pair.
        let d = corner([0.0, 50.0], [0.0, 1.0]);
        let e = corner([60.0, 50.0], [0.0, -1.0]);
        assert!(views(&[d, e], &[], &|_| false, 6).is_empty());
    }

    #[test]
    fn a_long_sliver_is_scaled_to_fit_its_view() {
        let long = Stretch::between([0.0, 0.0], [200.0, 0.0]);
        let ends = [
            long.to_image([0.0, 0.0]),
            long.to_image([CROP_WIDTH as f64 - 1.0, 0.0]),
        ];
        let span = ends[1][0] - ends[0][0];
        assert!(span > 200.0 && span < 2.0 * 200.0, "{span}");
        assert_eq!(Stretch::between([0.0, 0.0], [40.0, 0.0]).scale, ALONG_SCALE);
    }
}
