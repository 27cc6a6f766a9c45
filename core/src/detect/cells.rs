//! Reading a marker's cells straight off the image (docs/ARCHITECTURE.md §9.8, "Cell reads"):
//! the ROI's homography places every keypoint, each is sampled at its centre, and the gray level
//! picks the category. Stage 2 rectifies a ROI to a patch first, and a sliver a few pixels across
//! (a marker 60–100 cm away at 60–75°) smears over the patch until its network misreads it,
//! while its cells, one or two pixels each, still sit where a homography from a ROI within about
//! half a pixel puts them: sampled there, such markers decode with 0–2 errors. Only families
//! whose every category is a flat cell (black and white grids: AprilTag, ArUco) are read this
//! way; glyphs need the network.

use crate::family::{decode, Assignment, Decoded, Family};
use crate::geometry::{Homography, Quad};
use crate::image::GrayImage;
use crate::render::readback::Reader;

/// A family's cell levels and the points whose level is known before the code is, ready to
/// read ROIs.
pub struct CellReader {
    /// Gray level (0 black – 1 white) of each category's cell.
    levels: Vec<f64>,
    /// Points of the fixed cells and the quiet zone, in marker units, with their level: what
    /// the ROI is fitted to and the gray levels are calibrated by.
    known: Vec<([f64; 2], f64)>,
    /// Marker units → the unit square spanned by ROI points 0–3.
    to_unit: Homography,
    /// The known points in unit-square coordinates, and the corners of their bounding box
    /// there: a score maps each point once, and checks the box against the image once.
    known_unit: Vec<[f64; 2]>,
    known_box: Quad,
    /// The known levels' mean and scatter (sum of squared deviations): fixed per family, so
    /// a score accumulates only the gray levels' sums.
    level_mean: f64,
    level_scatter: f64,
    /// The lightest category's level less the darkest's.
    level_range: f64,
}

/// Where the known points fit their levels best, and how well ([`CellReader::fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fitted {
    roi: Quad,
    /// The fitted black-to-white step over the residuals' spread.
    score: f64,
    /// Level → gray: `gray = gain · level + offset`.
    gain: f64,
    offset: f64,
}

/// The frame fit's scores of the quads it has tried, by their corners' exact bits. Coordinate
/// ascent keeps coming back to quads it scored: the sweep after a move tries again every trial it
/// made after that move, a step back undoes one, and the ascent with side moves starts with the
/// corners-only ascent's first sweep. A score samples the image at every known point (~270 for
/// 36h11), so each quad is scored once; exact keys keep the ascent's path and result as they
/// were (a quarter of the trials on the 640×480 speed set were repeats).
#[derive(Default)]
struct ScoredQuads(std::collections::HashMap<[u64; 8], Option<Fitted>>);

impl ScoredQuads {
    fn score(
        &mut self,
        quad: &Quad,
        score: impl FnOnce(&Quad) -> Option<Fitted>,
    ) -> Option<Fitted> {
        let key: [u64; 8] = std::array::from_fn(|i| quad[i / 2][i % 2].to_bits());
        *self.0.entry(key).or_insert_with(|| score(quad))
    }
}

/// What the cells of one ROI gave.
#[derive(Debug, Clone, PartialEq)]
pub enum CellOutcome {
    Read(CellRead),
    /// The frame fitted (these corners), but the code did not decode from the cells: the
    /// network may read it from there (a sliver's cells are a pixel wide).
    Framed(Quad),
    /// No frame: clutter, or too far from a marker.
    Unfit,
}

