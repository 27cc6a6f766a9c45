//! Reading a rendered marker back: sample each keypoint's cell in a raster and classify it by the
//! nearest category template. This checks that a family's patterns are distinct and that a
//! rendering carries its own ID; it is not a detector (it needs the marker's exact placement).

use super::raster::rasterize;
use super::scene::{Item, MarkerScene};
use crate::family::pattern::{Path, Seg};
use crate::family::Family;
use tiny_skia::Pixmap;

/// Samples per cell side.
const K: usize = 6;
/// Fraction of the cell that is sampled: away from the edges, where anti-aliasing blends cells.
const SPAN: f64 = 0.8;

/// Category templates of a family: the gray levels at the sample points of a cell of each category,
/// in each quarter turn (a marker seen turned shows its patterns turned).
pub struct Reader {
    /// (category, quarter turns, samples)
    templates: Vec<(usize, usize, Vec<f64>)>,
}

fn sample_offsets() -> impl Iterator<Item = (f64, f64)> {
    (0..K * K).map(|n| {
        let (i, j) = (n % K, n / K);
        (
            ((i as f64 + 0.5) / K as f64 - 0.5) * SPAN,
            ((j as f64 + 0.5) / K as f64 - 0.5) * SPAN,
        )
    })
}

impl Reader {
    pub fn new(family: &Family) -> Self {
        const CELL_PX: f64 = 60.0;
        let templates = family
            .categories()
            .iter()
            .enumerate()
            .flat_map(|(c, pattern)| (0..4).map(move |turns| (c, turns, pattern)))
            .map(|(c, turns, pattern)| {
                let (s, co) = (turns as f64 * std::f64::consts::FRAC_PI_2).sin_cos();
                let square = |c| {
                    Path(vec![
                        Seg::Move(0.0, 0.0),
                        Seg::Line(c, 0.0),
                        Seg::Line(c, c),
                        Seg::Line(0.0, c),
                        Seg::Close,
                    ])
                };
                let mut items = vec![Item {
                    path: square(CELL_PX),
                    fill: Some(family.background()),
                    stroke: None,
                }];
                items.extend(pattern.items.iter().map(|it| Item {
                    path: it.path.map(|x, y| {
                        (
                            (co * x - s * y + 0.5) * CELL_PX,
                            (s * x + co * y + 0.5) * CELL_PX,
                        )
                    }),
                    fill: it.fill,
                    stroke: it.stroke.map(|(c, w)| (c, w * CELL_PX)),
                }));
                let scene = MarkerScene {
                    width_mm: CELL_PX,
                    height_mm: CELL_PX,
                    items,
                    scale: 1.0,
                    origin: [0.0; 2],
                };
                let pixmap = rasterize(&scene, 1.0).expect("a 60 px cell always renders");
                let samples = sample_offsets()
                    .map(|(u, v)| bilinear(&pixmap, (u + 0.5) * CELL_PX, (v + 0.5) * CELL_PX))
                    .collect();
                (c, turns, samples)
            })
            .collect();
        Self { templates }
    }

    /// Pairs of categories whose cells look alike in some quarter turn (RMS difference under 12
    /// gray levels): a reader, learned or not, cannot tell them apart. Each pair once, in the
    /// order found.
    pub fn indistinct_pairs(&self) -> Vec<(usize, usize)> {
        let n = self.templates.iter().map(|t| t.0 + 1).max().unwrap_or(0);
        // A table of the pairs found, not a search of the list: the list grows with the square of
        // the number of categories, and searching it for every template pair took 52 s for 400.
        let mut found = vec![false; n * n];
        let mut out = Vec::new();
        for (i, (a, _, ta)) in self.templates.iter().enumerate() {
            for (b, _, tb) in &self.templates[i + 1..] {
                if a == b || found[a * n + b] {
                    continue;
                }
                let ms = ta
                    .iter()
                    .zip(tb)
                    .map(|(x, y)| (x - y) * (x - y))
                    .sum::<f64>()
                    / ta.len() as f64;
                if ms < 144.0 {
                    found[a * n + b] = true;
                    out.push((*a, *b));
                }
            }
        }
        out
    }

    /// The darkest and the lightest gray level sampled in a category's cell, in any quarter
    /// turn: close together for a flat black or white cell, far apart for a glyph.
    pub fn gray_range(&self, category: usize) -> (f64, f64) {
        self.templates
            .iter()
            .filter(|(c, _, _)| *c == category)
            .flat_map(|(_, _, t)| t.iter().copied())
            .fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)))
    }

    /// Mean gray level (0 black – 255 white) of a category's cell.
    pub fn mean_gray(&self, category: usize) -> f64 {
        let (_, _, t) = self
            .templates
            .iter()
            .find(|(c, _, _)| *c == category)
            .expect("every category has templates");
        t.iter().sum::<f64>() / t.len() as f64
    }

    /// The category read at every keypoint of a raster of `scene` (rendered at `px_per_mm`).
    pub fn read(
        &self,
        family: &Family,
        scene: &MarkerScene,
        pixmap: &Pixmap,
        px_per_mm: f64,
    ) -> Vec<Option<usize>> {
        family
            .keypoints()
            .iter()
            .map(|k| {
                let samples: Vec<f64> = sample_offsets()
                    .map(|(u, v)| {
                        let mm = scene.to_mm([k.pos[0] + u * k.size, k.pos[1] + v * k.size]);
                        bilinear(pixmap, mm[0] * px_per_mm, mm[1] * px_per_mm)
                    })
                    .collect();
                self.templates
                    .iter()
                    .map(|(c, _, t)| {
                        (
                            t.iter()
                                .zip(&samples)
                                .map(|(a, b)| (a - b) * (a - b))
                                .sum::<f64>(),
                            *c,
                        )
                    })
                    .min_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(_, c)| c)
            })
            .collect()
    }
}

/// Gray level at a sub-pixel position (pixel centres at +0.5), clamped to the image.
fn bilinear(pixmap: &Pixmap, x: f64, y: f64) -> f64 {
    let pixels = pixmap.pixels();
    let gray = |i: usize| {
        let p = pixels[i];
        crate::image::luminance(p.red() as f32, p.green() as f32, p.blue() as f32)
    };
    crate::image::bilinear(
        pixmap.width(),
        pixmap.height(),
        (x - 0.5) as f32,
        (y - 0.5) as f32,
        gray,
    ) as f64
}

/// Most look-alike pairs [`warnings`] names one by one; the rest are counted in one line. A family
/// where every category looks like every other would otherwise print a line per pair (80 200 for
/// 400 categories), which hides the point: the design needs distinct patterns.
pub const MAX_REPORTED_PAIRS: usize = 20;

/// Every warning about a design: the model's own ([`Family::warnings`]) and the categories that
/// look alike once rendered (the detector can only tell categories apart by shape or colour).
pub fn warnings(family: &Family) -> Vec<String> {
    let mut out = family.warnings();
    let pairs = Reader::new(family).indistinct_pairs();
    for &(a, b) in pairs.iter().take(MAX_REPORTED_PAIRS) {
        out.push(format!(
            "{}: categories {:?} and {:?} look alike; the detector can only tell categories apart \
             by shape or colour",
            family.name(),
            family.categories()[a].name,
            family.categories()[b].name
        ));
    }
    if pairs.len() > MAX_REPORTED_PAIRS {
        out.push(format!(
            "{}: and {} more pairs of categories look alike",
            family.name(),
            pairs.len() - MAX_REPORTED_PAIRS
        ));
    }
    out
}
