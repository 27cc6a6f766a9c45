//! A test, a few hundred samples long, that a quad could frame one of a family's markers, run
//! before stage 2 spends a pass on it (docs/ARCHITECTURE.md §9.8, "Pre-read check"). The image
//! searches trace every dark convex blob the network's mask touches, and on the 640×480 speed
//! set those quads took 270 of the 381 stage-2 first passes for one read: a blob of clutter is
//! dark inside as on its rim, while a marker's inside holds some of its light cells.
//!
//! The check samples the quad's surroundings, its rim and its inside through the quad's
//! homography, and asks for what the family's own rendering shows: a rim darker than the
//! surroundings, and at least half the share of the inside that the family's darkest codes
//! leave on the surroundings' side.

use super::cells::square_to_quad;
use crate::family::Family;
use crate::geometry::{Homography, Quad};
use crate::image::GrayImage;
use crate::render::readback::Reader;
use crate::render::template::{rectified_template, template_corners};

/// The sampling grid's step, in ROI units (ROI points 0–3 at the unit square's corners). The
/// grid runs in rings around the ROI's rim, so every sample is a whole number of steps from it.
const STEP: f64 = 0.05;
/// Rings sampled outside the ROI (0.05 and 0.1 of the side out): within one cell of quiet zone
/// on grids of up to 10 cells, the frame included.
const OUTSIDE_RINGS: usize = 2;
/// Rings of the rim (0.05 and 0.1 in): within a frame of one cell on grids of up to 10 cells
/// (36h11's is 0.125 of the side).
const RIM_RINGS: usize = 2;
/// The inside starts this many rings in (0.2 of the side): past the frame and its blur.
const INSIDE_RING: usize = 4;
/// The least step from the surroundings to the rim, gray levels, that a marker in an image
/// shows. The development sets' quads that stage 2 read from the traced searches stepped by 48
/// at least (seed 40's 24 reads, 92 at least; the speed sets' two, 48 and ~100); clutter's
/// median is 27–35.
const MIN_STEP: f64 = 30.0;
/// The rendering's step must be at least this for the check to apply: a family whose ROI does
/// not sit on a dark frame is not checked.
const MIN_RENDERED_STEP: f64 = 100.0;
/// The share of the inside asked for, as a fraction of the darkest rendered codes' least share:
/// blur, noise and a ROI a few pixels off move light samples to the rim's side.
const SHARE_FRACTION: f64 = 0.5;
/// Codes rendered to find the least share: the darkest by their cells' mean gray. The share
/// follows the cells' gray closely, and a few renderings keep the detector's start-up short
/// (each takes about a millisecond; 36h11 has 587 codes).
const DARKEST_CODES: usize = 3;
/// Rendered template size, pixels: 67 px across the ROI, 5–8 px a cell on the built-in grids,
/// so each sample falls well inside its cell.
const TEMPLATE_PX: u32 = 96;

/// What a quad is asked for, derived from one family's rendering.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreCheck {
    /// The least share of the inside on the surroundings' side of the midway gray.
    min_share: f64,
}

/// A quad's samples, summarised: one per quad, whatever the families checked against it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuadSample {
    /// Median gray of the surroundings and of the rim.
    around: f64,
    rim: f64,
    /// Share of the inside's samples on the surroundings' side of the gray midway between them.
    share: f64,
}

impl PreCheck {
    /// `None` where the family's rendering shows no dark frame on lighter surroundings at the
    /// ROI (the traced searches outline dark blobs; a ROI inside a ring or on no frame is not
    /// theirs to find), or its darkest codes are too dark inside for the share to tell them
    /// from a blob.
    pub fn new(family: &Family) -> Option<Self> {
        let ids = darkest_codes(family, DARKEST_CODES);
        if ids.is_empty() {
            return None;
        }
        let mut min_share = f64::MAX;
        for id in ids {
            let s = rendered(family, id)?;
            if s.around - s.rim < MIN_RENDERED_STEP {
                return None;
            }
            min_share = min_share.min(s.share);
        }
        let min_share = SHARE_FRACTION * min_share;
        // A share this small is a few samples: noise would pass clutter and fail markers alike.
        (min_share >= 0.05).then_some(Self { min_share })
    }