/// The read of one ROI.
#[derive(Debug, Clone, PartialEq)]
pub struct CellRead {
    pub decoded: Decoded,
    /// The category read at every keypoint, in the family's template order as observed.
    pub observed: Vec<usize>,
    /// Every keypoint's centre in the image, in the family's template order as observed.
    pub centres: Vec<[f64; 2]>,
    /// How clearly each keypoint's gray level picks its category, 0–1: 0 halfway between two
    /// categories' levels, 1 on the chosen one's (in the same order).
    pub margins: Vec<f64>,
    /// The fitted ROI (ROI points 0–3 in the image).
    pub roi: Quad,
    /// How well the known cells and the quiet zone fit their levels there (the frame fit's
    /// score; a read needs at least 3).
    pub fit: f64,
}

/// A category whose cell varies by more than this (gray levels, 0–255, over the cell's inner
/// 80 %) is a glyph, not a flat cell.
const FLAT_SPREAD: f64 = 40.0;

/// The least fit score ([`CellReader::fit`]) a read needs: the known cells' black-to-white
/// step over the spread of their residuals. Slivers fitted onto their frames score 5–9 on the
/// development sets; a quad a few pixels off or over clutter 0–2.
const MIN_FIT: f64 = 3.0;

/// The fit's corner steps, pixels: coarse to fine.
const FIT_STEPS: [f64; 4] = [2.0, 1.0, 0.5, 0.25];
/// The farthest the fit moves a corner, pixels. The ROIs it is for are a few pixels off (a
/// traced tip blunted by blur: 4–5 px; dev seed 10 #77 needs 10–15, and 6 lost it and seed 13
/// #49); left free, it walked a corner of a large marker 80 px onto a partial alignment that
/// still decoded (dev seed 16 #6, before cell reads came last).
const MAX_FIT_SHIFT: f64 = 15.0;
/// Sweeps over the corners at one step at most: a sliver's fit creeps (dev seed 13 #49 reaches
/// the bar after 9–12 sweeps at some step).
const FIT_SWEEPS: usize = 16;
/// Below this score after the coarsest step the fit stops: clutter mostly stays there, while
/// the development sets' slivers are at 1.5–1.8 by then and end at 3–4.5 (a bar of 2 lost two
/// of them).
const GIVE_UP_FIT: f64 = 1.0;

/// The fit's moves: each corner alone…
const CORNER_MOVES: &[&[usize]] = &[&[0], &[1], &[2], &[3]];
/// …and, where that falls short of [`MIN_FIT`], also each side's two corners and the whole
/// quad together.
const SIDE_MOVES: &[&[usize]] = &[
    &[0],
    &[1],
    &[2],
    &[3],
    &[0, 1],
    &[1, 2],
    &[2, 3],
    &[3, 0],
    &[0, 1, 2, 3],
];
/// The wider moves are tried only where the corners alone got two thirds of the way to
/// [`MIN_FIT`]: clutter ends below the bar either way (they lifted none of ~100 quads of clutter
/// over it on a development image and the swarmathon photographs), and there they would double
/// the fit's time.
const SIDE_MOVES_FROM: f64 = 2.0;

