//! Contact sheets: thumbnails of synthesised images with their ground truth drawn on top (ROI in
//! green with its first corner marked, keypoints coloured by category, mask outline in orange), to
//! check by eye that the truth sits exactly on the markers.

use super::Truth;
use crate::image::GrayImage;
use tiny_skia::{Color, Paint, PathBuilder, Pixmap, Stroke, Transform};

const PALETTE: [(u8, u8, u8); 6] = [
    (230, 25, 75),
    (60, 120, 255),
    (255, 190, 0),
    (0, 200, 200),
    (200, 0, 200),
    (120, 220, 60),
];

/// A grid of `columns` thumbnails `thumb_width` pixels wide.
pub fn contact_sheet(
    samples: &[(GrayImage, Truth)],
    columns: u32,
    thumb_width: u32,
) -> Option<Pixmap> {
    let (first, _) = samples.first()?;
    let scale = thumb_width as f32 / first.width as f32;
    let thumb_height = (first.height as f32 * scale).round() as u32;
    let rows = (samples.len() as u32).div_ceil(columns);
    let mut sheet = Pixmap::new(
        columns * (thumb_width + 4) + 4,
        rows * (thumb_height + 4) + 4,
    )?;
    sheet.fill(Color::from_rgba8(40, 40, 40, 255));
    for (i, (image, truth)) in samples.iter().enumerate() {
        let (col, row) = (i as u32 % columns, i as u32 / columns);
        let (ox, oy) = (
            (4 + col * (thumb_width + 4)) as f32,
            (4 + row * (thumb_height + 4)) as f32,
        );
        let mut gray = Pixmap::new(image.width, image.height)?;
        for (dst, &g) in gray.pixels_mut().iter_mut().zip(&image.pixels) {
            *dst = tiny_skia::PremultipliedColorU8::from_rgba(g, g, g, 255)?;
        }
        let s = thumb_width as f32 / image.width as f32;
        let t = Transform::from_row(s, 0.0, 0.0, s, ox, oy);
        sheet.draw_pixmap(
            0,
            0,
            gray.as_ref(),
            &tiny_skia::PixmapPaint::default(),
            t,
            None,
        );
        // Pixel centres are at integer coordinates: shift by half a pixel onto the raster.
        let at = |p: [f64; 2]| ((p[0] as f32 + 0.5) * s + ox, (p[1] as f32 + 0.5) * s + oy);
        for m in &truth.markers {
            polyline(
                &mut sheet,
                m.mask.iter().map(|&p| at(p)),
                (255, 140, 0),
                1.0,
            );
            polyline(
                &mut sheet,
                m.roi.iter().take(4).map(|&p| at(p)),
                (0, 220, 0),
                1.5,
            );
            let (x, y) = at(m.roi[0]);
            dot(&mut sheet, x, y, 3.5, (0, 220, 0));
            for k in m.keypoints.iter().filter(|k| k.visible) {
                let (x, y) = at([k.x, k.y]);
                dot(&mut sheet, x, y, 1.6, PALETTE[k.category % PALETTE.len()]);
            }
        }
    }
    Some(sheet)
}

fn paint(c: (u8, u8, u8)) -> Paint<'static> {
    let mut p = Paint::default();
    p.set_color_rgba8(c.0, c.1, c.2, 255);
    p.anti_alias = true;
    p
}

fn polyline(
    pixmap: &mut Pixmap,
    points: impl Iterator<Item = (f32, f32)>,
    c: (u8, u8, u8),
    width: f32,
) {
    let mut pb = PathBuilder::new();
    for (i, (x, y)) in points.enumerate() {
        if i == 0 {
            pb.move_to(x, y)
        } else {
            pb.line_to(x, y)
        }
    }
    pb.close();
    if let Some(path) = pb.finish() {
        let stroke = Stroke {
            width,
            ..Stroke::default()
        };
        pixmap.stroke_path(&path, &paint(c), &stroke, Transform::identity(), None);
    }
}

fn dot(pixmap: &mut Pixmap, x: f32, y: f32, r: f32, c: (u8, u8, u8)) {
    if let Some(path) = PathBuilder::from_circle(x, y, r) {
        pixmap.fill_path(
            &path,
            &paint(c),
            tiny_skia::FillRule::Winding,
            Transform::identity(),
            None,
        );
    }
}
