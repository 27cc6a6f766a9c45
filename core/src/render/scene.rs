//! One vector scene per marker, in millimetres, that every output (SVG, PDF, raster) draws.

use crate::color::Rgb;
use crate::family::pattern::{Path, Seg};
use crate::family::Family;
use std::collections::{BTreeMap, HashMap};

/// A filled and/or stroked path in scene coordinates (mm, origin top-left, y down).
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub path: Path,
    pub fill: Option<Rgb>,
    /// Colour and width in mm.
    pub stroke: Option<(Rgb, f64)>,
}

/// A marker drawn at a physical size.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerScene {
    pub width_mm: f64,
    pub height_mm: f64,
    /// Drawn in order; the first is the background with the quiet zone.
    pub items: Vec<Item>,
    /// Marker units → mm: `mm = (p - origin) * scale`.
    pub scale: f64,
    pub origin: [f64; 2],
}

impl MarkerScene {
    pub fn to_mm(&self, p: [f64; 2]) -> [f64; 2] {
        [
            (p[0] - self.origin[0]) * self.scale,
            (p[1] - self.origin[1]) * self.scale,
        ]
    }
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RenderError {
    #[error("ID {id} does not exist: {family} has IDs 0 to {last}")]
    NoSuchId {
        family: String,
        id: usize,
        last: usize,
    },
    #[error("marker size {0} mm must be a positive number")]
    BadSize(f64),
    #[error("{0}")]
    Layout(String),
    #[error("cannot encode the image: {0}")]
    Encode(String),
}

/// Options that override the family's print defaults.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SceneOptions {
    /// Marker size in mm (distance between ROI points 0 and 1); default: the family's.
    pub side_mm: Option<f64>,
    /// Quiet zone in marker units; default: the family's.
    pub quiet_zone: Option<f64>,
}

pub fn marker_scene(
    family: &Family,
    id: usize,
    options: SceneOptions,
) -> Result<MarkerScene, RenderError> {
    let categories = family
        .keypoint_categories(id)
        .ok_or_else(|| RenderError::NoSuchId {
            family: family.name().to_string(),
            id,
            last: family.codebook().len().saturating_sub(1),
        })?;
    let side = options
        .side_mm
        .unwrap_or(family.spec().print.marker_side_mm);
    if !(side.is_finite() && side > 0.0) {
        return Err(RenderError::BadSize(side));
    }
    let qz = options.quiet_zone.unwrap_or(family.quiet_zone());
    if !(qz.is_finite() && qz >= 0.0) {
        return Err(RenderError::Layout(format!("quiet zone {qz} must be ≥ 0")));
    }
    let scale = side / family.roi_side();
    let area = family.extent().grow(qz);
    let mut scene = MarkerScene {
        width_mm: area.width() * scale,
        height_mm: area.height() * scale,
        items: Vec::new(),
        scale,
        origin: area.min,
    };
    let (w, h) = (scene.width_mm, scene.height_mm);
    scene.items.push(Item {
        path: Path(vec![
            Seg::Move(0.0, 0.0),
            Seg::Line(w, 0.0),
            Seg::Line(w, h),
            Seg::Line(0.0, h),
            Seg::Close,
        ]),
        fill: Some(family.background()),
        stroke: None,
    });

    let patterns = family.categories();
    let merge = family.is_grid();
    // Full-cell fills of grid cells become one outline per colour: no hairline seams between
    // neighbouring cells in vector viewers, and cutters see one shape.
    let mut regions: BTreeMap<(u8, u8, u8), Vec<(i64, i64)>> = BTreeMap::new();
    let mut order: Vec<Rgb> = Vec::new();
    for (k, &cat) in family.keypoints().iter().zip(&categories) {
        let Some(colour) = patterns[cat].cell_fill.filter(|_| merge && k.size == 1.0) else {
            continue;
        };
        let cell = (
            (k.pos[0] - 0.5).round() as i64,
            (k.pos[1] - 0.5).round() as i64,
        );
        let key = (colour.0, colour.1, colour.2);
        if !regions.contains_key(&key) {
            order.push(colour);
        }
        regions.entry(key).or_default().push(cell);
    }
    for colour in order {
        // A region of the background's colour is already there. Drawn anyway, it would meet the
        // other regions edge to edge, and anti-aliasing composites the two partial coverages of
        // a shared edge pixel into a light seam (a tenth of a gray step along every edge between
        // the colours), which the detector's refinement would fit as a shifted edge.
        if colour == family.background() {
            continue;
        }
        let cells = &regions[&(colour.0, colour.1, colour.2)];
        let outline = trace_cells(cells);
        scene.items.push(Item {
            path: outline.map(|x, y| {
                let p = scene.to_mm([x, y]);
                (p[0], p[1])
            }),
            fill: Some(colour),
            stroke: None,
        });
    }
    for (k, &cat) in family.keypoints().iter().zip(&categories) {
        let pattern = &patterns[cat];
        let merged = merge && pattern.cell_fill.is_some() && k.size == 1.0;
        for item in pattern.items.iter().skip(usize::from(merged)) {
            let path = item.path.map(|x, y| {
                let p = scene.to_mm([k.pos[0] + x * k.size, k.pos[1] + y * k.size]);
                (p[0], p[1])
            });
            scene.items.push(Item {
                path,
                fill: item.fill,
                stroke: item.stroke.map(|(c, w)| (c, w * k.size * scale)),
            });
        }
    }
    Ok(scene)
}

