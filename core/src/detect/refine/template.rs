//! The marker as it should look: the family's rendering of one ID as a blur pyramid in marker
//! units, with its gradients, looked up at any point of the marker plane.

use crate::family::Family;
use crate::image::luminance;
use crate::render::raster::rasterize;
use crate::render::scene::{marker_scene, RenderError, SceneOptions};

/// Texels per marker unit are a power of two, so that on grid families every cell edge falls on a
/// texel boundary at every level and the levels sample it symmetrically. The alignment wants
/// texels of at most half an image pixel (a coarser template, interpolated, blurs by an amount
/// that depends on where the edge falls between texels, which biases a fronto-parallel view,
/// whose edges all fall alike, by a tenth of a pixel); markers bigger than the template allows
/// are compared on a coarser copy of the image instead. At most this many texels across the
/// marker with its quiet zone (32 per cell on a 36h11 tag):
pub const MAX_TEXELS_ACROSS: f64 = 400.0;
/// At least this many texels across the marker with its quiet zone, however small the marker
/// looks: a far sliver or a degenerate start still gets a template with an inside to align.
const MIN_TEXELS_ACROSS: f64 = 16.0;
pub const TEXELS_PER_PIXEL: f64 = 1.4;

/// The rasteriser's anti-aliasing places slanted edges up to ⅛ of its pixel off (it samples
/// quarter scanlines), which would bias glyph families by a few hundredths of an image pixel: the
/// finest level averages several raster pixels per texel, so the slip shrinks as much.
fn supersample(texels: f64) -> usize {
    if texels <= 160.0 {
        4
    } else {
        2
    }
}

/// Where the template's gradient is below this share of its level's largest it is flat: such
/// points carry no information on the geometry, and the alignment skips them.
pub const EDGE: f64 = 0.02;

/// Blur levels at most (√2 apart: 0.5 to 0.5·2^6 finest texels).
const MAX_LEVELS: usize = 14;

/// One blur level: gray values 0–255 and their gradient per marker unit, texel centres at integer
/// coordinates.
#[derive(Debug, Clone)]
pub struct Level {
    pub width: usize,
    pub height: usize,
    /// Gray values 0–255, only while the template is built (the texels hold them too).
    values: Vec<f32>,
    /// Per texel: value, gradient (x, y) per marker unit, the change towards the next level per
    /// unit of blur variance, and two second derivatives per marker unit² — (T_xx − T_yy) / 2 and
    /// T_xy — for blur that differs between directions: side by side, so a lookup reads one cache
    /// line per corner.
    pub texels: Vec<[f32; 6]>,
    /// The largest gradient magnitude of the level.
    pub max_gradient: f64,
    /// Per cell between four texels (indexed by its top-left texel): whether a point inside may
    /// have a gradient of [`EDGE`] × the largest, one byte each so the alignment can skip flat
    /// points without reading their texels (four times 24 bytes, mostly outside the caches).
    /// A bilinear gradient is a weighted mean of the corners', never longer than the longest.
    edge_cells: Vec<bool>,
    /// Texels per marker unit.
    pub texels_per_unit: f64,
    /// Gaussian-equivalent blur of the level, in marker units.
    pub blur_units: f64,
    /// Points in flat regions (for the image's noise estimate).
    pub flat: Vec<[f64; 2]>,
}

/// The template at one point of one level.
#[derive(Debug, Clone, Copy)]
pub struct Lookup {
    pub value: f64,
    pub gradient: [f64; 2],
    /// How the value changes per unit of added blur variance (marker units²), towards the next
    /// level.
    pub blur_slope: f64,
    /// (T_xx − T_yy) / 2 and T_xy: how it changes when the blur grows in one direction more than
    /// in the other (the heat equation: ∂T/∂C = ½ ∇²T).
    pub half_difference: f64,
    pub cross: f64,
}

