//! Anti-aliased rasters of a scene through tiny-skia.

use super::primitives::Seg;
use super::scene::{MarkerScene, RenderError};
use crate::color::Rgb;
use tiny_skia::{FillRule, Paint, PathBuilder, Pixmap, Stroke, Transform};

/// Renders a marker with `px_per_mm` pixels per millimetre.
pub fn rasterize(scene: &MarkerScene, px_per_mm: f64) -> Result<Pixmap, RenderError> {
    let w = (scene.width_mm * px_per_mm).round();
    let h = (scene.height_mm * px_per_mm).round();
    if !(w >= 1.0 && h >= 1.0 && w * h <= 400e6) {
        return Err(RenderError::Layout(format!(
            "a {w}×{h} px image is not possible; pick a size between 1 px and 20000×20000 px"
        )));
    }
    let mut pixmap = Pixmap::new(w as u32, h as u32).expect("size checked above");
    // Scale so that the scene spans the whole image exactly even after rounding to pixels.
    let t = Transform::from_scale((w / scene.width_mm) as f32, (h / scene.height_mm) as f32);
    for item in &scene.items {
        let Some(path) = to_skia(&item.path.0) else {
            continue;
        };
        if let Some(c) = item.fill {
            pixmap.fill_path(&path, &paint(c), FillRule::Winding, t, None);
        }
        if let Some((c, width)) = item.stroke {
            let stroke = Stroke {
                width: width as f32,
                ..Stroke::default()
            };
            pixmap.stroke_path(&path, &paint(c), &stroke, t, None);
        }
    }
    Ok(pixmap)
}

/// Renders a marker `width_px` pixels wide (quiet zone included).
pub fn rasterize_width(scene: &MarkerScene, width_px: u32) -> Result<Pixmap, RenderError> {
    rasterize(scene, width_px as f64 / scene.width_mm)
}

pub fn encode_png(pixmap: &Pixmap) -> Result<Vec<u8>, RenderError> {
    pixmap
        .encode_png()
        .map_err(|e| RenderError::Encode(e.to_string()))
}

fn paint(c: Rgb) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(c.0, c.1, c.2, 255);
    p.anti_alias = true;
    p
}

fn to_skia(segs: &[Seg]) -> Option<tiny_skia::Path> {
    let mut pb = PathBuilder::new();
    for s in segs {
        match *s {
            Seg::Move(x, y) => pb.move_to(x as f32, y as f32),
            Seg::Line(x, y) => pb.line_to(x as f32, y as f32),
            Seg::Cubic(a, b, c, d, x, y) => {
                pb.cubic_to(a as f32, b as f32, c as f32, d as f32, x as f32, y as f32)
            }
            Seg::Close => pb.close(),
        }
    }
    pb.finish()
}

/// Gray level (0–255) of a pixel, from the premultiplied RGBA (opaque scenes).
pub fn gray_at(pixmap: &Pixmap, x: u32, y: u32) -> f64 {
    let p = pixmap.pixel(x, y).expect("inside the image");
    Rgb(p.red(), p.green(), p.blue()).luminance() * 255.0
}