impl CellReader {
    /// `None` when some category is not a flat cell, the quiet zone is thinner than half a cell
    /// (nothing light to calibrate against), or the layout is not a grid.
    pub fn new(family: &Family) -> Option<Self> {
        let cell = family.cell_size();
        if !family.is_grid() || family.quiet_zone() < 0.5 * cell {
            return None;
        }
        let reader = Reader::new(family);
        let levels = (0..family.categories().len())
            .map(|c| {
                let (lo, hi) = reader.gray_range(c);
                (hi - lo <= FLAT_SPREAD).then(|| reader.mean_gray(c) / 255.0)
            })
            .collect::<Option<Vec<f64>>>()?;
        let b = family.background();
        let background = crate::image::luminance(b.0 as f32, b.1 as f32, b.2 as f32) as f64 / 255.0;
        let mut known = Vec::new();
        // Each fixed cell at four points a quarter cell in from its centre…
        for k in family.keypoints() {
            if let Assignment::Fixed(c) = k.assignment {
                for (dx, dy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    let d = 0.25 * k.size;
                    known.push(([k.pos[0] + dx * d, k.pos[1] + dy * d], levels[c]));
                }
            }
        }
        // …and the quiet zone at a third and two thirds of a cell out, every half cell.
        let extent = family.extent();
        let depth = family.quiet_zone().min(cell);
        for out in [depth / 3.0, 2.0 * depth / 3.0] {
            let ring = extent.grow(out);
            let (w, h) = (ring.width(), ring.height());
            let steps = |len: f64| ((2.0 * len / cell).round() as usize).max(1);
            for i in 0..=steps(w) {
                let x = ring.min[0] + w * i as f64 / steps(w) as f64;
                known.push(([x, ring.min[1]], background));
                known.push(([x, ring.max[1]], background));
            }
            for j in 1..steps(h) {
                let y = ring.min[1] + h * j as f64 / steps(h) as f64;
                known.push(([ring.min[0], y], background));
                known.push(([ring.max[0], y], background));
            }
        }
        let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let to_unit = Homography::from_points(&family.roi_points()[..4], &unit).ok()?;
        let level_range = levels.iter().copied().fold(f64::MIN, f64::max)
            - levels.iter().copied().fold(f64::MAX, f64::min);
        let known_unit: Vec<[f64; 2]> = known.iter().map(|&(p, _)| to_unit.apply(p)).collect();
        let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
        for p in &known_unit {
            for a in 0..2 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
        let n = known.len() as f64;
        let level_mean = known.iter().map(|k| k.1).sum::<f64>() / n;
        let level_scatter = known.iter().map(|k| (k.1 - level_mean).powi(2)).sum();
        Some(Self {
            levels,
            known,
            to_unit,
            known_unit,
            known_box: Quad([lo, [hi[0], lo[1]], hi, [lo[0], hi[1]]]),
            level_mean,
            level_scatter,
            level_range,
        })
    }

    /// Marker units → the image, for ROI points 0–3 at `roi`.
    fn to_image(&self, roi: &Quad) -> Option<Homography> {
        Some(Homography(square_to_quad(roi)? * self.to_unit.0))
    }

    /// How well the known points fit their levels with the marker at `roi`: the fitted
    /// black-to-white step over the residuals' spread (gray levels), with the fit's gain and
    /// offset. `None` off the image or where the levels do not spread.
    ///
    /// This runs for every quad of every frame fit (thousands an image), so it maps points
    /// from the unit square and sums in one pass; where the known points' box lies inside the
    /// image, no point needs its own bounds check.
    fn score(&self, image: &GrayImage, roi: &Quad) -> Option<Fitted> {
        let n = self.known.len() as f64;
        if self.level_scatter < 1e-9 * n {
            return None;
        }
        let h = square_to_quad(roi)?;
        let h = [
            h[(0, 0)],
            h[(0, 1)],
            h[(0, 2)],
            h[(1, 0)],
            h[(1, 1)],
            h[(1, 2)],
            h[(2, 0)],
            h[(2, 1)],
            h[(2, 2)],
        ];
        let map = |[u, v]: [f64; 2]| {
            let w = h[6] * u + h[7] * v + h[8];
            (
                [
                    (h[0] * u + h[1] * v + h[2]) / w,
                    (h[3] * u + h[4] * v + h[5]) / w,
                ],
                w,
            )
        };
        // The weight w is affine in (u, v), so positive at the box's corners means positive
        // over the box, whose image is then the convex quad of the corners' images.
        let (max_x, max_y) = (image.width as f64 - 2.0, image.height as f64 - 2.0);
        let inside = self.known_box.iter().all(|&c| {
            let ([x, y], w) = map(c);
            w > 0.0 && x >= 0.0 && y >= 0.0 && x <= max_x && y <= max_y
        });
        let pixels: &[u8] = &image.pixels;
        let stride = image.width as usize;
        let (mut sum_y, mut sum_xy, mut sum_yy) = (0.0, 0.0, 0.0);
        for (&u, &(_, level)) in self.known_unit.iter().zip(&self.known) {
            let (p, _) = map(u);
            let gray = if inside {
                crate::image::bilinear_inside(pixels, stride, p[0] as f32, p[1] as f32) as f64
            } else {
                sample(image, p)?
            };
            sum_y += gray;
            sum_xy += (level - self.level_mean) * gray;
            sum_yy += gray * gray;
        }
        let mean_y = sum_y / n;
        let gain = sum_xy / self.level_scatter;
        let offset = mean_y - gain * self.level_mean;
        let scatter_y = sum_yy - n * mean_y * mean_y;
        let residual = (scatter_y - gain * sum_xy).max(0.0) / n;
        Some(Fitted {
            roi: *roi,
            score: gain * self.level_range / (residual + 1.0).sqrt(),
            gain,
            offset,
        })
    }

    /// Moves the ROI's corners to where the fixed cells and the quiet zone fit their levels
    /// best (coordinate ascent, 2 px steps down to a quarter pixel). A steep sliver's cells are
    /// a pixel or two wide, and a quad traced or grouped a few pixels off samples its
    /// neighbours; the frame, which is known whatever the code, pins it down.
    fn fit(&self, image: &GrayImage, roi: &Quad) -> Option<Fitted> {
        let mut scored = ScoredQuads::default();
        let by_corners = self.ascend(image, roi, CORNER_MOVES, &mut scored)?;
        if by_corners.score >= MIN_FIT || by_corners.score < SIDE_MOVES_FROM {
            return Some(by_corners);
        }
        // One corner at a time cannot slide a sliver's tip along its length without first
        // skewing the frame off the cells (dev seed 18 #68: traced 2.4 px off, the corners stop
        // 4.4 px off at 2.1; a side or the whole quad moved at once reaches the frame at 4.3 and
        // reads with 0 corrections). The corners alone go first: with the wider moves from the
        // start, the ascent takes a shift that climbs at once and misses a quad 14 px off that
        // single corners bring in (dev seed 10 #77).
        let by_sides = self.ascend(image, roi, SIDE_MOVES, &mut scored)?;
        Some(if by_sides.score > by_corners.score {
            by_sides
        } else {
            by_corners
        })
    }

    /// Coordinate ascent of the fit from `roi`, each trial moving the corners of one of `moves`
    /// together by one step along one axis. `scored` holds the quads scored before (by this
    /// ascent or another from the same ROI).
    fn ascend(
        &self,
        image: &GrayImage,
        roi: &Quad,
        moves: &[&[usize]],
        scored: &mut ScoredQuads,
    ) -> Option<Fitted> {
        let mut best = scored.score(roi, |quad| self.score(image, quad))?;
        for (round, step) in FIT_STEPS.into_iter().enumerate() {
            // A quad that the coarsest step leaves far from fitting sits on clutter, or too far
            // from a marker to be pulled in: the finer steps are not spent on it.
            if round == 1 && best.score < GIVE_UP_FIT {
                return Some(best);
            }
            for _ in 0..FIT_SWEEPS {
                let mut moved = false;
                for &corners in moves {
                    for axis in 0..2 {
                        for sign in [-1.0, 1.0] {
                            let mut trial = best.roi;
                            for &corner in corners {
                                trial[corner][axis] += sign * step;
                            }
                            let too_far = corners.iter().any(|&corner| {
                                let [dx, dy] = [
                                    trial[corner][0] - roi[corner][0],
                                    trial[corner][1] - roi[corner][1],
                                ];
                                dx.hypot(dy) > MAX_FIT_SHIFT
                            });
                            if too_far {
                                continue;
                            }
                            if let Some(fitted) =
                                scored.score(&trial, |quad| self.score(image, quad))
                            {
                                if fitted.score > best.score {
                                    (best, moved) = (fitted, true);
                                }
                            }
                        }
                    }
                }
                if !moved {
                    break;
                }
            }
        }
        Some(best)
    }

    /// Reads the marker in `roi` (the family's first four ROI points in the image), once its
    /// corners are fitted to the frame, accepting at most `max_errors` corrected symbols.
    pub fn read(
        &self,
        family: &Family,
        image: &GrayImage,
        roi: &Quad,
        max_errors: usize,
    ) -> Option<CellRead> {
        match self.read_or_frame(family, image, roi, max_errors) {
            CellOutcome::Read(read) => Some(read),
            CellOutcome::Framed(_) | CellOutcome::Unfit => None,
        }
    }

    /// [`CellReader::read`], saying on a failed read whether the frame fitted.
    fn read_or_frame(
        &self,
        family: &Family,
        image: &GrayImage,
        roi: &Quad,
        max_errors: usize,
    ) -> CellOutcome {
        self.read_fitted(family, image, self.frame(image, roi).as_ref(), max_errors)
    }

    /// The frame fitted from `roi`, where it fits well enough to read cells from; the part of
    /// a read that readers of one frame ([`CellReader::same_frame`]) share.
    pub fn frame(&self, image: &GrayImage, roi: &Quad) -> Option<Fitted> {
        self.fit(image, roi).filter(|f| f.score >= MIN_FIT)
    }

    /// The read of the cells in a frame [`CellReader::frame`] fitted (`None`: it did not fit).
    pub fn read_fitted(
        &self,
        family: &Family,
        image: &GrayImage,
        fitted: Option<&Fitted>,
        max_errors: usize,
    ) -> CellOutcome {
        let Some(fitted) = fitted else {
            return CellOutcome::Unfit;
        };
        match self.read_cells(family, image, fitted, max_errors) {
            Some(read) => CellOutcome::Read(read),
            None => CellOutcome::Framed(fitted.roi),
        }
    }

    /// Whether `other`'s frame fit is this one's: the same known points at the same levels
    /// and ROI (families of one layout, such as AprilTag 36h11 and ArUco 6x6_250, differ only
    /// in their codes), so one fit serves both.
    pub fn same_frame(&self, other: &CellReader) -> bool {
        self.known == other.known
            && self.to_unit.0 == other.to_unit.0
            && self.level_range == other.level_range
    }

    fn read_cells(
        &self,
        family: &Family,
        image: &GrayImage,
        fitted: &Fitted,
        max_errors: usize,
    ) -> Option<CellRead> {
        let Fitted {
            roi,
            score: fit,
            gain,
            offset,
        } = *fitted;
        let to_image = self.to_image(&roi)?;
        let keypoints = family.keypoints();
        let centres: Vec<[f64; 2]> = keypoints.iter().map(|k| to_image.apply(k.pos)).collect();
        let values = centres
            .iter()
            .map(|&p| sample(image, p))
            .collect::<Option<Vec<f64>>>()?;
        let (observed, margins): (Vec<usize>, Vec<f64>) = values
            .iter()
            .zip(keypoints)
            .map(|(&v, k)| {
                let level = (v - offset) / gain;
                // A code cell takes the nearest symbol category; a fixed cell the nearest of
                // all, so that a wrong frame counts as a mismatch.
                let mut by_distance: Vec<(f64, usize)> = (0..self.levels.len())
                    .filter(|&c| match k.assignment {
                        Assignment::Symbol(_) => family.category_symbol(c).is_some(),
                        Assignment::Fixed(_) => true,
                    })
                    .map(|c| ((self.levels[c] - level).abs(), c))
                    .collect();
                by_distance.sort_by(|a, b| a.0.total_cmp(&b.0));
                let best = by_distance[0].0;
                // Categories drawn alike (a frame's own black and the code's) tie: a fixed
                // cell then takes its own.
                let category = match k.assignment {
                    Assignment::Fixed(c) if (self.levels[c] - level).abs() <= best + 1e-9 => c,
                    _ => by_distance[0].1,
                };
                let margin = by_distance
                    .iter()
                    .find(|(d, _)| *d > best + 1e-9)
                    .map_or(1.0, |&(next, _)| (next - best) / (next + best).max(1e-9));
                (category, margin)
            })
            .unzip();
        let read: Vec<Option<usize>> = observed.iter().map(|&c| Some(c)).collect();
        let decoded = decode(family, &read, Some(max_errors))?;
        Some(CellRead {
            decoded,
            observed,
            centres,
            margins,
            roi,
            fit,
        })
    }
}

/// Bilinear gray level at an image point; `None` outside the image.
fn sample(image: &GrayImage, [x, y]: [f64; 2]) -> Option<f64> {
    let inside =
        x >= 0.0 && y >= 0.0 && x <= (image.width - 1) as f64 && y <= (image.height - 1) as f64;
    inside.then(|| image.sample(x as f32, y as f32) as f64)
}

/// The homography taking the unit square's corners (0,0), (1,0), (1,1), (0,1) to `quad`'s, in
/// closed form (Heckbert 1989): the fit evaluates hundreds of quads per ROI, and a DLT's SVD
/// for each cost more than the sampling. `None` for a degenerate quad.
pub(super) fn square_to_quad(quad: &Quad) -> Option<nalgebra::Matrix3<f64>> {
    let [[x0, y0], [x1, y1], [x2, y2], [x3, y3]] = quad.0;
    let (dx1, dx2, dx3) = (x1 - x2, x3 - x2, x0 - x1 + x2 - x3);
    let (dy1, dy2, dy3) = (y1 - y2, y3 - y2, y0 - y1 + y2 - y3);
    let den = dx1 * dy2 - dx2 * dy1;
    if den.abs() < 1e-12 {
        return None;
    }
    let g = (dx3 * dy2 - dx2 * dy3) / den;
    let h = (dx1 * dy3 - dx3 * dy1) / den;
    Some(nalgebra::Matrix3::new(
        x1 - x0 + g * x1,
        x3 - x0 + h * x3,
        x0,
        y1 - y0 + g * y1,
        y3 - y0 + h * y3,
        y0,
        g,
        h,
        1.0,
    ))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    fn family(name: &str) -> Family {
        crate::builtin::get(name).unwrap().unwrap()
    }

    #[test]
    fn families_of_one_layout_share_a_frame_fit_and_others_do_not() {
        let reader = |name: &str| CellReader::new(&family(name)).unwrap();
        let april = reader("apriltag-36h11");
        assert!(april.same_frame(&reader("aruco-6x6_250")));
        assert!(april.same_frame(&reader("artoolkitplus-bch")));
        assert!(!april.same_frame(&reader("apriltag-16h5")));
        assert!(!april.same_frame(&reader("aruco-4x4_50")));
    }

    #[test]
    fn flat_celled_families_are_read_and_glyph_families_are_not() {
        assert!(CellReader::new(&family("apriltag-36h11")).is_some());
        assert!(CellReader::new(&family("aruco-6x6_250")).is_some());
        assert!(CellReader::new(&family("apriltag-xo-36h11")).is_none());
    }

    /// A 36h11 marker (ID 111) 80 cm away at 60°, 13 px across (`tagsmith eval generate
    /// apriltag-36h11 --seed 13`, image 76, cut at x 690–790, y 200–260), and the quad traced
    /// around it, 1–2 px off at every corner: stage 2 reads nothing from that quad.
    pub(in crate::detect) const SLIVER: &[u8] = include_bytes!("testdata/sliver-80cm-60deg.png");
    pub(in crate::detect) const SLIVER_TRUTH: Quad =
        Quad([[31.5, 22.5], [75.7, 27.9], [65.6, 35.4], [19.1, 29.5]]);
    pub(in crate::detect) const SLIVER_TRACED: Quad =
        Quad([[31.8, 21.8], [73.8, 29.5], [67.7, 33.6], [18.8, 30.1]]);

    #[test]
    fn a_sliver_traced_a_pixel_or_two_off_is_fitted_to_its_frame_and_read() {
        let family = family("apriltag-36h11");
        let image = crate::image::decode(SLIVER, &Default::default()).unwrap();
        let reader = CellReader::new(&family).unwrap();
        let unfitted = reader.score(&image, &SLIVER_TRACED).unwrap().score;
        assert!(
            unfitted < MIN_FIT,
            "the traced quad already fits: {unfitted}"
        );
        let read = reader
            .read(&family, &image, &SLIVER_TRACED, 2)
            .expect("read");
        assert_eq!(read.decoded.id, 111);
        assert!(read.decoded.corrected_errors <= 1, "{read:?}");
        // Within a quarter of a cell along the marker's long sides (cells 4–5 px long there).
        for (got, truth) in read.roi.iter().zip(SLIVER_TRUTH.0) {
            let off = (got[0] - truth[0]).hypot(got[1] - truth[1]);
            assert!(off < 1.25, "{:?} vs {SLIVER_TRUTH:?}", read.roi);
        }
    }

    /// A 36h11 marker (ID 328) 70 cm away at 70°, 8 px across and 55 px long (`tagsmith eval
    /// generate apriltag-36h11 --seed 18`, image 68, cut at x 760–880, y 310–375), and the quad
    /// traced around it, 2.4 px off along its length.
    pub(in crate::detect) const FLAT_SLIVER: &[u8] =
        include_bytes!("testdata/sliver-70cm-70deg.png");
    pub(in crate::detect) const FLAT_SLIVER_TRUTH: Quad = Quad([
        [27.10, 27.94],
        [78.68, 29.27],
        [85.02, 37.44],
        [29.67, 35.92],
    ]);
    pub(in crate::detect) const FLAT_SLIVER_TRACED: Quad = Quad([
        [26.60, 28.68],
        [78.41, 29.69],
        [83.64, 35.42],
        [30.58, 35.90],
    ]);

    #[test]
    fn the_fit_scores_each_quad_it_tries_once() {
        let family = family("apriltag-36h11");
        let image = crate::image::decode(FLAT_SLIVER, &Default::default()).unwrap();
        let reader = CellReader::new(&family).unwrap();
        let mut scored = ScoredQuads::default();
        let calls = std::cell::Cell::new(0);
        let mut score = |quad: &Quad| {
            scored.score(quad, |q| {
                calls.set(calls.get() + 1);
                reader.score(&image, q)
            })
        };
        let first = score(&FLAT_SLIVER_TRACED);
        let mut moved = FLAT_SLIVER_TRACED;
        moved[2][0] += 0.25;
        let other = score(&moved);
        assert_eq!(score(&FLAT_SLIVER_TRACED), first);
        assert_eq!(score(&moved), other);
        assert_ne!(first, other);
        assert_eq!(calls.get(), 2);
    }

    #[test]
    fn a_sliver_whose_corners_alone_stall_is_fitted_by_moving_its_sides() {
        let family = family("apriltag-36h11");
        let image = crate::image::decode(FLAT_SLIVER, &Default::default()).unwrap();
        let reader = CellReader::new(&family).unwrap();
        let by_corners = reader
            .ascend(
                &image,
                &FLAT_SLIVER_TRACED,
                CORNER_MOVES,
                &mut ScoredQuads::default(),
            )
            .unwrap();
        assert!(
            by_corners.score < MIN_FIT,
            "the corners alone fit: {by_corners:?}"
        );
        let read = reader
            .read(&family, &image, &FLAT_SLIVER_TRACED, 2)
            .expect("read");
        assert_eq!(read.decoded.id, 328);
        assert!(read.decoded.corrected_errors <= 1, "{read:?}");
        for (got, truth) in read.roi.iter().zip(FLAT_SLIVER_TRUTH.0) {
            let off = (got[0] - truth[0]).hypot(got[1] - truth[1]);
            assert!(off < 2.0, "{:?} vs {FLAT_SLIVER_TRUTH:?}", read.roi);
        }
    }

    #[test]
    fn gray_ground_beside_a_marker_is_not_read() {
        let family = family("apriltag-36h11");
        let image = crate::image::decode(SLIVER, &Default::default()).unwrap();
        let reader = CellReader::new(&family).unwrap();
        let beside = SLIVER_TRACED.map(|[x, y]| [x - 15.0, y + 18.0]);
        assert!(reader.read(&family, &image, &beside, 2).is_none());
    }

    #[test]
    fn the_closed_form_square_to_quad_agrees_with_the_dlt() {
        let quad = [[10.0, 20.0], [50.0, 25.0], [45.0, 70.0], [5.0, 60.0]];
        let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let closed = Homography(square_to_quad(&Quad(quad)).unwrap());
        let dlt = Homography::from_points(&unit, &quad).unwrap();
        for p in [[0.0, 0.0], [1.0, 1.0], [0.3, 0.8], [0.5, 0.5]] {
            let (a, b) = (closed.apply(p), dlt.apply(p));
            assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9, "{a:?} vs {b:?}");
        }
        assert!(square_to_quad(&Quad([[0.0, 0.0]; 4])).is_none());
    }