#[derive(Debug, Clone)]
pub struct Template {
    pub family: String,
    pub id: usize,
    pub texels_per_unit: f64,
    /// Sharpest first; each level's blur is √2 times the one before.
    pub levels: Vec<Level>,
    /// The scene's top-left corner in marker units.
    pub(crate) origin: [f64; 2],
    /// The smallest keypoint's size (marker units): a grid's cell, a ring's dot.
    pub feature_size: f64,
    /// Where the alignment compares (marker units, x0, y0, x1, y1): the marker and a little of its
    /// quiet zone — printed markers often have less than the family asks for.
    pub support: [f64; 4],
}

impl Template {
    /// The texel density for a marker of `family` seen at `pixels_per_unit`: at least 1.4
    /// texels per pixel (the sharpest level used, one texel of blur, is then 0.7 px: sharper than
    /// any lens and pixel together), a power of two, at most [`MAX_TEXELS_ACROSS`].
    pub fn texels_for(family: &Family, pixels_per_unit: f64) -> f64 {
        let area = family.extent().grow(family.quiet_zone());
        let across = area.width().max(area.height());
        let most = (MAX_TEXELS_ACROSS / across).log2().floor().exp2();
        let least = (MIN_TEXELS_ACROSS / across).log2().ceil().exp2();
        (TEXELS_PER_PIXEL * pixels_per_unit)
            .log2()
            .ceil()
            .exp2()
            .min(most)
            .max(least)
    }

    /// Renders ID `id` of `family` (its print quiet zone included) with `texels_per_unit` (a
    /// power of two) and builds the pyramid.
    pub fn render(family: &Family, id: usize, texels_per_unit: f64) -> Result<Self, RenderError> {
        let scene = marker_scene(family, id, SceneOptions::default())?;
        let units = scene.width_mm.max(scene.height_mm) / scene.scale;
        let sub = supersample(units * texels_per_unit);
        let pixmap = rasterize(&scene, sub as f64 * texels_per_unit / scene.scale)?;
        let (w, h) = (
            pixmap.width() as usize / sub,
            pixmap.height() as usize / sub,
        );
        let mut values = vec![0f32; w * h];
        let data = pixmap.data();
        let stride = pixmap.width() as usize;
        // Opaque scenes: the premultiplied bytes are the colour.
        let weight = 1.0 / (sub * sub) as f64;
        for y in 0..h {
            for x in 0..w {
                let mut sum = 0.0;
                for sy in 0..sub {
                    let row = (y * sub + sy) * stride;
                    for sx in 0..sub {
                        let p = &data[(row + x * sub + sx) * 4..][..3];
                        sum += luminance(p[0] as f32, p[1] as f32, p[2] as f32) as f64;
                    }
                }
                values[y * w + x] = (sum * weight) as f32;
            }
        }
        // Blur steps of √2: the fit's first-order blur term then bridges at most a doubling of
        // the variance between a level and the image. Each level is the one before blurred by the
        // missing variance; when the blur reaches two texels the texels are merged in pairs (the
        // merge is a blur of its own, counted), so a level has 0.7–2 texels per σ.
        let finest = texels_per_unit;
        // A box of one texel (coverage anti-aliasing, then the box average): variance 1/12.
        let mut variance = 1.0 / 12.0;
        let mut base = (values, w, h, 1.0f64); // values, size, texel size in finest texels
        let mut levels = Vec::new();
        // Levels blurred by less than a texel are interpolated with an error that depends on where
        // an edge falls between texels: the sharpest level has one texel of blur.
        let mut sigma = 1.0f64;
        while levels.len() < MAX_LEVELS {
            let (ref values, w, h, texel) = base;
            if sigma / texel >= 2.0 && w.min(h) >= 24 {
                let (merged, w2, h2) = merge_pairs(values, w, h);
                variance += texel * texel / 4.0;
                base = (merged, w2, h2, 2.0 * texel);
                continue;
            }
            let extra = ((sigma * sigma - variance).max(0.0)).sqrt() / texel;
            let (blurred, added) = gaussian(values, w, h, extra);
            variance += added * texel * texel;
            levels.push(Level::new(
                w,
                h,
                blurred.clone(),
                finest / texel,
                variance.sqrt() / finest,
            ));
            base = (blurred, w, h, texel);
            if w.min(h) < 24 && sigma / texel >= 1.4 {
                break;
            }
            sigma *= std::f64::consts::SQRT_2;
        }
        let origin = scene.origin;
        let mut template = Self {
            family: family.name().to_string(),
            id,
            texels_per_unit,
            levels,
            origin,
            feature_size: family
                .keypoints()
                .iter()
                .map(|k| k.size)
                .fold(f64::INFINITY, f64::min)
                .min(family.cell_size()),
            support: {
                let e = family.extent();
                let margin = family.quiet_zone().min(0.5 * family.cell_size());
                [
                    e.min[0] - margin,
                    e.min[1] - margin,
                    e.max[0] + margin,
                    e.max[1] + margin,
                ]
            },
        };
        for k in 0..template.levels.len() {
            template.select_flat(k);
            template.fill_blur_slope(k);
        }
        // The gray values are in the texels too; the plain copy only served the next level.
        for level in &mut template.levels {
            level.values = Vec::new();
        }
        Ok(template)
    }