    /// Whether a quad sampled as `sample` may hold one of the family's markers (a quad that
    /// could not be sampled gets no verdict and goes on).
    pub fn passes(&self, sample: Option<&QuadSample>) -> bool {
        sample.is_none_or(|s| s.around - s.rim >= MIN_STEP && s.share >= self.min_share)
    }

    /// The inside's half of [`PreCheck::passes`] alone, for a quad whose corners are still to
    /// be fitted to the frame (cell reads): a quad a few pixels off samples the quiet zone as
    /// rim, so its step may not show (dev seed 40: a cell read from a quad stepping 13 gray
    /// levels), while its inside still holds the light cells.
    pub fn has_light_inside(&self, sample: Option<&QuadSample>) -> bool {
        sample.is_none_or(|s| s.share >= self.min_share)
    }
}

/// The IDs of the `n` codes whose cells are darkest on average.
fn darkest_codes(family: &Family, n: usize) -> Vec<usize> {
    if !family.is_grid() || family.roi_points().len() < 4 {
        return Vec::new();
    }
    let reader = Reader::new(family);
    let gray: Vec<f64> = (0..family.categories().len())
        .map(|c| reader.mean_gray(c))
        .collect();
    let mut by_gray: Vec<(f64, usize)> = (0..family.codebook().len())
        .filter_map(|id| {
            let cats = family.keypoint_categories(id)?;
            Some((cats.iter().map(|&c| gray[c]).sum::<f64>(), id))
        })
        .collect();
    by_gray.sort_by(|a, b| a.0.total_cmp(&b.0));
    by_gray.into_iter().take(n).map(|(_, id)| id).collect()
}

/// Code `id` rendered and rectified as stage 2 sees it, sampled at its ROI.
fn rendered(family: &Family, id: usize) -> Option<QuadSample> {
    let template = rectified_template(family, id, TEMPLATE_PX).ok()?;
    // The template's ROI square, in pixel-centre coordinates (see `rectified_template`).
    let corners =
        template_corners(TEMPLATE_PX, family.spec().roi.margin).map(|[x, y]| [x - 0.5, y - 0.5]);
    QuadSample::of(&template, &corners)
}

impl QuadSample {
    /// The samples of the quad `corners` (ROI points 0–3) in `image`; `None` for a degenerate
    /// quad or one whose surroundings reach past its horizon (a view so steep that the grid
    /// would fold back).
    pub fn of(image: &GrayImage, corners: &Quad) -> Option<Self> {
        let to_image = Homography(square_to_quad(corners)?);
        let n = 2 * OUTSIDE_RINGS + (1.0 / STEP).round() as usize;
        let unit = |i: usize| (i as f64 - OUTSIDE_RINGS as f64) * STEP;
        let h = &to_image.0;
        let w = |u: f64, v: f64| h[(2, 0)] * u + h[(2, 1)] * v + h[(2, 2)];
        // w is affine in (u, v): positive at the grid's four corners, positive all over.
        let (lo, hi) = (unit(0), unit(n));
        if [(lo, lo), (hi, lo), (hi, hi), (lo, hi)]
            .iter()
            .any(|&(u, v)| w(u, v) <= 1e-9)
        {
            return None;
        }
        let (mut around, mut rim, mut inside) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..=n {
            for j in 0..=n {
                // Rings from the grid's edge; the ROI's rim is ring OUTSIDE_RINGS.
                let ring = i.min(j).min(n - i).min(n - j);
                let samples = if ring < OUTSIDE_RINGS {
                    &mut around
                } else if ring > OUTSIDE_RINGS && ring <= OUTSIDE_RINGS + RIM_RINGS {
                    &mut rim
                } else if ring >= OUTSIDE_RINGS + INSIDE_RING {
                    &mut inside
                } else {
                    continue;
                };
                let [x, y] = to_image.apply([unit(i), unit(j)]);
                samples.push(image.sample(x as f32, y as f32) as f64);
            }
        }
        let (around, rim) = (median(&mut around)?, median(&mut rim)?);
        let midway = 0.5 * (around + rim);
        let towards_around = inside
            .iter()
            .filter(|&&g| (g - midway) * (around - rim) > 0.0)
            .count();
        Some(Self {
            around,
            rim,
            share: towards_around as f64 / inside.len().max(1) as f64,
        })
    }
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mid = values.len() / 2;
    Some(*values.select_nth_unstable_by(mid, f64::total_cmp).1)
}

