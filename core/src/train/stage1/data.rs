//! Stage 1's training scenes at 256², one family per scene drawn from the stage's families
//! (square built-ins and random designs): half in the synthesiser's quad mode with marker
//! sides log-uniform from 12 px to about 160 px (larger markers are found on a coarser pyramid
//! level), half in camera mode (98°, 0.1–0.8 m, views up to 78°, half of them steeper than 55°);
//! some scenes empty, some with heavy noise.
//!
//! Sample `i` of a run is a pure function of (run seed, i).

use crate::detect::stage1::targets::{cells_inside, encode, MarkerQuad, Targets};
use crate::detect::stage2::normalise_patch;
use crate::family::Family;
use crate::geometry::Quad;
use crate::image::GrayImage;
use crate::synth::{synthesize, Mode, SynthConfig};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Scene side in pixels.
pub const SCENE: u32 = 256;

pub struct SceneSample {
    pub image: GrayImage,
    /// [`normalise_patch`] of the image: the network's input.
    pub input: Vec<f32>,
    pub targets: Targets,
    /// Per-cell weight of the mask loss (see [`mask_weights`]).
    pub mask_weight: Vec<f32>,
    /// The markers' ROI corners, for validation.
    pub quads: Vec<Quad>,
}

/// The scene of sample `seed`.
pub fn make_sample(families: &[Family], seed: u64) -> Result<SceneSample, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let family = &families[rng.random_range(0..families.len())];
    // Half the scenes through a camera: steep views foreshorten a marker far more than the quad
    // mode's jittered squares, and markers may leave the frame. With views uniform to 75° on a
    // third of the scenes, the shipped model of 2026-11-30 missed 13 of the harness's 65
    // Difficult markers, every one seen at 65–75°: a steep view was 7 % of its scenes.
    let camera = rng.random_bool(0.5);
    let mut config = SynthConfig::new(if camera { Mode::Camera } else { Mode::Quad });
    config.width = SCENE;
    config.height = SCENE;
    let (lo, hi) = (0.05f64.ln(), 0.62f64.ln());
    let side = rng.random_range(lo..hi).exp();
    config.quad_side = [side, side * 1.2];
    config.distance_m = [0.1, 0.8];
    config.view_angle_deg = if rng.random_bool(0.5) {
        [55.0, 78.0]
    } else {
        [0.0, 78.0]
    };
    config.markers = if rng.random_bool(0.08) {
        [0, 0]
    } else if camera {
        [1, 3]
    } else {
        [1, 4]
    };
    camera_look(&mut config, &mut rng);
    let sample = synthesize(family, &config, rng.random()).map_err(|e| e.to_string())?;
    let quads: Vec<MarkerQuad> = sample
        .truth
        .markers
        .iter()
        .map(|m| MarkerQuad {
            corners: Quad([m.roi[0], m.roi[1], m.roi[2], m.roi[3]]),
            outline: m.mask.clone(),
        })
        .collect();
    let targets = encode(SCENE as usize, SCENE as usize, &quads);
    Ok(SceneSample {
        input: normalise_patch(&sample.image),
        image: sample.image,
        mask_weight: mask_weights(&targets, &quads),
        targets,
        quads: quads.iter().map(|q| q.corners).collect(),
    })
}

/// How a camera spoils the family-free networks' training scenes (stage 1's, the verifier's):
/// motion blur, defocus, and heavy sensor noise on a fifth of them.
pub fn camera_look(config: &mut SynthConfig, rng: &mut ChaCha8Rng) {
    config.augment.motion_blur_length = [3, 15];
    config.augment.blur_sigma = [0.0, 2.0];
    if rng.random_bool(0.2) {
        // Past σ = 90 too: the harness's noise sweep asks for half the markers at σ = 125.
        config.augment.noise_sigma = [15.0, 130.0];
    }
}

/// A marker's mask cells count as if it covered this many cells, when it covers fewer.
const MASK_EVEN_CELLS: f64 = 64.0;
/// The most weight one mask cell gets.
const MASK_MOST_WEIGHT: f64 = 4.0;

/// Weights of the mask loss: 1 on the background, and on a small marker's cells
/// `sqrt(64 / cells)` (at most 4), so that a marker covering 12 cells weighs more like a large one.
/// Under a plain mean the background and the large markers decide the loss, and the network
/// learned to put a thin far marker's mask under the detector's threshold (0.07 on a 60-cm
/// sliver where the traced search needs 0.1).
pub fn mask_weights(targets: &Targets, quads: &[MarkerQuad]) -> Vec<f32> {
    let mut weights = vec![1.0f32; targets.mask.len()];
    for q in quads {
        let cells: Vec<usize> = cells_inside(&q.outline, targets.columns, targets.rows).collect();
        if cells.is_empty() {
            continue;
        }
        let w = (MASK_EVEN_CELLS / cells.len() as f64)
            .sqrt()
            .clamp(1.0, MASK_MOST_WEIGHT) as f32;
        for i in cells {
            weights[i] = weights[i].max(w);
        }
    }
    weights
}
