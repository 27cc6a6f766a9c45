//! The verifier's samples: one cluttered scene each, its candidate quads as the detector meets
//! them — stage 1's first selection and the outline and traced searches, run by the shipped
//! stage 1 — labelled against the scene's truth, with the markers' own outlines (jittered as a
//! stage-1 ROI is) added as positives so that every marker counts, including those stage 1
//! misses, and with quads inside or around a marker as negatives (a data cell, a row of
//! markers: quads whose reads decode to nothing or to a wrong code).
//!
//! Sample `i` of a run is a pure function of (run seed, i).

use crate::detect::stage1::{ProposeOptions, Stage1};
use crate::detect::verifier::input_patch;
use crate::family::Family;
use crate::geometry::Quad;
use crate::image::GrayImage;
use crate::synth::{synthesize_mixed, Mode, SynthConfig};
use crate::train::stage1::data::camera_look;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A candidate within this share of the marker's longest side at every corner (in the best of
/// the four turns) frames the marker: stage 2 reads ROIs off by a tenth of the side.
pub const POSITIVE_MOVE: f64 = 0.2;
/// A candidate whose best match moves a corner by more than this share frames no marker.
pub const NEGATIVE_MOVE: f64 = 0.5;
/// Jitter of a marker's own outline, as a share of its longest side (standard deviation).
const JITTER: f64 = 0.04;

pub struct VerifierSample {
    pub image: GrayImage,
    pub quads: Vec<Quad>,
    /// 1 for a quad framing a marker, 0 for one framing none.
    pub labels: Vec<f32>,
    /// The normalised patches, one per quad.
    pub patches: Vec<f32>,
    /// How many of the quads (the first) are the scene's own candidates; the markers' outlines
    /// and the quads inside and around them follow.
    pub candidates: usize,
}

/// The scene of sample `seed`: 1–3 families, 0–4 markers, half through a camera.
pub fn make_sample(
    families: &[Family],
    stage1: &Stage1,
    patch: usize,
    seed: u64,
) -> Result<VerifierSample, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let count = rng.random_range(1..=3usize.min(families.len()));
    let chosen: Vec<&Family> = (0..count)
        .map(|_| &families[rng.random_range(0..families.len())])
        .collect();
    let camera = rng.random_bool(0.5);
    let mut config = SynthConfig::new(if camera { Mode::Camera } else { Mode::Quad });
    (config.width, config.height) = if rng.random_bool(0.5) {
        (480, 360)
    } else {
        (320, 320)
    };
    let (lo, hi) = (0.04f64.ln(), 0.5f64.ln());
    let side = rng.random_range(lo..hi).exp();
    config.quad_side = [side, side * 1.3];
    config.distance_m = [0.1, 1.0];
    config.view_angle_deg = [0.0, 78.0];
    config.markers = if rng.random_bool(0.15) {
        [0, 0]
    } else {
        [1, 4]
    };
    camera_look(&mut config, &mut rng);
    let scene = synthesize_mixed(&chosen, &config, rng.random()).map_err(|e| e.to_string())?;
    let truth: Vec<Quad> = (scene.truth.markers.iter())
        .filter_map(|m| Quad::try_from(&m.roi[..]).ok())
        .collect();
    let mut image = scene.image;
    let mut distractors = Vec::new();
    for _ in 0..rng.random_range(0..=4) {
        if let Some(quad) = paint_distractor(&mut image, &truth, &mut rng) {
            distractors.push(quad);
        }
    }
    let candidates = candidates(stage1, &image);
    let mut quads = Vec::new();
    let mut labels = Vec::new();
    for quad in candidates {
        let label = match best_move(&quad, &truth) {
            Some(m) if m <= POSITIVE_MOVE => 1.0,
            Some(m) if m <= NEGATIVE_MOVE => continue,
            _ => 0.0,
        };
        quads.push(quad);
        labels.push(label);
    }
    let own = quads.len();
    // The distractors' own outlines: stage 1 may not propose them here, but on a photograph it
    // proposes their like.
    for d in distractors {
        quads.push(d);
        labels.push(0.0);
    }
    for t in &truth {
        let side = t.longest_side();
        for k in 0..2 {
            let jitter = if k == 0 { JITTER / 2.0 } else { JITTER };
            quads.push(t.map(|[x, y]| {
                [
                    x + normal(&mut rng) * jitter * side,
                    y + normal(&mut rng) * jitter * side,
                ]
            }));
            labels.push(1.0);
        }
        // A quarter of the marker somewhere inside it (a data cell or a group of them), and
        // the marker with its surroundings.
        let inner = rng.random_range(0.2..0.45);
        let at = [rng.random_range(0.25..0.75), rng.random_range(0.25..0.75)];
        quads.push(part_of(t, at, inner));
        labels.push(0.0);
        quads.push(t.scaled(rng.random_range(1.8..2.6)));
        labels.push(0.0);
    }
    let mut patches = Vec::with_capacity(quads.len() * patch * patch);
    let mut kept_quads = Vec::with_capacity(quads.len());
    let mut kept_labels = Vec::with_capacity(quads.len());
    let mut kept_candidates = 0;
    for (i, (quad, label)) in quads.into_iter().zip(labels).enumerate() {
        if let Some(p) = input_patch(&image, &quad, patch) {
            patches.extend(p);
            kept_quads.push(quad);
            kept_labels.push(label);
            kept_candidates += usize::from(i < own);
        }
    }
    Ok(VerifierSample {
        image,
        quads: kept_quads,
        labels: kept_labels,
        patches,
        candidates: kept_candidates,
    })
}