    /// The memory the template holds, bytes (for the cache's budget).
    pub fn bytes(&self) -> usize {
        self.levels
            .iter()
            .map(|l| {
                l.texels.len() * std::mem::size_of::<[f32; 6]>()
                    + l.edge_cells.len()
                    + l.flat.len() * std::mem::size_of::<[f64; 2]>()
            })
            .sum()
    }

    /// Marker units of a texel centre of level `k`.
    fn texel_to_units(&self, k: usize, x: f64, y: f64) -> [f64; 2] {
        // Level k's texel i spans the finest texels i·2^k to (i+1)·2^k.
        let t = self.levels[k].texels_per_unit;
        [
            self.origin[0] + (x + 0.5) / t,
            self.origin[1] + (y + 0.5) / t,
        ]
    }

    fn select_flat(&mut self, k: usize) {
        let level = &self.levels[k];
        let (w, h) = (level.width, level.height);
        let mut flat = Vec::new();
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let [_, gx, gy, ..] = level.texels[y * w + x];
                let (gx, gy) = (gx as f64, gy as f64);
                if gx * gx + gy * gy < (0.002 * level.max_gradient).powi(2) {
                    flat.push((x, y));
                }
            }
        }
        let stride = flat.len().div_ceil(400).max(1);
        self.levels[k].flat = flat
            .iter()
            .step_by(stride)
            .map(|&(x, y)| self.texel_to_units(k, x as f64, y as f64))
            .collect();
    }

    /// The change of each texel of level `k` towards the next level per unit of blur variance:
    /// the fit then interpolates between two true blurs (exact at both ends; thin strokes do not
    /// follow a first-order extrapolation of one level).
    fn fill_blur_slope(&mut self, k: usize) {
        let Some(next) = self.levels.get(k + 1) else {
            return;
        };
        let level = &self.levels[k];
        let dv = next.blur_units.powi(2) - level.blur_units.powi(2);
        let (w, h) = (level.width, level.height);
        // The next level has the same texels or half as many each way (centred on pairs).
        let ratio = level.texels_per_unit / next.texels_per_unit;
        let (nw, nh) = (next.width, next.height);
        let mut slopes = vec![0f32; w * h];
        // Where each column falls on the next level, worked out once rather than per texel.
        let columns: Vec<(usize, usize, f32)> = (0..w)
            .map(|x| {
                let nx = ((x as f64 + 0.5) / ratio - 0.5).clamp(0.0, (nw - 1) as f64);
                let x0 = nx as usize;
                (x0, (x0 + 1).min(nw - 1), (nx - nx.floor()) as f32)
            })
            .collect();
        let per_variance = 1.0 / dv;
        for y in 0..h {
            let ny = ((y as f64 + 0.5) / ratio - 0.5).clamp(0.0, (nh - 1) as f64);
            let (y0, fy) = (ny as usize, (ny - ny.floor()) as f32);
            let y1 = (y0 + 1).min(nh - 1);
            for (x, &(x0, x1, fx)) in columns.iter().enumerate() {
                let v = &next.values;
                let at = crate::image::mix(
                    v[y0 * nw + x0],
                    v[y0 * nw + x1],
                    v[y1 * nw + x0],
                    v[y1 * nw + x1],
                    fx,
                    fy,
                );
                slopes[y * w + x] = ((at - level.values[y * w + x]) as f64 * per_variance) as f32;
            }
        }
        for (t, s) in self.levels[k].texels.iter_mut().zip(slopes) {
            t[3] = s;
        }
    }

    /// Value, gradient and blur slope of level `k` at `u` (marker units), bilinear; `None`
    /// outside the level and where the template is surely flat (gradient below [`EDGE`] × the
    /// level's largest everywhere between the four texels), without reading the texels then.
    #[inline(always)]
    pub fn lookup_edge(&self, k: usize, u: [f64; 2]) -> Option<Lookup> {
        let level = &self.levels[k];
        let t = level.texels_per_unit;
        let x = (u[0] - self.origin[0]) * t - 0.5;
        let y = (u[1] - self.origin[1]) * t - 0.5;
        if !(x >= 0.0 && y >= 0.0) {
            return None;
        }
        let (x0, y0) = (x as usize, y as usize);
        if x0 + 1 >= level.width || y0 + 1 >= level.height {
            return None;
        }
        if !level.edge_cells[y0 * level.width + x0] {
            return None;
        }
        let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
        let i = y0 * level.width + x0;
        let j = i + level.width;
        let t = &level.texels;
        let (a, b, c, d) = (t[i], t[i + 1], t[j], t[j + 1]);
        let weights = [
            (1.0 - fx) * (1.0 - fy),
            fx * (1.0 - fy),
            (1.0 - fx) * fy,
            fx * fy,
        ];
        let mix = |n: usize| {
            (weights[0] * a[n] + weights[1] * b[n] + weights[2] * c[n] + weights[3] * d[n]) as f64
        };
        Some(Lookup {
            value: mix(0),
            gradient: [mix(1), mix(2)],
            blur_slope: mix(3),
            half_difference: mix(4),
            cross: mix(5),
        })
    }
}

