//! The Families panel: built-in families, the user's own (their folder, files opened or dropped),
//! and the way into the designer (duplicate a built-in, edit one of the user's).

use super::files::{user_families, FileAccess, OpenedFile};
use super::train::attached_model;
use super::{preview, Studio};
use egui::{ColorImage, TextureHandle, TextureOptions};
use std::path::PathBuf;
use tagsmith::detect::stage2::shipped_model_for;
use tagsmith::family::{Family, FamilySpec};

/// Pixels across a thumbnail: twice its size on screen, so it stays sharp on high-DPI displays.
const THUMBNAIL_PX: u32 = 176;
/// Points across a thumbnail on screen: a 10×10-cell marker at 8 points a cell.
const THUMBNAIL_SIZE: f32 = 88.0;
/// The narrowest a gallery card gets (points): the marker and a line of numbers beside it.
const CARD_MIN_WIDTH: f32 = 320.0;
/// Points between cards.
const CARD_GAP: f32 = 8.0;

#[derive(Debug, Clone, PartialEq)]
pub enum Origin {
    Builtin,
    /// In the user's family folder.
    UserFolder(PathBuf),
    /// Opened or dropped this session (`path` when it is a file on disk).
    Opened {
        name: String,
        path: Option<PathBuf>,
    },
}

#[derive(Debug, Clone)]
pub struct Entry {
    pub spec: FamilySpec,
    pub origin: Origin,
    /// The code's alphabet size and length, kept from loading so that the designer can offer
    /// matching codebooks without validating every family each frame.
    pub q: usize,
    pub code_len: usize,
    pub keypoints: usize,
    pub codes: usize,
    /// Whether a shipped model reads it ([`shipped_model_for`]): a built-in's own, or the model
    /// of its layout for a user's family (a grid design with a code table of its own).
    shipped_weights: bool,
    thumbnail: Thumbnail,
}

/// A marker ([`showcase_id`]) drawn by the core's renderer when the entry is made (`None` when
/// the family cannot draw it), and its texture, uploaded on first show. The entry is rebuilt when its file changes, so
/// the texture never goes stale and no frame renders a thumbnail again.
#[derive(Clone, Default)]
struct Thumbnail {
    image: Option<ColorImage>,
    texture: Option<TextureHandle>,
}

impl std::fmt::Debug for Thumbnail {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Thumbnail")
            .field("to_upload", &self.image.as_ref().map(|i| i.size))
            .field("uploaded", &self.texture.as_ref().map(|t| t.size()))
            .finish()
    }
}

impl Entry {
    fn new(family: &Family, origin: Origin) -> Self {
        Self {
            spec: family.spec().clone(),
            origin,
            q: family.q(),
            code_len: family.code_len(),
            keypoints: family.keypoints().len(),
            codes: family.codebook().len(),
            shipped_weights: shipped_model_for(family).is_some(),
            thumbnail: Thumbnail {
                image: thumbnail(family),
                texture: None,
            },
        }
    }

    /// Keypoints, codes and the family's stated minimum distance, as the gallery shows them.
    pub fn summary(&self) -> String {
        let distance = self
            .spec
            .codebook
            .min_distance
            .map_or("not stated".into(), |d| d.to_string());
        format!(
            "{} keypoints · {} codes · minimum distance {distance}",
            self.keypoints, self.codes
        )
    }

    /// Whether the detector reads this family, and how the gallery says it: with the weights
    /// shipped for a built-in, with a model the Train panel attached beside the user's file, or
    /// with the shipped model of the user's family's layout.
    pub fn detection(&self) -> (bool, &'static str) {
        let file = match &self.origin {
            Origin::Builtin => {
                return if self.shipped_weights {
                    (true, "detects: shipped weights")
                } else {
                    (false, "no shipped weights: train them in Train")
                };
            }
            Origin::UserFolder(path) => Some(path),
            Origin::Opened { path, .. } => path.as_ref(),
        };
        if file.is_some_and(|f| attached_model(f).is_file()) {
            (true, "detects: your trained model")
        } else if self.shipped_weights {
            (true, "detects: the shipped model of its layout")
        } else {
            (false, "no weights yet: train them in Train")
        }
    }

    fn texture(&mut self, ctx: &egui::Context) -> Option<&TextureHandle> {
        let t = &mut self.thumbnail;
        if t.texture.is_none() {
            let image = t.image.take()?;
            let name = format!("family-thumbnail-{}", self.spec.name);
            t.texture = Some(ctx.load_texture(name, image, TextureOptions::LINEAR));
        }
        t.texture.as_ref()
    }
}

