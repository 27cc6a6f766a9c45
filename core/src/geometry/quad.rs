//! [`Quad`]: four points in order around a quadrilateral — an ROI, a marker's outline, a
//! candidate from any proposal source — and what every stage asks of one.

use std::ops::{Deref, DerefMut};

use serde::{Deserialize, Serialize};

use super::{check_coordinate, distance, polygon_area, GeometryError, MIN_QUAD_AREA};

/// Four corners in order around a quadrilateral, in pixels or marker units. Serialised as the
/// bare array of four `[x, y]` points, as detections, reports and model files always held them;
/// it dereferences to that array, so `quad[i]` is corner `i`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Quad(pub [[f64; 2]; 4]);

impl Deref for Quad {
    type Target = [[f64; 2]; 4];

    fn deref(&self) -> &Self::Target {
        &self.0
    }
}

impl DerefMut for Quad {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut self.0
    }
}

impl From<[[f64; 2]; 4]> for Quad {
    fn from(corners: [[f64; 2]; 4]) -> Self {
        Quad(corners)
    }
}

impl From<Quad> for [[f64; 2]; 4] {
    fn from(quad: Quad) -> Self {
        quad.0
    }
}

impl PartialEq<[[f64; 2]; 4]> for Quad {
    fn eq(&self, other: &[[f64; 2]; 4]) -> bool {
        self.0 == *other
    }
}

impl TryFrom<&[[f64; 2]]> for Quad {
    type Error = std::array::TryFromSliceError;

    fn try_from(points: &[[f64; 2]]) -> Result<Self, Self::Error> {
        Ok(Quad(points.try_into()?))
    }
}

impl Quad {
    /// Each corner moved by `f`.
    pub fn map(self, f: impl FnMut([f64; 2]) -> [f64; 2]) -> Quad {
        Quad(self.0.map(f))
    }

    /// The sides' lengths, side `i` running from corner `i` to corner `i + 1`.
    pub fn sides(&self) -> [f64; 4] {
        std::array::from_fn(|i| distance(self[i], self[(i + 1) % 4]))
    }

    pub fn shortest_side(&self) -> f64 {
        self.sides().into_iter().fold(f64::MAX, f64::min)
    }

    pub fn longest_side(&self) -> f64 {
        self.sides().into_iter().fold(0.0, f64::max)
    }

    /// The larger of the two ratios longer / shorter between opposite sides: 1 for a
    /// parallelogram, large for a quad seen in steep perspective or a sliver of clutter.
    pub fn opposite_sides_ratio(&self) -> f64 {
        let side = self.sides().map(|s| s.max(1e-9));
        let ratio = |a: f64, b: f64| a.max(b) / a.min(b);
        ratio(side[0], side[2]).max(ratio(side[1], side[3]))
    }

    /// The signed area: positive when the corners run clockwise in the image (y down).
    pub fn signed_area(&self) -> f64 {
        polygon_area(&self.0)
    }

    /// The enclosed area (of a simple quad).
    pub fn area(&self) -> f64 {
        self.signed_area().abs()
    }

    /// The mean of the four corners.
    pub fn centre(&self) -> [f64; 2] {
        let s = self
            .iter()
            .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
        [s[0] / 4.0, s[1] / 4.0]
    }

    /// Where the diagonals 0–2 and 1–3 cross: the centre of the square a camera saw as this quad
    /// (`None` for a degenerate quad).
    pub fn diagonal_crossing(&self) -> Option<[f64; 2]> {
        let c = &self.0;
        let d1 = [c[2][0] - c[0][0], c[2][1] - c[0][1]];
        let d2 = [c[3][0] - c[1][0], c[3][1] - c[1][1]];
        let den = d1[0] * d2[1] - d1[1] * d2[0];
        if den.abs() < 1e-9 {
            return None;
        }
        let r = [c[1][0] - c[0][0], c[1][1] - c[0][1]];
        let t = (r[0] * d2[1] - r[1] * d2[0]) / den;
        Some([c[0][0] + t * d1[0], c[0][1] + t * d1[1]])
    }

