//! Anti-aliased rasters of a scene through tiny-skia.

use super::scene::{MarkerScene, RenderError};
use crate::color::Rgb;
use crate::family::pattern::Seg;
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
        draw(&mut pixmap, &item.path.0, item.fill, item.stroke, t);
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

/// Fills and/or strokes one path (stroke width in the path's own units).
fn draw(
    pixmap: &mut Pixmap,
    segs: &[Seg],
    fill: Option<Rgb>,
    stroke: Option<(Rgb, f64)>,
    t: Transform,
) {
    let Some(path) = to_skia(segs) else {
        return;
    };
    if let Some(c) = fill {
        pixmap.fill_path(&path, &paint(c), FillRule::Winding, t, None);
    }
    if let Some((c, width)) = stroke {
        let stroke = Stroke {
            width: width as f32,
            ..Stroke::default()
        };
        pixmap.stroke_path(&path, &paint(c), &stroke, t, None);
    }
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

/// Renders an SVG made by this crate (a sheet page) `width_px` pixels wide on white, with the
/// embedded label font: the studio's live print preview.
pub fn rasterize_svg(svg: &str, width_px: u32) -> Result<Pixmap, RenderError> {
    let tree = super::pdf::parse_svg(svg)?;
    let size = tree.size();
    let scale = width_px as f32 / size.width();
    let height_px = (size.height() * scale).round().max(1.0) as u32;
    let mut pixmap = Pixmap::new(width_px.max(1), height_px).ok_or_else(|| {
        RenderError::Layout(format!(
            "a {width_px}×{height_px} px preview is not possible"
        ))
    })?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        Transform::from_scale(scale, scale),
        &mut pixmap.as_mut(),
    );
    Ok(pixmap)
}

/// One category's pattern on the family background, `px` pixels square, with the keypoint's cell
/// spanning the middle `1 / view` of the image (patterns may spill over their cell a little).
pub fn category_swatch(
    pattern: &crate::family::pattern::CategoryPattern,
    background: Rgb,
    px: u32,
    view: f64,
) -> Result<Pixmap, RenderError> {
    let mut pixmap = Pixmap::new(px.max(1), px.max(1))
        .ok_or_else(|| RenderError::Layout(format!("a {px} px swatch is not possible")))?;
    pixmap.fill(tiny_skia::Color::from_rgba8(
        background.0,
        background.1,
        background.2,
        255,
    ));
    let s = (px as f64 / view) as f32;
    // Cell coordinates are relative to the keypoint, so the centre of the image is (0, 0).
    let t = Transform::from_scale(s, s).post_translate(px as f32 / 2.0, px as f32 / 2.0);
    for item in &pattern.items {
        draw(&mut pixmap, &item.path.0, item.fill, item.stroke, t);
    }
    Ok(pixmap)
}
