//! Image augmentations on a float canvas (0 = black, 1 = white). Each takes its strength as an
//! argument; `AugmentRanges` says from which ranges the synthesiser draws them.

use super::Canvas;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// Parameter ranges of the augmentations (documented defaults; sigmas in pixels or gray levels
/// of 0–255).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AugmentRanges {
    /// Gray level a marker's black is drawn with (0–255).
    pub marker_black: [f32; 2],
    /// Gray level a marker's white is drawn with (0–255).
    pub marker_white: [f32; 2],
    /// Per-channel gain range of a random white balance, applied to the marker's colours before
    /// they are turned to gray (families may use coloured patterns).
    #[serde(default = "unit_gain")]
    pub white_balance: [f32; 2],
    /// Probability and gain range of a spotlight (a radial brightening/darkening).
    pub spotlight_probability: f64,
    pub spotlight_gain: [f32; 2],
    /// Gaussian blur sigma in pixels.
    pub blur_sigma: [f32; 2],
    /// Gaussian noise sigma in gray levels.
    pub noise_sigma: [f32; 2],
    /// Probability and kernel length (pixels) of a linear motion blur.
    pub motion_blur_probability: f64,
    pub motion_blur_length: [u32; 2],
    /// Probability that a single marker moves: a motion blur over its own region only.
    #[serde(default)]
    pub marker_motion_blur_probability: f64,
    /// Direction range of the motion blur, degrees.
    #[serde(default = "half_turn")]
    pub motion_blur_angle_deg: [f32; 2],
    /// Probability and k1 range of barrel distortion (k1 < 0), applied to the whole image and to
    /// the ground truth with the same model.
    pub barrel_probability: f64,
    pub barrel_k1: [f64; 2],
}

fn unit_gain() -> [f32; 2] {
    [1.0, 1.0]
}

fn half_turn() -> [f32; 2] {
    [0.0, 180.0]
}

impl Default for AugmentRanges {
    fn default() -> Self {
        Self {
            marker_black: [0.0, 90.0],
            marker_white: [150.0, 255.0],
            white_balance: [0.85, 1.15],
            spotlight_probability: 0.3,
            spotlight_gain: [-0.35, 0.35],
            blur_sigma: [0.0, 1.5],
            noise_sigma: [0.0, 12.0],
            motion_blur_probability: 0.2,
            motion_blur_length: [3, 11],
            marker_motion_blur_probability: 0.15,
            motion_blur_angle_deg: half_turn(),
            barrel_probability: 0.25,
            // Past r = 1/sqrt(3|k1|) the model folds back; at -0.18 that stays outside a 98° frame.
            barrel_k1: [-0.18, -0.02],
        }
    }
}

impl AugmentRanges {
    /// No augmentation at all: exact renderings, for tests and ground-truth checks.
    pub fn none() -> Self {
        Self {
            marker_black: [0.0, 0.0],
            marker_white: [255.0, 255.0],
            white_balance: unit_gain(),
            spotlight_probability: 0.0,
            spotlight_gain: [0.0, 0.0],
            blur_sigma: [0.0, 0.0],
            noise_sigma: [0.0, 0.0],
            motion_blur_probability: 0.0,
            motion_blur_length: [1, 1],
            marker_motion_blur_probability: 0.0,
            motion_blur_angle_deg: half_turn(),
            barrel_probability: 0.0,
            barrel_k1: [0.0, 0.0],
        }
    }
}

/// Draws from [lo, hi] (a point range returns lo).
pub fn draw(rng: &mut ChaCha8Rng, r: [f32; 2]) -> f32 {
    if r[1] > r[0] {
        rng.random_range(r[0]..=r[1])
    } else {
        r[0]
    }
}

/// Multiplies by 1 + gain·falloff around a random centre.
pub fn spotlight(c: &mut Canvas, rng: &mut ChaCha8Rng, gain: f32) {
    let (cx, cy) = (
        rng.random_range(0.0..c.width as f32),
        rng.random_range(0.0..c.height as f32),
    );
    let radius = rng.random_range(0.2..0.8) * c.width.max(c.height) as f32;
    for y in 0..c.height {
        for x in 0..c.width {
            let d2 = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)) / (radius * radius);
            let v = c.get(x, y) * (1.0 + gain * (-d2).exp());
            c.set(x, y, v);
        }
    }
}

/// Separable Gaussian blur.
pub fn gaussian_blur(c: &mut Canvas, sigma: f32) {
    if sigma < 0.3 {
        return;
    }
    let r = (3.0 * sigma).ceil() as i64;
    let kernel: Vec<f32> = (-r..=r)
        .map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / sum).collect();
    convolve_line(c, &kernel, true);
    convolve_line(c, &kernel, false);
}

fn convolve_line(c: &mut Canvas, kernel: &[f32], horizontal: bool) {
    let r = (kernel.len() / 2) as i64;
    let (w, h) = (c.width as i64, c.height as i64);
    let src = c.pixels.clone();
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for (k, weight) in kernel.iter().enumerate() {
                let o = k as i64 - r;
                let (sx, sy) = if horizontal {
                    ((x + o).clamp(0, w - 1), y)
                } else {
                    (x, (y + o).clamp(0, h - 1))
                };
                acc += weight * src[(sy * w + sx) as usize];
            }
            c.pixels[(y * w + x) as usize] = acc;
        }
    }
}

/// Averages `length` samples along a line at `angle` (radians): a linear motion blur.
pub fn motion_blur(c: &mut Canvas, length: u32, angle: f32) {
    if length < 2 {
        return;
    }
    let src = c.clone();
    let (dx, dy) = (angle.cos(), angle.sin());
    let half = (length - 1) as f32 / 2.0;
    for y in 0..c.height {
        for x in 0..c.width {
            let mut acc = 0.0;
            for i in 0..length {
                let t = i as f32 - half;
                acc += src.sample(x as f32 + t * dx, y as f32 + t * dy);
            }
            c.set(x, y, acc / length as f32);
        }
    }
}

/// Motion blur of the rectangle [x0, x1] × [y0, y1] only (clamped to the canvas).
pub fn motion_blur_region(c: &mut Canvas, region: [f64; 4], length: u32, angle: f32) {
    let x0 = region[0].floor().max(0.0) as u32;
    let y0 = region[1].floor().max(0.0) as u32;
    let x1 = (region[2].ceil().max(0.0) as u32).min(c.width.saturating_sub(1));
    let y1 = (region[3].ceil().max(0.0) as u32).min(c.height.saturating_sub(1));
    if x1 <= x0 || y1 <= y0 {
        return;
    }
    let mut part = Canvas::new(x1 - x0 + 1, y1 - y0 + 1, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            part.set(x - x0, y - y0, c.get(x, y));
        }
    }
    motion_blur(&mut part, length, angle);
    for y in y0..=y1 {
        for x in x0..=x1 {
            c.set(x, y, part.get(x - x0, y - y0));
        }
    }
}

/// Adds Gaussian noise with `sigma` in gray levels (of 255).
pub fn noise(c: &mut Canvas, rng: &mut ChaCha8Rng, sigma: f32) {
    if sigma <= 0.0 {
        return;
    }
    let s = sigma / 255.0;
    for p in c.pixels.iter_mut() {
        // Box–Muller with one of the pair used: simple and fast enough at these sizes.
        let (u1, u2): (f32, f32) = (rng.random_range(1e-7..1.0), rng.random());
        *p += s * (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
    }
}