    /// How thin the quad is: its shortest side, or the width across its longer diagonal where
    /// that is less (a square turned steeply about its diagonal is a thin rhombus with long
    /// sides).
    pub fn width(&self) -> f64 {
        let diagonal = |i: usize| distance(self[i + 2], self[i]);
        let longer = diagonal(0).max(diagonal(1));
        if longer <= 0.0 {
            return 0.0;
        }
        self.shortest_side().min(2.0 * self.area() / longer)
    }

    /// The quad scaled by `factor` about its [`centre`](Self::centre).
    pub fn scaled(&self, factor: f64) -> Quad {
        let c = self.centre();
        self.map(|p| [c[0] + factor * (p[0] - c[0]), c[1] + factor * (p[1] - c[1])])
    }

    /// Whether `p` lies inside (even-odd rule).
    pub fn encloses(&self, p: [f64; 2]) -> bool {
        super::inside_polygon(&self.0, p)
    }

    /// How far the farthest-moved corner lies from the same corner of `other`.
    pub fn largest_corner_move(&self, other: &Quad) -> f64 {
        (0..4)
            .map(|i| distance(self[i], other[i]))
            .fold(0.0, f64::max)
    }

    /// Axis-aligned bounds: [min x, min y, max x, max y].
    pub fn bounding_box(&self) -> [f64; 4] {
        super::bounding_box(&self.0)
    }

    /// Checks that the quad (an ROI: four corners in order around it, in pixels) can be an
    /// outline a marker projects to, before any solver runs on it: every coordinate finite, not
    /// subnormal and within ±[`MAX_COORDINATE`](super::MAX_COORDINATE); no two corners
    /// coincident; no three collinear; opposite edges not crossing (a bow-tie); and an area of
    /// at least [`MIN_QUAD_AREA`]. The error says which, naming corners from 1.
    pub fn check(&self) -> Result<(), GeometryError> {
        self.check_with_min_area(MIN_QUAD_AREA)
    }

