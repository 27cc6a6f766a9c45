//! The dark frame around a ROI that lies inside the drawing (AprilTag 3's standard41h12 and
//! circle21h7: their ROI is where the black frame meets the white one, with data cells outside
//! the frame). Stage 1 and the image searches outline dark squares on their outer edge, as they
//! do every other square family's ROI; such a family's stage 2 reads from the ROI that outline
//! places.

use crate::family::{Assignment, Family};
use crate::geometry::{Homography, Quad};
use crate::render::readback::Reader;

/// A category's rendered gray below which its cells count as the frame's.
const DARK_GRAY: f64 = 128.0;

/// Where a family's dark frame lies around its ROI, in marker units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Outline {
    /// The frame's outer corners, TL, TR, BR, BL (as the ROI's).
    outline: [[f64; 2]; 4],
    /// The ROI's first four points.
    roi: [[f64; 2]; 4],
}

impl Outline {
    /// `None` unless the family is a grid whose square ROI has whole rings of fixed dark cells
    /// around it: the ROI is then the outline stage 1 finds.
    pub fn new(family: &Family) -> Option<Self> {
        if !family.is_grid() || family.roi_points().len() < 4 {
            return None;
        }
        let p = family.roi_points();
        let roi = [p[0], p[1], p[2], p[3]];
        let axis_aligned = roi[0][1] == roi[1][1]
            && roi[1][0] == roi[2][0]
            && roi[2][1] == roi[3][1]
            && roi[3][0] == roi[0][0]
            && roi[0][0] < roi[1][0]
            && roi[0][1] < roi[3][1];
        if !axis_aligned {
            return None;
        }
        // Rendered only when a ring of fixed cells asks: most ROIs have no cells round them.
        let reader = std::cell::OnceCell::new();
        let dark = |c: usize| reader.get_or_init(|| Reader::new(family)).mean_gray(c) < DARK_GRAY;
        let cell = family.cell_size();
        let (mut min, mut max) = (roi[0], roi[2]);
        loop {
            let inside = |q: [f64; 2], lo: [f64; 2], hi: [f64; 2]| {
                (0..2).all(|a| q[a] > lo[a] && q[a] < hi[a])
            };
            let (lo, hi) = (
                [min[0] - cell, min[1] - cell],
                [max[0] + cell, max[1] + cell],
            );
            let ring: Vec<_> = (family.keypoints().iter())
                .filter(|k| inside(k.pos, lo, hi) && !inside(k.pos, min, max))
                .collect();
            let across = [(max[0] - min[0]) / cell, (max[1] - min[1]) / cell];
            let whole = ((across[0] + 2.0) * (across[1] + 2.0) - across[0] * across[1]).round();
            let framed = ring.len() as f64 == whole
                && (ring.iter()).all(|k| matches!(k.assignment, Assignment::Fixed(c) if dark(c)));
            if !framed {
                break;
            }
            (min, max) = (lo, hi);
        }
        (min != roi[0]).then_some(Self {
            outline: [min, [max[0], min[1]], max, [min[0], max[1]]],
            roi,
        })
    }

    /// The ROI in the image of a marker whose frame `outline` outlines.
    pub fn roi_in(&self, outline: &Quad) -> Option<Quad> {
        let to_image = Homography::from_points(&self.outline, &outline[..]).ok()?;
        Some(Quad(self.roi.map(|p| to_image.apply(p))))
    }

    /// The frame's outline in the image of a marker whose ROI is `roi`.
    pub fn around(&self, roi: &Quad) -> Option<Quad> {
        let to_image = Homography::from_points(&self.roi, &roi[..]).ok()?;
        Some(Quad(self.outline.map(|p| to_image.apply(p))))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin;

    #[test]
    fn families_with_data_cells_outside_the_frame_are_outlined_by_the_frame() {
        for name in ["apriltag-standard41h12", "apriltag-circle21h7"] {
            let outline = Outline::new(&builtin::get(name).unwrap().unwrap()).expect(name);
            assert_eq!(
                outline.outline,
                [[1.0, 1.0], [8.0, 1.0], [8.0, 8.0], [1.0, 8.0]]
            );
        }
        for name in builtin::names() {
            if !name.starts_with("apriltag-standard") && !name.starts_with("apriltag-circle") {
                let family = builtin::get(name).unwrap().unwrap();
                assert_eq!(Outline::new(&family), None, "{name}");
            }
        }
    }

    #[test]
    fn the_roi_inside_an_outline_maps_back_to_it() {
        let outline =
            Outline::new(&builtin::get("apriltag-standard41h12").unwrap().unwrap()).unwrap();
        let seen = Quad([
            [100.0, 120.0],
            [240.0, 110.0],
            [250.0, 260.0],
            [90.0, 240.0],
        ]);
        let roi = outline.roi_in(&seen).unwrap();
        // Five of the frame's seven cells, inside it.
        let ratio = roi.sides().iter().sum::<f64>() / seen.sides().iter().sum::<f64>();
        assert!((ratio - 5.0 / 7.0).abs() < 0.02, "{ratio}");
        let back = outline.around(&roi).unwrap();
        assert!(back.largest_corner_move(&seen) < 1e-9);
    }
}
