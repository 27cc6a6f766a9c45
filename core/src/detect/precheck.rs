//! A test, a few hundred samples long, that a quad could frame one of a family's markers, run
//! before stage 2 spends a pass on it (docs/ARCHITECTURE.md §9.8, "Pre-read check"). The image
//! searches trace every dark convex blob the network's mask touches, and on the 640×480 speed
//! set those quads took 270 of the 381 stage-2 first passes for one read: a blob of clutter is
//! dark inside as on its rim, while a marker's inside holds some of its light cells.
//!
//! The check samples the quad's surroundings, its rim and its inside through the quad's
//! homography, and asks for what the family's own rendering shows: the rim stepping away from
//! the surroundings (dark frame on a light quiet zone, or the reverse), and at least half the
//! share of the inside that the family's darkest codes leave on the surroundings' side.

use crate::family::Family;
use crate::geometry::Homography;
use crate::image::{bilinear, GrayImage};
use crate::render::readback::Reader;
use crate::render::template::{rectified_template, template_corners};

/// The sampling grid, in ROI units (ROI points 0–3 at the unit square's corners): from
/// −[`OUTSIDE`] to 1 + [`OUTSIDE`] in steps of [`STEP`] along both axes.
const STEP: f64 = 0.05;
/// How far outside the ROI the surroundings are sampled. Within every built-in square family's
/// rendering (1 cell of quiet zone on 6–9 cells: 0.11–0.17 of the side) and inside the rectified
/// template's margin (0.21 of the side).
const OUTSIDE: f64 = 0.15;
/// The rim: samples less than this far inside the ROI (a 36h11 frame cell is 0.125).
const RIM: f64 = 0.1;
/// The inside: samples more than this far inside the ROI.
const INSIDE: f64 = 0.2;
/// The least step from the surroundings to the rim, gray levels, that a marker in an image
/// shows. The development sets' quads that stage 2 read from the traced searches stepped by 48
/// at least (seed 40's 24 reads, 92 at least; the speed sets' two, 48 and ~100); clutter's
/// median is 27–35.
const MIN_STEP: f64 = 30.0;
/// The rendering's step must be at least this for the check to apply: a family whose ROI does
/// not sit on a contrasting frame is not checked.
const MIN_RENDERED_STEP: f64 = 100.0;
/// The share of the inside asked for, as a fraction of the darkest rendered codes' least share:
/// blur, noise and a ROI a few pixels off move light samples to the rim's side.
const SHARE_FRACTION: f64 = 0.5;
/// Codes rendered to find the least share: the darkest by their cells' mean gray.
const DARKEST_CODES: usize = 3;
/// Rendered template size, pixels.
const TEMPLATE_PX: u32 = 96;

/// What a quad is asked for, derived from one family's rendering.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreCheck {
    /// +1 where the surroundings are lighter than the rim, −1 where darker.
    polarity: f64,
    /// The least share of the inside on the surroundings' side of the midway gray.
    min_share: f64,
}

/// A quad's samples, summarised.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sampled {
    /// Median gray of the surroundings and of the rim.
    around: f64,
    rim: f64,
    /// Share of the inside's samples on the surroundings' side of the gray midway between them.
    share: f64,
}

impl PreCheck {
    /// `None` where the family's rendering shows no frame to check (glyph-free insides are
    /// fine; a ROI inside a lighter or unframed ring is not), or its darkest codes are too dark
    /// inside for the share to tell them from a blob.
    pub fn new(family: &Family) -> Option<Self> {
        if !family.is_grid() || family.roi_points().len() < 4 {
            return None;
        }
        let reader = Reader::new(family);
        let gray: Vec<f64> = (0..family.categories().len())
            .map(|c| reader.mean_gray(c))
            .collect();
        let mut by_darkness: Vec<(f64, usize)> = (0..family.codebook().len())
            .filter_map(|id| {
                let cats = family.keypoint_categories(id)?;
                Some((cats.iter().map(|&c| gray[c]).sum::<f64>(), id))
            })
            .collect();
        by_darkness.sort_by(|a, b| a.0.total_cmp(&b.0));
        let margin = family.spec().roi.margin;
        let corners = template_corners(TEMPLATE_PX, margin).map(|[x, y]| [x - 0.5, y - 0.5]);
        let mut polarity = 0.0;
        let mut min_share = f64::MAX;
        for &(_, id) in by_darkness.iter().take(DARKEST_CODES) {
            let template = rectified_template(family, id, TEMPLATE_PX).ok()?;
            let s = sample(&template, &corners)?;
            let step = s.around - s.rim;
            if step.abs() < MIN_RENDERED_STEP || (polarity != 0.0 && step.signum() != polarity) {
                return None;
            }
            polarity = step.signum();
            min_share = min_share.min(s.share);
        }
        let min_share = SHARE_FRACTION * min_share;
        // A share this small is a few samples: noise would pass clutter and fail markers alike.
        (polarity != 0.0 && min_share >= 0.05).then_some(Self {
            polarity,
            min_share,
        })
    }

    /// Whether the quad (ROI points 0–3 in `image`) may hold one of the family's markers.
    pub fn passes(&self, image: &GrayImage, corners: &[[f64; 2]; 4]) -> bool {
        let Some(s) = sample(image, corners) else {
            return true;
        };
        self.polarity * (s.around - s.rim) >= MIN_STEP && s.share >= self.min_share
    }