/// The ID a card shows: among the first few, the one whose code uses the most symbols (ID 0 of
/// a quaternary family is all one symbol, a black square that hides the design).
fn showcase_id(family: &Family) -> usize {
    let codebook = family.codebook();
    let variety = |id: usize| {
        let mut seen = [false; 256];
        codebook
            .code(id)
            .unwrap_or(&[])
            .iter()
            .for_each(|&s| seen[s as usize] = true);
        seen.iter().filter(|&&b| b).count()
    };
    // The lowest ID of the most varied: a family whose ID 0 shows every symbol keeps ID 0.
    (0..codebook.len().min(16))
        .max_by_key(|&id| (variety(id), std::cmp::Reverse(id)))
        .unwrap_or(0)
}

fn thumbnail(family: &Family) -> Option<ColorImage> {
    let id = showcase_id(family);
    let scene =
        tagsmith::render::marker_scene(family, id, tagsmith::render::SceneOptions::default())
            .ok()?;
    let pixmap = tagsmith::render::raster::rasterize_width(&scene, THUMBNAIL_PX).ok()?;
    Some(preview::pixmap_image(&pixmap))
}

#[derive(Default)]
pub struct Library {
    pub entries: Vec<Entry>,
    pub selected: Option<usize>,
}

impl Library {
    /// Re-reads the built-ins and the user folder (keeping files opened this session). Returns
    /// one message per user file that does not load.
    pub fn reload(&mut self, files: &dyn FileAccess) -> Vec<String> {
        let selected = self.selected_name();
        let opened: Vec<Entry> = self
            .entries
            .drain(..)
            .filter(|e| matches!(e.origin, Origin::Opened { .. }))
            .collect();
        for name in tagsmith::builtin::names() {
            if let Some(Ok(f)) = tagsmith::builtin::get(name) {
                self.entries.push(Entry::new(&f, Origin::Builtin));
            }
        }
        let mut problems = Vec::new();
        for file in user_families(files) {
            match parse(&file) {
                Ok(family) => self.entries.push(Entry::new(
                    &family,
                    Origin::UserFolder(file.path.clone().unwrap_or_default()),
                )),
                Err(e) => problems.push(e),
            }
        }
        for e in opened {
            if !self.entries.iter().any(|x| same_file(x, &e)) {
                self.entries.push(e);
            }
        }
        self.selected = selected.and_then(|n| self.entries.iter().position(|e| e.spec.name == n));
        problems
    }

    fn selected_name(&self) -> Option<String> {
        self.selected
            .and_then(|i| self.entries.get(i))
            .map(|e| e.spec.name.clone())
    }

    /// Adds an opened file if it is a valid family; the error names the file and the field.
    pub fn add_opened(&mut self, file: &OpenedFile) -> Result<FamilySpec, String> {
        let family = parse(file)?;
        let entry = Entry::new(
            &family,
            Origin::Opened {
                name: file.name.clone(),
                path: file.path.clone(),
            },
        );
        self.entries.retain(|e| !same_file(e, &entry));
        self.entries.push(entry);
        self.selected = Some(self.entries.len() - 1);
        Ok(family.spec().clone())
    }
}

fn same_file(a: &Entry, b: &Entry) -> bool {
    let path = |e: &Entry| match &e.origin {
        Origin::UserFolder(p) => Some(p.clone()),
        Origin::Opened { path, .. } => path.clone(),
        Origin::Builtin => None,
    };
    match (&a.origin, &b.origin) {
        (
            Origin::Opened {
                name: x,
                path: None,
            },
            Origin::Opened {
                name: y,
                path: None,
            },
        ) => x == y,
        _ => path(a).is_some() && path(a) == path(b),
    }
}

/// A family file through the core's loader: every problem as `file: json.path: message`.
fn parse(file: &OpenedFile) -> Result<Family, String> {
    let text = std::str::from_utf8(&file.bytes)
        .map_err(|_| format!("{}: not a text (UTF-8) file", file.name))?;
    tagsmith::family::from_json_str(text).map_err(|e| e.in_file(&file.name).to_string())
}