impl Level {
    fn new(
        width: usize,
        height: usize,
        values: Vec<f32>,
        texels_per_unit: f64,
        blur_units: f64,
    ) -> Self {
        let (w, h) = (width, height);
        let mut texels: Vec<[f32; 6]> = values
            .iter()
            .map(|&v| [v, 0.0, 0.0, 0.0, 0.0, 0.0])
            .collect();
        let mut max_gradient = 0f64;
        let second = (texels_per_unit * texels_per_unit) as f32;
        let scale = 0.5 * texels_per_unit as f32;
        for y in 1..h.saturating_sub(1) {
            for x in 1..w.saturating_sub(1) {
                let gx = (values[y * w + x + 1] - values[y * w + x - 1]) * scale;
                let gy = (values[(y + 1) * w + x] - values[(y - 1) * w + x]) * scale;
                let v = |dx: isize, dy: isize| {
                    values[(y as isize + dy) as usize * w + (x as isize + dx) as usize]
                };
                let txx = v(1, 0) - 2.0 * v(0, 0) + v(-1, 0);
                let tyy = v(0, 1) - 2.0 * v(0, 0) + v(0, -1);
                let txy = (v(1, 1) - v(1, -1) - v(-1, 1) + v(-1, -1)) / 4.0;
                texels[y * w + x][1] = gx;
                texels[y * w + x][2] = gy;
                texels[y * w + x][4] = 0.5 * (txx - tyy) * second;
                texels[y * w + x][5] = txy * second;
                max_gradient = max_gradient.max((gx * gx + gy * gy) as f64);
            }
        }
        let max_gradient = max_gradient.sqrt();
        // A hair below the threshold: the lookup's f32 rounding must not make a point pass that
        // the mask drops.
        let floor = (0.999 * EDGE * max_gradient).powi(2) as f32;
        let longest = |i: usize| {
            [i, i + 1, i + w, i + w + 1]
                .map(|j| texels[j][1] * texels[j][1] + texels[j][2] * texels[j][2])
                .into_iter()
                .fold(0f32, f32::max)
        };
        let edge_cells = (0..w * h)
            .map(|i| i % w + 1 < w && i / w + 1 < h && longest(i) >= floor)
            .collect();
        Self {
            width,
            height,
            values,
            texels,
            max_gradient,
            edge_cells,
            texels_per_unit,
            blur_units,
            flat: Vec::new(),
        }
    }
}

