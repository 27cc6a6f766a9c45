//! Keypoint positions and the layout's rotational symmetries.

use super::spec::{GridLayout, KeypointSet, Layout, RingsLayout};
use super::{Assignment, Family};
use std::collections::HashMap;

/// A keypoint of the family, in canonical order.
#[derive(Debug, Clone, PartialEq)]
pub struct Keypoint {
    /// Centre in marker units.
    pub pos: [f64; 2],
    /// Side of the keypoint's cell in marker units.
    pub size: f64,
    pub assignment: Assignment,
}

/// Axis-aligned rectangle in marker units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Extent {
    pub min: [f64; 2],
    pub max: [f64; 2],
}

impl Extent {
    pub fn width(&self) -> f64 {
        self.max[0] - self.min[0]
    }
    pub fn height(&self) -> f64 {
        self.max[1] - self.min[1]
    }
    pub fn grow(&self, by: f64) -> Extent {
        Extent {
            min: [self.min[0] - by, self.min[1] - by],
            max: [self.max[0] + by, self.max[1] + by],
        }
    }
}

/// A rotation that maps the keypoint layout onto itself.
#[derive(Debug, Clone, PartialEq)]
pub struct Rotation {
    /// Clockwise angle in degrees (y down) of the physical rotation of the marker.
    pub angle_deg: f64,
    /// When the marker is rotated, canonical keypoint `i` appears where keypoint `perm[i]` was.
    pub keypoint_perm: Vec<usize>,
    /// The same on code positions (symbol `j` appears at code position `code_perm[j]`), when the
    /// rotation maps symbol keypoints onto symbol keypoints.
    pub code_perm: Option<Vec<usize>>,
    /// Whether every fixed keypoint lands on a fixed keypoint of the same category.
    pub preserves_fixed: bool,
}

/// Rotation candidates of a layout: (centre, angles in degrees).
pub(super) fn rotation_candidates(layout: &Layout) -> ([f64; 2], Vec<f64>) {
    match layout {
        Layout::Grid(GridLayout { size, .. }) => {
            let c = *size as f64 / 2.0;
            ([c, c], vec![0.0, 90.0, 180.0, 270.0])
        }
        Layout::Rings(RingsLayout { slots, .. }) => {
            let step = 360.0 / *slots as f64;
            ([0.0, 0.0], (0..*slots).map(|k| k as f64 * step).collect())
        }
    }
}

/// Finds which candidate rotations map every keypoint onto a keypoint of the same size.
pub(super) fn symmetries(
    keypoints: &[Keypoint],
    centre: [f64; 2],
    angles: &[f64],
) -> Vec<Rotation> {
    // Positions are quantised to a 1e-6 lattice of the layout's scale so that floating-point
    // rotation lands on the same key as the exact position.
    let scale = keypoints.iter().map(|k| k.size).fold(1e-9, f64::max);
    let key = |p: [f64; 2]| {
        (
            (p[0] / scale * 1e4).round() as i64,
            (p[1] / scale * 1e4).round() as i64,
        )
    };
    let index: HashMap<(i64, i64), usize> = keypoints
        .iter()
        .enumerate()
        .map(|(i, k)| (key(k.pos), i))
        .collect();
    let code_index: HashMap<usize, usize> = keypoints
        .iter()
        .enumerate()
        .filter_map(|(i, k)| match k.assignment {
            Assignment::Symbol(n) => Some((i, n)),
            Assignment::Fixed(_) => None,
        })
        .collect();
    let code_keypoints: Vec<usize> = {
        let mut v = vec![0; code_index.len()];
        for (&kp, &n) in &code_index {
            v[n] = kp;
        }
        v
    };

    let mut out = Vec::new();
    for &angle in angles {
        let (s, c) = angle.to_radians().sin_cos();
        let perm: Option<Vec<usize>> = keypoints
            .iter()
            .map(|k| {
                let d = [k.pos[0] - centre[0], k.pos[1] - centre[1]];
                // Clockwise on screen with y down is the standard rotation matrix.
                let p = [
                    centre[0] + c * d[0] - s * d[1],
                    centre[1] + s * d[0] + c * d[1],
                ];
                let j = *index.get(&key(p))?;
                ((keypoints[j].size - k.size).abs() <= 1e-9 * scale).then_some(j)
            })
            .collect();
        let Some(perm) = perm else { continue };
        let preserves_fixed = keypoints.iter().zip(&perm).all(|(k, &j)| {
            match (k.assignment, keypoints[j].assignment) {
                (Assignment::Fixed(a), Assignment::Fixed(b)) => a == b,
                (Assignment::Symbol(_), Assignment::Symbol(_)) => true,
                _ => false,
            }
        });
        let code_perm: Option<Vec<usize>> = code_keypoints
            .iter()
            .map(|&kp| code_index.get(&perm[kp]).copied())
            .collect();
        out.push(Rotation {
            angle_deg: angle,
            keypoint_perm: perm,
            code_perm,
            preserves_fixed,
        });
    }
    out
}

pub(super) fn regressed_keypoints(family: &Family) -> Vec<usize> {
    let n = family.keypoints().len();
    match &family.spec().keypoint_set {
        KeypointSet::All => (0..n).collect(),
        KeypointSet::Custom(list) => list.iter().map(|&i| i as usize).collect(),
        set @ (KeypointSet::Boundary | KeypointSet::Corners) => {
            let e = family.extent();
            let kps = family.keypoints();
            match family.spec().layout {
                Layout::Grid(_) => (0..n)
                    .filter(|&i| {
                        let [x, y] = kps[i].pos;
                        let on = |v: f64, lo: f64, hi: f64| {
                            (v - lo - 0.5).abs() < 1e-9 || (hi - v - 0.5).abs() < 1e-9
                        };
                        let (bx, by) = (on(x, e.min[0], e.max[0]), on(y, e.min[1], e.max[1]));
                        if matches!(set, KeypointSet::Corners) {
                            bx && by
                        } else {
                            bx || by
                        }
                    })
                    .collect(),
                Layout::Rings(RingsLayout { ref radii, .. }) => {
                    let outer = radii.iter().copied().fold(0.0, f64::max);
                    (0..n)
                        .filter(|&i| {
                            let [x, y] = kps[i].pos;
                            (x.hypot(y) - outer).abs() < 1e-9
                        })
                        .collect()
                }
            }
        }
    }
}
