//! What the stage-1 network is trained to output for an image, on its stride-4 grid: a Gaussian
//! bump at each marker corner, the corner's offset from the centre of the cells around it, the
//! unit direction from the corner to the marker's centre, and the marker mask.
//!
//! The centre is where the diagonals cross: under perspective that is the projection of the
//! marker's centre, and the direction from a corner to it points exactly at the opposite corner,
//! which is what [`super::group`] relies on.

use super::STRIDE;
use crate::geometry::{inside_polygon, Quad};

/// A marker as stage 1 sees it: its four ROI corners (in the family's order) and its outline.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerQuad {
    pub corners: Quad,
    pub outline: Vec<[f64; 2]>,
}

/// Per-cell targets, row-major over a `columns` × `rows` grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Targets {
    pub columns: usize,
    pub rows: usize,
    /// Gaussian bumps (max over corners), 1 at each corner's own cell.
    pub heat: Vec<f32>,
    /// The corner's position relative to the cell centre, in cells.
    pub offset: Vec<[f32; 2]>,
    /// Unit vector from the corner to the marker centre.
    pub direction: Vec<[f32; 2]>,
    /// 1 where `offset` and `direction` are defined (the 3 × 3 cells around each corner).
    pub regress: Vec<f32>,
    pub mask: Vec<f32>,
}

/// Gaussian bump width in cells: narrow enough that the corners of a 12-px marker (3 cells
/// apart) stay separate peaks.
const SIGMA_CELLS: f64 = 0.8;

/// The cells of a `columns` × `rows` map whose centre lies inside `outline`: a marker's mask.
pub fn cells_inside(
    outline: &[[f64; 2]],
    columns: usize,
    rows: usize,
) -> impl Iterator<Item = usize> + '_ {
    let s = STRIDE as f64;
    (0..columns * rows).filter(move |&i| {
        let (cx, cy) = (i % columns, i / columns);
        inside_polygon(outline, [(cx as f64 + 0.5) * s, (cy as f64 + 0.5) * s])
    })
}

/// The targets for a `width` × `height` image (multiples of [`STRIDE`]) showing `markers`.
pub fn encode(width: usize, height: usize, markers: &[MarkerQuad]) -> Targets {
    let (columns, rows) = (width / STRIDE, height / STRIDE);
    let cells = columns * rows;
    let mut t = Targets {
        columns,
        rows,
        heat: vec![0.0; cells],
        offset: vec![[0.0; 2]; cells],
        direction: vec![[0.0; 2]; cells],
        regress: vec![0.0; cells],
        mask: vec![0.0; cells],
    };
    let s = STRIDE as f64;
    for m in markers {
        let Some(centre) = m.corners.diagonal_crossing() else {
            continue;
        };
        for i in cells_inside(&m.outline, columns, rows) {
            t.mask[i] = 1.0;
        }
        for corner in m.corners.0 {
            let (gx, gy) = (corner[0] / s, corner[1] / s);
            let (dx, dy) = (centre[0] - corner[0], centre[1] - corner[1]);
            let len = dx.hypot(dy).max(1e-9);
            let dir = [(dx / len) as f32, (dy / len) as f32];
            let (ix, iy) = (gx.floor() as i64, gy.floor() as i64);
            for ny in iy - 3..=iy + 3 {
                for nx in ix - 3..=ix + 3 {
                    if nx < 0 || ny < 0 || nx >= columns as i64 || ny >= rows as i64 {
                        continue;
                    }
                    let i = ny as usize * columns + nx as usize;
                    let (ox, oy) = (gx - (nx as f64 + 0.5), gy - (ny as f64 + 0.5));
                    let bump = if (nx, ny) == (ix, iy) {
                        1.0
                    } else {
                        (-(ox * ox + oy * oy) / (2.0 * SIGMA_CELLS * SIGMA_CELLS)).exp() as f32
                    };
                    // The corner's own cell is the only exact 1, so the loss knows its positives.
                    let bump = if (nx, ny) == (ix, iy) {
                        bump
                    } else {
                        bump.min(0.99)
                    };
                    t.heat[i] = t.heat[i].max(bump);
                    if (nx - ix).abs() <= 1 && (ny - iy).abs() <= 1 {
                        t.offset[i] = [ox as f32, oy as f32];
                        t.direction[i] = dir;
                        t.regress[i] = 1.0;
                    }
                }
            }
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_are_peaks_with_their_offsets_and_directions_to_the_centre() {
        let corners = [[20.5, 21.0], [60.0, 20.0], [61.0, 62.0], [19.0, 60.0]];
        let t = encode(
            96,
            80,
            &[MarkerQuad {
                corners: Quad(corners),
                outline: corners.to_vec(),
            }],
        );
        assert_eq!((t.columns, t.rows), (24, 20));
        let peaks: Vec<usize> = (0..t.heat.len()).filter(|&i| t.heat[i] == 1.0).collect();
        assert_eq!(peaks.len(), 4);
        for c in corners {
            let i = (c[1] / 4.0) as usize * 24 + (c[0] / 4.0) as usize;
            assert_eq!(t.heat[i], 1.0);
            let cell = [(i % 24) as f64 + 0.5, (i / 24) as f64 + 0.5];
            let back = [
                (cell[0] + t.offset[i][0] as f64) * 4.0,
                (cell[1] + t.offset[i][1] as f64) * 4.0,
            ];
            assert!((back[0] - c[0]).abs() < 1e-4 && (back[1] - c[1]).abs() < 1e-4);
            let d = t.direction[i];
            let to_centre = [40.0 - c[0], 40.0 - c[1]];
            let cos = (d[0] as f64 * to_centre[0] + d[1] as f64 * to_centre[1])
                / to_centre[0].hypot(to_centre[1]);
            assert!(cos > 0.99, "{cos}");
        }
        assert_eq!(t.mask[10 * 24 + 10], 1.0);
        assert_eq!(t.mask[2 * 24 + 2], 0.0);
        assert_eq!(t.regress.iter().filter(|&&r| r > 0.0).count(), 36);
    }
}