/// The quads the detector's first selections meet: stage 1's grouping, the outlined and the
/// traced quads (none read yet).
pub fn candidates(stage1: &Stage1, image: &GrayImage) -> Vec<Quad> {
    let search = stage1.search(image, &ProposeOptions::default());
    let mut out: Vec<Quad> = search
        .proposals(&[], &[])
        .iter()
        .map(|p| p.corners)
        .collect();
    for outlined in [search.outline(image, &[]), search.traced(image, &[])] {
        out.extend(outlined.proposals(&[], &[]).iter().map(|p| p.corners));
    }
    out
}

/// The smallest, over the true outlines and the four turns of `quad`, of the largest corner move
/// as a share of the outline's longest side; `None` without a true outline.
pub fn best_move(quad: &Quad, truth: &[Quad]) -> Option<f64> {
    truth
        .iter()
        .flat_map(|t| {
            (0..4).map(move |turn| {
                let turned = Quad(std::array::from_fn(|i| quad[(i + turn) % 4]));
                turned.largest_corner_move(t) / t.longest_side().max(1e-9)
            })
        })
        .min_by(f64::total_cmp)
}

/// The part of `quad` around its unit-square point `at`, `share` of its side across.
fn part_of(quad: &Quad, at: [f64; 2], share: f64) -> Quad {
    let point = |u: f64, v: f64| {
        let top = lerp(quad[0], quad[1], u);
        let bottom = lerp(quad[3], quad[2], u);
        lerp(top, bottom, v)
    };
    let h = share / 2.0;
    Quad([
        point(at[0] - h, at[1] - h),
        point(at[0] + h, at[1] - h),
        point(at[0] + h, at[1] + h),
        point(at[0] - h, at[1] + h),
    ])
}

fn lerp(a: [f64; 2], b: [f64; 2], t: f64) -> [f64; 2] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t]
}

/// A standard normal draw (Box–Muller).
fn normal(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = rng.random_range(f64::EPSILON..1.0);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// Kinds of clutter that frame like a marker without being one: what stage 1 proposes on
/// photographs (boards, tiles, keyboards, text) and the procedural backgrounds lack.
#[derive(Clone, Copy)]
enum Distractor {
    Checkerboard,
    Tiles,
    Text,
    Window,
}

/// Paints a distractor at a random place away from the markers (their outlines grown by half);
/// returns its outline, or `None` where there was no room.
fn paint_distractor(image: &mut GrayImage, truth: &[Quad], rng: &mut ChaCha8Rng) -> Option<Quad> {
    let (w, h) = (image.width as f64, image.height as f64);
    let side = rng.random_range(0.06..0.35) * w.min(h);
    let aspect = if rng.random_bool(0.6) {
        1.0
    } else {
        rng.random_range(0.4..2.5)
    };
    let (half_u, half_v) = (side / 2.0, side * aspect / 2.0);
    let centre = [rng.random_range(0.0..w), rng.random_range(0.0..h)];
    let angle: f64 = rng.random_range(0.0..std::f64::consts::PI);
    let (sin, cos) = angle.sin_cos();
    let corner = |u: f64, v: f64| [centre[0] + cos * u - sin * v, centre[1] + sin * u + cos * v];
    let outline = Quad([
        corner(-half_u, -half_v),
        corner(half_u, -half_v),
        corner(half_u, half_v),
        corner(-half_u, half_v),
    ]);
    let grown: Vec<Quad> = truth.iter().map(|t| t.scaled(1.5)).collect();
    let [x0, y0, x1, y1] = outline.bounding_box();
    let clear = |q: &Quad| {
        let [a0, b0, a1, b1] = q.bounding_box();
        a1 < x0 || a0 > x1 || b1 < y0 || b0 > y1
    };
    if !grown.iter().all(clear) {
        return None;
    }
    let kind = [
        Distractor::Checkerboard,
        Distractor::Tiles,
        Distractor::Text,
        Distractor::Window,
    ][rng.random_range(0..4)];
    let cells = rng.random_range(3..9) as f64;
    let dark = rng.random_range(0..70) as u8;
    let light = rng.random_range(170..=255) as u8;
    let glyphs: Vec<bool> = (0..256).map(|_| rng.random_bool(0.55)).collect();
    let (width, height) = (image.width as i64, image.height as i64);
    for y in (y0.floor() as i64).max(0)..(y1.ceil() as i64).min(height) {
        for x in (x0.floor() as i64).max(0)..(x1.ceil() as i64).min(width) {
            let (dx, dy) = (x as f64 - centre[0], y as f64 - centre[1]);
            let (u, v) = (cos * dx + sin * dy, -sin * dx + cos * dy);
            if u.abs() > half_u || v.abs() > half_v {
                continue;
            }
            // Unit coordinates across the distractor.
            let (s, t) = ((u + half_u) / (2.0 * half_u), (v + half_v) / (2.0 * half_v));
            let (i, j) = ((s * cells) as usize, (t * cells) as usize);
            let (fs, ft) = ((s * cells).fract(), (t * cells).fract());
            let is_dark = match kind {
                Distractor::Checkerboard => (i + j).is_multiple_of(2),
                Distractor::Tiles => fs > 0.12 && ft > 0.12,
                // Rows of glyph-like blocks with gaps between lines and words.
                Distractor::Text => {
                    let line = (t * 2.0 * cells) as usize;
                    let column = (s * 4.0 * cells) as usize;
                    line.is_multiple_of(2)
                        && glyphs[(line * 31 + column) % 256]
                        && (s * 4.0 * cells).fract() > 0.2
                }
                Distractor::Window => {
                    let frame = 0.08;
                    s < frame
                        || s > 1.0 - frame
                        || t < frame
                        || t > 1.0 - frame
                        || (s - 0.5).abs() < frame / 2.0
                }
            };
            image.pixels[y as usize * image.width as usize + x as usize] =
                if is_dark { dark } else { light };
        }
    }
    Some(outline)
}
