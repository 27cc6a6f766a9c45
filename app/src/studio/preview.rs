//! Pictures in the studio: the core renders, this module only turns pixmaps into textures (cached
//! per design revision) and maps between marker units and screen points for overlays and clicks.

use egui::{Color32, ColorImage, Pos2, Rect, Stroke, TextureHandle, TextureOptions, Vec2};
use std::collections::HashMap;
use tagsmith::family::Family;
use tagsmith::render::{marker_scene, MarkerScene, SceneOptions};

/// Colours for keypoint categories, by category index (distinct on black and white cells).
pub const CATEGORY_COLOURS: [Color32; 8] = [
    Color32::from_rgb(230, 80, 60),
    Color32::from_rgb(40, 150, 230),
    Color32::from_rgb(60, 180, 90),
    Color32::from_rgb(240, 170, 30),
    Color32::from_rgb(170, 90, 220),
    Color32::from_rgb(20, 190, 190),
    Color32::from_rgb(230, 90, 170),
    Color32::from_rgb(140, 140, 60),
];

pub fn category_colour(index: usize) -> Color32 {
    CATEGORY_COLOURS[index % CATEGORY_COLOURS.len()]
}

/// Textures keyed by what they show; an entry is rebuilt when its key's revision changes.
#[derive(Default)]
pub struct Textures {
    cache: HashMap<String, (u64, TextureHandle)>,
}

impl Textures {
    pub fn get_or_make(
        &mut self,
        ctx: &egui::Context,
        key: &str,
        revision: u64,
        make: impl FnOnce() -> Result<ColorImage, String>,
    ) -> Result<TextureHandle, String> {
        if let Some((rev, tex)) = self.cache.get(key) {
            if *rev == revision {
                return Ok(tex.clone());
            }
        }
        let image = make()?;
        let tex = ctx.load_texture(key, image, TextureOptions::LINEAR);
        self.cache.insert(key.to_string(), (revision, tex.clone()));
        Ok(tex)
    }
}

pub fn pixmap_image(pixmap: &tiny_skia::Pixmap) -> ColorImage {
    ColorImage::from_rgba_premultiplied(
        [pixmap.width() as usize, pixmap.height() as usize],
        pixmap.data(),
    )
}

pub fn gray_image(image: &tagsmith::image::GrayImage) -> ColorImage {
    ColorImage::from_gray([image.width as usize, image.height as usize], &image.pixels)
}

/// A marker drawn into a screen rectangle: maps marker units to screen points and back.
pub struct MarkerView {
    pub scene: MarkerScene,
    pub rect: Rect,
}

impl MarkerView {
    pub fn new(family: &Family, id: usize, rect: Rect) -> Result<Self, String> {
        let scene = marker_scene(family, id, SceneOptions::default()).map_err(|e| e.to_string())?;
        Ok(Self { scene, rect })
    }

    fn points_per_mm(&self) -> f32 {
        self.rect.width() / self.scene.width_mm as f32
    }

    pub fn to_screen(&self, p: [f64; 2]) -> Pos2 {
        let mm = self.scene.to_mm(p);
        self.rect.min + Vec2::new(mm[0] as f32, mm[1] as f32) * self.points_per_mm()
    }

    pub fn to_marker(&self, pos: Pos2) -> [f64; 2] {
        let mm = (pos - self.rect.min) / self.points_per_mm();
        [
            mm.x as f64 / self.scene.scale + self.scene.origin[0],
            mm.y as f64 / self.scene.scale + self.scene.origin[1],
        ]
    }

    /// Screen size of `units` marker units.
    pub fn scale(&self, units: f64) -> f32 {
        (units * self.scene.scale) as f32 * self.points_per_mm()
    }
}

/// Screen size of a marker preview that fits `available`, keeping the scene's aspect ratio.
pub fn fit(scene_w: f64, scene_h: f64, available: Vec2) -> Vec2 {
    let s = (available.x / scene_w as f32).min(available.y / scene_h as f32);
    Vec2::new(scene_w as f32, scene_h as f32) * s.max(1.0)
}

/// Draws numbered points joined by arrows in order (and back to the first): the ROI.
pub fn draw_ordered_points(painter: &egui::Painter, points: &[Pos2], colour: Color32) {
    let n = points.len();
    let stroke = Stroke::new(2.0, colour);
    for i in 0..n {
        // Two points are one arrow; three or more close the loop back to the first.
        if n < 2 || (n == 2 && i == 1) {
            break;
        }
        let (a, b) = (points[i], points[(i + 1) % n]);
        let along = (b - a).normalized();
        let (from, to) = (a + along * 9.0, b - along * 9.0);
        painter.line_segment([from, to], stroke);
        let side = along.rot90() * 4.0;
        let head = to - along * 9.0;
        painter.line_segment([to, head + side], stroke);
        painter.line_segment([to, head - side], stroke);
    }
    for (i, &p) in points.iter().enumerate() {
        painter.circle(p, 7.0, colour, Stroke::new(1.0, Color32::WHITE));
        painter.text(
            p,
            egui::Align2::CENTER_CENTER,
            (i + 1).to_string(),
            egui::FontId::proportional(10.0),
            Color32::WHITE,
        );
    }
}