/// Outlines of the union of unit cells (integer top-left corners), as closed polygons wound
/// clockwise (holes counter-clockwise), for the non-zero fill rule.
pub fn trace_cells(cells: &[(i64, i64)]) -> Path {
    type V = (i64, i64);
    let mut edges: HashMap<(V, V), ()> = HashMap::new();
    for &(x, y) in cells {
        let corners = [(x, y), (x + 1, y), (x + 1, y + 1), (x, y + 1)];
        for i in 0..4 {
            let (a, b) = (corners[i], corners[(i + 1) % 4]);
            // An edge shared by two cells appears once in each direction: both go.
            if edges.remove(&(b, a)).is_none() {
                edges.insert((a, b), ());
            }
        }
    }
    let mut outgoing: BTreeMap<V, Vec<V>> = BTreeMap::new();
    for &(a, b) in edges.keys() {
        outgoing.entry(a).or_default().push(b);
    }
    for v in outgoing.values_mut() {
        v.sort();
    }
    let mut segs = Vec::new();
    while let Some((&start, _)) = outgoing.iter().find(|(_, v)| !v.is_empty()) {
        let mut loop_pts = vec![start];
        let mut prev_dir: Option<V> = None;
        let mut at = start;
        loop {
            let nexts = outgoing
                .get_mut(&at)
                .expect("every vertex on a loop has an edge out");
            // Where two cells touch only at a corner, turn right (clockwise) so loops stay simple.
            let pick = match prev_dir {
                Some(d) if nexts.len() > 1 => {
                    let right = (-d.1, d.0);
                    nexts
                        .iter()
                        .position(|n| (n.0 - at.0, n.1 - at.1) == right)
                        .unwrap_or(0)
                }
                _ => 0,
            };
            let next = nexts.remove(pick);
            prev_dir = Some((next.0 - at.0, next.1 - at.1));
            at = next;
            if at == start {
                break;
            }
            loop_pts.push(at);
        }
        // Drop vertices in the middle of straight runs.
        let n = loop_pts.len();
        let corners: Vec<V> = (0..n)
            .filter(|&i| {
                let (p, c, q) = (
                    loop_pts[(i + n - 1) % n],
                    loop_pts[i],
                    loop_pts[(i + 1) % n],
                );
                (c.0 - p.0) * (q.1 - c.1) - (c.1 - p.1) * (q.0 - c.0) != 0
            })
            .map(|i| loop_pts[i])
            .collect();
        for (i, &(x, y)) in corners.iter().enumerate() {
            let (x, y) = (x as f64, y as f64);
            segs.push(if i == 0 {
                Seg::Move(x, y)
            } else {
                Seg::Line(x, y)
            });
        }
        segs.push(Seg::Close);
    }
    Path(segs)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loops(p: &Path) -> usize {
        p.0.iter().filter(|s| matches!(s, Seg::Close)).count()
    }

    #[test]
    fn a_ring_of_cells_becomes_an_outer_outline_and_a_hole() {
        let mut cells = Vec::new();
        for i in 0..4 {
            cells.extend([(i, 0), (i, 3), (0, i), (3, i)]);
        }
        cells.sort();
        cells.dedup();
        let p = trace_cells(&cells);
        assert_eq!(loops(&p), 2);
        // 4 corners outside + 4 inside, each a Move/Line, plus 2 closes.
        assert_eq!(p.0.len(), 10);
    }

    #[test]
    fn diagonal_neighbours_give_two_simple_loops() {
        let p = trace_cells(&[(0, 0), (1, 1)]);
        assert_eq!(loops(&p), 2);
        assert_eq!(p.0.len(), 10);
    }
}
