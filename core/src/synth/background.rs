//! Backgrounds: random crops of the photographs in `assets/backgrounds/` (freely licensed, see
//! the README there) or procedural textures (gradients, value noise), with clutter that looks like
//! markers on top (dark and light rectangles and bars), so the detector learns what is *not* one.

use super::Canvas;
use crate::image::GrayImage;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::sync::OnceLock;

fn photos() -> &'static [GrayImage] {
    static DECODED: OnceLock<Vec<GrayImage>> = OnceLock::new();
    DECODED.get_or_init(|| {
        (crate::assets::BACKGROUNDS.iter())
            .map(|path| {
                crate::image::decode(crate::assets::file(path), &Default::default())
                    .unwrap_or_else(|e| panic!("background {path}: {e}"))
            })
            .collect()
    })
}

/// A photograph, randomly cropped, scaled, flipped and re-lit to fill the canvas.
fn photo(rng: &mut ChaCha8Rng, width: u32, height: u32) -> Canvas {
    let all = photos();
    let p = &all[rng.random_range(0..all.len())];
    // Pixels of the photo per canvas pixel: from a zoomed-in crop to the whole photo squeezed.
    let fit = (p.width as f32 / width as f32).min(p.height as f32 / height as f32);
    let scale = fit * rng.random_range(0.3..1.0f32);
    let (span_x, span_y) = (width as f32 * scale, height as f32 * scale);
    let (x0, y0) = (
        rng.random_range(0.0..=(p.width as f32 - span_x).max(0.0)),
        rng.random_range(0.0..=(p.height as f32 - span_y).max(0.0)),
    );
    let flip = rng.random_bool(0.5);
    let (gain, offset) = (
        rng.random_range(0.6..1.2f32),
        rng.random_range(-0.2..0.2f32),
    );
    let src = Canvas {
        width: p.width,
        height: p.height,
        pixels: p.pixels.iter().map(|&v| v as f32 / 255.0).collect(),
    };
    let mut c = Canvas::new(width, height, 0.0);
    for y in 0..height {
        for x in 0..width {
            let u = if flip { width - 1 - x } else { x };
            let v = src.sample(x0 + u as f32 * scale, y0 + y as f32 * scale);
            c.set(x, y, gain * v + offset);
        }
    }
    c
}

pub fn procedural(rng: &mut ChaCha8Rng, width: u32, height: u32) -> Canvas {
    let mut c = if rng.random_bool(0.5) {
        photo(rng, width, height)
    } else {
        texture(rng, width, height)
    };
    clutter(&mut c, rng);
    c.clamp();
    c
}

fn texture(rng: &mut ChaCha8Rng, width: u32, height: u32) -> Canvas {
    let mut c = Canvas::new(width, height, 0.0);
    // A gradient between two random gray levels along a random direction.
    let (a, b) = (rng.random_range(0.1..0.9f32), rng.random_range(0.1..0.9f32));
    let angle = rng.random_range(0.0..std::f32::consts::TAU);
    let (dx, dy) = (angle.cos() / width as f32, angle.sin() / height as f32);
    // Coarse value noise, bilinearly upsampled: texture at a random scale.
    let cells = rng.random_range(3..24u32);
    let (gw, gh) = (cells + 2, (cells * height / width.max(1)).max(1) + 2);
    let grid: Vec<f32> = (0..gw * gh)
        .map(|_| rng.random_range(-0.25..0.25))
        .collect();
    let noise_gain = rng.random_range(0.0..1.0f32);
    for y in 0..height {
        for x in 0..width {
            let t = (x as f32 * dx + y as f32 * dy).rem_euclid(1.0);
            let gx = x as f32 / width as f32 * (gw - 2) as f32;
            let gy = y as f32 / height as f32 * (gh - 2) as f32;
            let (ix, iy) = (gx as usize, gy as usize);
            let (fx, fy) = (gx.fract(), gy.fract());
            let at = |i: usize, j: usize| grid[j * gw as usize + i];
            let n = (at(ix, iy) * (1.0 - fx) + at(ix + 1, iy) * fx) * (1.0 - fy)
                + (at(ix, iy + 1) * (1.0 - fx) + at(ix + 1, iy + 1) * fx) * fy;
            c.set(x, y, a + (b - a) * t + noise_gain * n);
        }
    }
    c
}

fn clutter(c: &mut Canvas, rng: &mut ChaCha8Rng) {
    let (width, height) = (c.width, c.height);
    // Clutter: rectangles and bars in dark or light gray, some of them square like tags.
    for _ in 0..rng.random_range(0..12) {
        let w = rng.random_range(0.02..0.3) * width as f32;
        let h = if rng.random_bool(0.4) {
            w
        } else {
            rng.random_range(0.01..0.3) * height as f32
        };
        let (x0, y0) = (
            rng.random_range(-0.1..1.0) * width as f32,
            rng.random_range(-0.1..1.0) * height as f32,
        );
        let value = if rng.random_bool(0.5) {
            rng.random_range(0.0..0.25)
        } else {
            rng.random_range(0.75..1.0)
        };
        let (s, co) = rng.random_range(0.0..std::f32::consts::PI).sin_cos();
        let (cx, cy) = (x0 + w / 2.0, y0 + h / 2.0);
        let reach = (w.hypot(h) / 2.0).ceil() as i64;
        for y in (cy as i64 - reach).max(0)..(cy as i64 + reach).min(height as i64) {
            for x in (cx as i64 - reach).max(0)..(cx as i64 + reach).min(width as i64) {
                let (px, py) = (x as f32 - cx, y as f32 - cy);
                let (u, v) = (co * px + s * py, -s * px + co * py);
                if u.abs() <= w / 2.0 && v.abs() <= h / 2.0 {
                    c.set(x as u32, y as u32, value);
                }
            }
        }
    }
}
