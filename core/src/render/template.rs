//! The rectified template: a marker as stage 2 sees it, warped so that the ROI's first four points
//! land on a square inset by the ROI margin a (docs/ARCHITECTURE.md §6.3, §9.1). The designer shows
//! it beside the marker so a user sees what the detector will be given.

use super::raster::{gray_at, rasterize};
use super::scene::{marker_scene, RenderError, SceneOptions};
use crate::family::Family;
use crate::geometry::{warp_bilinear, Homography, Quad};
use crate::image::GrayImage;

/// The ROI square's corners in a `size`-pixel template with margin `a` (fraction of the side).
pub fn template_corners(size: u32, margin: f64) -> Quad {
    let (lo, hi) = (margin * size as f64, (1.0 - margin) * size as f64);
    Quad([[lo, lo], [hi, lo], [hi, hi], [lo, hi]])
}

/// Renders ID `id` and rectifies it into a `size` × `size` gray template with the family's ROI
/// margin.
pub fn rectified_template(family: &Family, id: usize, size: u32) -> Result<GrayImage, RenderError> {
    let scene = marker_scene(family, id, SceneOptions::default())?;
    // Render with the ROI about as many pixels across as the template, so the warp neither
    // aliases nor blurs.
    let roi = family.roi_points();
    let roi_mm = (scene.to_mm(roi[1])[0] - scene.to_mm(roi[0])[0])
        .hypot(scene.to_mm(roi[1])[1] - scene.to_mm(roi[0])[1]);
    let margin = family.spec().roi.margin;
    let px_per_mm = size as f64 * (1.0 - 2.0 * margin) / roi_mm.max(1e-9) * 2.0;
    let pixmap = rasterize(&scene, px_per_mm)?;
    // The raster spans the scene exactly, so its true scale differs from the request by rounding.
    let (sx, sy) = (
        pixmap.width() as f64 / scene.width_mm,
        pixmap.height() as f64 / scene.height_mm,
    );
    let mut src = GrayImage::new(pixmap.width(), pixmap.height(), 255);
    for y in 0..pixmap.height() {
        for x in 0..pixmap.width() {
            src.pixels[(y * pixmap.width() + x) as usize] = gray_at(&pixmap, x, y).round() as u8;
        }
    }
    let roi_px: Vec<[f64; 2]> = roi[..4]
        .iter()
        .map(|&p| {
            let mm = scene.to_mm(p);
            // Pixel centres sit at +0.5 in the raster's continuous coordinates.
            [mm[0] * sx - 0.5, mm[1] * sy - 0.5]
        })
        .collect();
    let corners: Vec<[f64; 2]> = template_corners(size, margin)
        .iter()
        .map(|p| [p[0] - 0.5, p[1] - 0.5])
        .collect();
    let out_to_src = Homography::from_points(&corners, &roi_px)
        .map_err(|e| RenderError::Layout(format!("the ROI cannot be rectified: {e}")))?;
    let background = gray_at(&pixmap, 0, 0).round() as u8;
    Ok(warp_bilinear(&src, &out_to_src, size, size, background))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_roi_corners_of_a_framed_tag_land_on_the_template_square() {
        let family = crate::builtin::get("aruco-4x4_50").unwrap().unwrap();
        let t = rectified_template(&family, 0, 120).unwrap();
        let [lo, hi] = [0.15 * 120.0, 0.85 * 120.0];
        // Just inside the ROI corner: the black frame; just outside: the white quiet zone.
        let at = |x: f64, y: f64| t.get(x as u32, y as u32);
        assert!(at(lo + 3.0, lo + 3.0) < 40, "inside the top-left corner");
        assert!(at(lo - 4.0, lo - 4.0) > 215, "outside the top-left corner");
        assert!(
            at(hi - 4.0, hi - 4.0) < 40,
            "inside the bottom-right corner"
        );
        assert!(
            at(hi + 3.0, hi + 3.0) > 215,
            "outside the bottom-right corner"
        );
    }
}