/// Averages texels in pairs along both axes: texel i of the result is centred between texels 2i
/// and 2i + 1 of the input, so the levels stay aligned with the finest texel grid.
fn merge_pairs(values: &[f32], w: usize, h: usize) -> (Vec<f32>, usize, usize) {
    let (w2, h2) = (w / 2, h / 2);
    let mut out = vec![0f32; w2 * h2];
    for y in 0..h2 {
        for x in 0..w2 {
            let at = |dx: usize, dy: usize| values[(2 * y + dy) * w + 2 * x + dx];
            out[y * w2 + x] = 0.25 * (at(0, 0) + at(1, 0) + at(0, 1) + at(1, 1));
        }
    }
    (out, w2, h2)
}

/// Separable Gaussian blur of σ texels (edges clamped); returns the image and the variance the
/// sampled kernel really adds.
fn gaussian(values: &[f32], w: usize, h: usize, sigma: f64) -> (Vec<f32>, f64) {
    if sigma < 0.05 {
        return (values.to_vec(), 0.0);
    }
    let radius = (3.0 * sigma).ceil() as isize;
    let raw: Vec<f64> = (-radius..=radius)
        .map(|t| (-(t * t) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let total: f64 = raw.iter().sum();
    let kernel: Vec<f32> = raw.iter().map(|k| (k / total) as f32).collect();
    let variance: f64 = (-radius..=radius)
        .zip(&raw)
        .map(|(t, k)| (t * t) as f64 * k / total)
        .sum();
    let r = radius as usize;
    // Rows through a buffer padded with the edge values, then columns as weighted sums of whole
    // rows: both inner loops are plain contiguous multiply-adds.
    let mut line = vec![0f32; w + 2 * r];
    let mut rows = vec![0f32; w * h];
    for y in 0..h {
        let src = &values[y * w..(y + 1) * w];
        line[..r].fill(src[0]);
        line[r..r + w].copy_from_slice(src);
        line[r + w..].fill(src[w - 1]);
        for (x, out) in rows[y * w..(y + 1) * w].iter_mut().enumerate() {
            *out = line[x..x + kernel.len()]
                .iter()
                .zip(&kernel)
                .map(|(a, b)| a * b)
                .sum();
        }
    }
    let mut out = vec![0f32; w * h];
    for y in 0..h {
        let dst = &mut out[y * w..(y + 1) * w];
        for (t, k) in kernel.iter().enumerate() {
            let sy = (y as isize + t as isize - radius).clamp(0, h as isize - 1) as usize;
            let src = &rows[sy * w..(sy + 1) * w];
            for (d, s) in dst.iter_mut().zip(src) {
                *d += k * s;
            }
        }
    }
    // Two axes, each adding `variance` along its own direction: per axis it is `variance`.
    (out, variance)
}