#[cfg(test)]
mod tests {
    use super::super::cells::tests::{
        FLAT_SLIVER, FLAT_SLIVER_TRACED, FLAT_SLIVER_TRUTH, SLIVER, SLIVER_TRACED, SLIVER_TRUTH,
    };
    use super::*;

    fn builtin(name: &str) -> Option<Family> {
        crate::builtin::get(name).map(Result::unwrap)
    }

    fn square(x: f64, y: f64, side: f64) -> Quad {
        Quad([[x, y], [x + side, y], [x + side, y + side], [x, y + side]])
    }

    fn fill(image: &mut GrayImage, corners: &Quad, gray: u8) {
        let [x0, y0] = corners[0];
        let [x1, y1] = corners[2];
        for y in y0 as u32..y1 as u32 {
            for x in x0 as u32..x1 as u32 {
                image.pixels[(y * image.width + x) as usize] = gray;
            }
        }
    }

    fn template_roi(family: &Family) -> Quad {
        template_corners(TEMPLATE_PX, family.spec().roi.margin).map(|[x, y]| [x - 0.5, y - 0.5])
    }

    #[test]
    fn a_rendered_marker_passes_and_a_dark_blob_does_not() {
        let family = builtin("apriltag-36h11").unwrap();
        let check = PreCheck::new(&family).expect("36h11 has a dark frame on a light zone");
        let template = rectified_template(&family, 7, TEMPLATE_PX).unwrap();
        let roi = template_roi(&family);
        assert!(check.passes(QuadSample::of(&template, &roi).as_ref()));
        // The marker's quad 3 px off to one side: the rim is muddled, the light cells are in.
        let shifted = roi.map(|[x, y]| [x + 3.0, y]);
        assert!(check.has_light_inside(QuadSample::of(&template, &shifted).as_ref()));
        // A dark square on light ground, and a flat gray square: no light inside, no step.
        let mut image = GrayImage::new(120, 120, 210);
        let blob = square(30.0, 30.0, 60.0);
        fill(&mut image, &blob, 30);
        let sample = QuadSample::of(&image, &blob);
        assert!(!check.passes(sample.as_ref()));
        assert!(!check.has_light_inside(sample.as_ref()));
        let flat = GrayImage::new(120, 120, 128);
        assert!(!check.passes(QuadSample::of(&flat, &blob).as_ref()));
    }

    /// The far slivers the cell reads and the edge fits are for (13 and 8 px across): their
    /// true quads pass, and the quads traced 1–2.4 px off still show light inside.
    #[test]
    fn far_slivers_pass_from_their_true_and_their_traced_quads() {
        let check = PreCheck::new(&builtin("apriltag-36h11").unwrap()).unwrap();
        for (png, truth, traced) in [
            (SLIVER, SLIVER_TRUTH, SLIVER_TRACED),
            (FLAT_SLIVER, FLAT_SLIVER_TRUTH, FLAT_SLIVER_TRACED),
        ] {
            let image = crate::image::decode(png, &Default::default()).unwrap();
            let sample = QuadSample::of(&image, &truth);
            assert!(check.passes(sample.as_ref()), "{sample:?}");
            let sample = QuadSample::of(&image, &traced);
            assert!(check.has_light_inside(sample.as_ref()), "{sample:?}");
        }
    }