    /// The score by its definition: each known point mapped through the ROI's homography and
    /// sampled with bounds checks, the line fitted in two passes, the residuals summed.
    fn score_by_definition(reader: &CellReader, image: &GrayImage, roi: &Quad) -> f64 {
        let to_image = reader.to_image(roi).unwrap();
        let pairs: Vec<(f64, f64)> = (reader.known.iter())
            .map(|&(p, level)| (level, sample(image, to_image.apply(p)).unwrap()))
            .collect();
        let n = pairs.len() as f64;
        let mx = pairs.iter().map(|p| p.0).sum::<f64>() / n;
        let my = pairs.iter().map(|p| p.1).sum::<f64>() / n;
        let sxx: f64 = pairs.iter().map(|p| (p.0 - mx).powi(2)).sum();
        let sxy: f64 = pairs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let gain = sxy / sxx;
        let offset = my - gain * mx;
        let residual = (pairs.iter())
            .map(|&(x, y)| (y - gain * x - offset).powi(2))
            .sum::<f64>()
            / n;
        gain * reader.level_range / (residual + 1.0).sqrt()
    }

    #[test]
    fn the_fast_score_is_the_score_by_definition_inside_and_at_the_edge_of_the_image() {
        let reader = CellReader::new(&family("apriltag-36h11")).unwrap();
        let image = crate::image::decode(SLIVER, &Default::default()).unwrap();
        // The true quad lies well inside; moved right until its rightmost quiet-zone sample
        // lies within the image's last pixel, it is scored through the checked samples.
        let to_image = reader.to_image(&SLIVER_TRUTH).unwrap();
        let rightmost = (reader.known.iter())
            .map(|&(p, _)| to_image.apply(p)[0])
            .fold(f64::MIN, f64::max);
        let shift = image.width as f64 - 1.5 - rightmost;
        let at_edge = SLIVER_TRUTH.map(|[x, y]| [x + shift, y]);
        for roi in [SLIVER_TRUTH, SLIVER_TRACED, at_edge] {
            let fast = reader.score(&image, &roi).unwrap().score;
            let defined = score_by_definition(&reader, &image, &roi);
            assert!(
                (fast - defined).abs() < 1e-9 * defined.abs().max(1.0),
                "{fast} vs {defined}"
            );
        }
        let off_image = SLIVER_TRUTH.map(|[x, y]| [x - 30.0, y]);
        assert!(reader.score(&image, &off_image).is_none());
    }
}