    /// [`check`](Self::check) with another least area (0 for outlines known to come from a
    /// projection, such as a benchmark set's ground truth, where a marker far away may cover
    /// less than a pixel).
    pub fn check_with_min_area(&self, min_area: f64) -> Result<(), GeometryError> {
        let quad = &self.0;
        if quad.iter().flatten().any(|v| !v.is_finite()) {
            return Err(GeometryError::NotFinite);
        }
        quad.iter()
            .flatten()
            .try_for_each(|&v| check_coordinate(v))?;
        // Coordinates within ±1e7 px: differences, products and areas below are exact enough.
        for i in 0..4 {
            for j in i + 1..4 {
                if distance(quad[i], quad[j]) <= 1e-9 {
                    return Err(GeometryError::CoincidentCorners(i + 1, j + 1));
                }
            }
        }
        let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
            (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
        };
        // With four points every triple is three consecutive corners: each one's sign is its
        // turn.
        for k in 0..4 {
            let (a, o, b) = (quad[(k + 3) % 4], quad[k], quad[(k + 1) % 4]);
            // Collinear to rounding: the sine of the angle at `o` under 1e-9.
            if cross(o, a, b).abs() <= 1e-9 * distance(o, a) * distance(o, b) {
                let mut ids = [(k + 3) % 4 + 1, k + 1, (k + 1) % 4 + 1];
                ids.sort_unstable();
                return Err(GeometryError::CollinearCorners(ids[0], ids[1], ids[2]));
            }
        }
        // Segments p–q and r–s cross when each one's ends lie on both sides of the other's line;
        // with no three corners collinear no orientation is zero.
        let crosses = |p: [f64; 2], q: [f64; 2], r: [f64; 2], s: [f64; 2]| {
            (cross(p, q, r) > 0.0) != (cross(p, q, s) > 0.0)
                && (cross(r, s, p) > 0.0) != (cross(r, s, q) > 0.0)
        };
        if crosses(quad[0], quad[1], quad[2], quad[3])
            || crosses(quad[1], quad[2], quad[3], quad[0])
        {
            return Err(GeometryError::SelfIntersecting);
        }
        let area = self.area();
        if area < min_area {
            return Err(GeometryError::TooSmall(area));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check_quad(corners: &[[f64; 2]; 4]) -> Result<(), GeometryError> {
        Quad(*corners).check()
    }

    /// A marker seen at an angle: a valid, convex, non-square outline.
    const PERSPECTIVE: [[f64; 2]; 4] = [
        [329.95, 442.66],
        [286.03, 446.36],
        [285.24, 402.35],
        [328.57, 398.87],
    ];

    /// The `--roi` that spun in the homography's SVD forever.
    #[test]
    fn the_subnormal_roi_is_refused_at_once() {
        let roi = [[0.0, 0.0], [5e-324, 0.0], [5e-324, 5e-324], [0.0, 5e-324]];
        let started = std::time::Instant::now();
        let e = check_quad(&roi).unwrap_err();
        assert_eq!(e, GeometryError::Subnormal(5e-324));
        assert!(e.to_string().contains("subnormal"), "{e}");
        // And no solver reached with it runs unbounded either.
        let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        assert!(super::super::Homography::from_points(&unit, &roi).is_err());
        assert!(started.elapsed().as_secs_f64() < 1.0);
    }

    #[test]
    fn a_perspective_quad_passes_in_either_direction() {
        assert_eq!(check_quad(&PERSPECTIVE), Ok(()));
        let mut reversed = PERSPECTIVE;
        reversed.reverse();
        assert_eq!(check_quad(&reversed), Ok(()));
        // Concave outlines are not refused: they do not cross themselves.
        let dart = [[0.0, 0.0], [10.0, 5.0], [0.0, 10.0], [3.0, 5.0]];
        assert_eq!(check_quad(&dart), Ok(()));
    }

    #[test]
    fn each_bad_quad_is_named_for_what_is_wrong() {
        let bow_tie = [[0.0, 0.0], [10.0, 10.0], [10.0, 0.0], [0.0, 10.0]];
        let e = check_quad(&bow_tie).unwrap_err();
        assert_eq!(e, GeometryError::SelfIntersecting);
        assert!(e.to_string().contains("bow-tie"), "{e}");
        let other_tie = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0], [10.0, 10.0]];
        assert_eq!(check_quad(&other_tie), Err(GeometryError::SelfIntersecting));

        let collinear = [[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [3.0, 8.0]];
        let e = check_quad(&collinear).unwrap_err();
        assert_eq!(e, GeometryError::CollinearCorners(1, 2, 3));
        assert_eq!(e.to_string(), "the quad's corners 1, 2 and 3 are collinear");
        let wrapping = [[0.0, 10.0], [3.0, 8.0], [0.0, 0.0], [0.0, 5.0]];
        assert_eq!(
            check_quad(&wrapping),
            Err(GeometryError::CollinearCorners(1, 3, 4))
        );

        let coincident = [[0.0, 0.0], [10.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
        let e = check_quad(&coincident).unwrap_err();
        assert_eq!(e, GeometryError::CoincidentCorners(2, 3));
        assert!(e.to_string().contains("corners 2 and 3 coincide"), "{e}");
        assert_eq!(
            check_quad(&[[4.0, 4.0]; 4]),
            Err(GeometryError::CoincidentCorners(1, 2))
        );

        let mut nan = PERSPECTIVE;
        nan[2][1] = f64::NAN;
        assert_eq!(check_quad(&nan), Err(GeometryError::NotFinite));
        let mut inf = PERSPECTIVE;
        inf[0][0] = f64::NEG_INFINITY;
        assert_eq!(check_quad(&inf), Err(GeometryError::NotFinite));

        let mut far = PERSPECTIVE;
        far[3][0] = 2e7;
        let e = check_quad(&far).unwrap_err();
        assert_eq!(e, GeometryError::TooLarge(2e7));
        assert!(e.to_string().contains("beyond"), "{e}");

        let tiny = [[0.0, 0.0], [0.5, 0.0], [0.5, 0.5], [0.0, 0.5]];
        let e = check_quad(&tiny).unwrap_err();
        assert_eq!(e, GeometryError::TooSmall(0.25));
        assert!(e.to_string().contains("under 1 px²"), "{e}");
        assert_eq!(Quad(tiny).check_with_min_area(0.0), Ok(()));
    }

    /// A 4 × 2 rectangle, clockwise in the image (y down).
    const RECTANGLE: Quad = Quad([[0.0, 0.0], [4.0, 0.0], [4.0, 2.0], [0.0, 2.0]]);

    #[test]
    fn a_rectangle_has_its_sides_area_centre_and_width() {
        assert_eq!(RECTANGLE.sides(), [4.0, 2.0, 4.0, 2.0]);
        assert_eq!(RECTANGLE.signed_area(), 8.0);
        assert_eq!(RECTANGLE.area(), 8.0);
        assert_eq!(RECTANGLE.centre(), [2.0, 1.0]);
        assert_eq!(RECTANGLE.diagonal_crossing(), Some([2.0, 1.0]));
        assert_eq!(RECTANGLE.width(), 2.0);
        assert_eq!(RECTANGLE.opposite_sides_ratio(), 1.0);
        assert_eq!(RECTANGLE.bounding_box(), [0.0, 0.0, 4.0, 2.0]);
    }

    #[test]
    fn the_other_way_round_the_signed_area_turns_negative() {
        let mut reversed = RECTANGLE;
        reversed.reverse();
        assert_eq!(reversed.signed_area(), -8.0);
        assert_eq!(reversed.area(), 8.0);
    }

    /// A square turned steeply about its diagonal: long sides, thin across.
    #[test]
    fn a_thin_rhombus_is_as_wide_as_across_its_long_diagonal() {
        let rhombus = Quad([[0.0, 0.0], [40.0, -5.0], [80.0, 0.0], [40.0, 5.0]]);
        assert!(rhombus.shortest_side() > 40.0);
        assert!((rhombus.width() - 10.0).abs() < 1e-9, "{}", rhombus.width());
    }

    #[test]
    fn scaling_keeps_the_centre_and_grows_the_sides() {
        let grown = RECTANGLE.scaled(1.5);
        assert_eq!(grown.centre(), RECTANGLE.centre());
        assert_eq!(grown.sides(), [6.0, 3.0, 6.0, 3.0]);
        assert!(grown.encloses([4.5, 1.0]) && !RECTANGLE.encloses([4.5, 1.0]));
        assert_eq!(grown.largest_corner_move(&RECTANGLE), 1.0f64.hypot(0.5));
    }

    #[test]
    fn it_serialises_as_the_bare_array_of_corners() {
        let json = serde_json::to_string(&RECTANGLE).unwrap();
        assert_eq!(json, "[[0.0,0.0],[4.0,0.0],[4.0,2.0],[0.0,2.0]]");
        assert_eq!(serde_json::from_str::<Quad>(&json).unwrap(), RECTANGLE);
        assert!(Quad::try_from(&RECTANGLE[..3]).is_err());
        assert_eq!(Quad::try_from(&RECTANGLE[..]).unwrap(), RECTANGLE);
    }

    #[test]
    fn the_diagonals_of_a_perspective_quad_cross_off_its_mean() {
        let c = Quad([[0.0, 0.0], [10.0, 0.0], [8.0, 6.0], [2.0, 6.0]]);
        let x = c.diagonal_crossing().unwrap();
        assert!((x[1] - 60.0 / 16.0).abs() < 1e-9, "{x:?}");
        assert!(x[1] < 3.0 + 1.0);
    }
}