    #[test]
    fn every_code_of_the_shipped_square_families_passes_its_check() {
        for name in ["apriltag-36h11", "aruco-6x6_250", "apriltag-xo-36h11"] {
            let family = builtin(name).unwrap();
            let check = PreCheck::new(&family).unwrap();
            let roi = template_roi(&family);
            for id in 0..family.codebook().len() {
                let template = rectified_template(&family, id, TEMPLATE_PX).unwrap();
                let sample = QuadSample::of(&template, &roi);
                assert!(check.passes(sample.as_ref()), "{name} #{id}: {sample:?}");
            }
        }
    }

    #[test]
    fn built_in_families_framed_in_black_on_white_are_checked() {
        let checked: Vec<&str> = crate::builtin::names()
            .filter(|n| PreCheck::new(&builtin(n).unwrap()).is_some())
            .collect();
        for name in [
            "apriltag-16h5",
            "apriltag-36h11",
            "apriltag-xo-36h11",
            "aruco-4x4_50",
            "aruco-6x6_250",
        ] {
            assert!(checked.contains(&name), "{name} is not checked");
        }
        // Ring families have no square ROI; AprilTag 41h12's ROI lies inside its black ring.
        for name in ["runetag", "apriltag-standard41h12"] {
            assert!(!checked.contains(&name), "{name} is checked");
        }
    }

    /// The verify phase's check, asked of what a photograph shows: a marker of every shipped
    /// family and of a random square design passes; a checkerboard, the commonest square clutter
    /// of calibration scenes, does not.
    #[test]
    fn markers_of_every_shipped_family_and_a_random_design_pass_and_a_checkerboard_does_not() {
        let mut pick = {
            let mut state = 7usize;
            move |n: usize| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (state >> 33) % n
            }
        };
        let random = Family::from_spec(crate::family::designs::random_square(3, &mut pick))
            .expect("a random square design is a valid family");
        let mut families: Vec<Family> = ["apriltag-36h11", "aruco-6x6_250", "apriltag-xo-36h11"]
            .iter()
            .map(|n| builtin(n).unwrap())
            .collect();
        families.push(random);
        let mut board = GrayImage::new(200, 200, 215);
        let cell = 20.0;
        for j in 0..8 {
            for i in 0..8 {
                if (i + j) % 2 == 0 {
                    let corner = square(20.0 + i as f64 * cell, 20.0 + j as f64 * cell, cell);
                    fill(&mut board, &corner, 35);
                }
            }
        }
        for family in &families {
            let check = PreCheck::new(family).expect("framed in black on white");
            let roi = template_roi(family);
            let template = rectified_template(family, 1, TEMPLATE_PX).unwrap();
            let sample = QuadSample::of(&template, &roi);
            assert!(
                check.passes(sample.as_ref()),
                "{}: {sample:?}",
                family.name()
            );
            // The whole board, and quads of 4 × 4 and 6 × 6 of its squares.
            for quad in [
                square(20.0, 20.0, 160.0),
                square(40.0, 40.0, 80.0),
                square(40.0, 40.0, 120.0),
            ] {
                let sample = QuadSample::of(&board, &quad);
                assert!(
                    !check.passes(sample.as_ref()),
                    "{}: {sample:?}",
                    family.name()
                );
            }
        }
    }

    #[test]
    fn a_family_too_dark_inside_to_tell_from_a_blob_is_not_checked() {
        // TopoTag-like: a dark ground up to the rim, with a few light dots inside.
        let family = builtin("topotag-like").unwrap();
        let id = darkest_codes(&family, 1)[0];
        let s = rendered(&family, id).expect("renders");
        assert!(s.around - s.rim >= MIN_RENDERED_STEP, "{s:?}");
        assert!(SHARE_FRACTION * s.share < 0.05, "{s:?}");
        assert_eq!(PreCheck::new(&family), None);
    }
}
