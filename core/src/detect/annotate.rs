//! An annotated copy of an image: the input ROI (yellow), the marker's outline from its keypoints
//! (green, the canonical first corner ringed in red) and every keypoint coloured by category.

use crate::geometry::Quad;
use crate::image::GrayImage;
use crate::render::raster::encode_png;
use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Stroke, Transform};

/// Category colours, cycled.
const PALETTE: [(u8, u8, u8); 6] = [
    (230, 25, 75),
    (0, 130, 200),
    (245, 130, 48),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
];

/// What is drawn for one marker: the ROI it was read from, its outline when decoded, its
/// keypoints as (x, y, category).
pub struct Overlay<'a> {
    pub roi: &'a Quad,
    pub corners: Option<&'a Quad>,
    pub keypoints: Vec<(f64, f64, usize)>,
}

/// PNG bytes of `image` with the overlays of one ROI; `keypoints` are (x, y, category).
pub fn annotate(
    image: &GrayImage,
    roi: &Quad,
    corners: Option<&Quad>,
    keypoints: &[(f64, f64, usize)],
) -> Result<Vec<u8>, String> {
    annotate_all(
        image,
        &[Overlay {
            roi,
            corners,
            keypoints: keypoints.to_vec(),
        }],
    )
}

/// PNG bytes of `image` with every marker's overlays.
pub fn annotate_all(image: &GrayImage, overlays: &[Overlay]) -> Result<Vec<u8>, String> {
    let mut pixmap = Pixmap::new(image.width, image.height).ok_or("the image is empty")?;
    for (px, &g) in pixmap.pixels_mut().iter_mut().zip(&image.pixels) {
        *px = tiny_skia::ColorU8::from_rgba(g, g, g, 255).premultiply();
    }
    let scale = (image.width.max(image.height) as f32 / 640.0).max(1.0);
    let paint = |r: u8, g: u8, b: u8| {
        let mut p = Paint::default();
        p.set_color(Color::from_rgba8(r, g, b, 255));
        p.anti_alias = true;
        p
    };
    let stroke = Stroke {
        width: 1.5 * scale,
        ..Stroke::default()
    };
    let polygon = |pts: &Quad| {
        let mut pb = PathBuilder::new();
        pb.move_to(pts[0][0] as f32, pts[0][1] as f32);
        for p in &pts[1..] {
            pb.line_to(p[0] as f32, p[1] as f32);
        }
        pb.close();
        pb.finish()
    };
    for o in overlays {
        if let Some(path) = polygon(o.roi) {
            pixmap.stroke_path(
                &path,
                &paint(255, 220, 0),
                &stroke,
                Transform::identity(),
                None,
            );
        }
        if let Some(c) = o.corners {
            if let Some(path) = polygon(c) {
                pixmap.stroke_path(
                    &path,
                    &paint(0, 200, 60),
                    &stroke,
                    Transform::identity(),
                    None,
                );
            }
            if let Some(ring) =
                PathBuilder::from_circle(c[0][0] as f32, c[0][1] as f32, 5.0 * scale)
            {
                pixmap.stroke_path(
                    &ring,
                    &paint(255, 0, 0),
                    &stroke,
                    Transform::identity(),
                    None,
                );
            }
        }
        for &(x, y, category) in &o.keypoints {
            let (r, g, b) = PALETTE[category % PALETTE.len()];
            if let Some(dot) = PathBuilder::from_circle(x as f32, y as f32, 2.0 * scale) {
                pixmap.fill_path(
                    &dot,
                    &paint(r, g, b),
                    FillRule::Winding,
                    Transform::identity(),
                    None,
                );
            }
        }
    }
    encode_png(&pixmap).map_err(|e| e.to_string())
}