    /// The inside's half of [`PreCheck::passes`] alone, for a quad whose corners are still to
    /// be fitted to the frame (cell reads): a quad a few pixels off samples the quiet zone as
    /// rim, so its step may not show (dev seed 40: a cell read from a quad stepping 13 gray
    /// levels), while its inside still holds the light cells.
    pub fn has_light_inside(&self, image: &GrayImage, corners: &[[f64; 2]; 4]) -> bool {
        sample(image, corners).is_none_or(|s| s.share >= self.min_share)
    }
}

/// The samples of the quad `corners` in `image`; `None` for a degenerate quad.
fn sample(image: &GrayImage, corners: &[[f64; 2]; 4]) -> Option<Sampled> {
    let unit = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let to_image = Homography::from_points(&unit, corners).ok()?;
    let (mut around, mut rim, mut inside) = (Vec::new(), Vec::new(), Vec::new());
    let n = ((1.0 + 2.0 * OUTSIDE) / STEP).round() as usize;
    for i in 0..=n {
        for j in 0..=n {
            let (u, v) = (-OUTSIDE + STEP * i as f64, -OUTSIDE + STEP * j as f64);
            // Signed depth inside the ROI: negative outside it.
            let depth = u.min(v).min(1.0 - u).min(1.0 - v);
            let samples = if depth < -0.01 {
                &mut around
            } else if depth > 0.01 && depth < RIM {
                &mut rim
            } else if depth > INSIDE {
                &mut inside
            } else {
                continue;
            };
            let [x, y] = to_image.apply([u, v]);
            if !x.is_finite() || !y.is_finite() {
                return None;
            }
            let px = &image.pixels;
            samples.push(
                bilinear(image.width, image.height, x as f32, y as f32, |k| {
                    px[k] as f32
                }) as f64,
            );
        }
    }
    let (around, rim) = (median(&mut around)?, median(&mut rim)?);
    let midway = 0.5 * (around + rim);
    let towards_around = inside
        .iter()
        .filter(|&&g| (g - midway) * (around - rim) > 0.0)
        .count();
    Some(Sampled {
        around,
        rim,
        share: towards_around as f64 / inside.len().max(1) as f64,
    })
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
    use super::*;

    fn builtin(name: &str) -> Option<Family> {
        crate::builtin::get(name).map(Result::unwrap)
    }

    fn square(x: f64, y: f64, side: f64) -> [[f64; 2]; 4] {
        [[x, y], [x + side, y], [x + side, y + side], [x, y + side]]
    }

    fn fill(image: &mut GrayImage, corners: &[[f64; 2]; 4], gray: u8) {
        let [x0, y0] = corners[0];
        let [x1, y1] = corners[2];
        for y in y0 as u32..y1 as u32 {
            for x in x0 as u32..x1 as u32 {
                image.pixels[(y * image.width + x) as usize] = gray;
            }
        }
    }

    #[test]
    fn a_rendered_marker_passes_and_a_dark_blob_does_not() {
        let family = builtin("apriltag-36h11").unwrap();
        let check = PreCheck::new(&family).expect("36h11 has a dark frame on a light zone");
        assert_eq!(check.polarity, 1.0);
        // Any ID, rendered as stage 2 would see it: the ROI square of the template.
        let template = rectified_template(&family, 7, TEMPLATE_PX).unwrap();
        let corners = template_corners(TEMPLATE_PX, family.spec().roi.margin)
            .map(|[x, y]| [x - 0.5, y - 0.5]);
        assert!(check.passes(&template, &corners));
        // A dark square on light ground, and a flat gray square: no light inside, no step.
        let mut image = GrayImage::new(120, 120, 210);
        let blob = square(30.0, 30.0, 60.0);
        fill(&mut image, &blob, 30);
        assert!(!check.passes(&image, &blob));
        assert!(!check.has_light_inside(&image, &blob));
        // The marker's quad 3 px off to one side: no clean rim, but its light cells are inside.
        let shifted = corners.map(|[x, y]| [x + 3.0, y]);
        assert!(check.has_light_inside(&template, &shifted));
        let flat = GrayImage::new(120, 120, 128);
        assert!(!check.passes(&flat, &blob));
    }

    #[test]
    fn every_code_of_the_shipped_square_families_passes_its_check() {
        for name in ["apriltag-36h11", "aruco-6x6_250", "apriltag-xo-36h11"] {
            let family = builtin(name).unwrap();
            let check = PreCheck::new(&family).unwrap();
            let corners = template_corners(TEMPLATE_PX, family.spec().roi.margin)
                .map(|[x, y]| [x - 0.5, y - 0.5]);
            // Every 7th ID keeps the test short; the darkest codes set the bar.
            for id in (0..family.codebook().len()).step_by(7) {
                let template = rectified_template(&family, id, TEMPLATE_PX).unwrap();
                assert!(check.passes(&template, &corners), "{name} #{id}");
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
        // Ring families have no square ROI on a frame.
        assert!(!checked.contains(&"runetag"));
    }

    #[test]
    fn a_family_whose_roi_sits_on_no_frame_is_not_checked() {
        // TopoTag-like: a ground of one category, no frame step at the ROI's rim.
        let family = builtin("topotag-like").unwrap();
        assert_eq!(PreCheck::new(&family), None);
    }
}