pub fn show(studio: &mut Studio, ui: &mut egui::Ui) {
    ui.heading("Families");
    ui.label("Pick a family. Duplicate a built-in to start a new design, or edit one of your own.");
    if let Some(dir) = studio.files.user_folder() {
        ui.weak(format!("Your families folder: {}", dir.display()));
    }
    ui.add_space(6.0);
    let mut action = None;
    ui.horizontal(|ui| {
        let selected = studio
            .library
            .selected
            .and_then(|i| studio.library.entries.get(i));
        let is_builtin = selected.is_some_and(|e| e.origin == Origin::Builtin);
        if ui
            .add_enabled(
                selected.is_some(),
                egui::Button::new("Duplicate as new design"),
            )
            .clicked()
        {
            action = Some(true);
        }
        if ui
            .add_enabled(selected.is_some() && !is_builtin, egui::Button::new("Edit"))
            .on_disabled_hover_text("built-in families are duplicated, not edited")
            .clicked()
        {
            action = Some(false);
        }
        if studio.files.user_folder().is_some() && ui.button("Reload folder").clicked() {
            studio.reload_library();
        }
    });
    ui.separator();
    egui::ScrollArea::vertical().show(ui, |ui| gallery(studio, ui));
    if let Some(duplicate) = action {
        let entry = studio.library.entries[studio.library.selected.expect("enabled")].clone();
        if duplicate {
            let mut spec = entry.spec;
            spec.name = format!("{}-copy", spec.name);
            spec.title = format!("{} (copy)", spec.title);
            studio.start_design(spec, None, false);
        } else {
            let path = match entry.origin {
                Origin::UserFolder(p) => Some(p),
                Origin::Opened { path, .. } => path,
                Origin::Builtin => None,
            };
            studio.start_design(entry.spec, path, true);
        }
    }
}

/// The families as cards, as many across as the panel fits (each at least `CARD_MIN_WIDTH`,
/// widened to fill the row): at 1400×900 every built-in is on screen without scrolling. Clicking
/// a card's marker or name selects it.
fn gallery(studio: &mut Studio, ui: &mut egui::Ui) {
    let library = &mut studio.library;
    let width = ui.available_width();
    let columns = (((width + CARD_GAP) / (CARD_MIN_WIDTH + CARD_GAP)).floor() as usize).max(1);
    let card_width = (width - CARD_GAP * (columns as f32 - 1.0)) / columns as f32;
    let count = library.entries.len();
    for first in (0..count).step_by(columns) {
        ui.horizontal_top(|ui| {
            ui.spacing_mut().item_spacing.x = CARD_GAP;
            for i in first..(first + columns).min(count) {
                let selected = library.selected == Some(i);
                if card(ui, &mut library.entries[i], selected, card_width) {
                    library.selected = Some(i);
                }
            }
        });
        ui.add_space(CARD_GAP);
    }
}

/// One family: its marker beside its name, title, numbers, whether it detects and its print
/// size. Returns whether it was clicked.
fn card(ui: &mut egui::Ui, e: &mut Entry, selected: bool, width: f32) -> bool {
    let visuals = ui.visuals();
    let (stroke, fill) = if selected {
        (
            visuals.selection.stroke,
            visuals.selection.bg_fill.gamma_multiply(0.3),
        )
    } else {
        (
            visuals.widgets.noninteractive.bg_stroke,
            visuals.faint_bg_color,
        )
    };
    let frame = egui::Frame::group(ui.style()).stroke(stroke).fill(fill);
    let inner = width - frame.total_margin().sum().x;
    frame
        .show(ui, |ui| {
            ui.set_width(inner);
            ui.horizontal_top(|ui| {
                let mut clicked = match e.texture(ui.ctx()) {
                    Some(tex) => {
                        let [w, h] = tex.size().map(|n| n as f32);
                        let size = egui::vec2(w, h) * (THUMBNAIL_SIZE / w.max(h));
                        let image = egui::Image::new(tex)
                            .alt_text(format!("{} marker", e.spec.name))
                            .fit_to_exact_size(size)
                            .sense(egui::Sense::click());
                        ui.add_sized(egui::Vec2::splat(THUMBNAIL_SIZE), image)
                            .clicked()
                    }
                    None => {
                        ui.add_sized(
                            egui::Vec2::splat(THUMBNAIL_SIZE),
                            egui::Label::new(egui::RichText::new("no preview").weak()),
                        );
                        false
                    }
                };
                ui.vertical(|ui| {
                    // Names and titles stay on one line; a long one is cut with "…" and shown
                    // whole on hover.
                    ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Truncate);
                    let name = egui::RichText::new(&e.spec.name).strong();
                    clicked |= ui.selectable_label(selected, name).clicked();
                    ui.add(egui::Label::new(egui::RichText::new(&e.spec.title).weak()));
                    ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Wrap);
                    ui.label(e.summary());
                    let (detects, how) = e.detection();
                    let text = egui::RichText::new(how);
                    ui.label(if detects { text } else { text.weak() });
                    ui.weak(format!(
                        "{} mm printed · {}",
                        e.spec.print.marker_side_mm,
                        match &e.origin {
                            Origin::Builtin => "built-in".to_string(),
                            Origin::UserFolder(_) => "your folder".to_string(),
                            Origin::Opened { name, .. } => format!("opened: {name}"),
                        }
                    ));
                });
                clicked
            })
            .inner
        })
        .inner
}
