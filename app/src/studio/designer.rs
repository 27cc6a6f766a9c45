//! The Designer panel: every part of a family spec, edited through `family::edit::Edit`, with the
//! marker, its keypoints and ROI, and the rectified template drawn live beside the controls.

use super::codegen::{default_budget, CodegenJob};
use super::design::Design;
use super::files::Purpose;
use super::preview::{self, category_colour, MarkerView};
use super::Studio;
use egui::{Color32, Pos2, Sense, Stroke, Ui};
use tagsmith::codebook::GenerateParams;
use tagsmith::family::edit::{CellValue, Edit};
use tagsmith::family::spec::ExtraKeypoint as ExtraKeypointSpec;
use tagsmith::family::spec::{KeypointSet, Layout, Primitive, Role, Shape};
use tagsmith::family::Family;

/// What a click on the marker does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tool {
    #[default]
    Look,
    PaintCells,
    PlaceExtras,
    PickRoi,
    PickKeypoints,
}

#[derive(Debug, Clone, PartialEq)]
pub struct CodegenSettings {
    pub min_distance: u32,
    pub count: usize,
    pub seed: u64,
}

impl Default for CodegenSettings {
    fn default() -> Self {
        Self {
            min_distance: 5,
            count: 100,
            seed: 1,
        }
    }
}

#[derive(Default)]
pub struct DesignerState {
    pub tool: Tool,
    pub paint: Option<CellValue>,
    pub extra_category: Option<String>,
    pub extra_size: Option<f64>,
    pub roi_draft: Vec<[f64; 2]>,
    pub selected_category: Option<String>,
    pub new_category: String,
    pub rename_to: String,
    pub preview_id: usize,
    pub codegen: CodegenSettings,
    pub job: Option<CodegenJob>,
    pub radii_text: Option<String>,
    /// The last refused edit, shown next to the section that made it.
    pub refused: Option<(&'static str, String)>,
    /// Cached (revision, minimum distance) of the codebook: a full pairwise scan is not free.
    min_distance: Option<(u64, Option<u32>)>,
}

/// Applies an edit, remembering a refusal for the `section` to show.
fn edit(studio: &mut Studio, section: &'static str, e: Edit) {
    let Some(design) = studio.design.as_mut() else {
        return;
    };
    match design.apply(&e) {
        Ok(()) => studio.designer.refused = None,
        Err(err) => studio.designer.refused = Some((section, err.to_string())),
    }
}

/// Like `edit`, for one frame of a dragged value: the gesture is one undo step.
fn edit_dragged(studio: &mut Studio, section: &'static str, group: &str, e: Edit) {
    let Some(design) = studio.design.as_mut() else {
        return;
    };
    match design.apply_grouped(&e, group) {
        Ok(()) => studio.designer.refused = None,
        Err(err) => studio.designer.refused = Some((section, err.to_string())),
    }
}

/// Validation problems under the JSON paths a section edits, and a refused edit of that section.
fn messages(ui: &mut Ui, studio: &Studio, section: &'static str, paths: &[&str]) {
    let Some(design) = &studio.design else {
        return;
    };
    let colour = ui.visuals().error_fg_color;
    for p in design.problems_at(paths) {
        ui.colored_label(colour, p.as_str());
    }
    if let Some((s, text)) = &studio.designer.refused {
        if *s == section {
            ui.colored_label(colour, text.as_str());
        }
    }
}

/// A number with a label that screen readers and tests find it by.
fn number<T: egui::emath::Numeric>(
    ui: &mut Ui,
    label: &str,
    value: &mut T,
    range: std::ops::RangeInclusive<T>,
    speed: f64,
) -> egui::Response {
    ui.horizontal(|ui| {
        let l = ui.label(label);
        ui.add(egui::DragValue::new(value).range(range).speed(speed))
            .labelled_by(l.id)
    })
    .inner
}

fn text_field(ui: &mut Ui, label: &str, value: &mut String) -> egui::Response {
    ui.horizontal(|ui| {
        let l = ui.label(label);
        ui.text_edit_singleline(value).labelled_by(l.id)
    })
    .inner
}

pub fn show(studio: &mut Studio, ui: &mut Ui, ctx: &egui::Context) {
    if studio.design.is_none() {
        ui.heading("No design yet");
        ui.label("Go to Families and duplicate a built-in family, or open a family file.");
        return;
    }
    poll_codegen(studio, ctx);
    egui::Panel::left("designer-controls")
        .resizable(true)
        .default_size(380.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| controls(studio, ui));
        });
    egui::CentralPanel::default_margins().show(ui, |ui| marker_area(studio, ui, ctx));
}

fn controls(studio: &mut Studio, ui: &mut Ui) {
    egui::CollapsingHeader::new("Identity")
        .default_open(true)
        .show(ui, |ui| identity(studio, ui));
    egui::CollapsingHeader::new("Layout")
        .default_open(true)
        .show(ui, |ui| layout(studio, ui));
    egui::CollapsingHeader::new("Pattern categories")
        .default_open(true)
        .show(ui, |ui| categories(studio, ui));
    egui::CollapsingHeader::new("Keypoints")
        .default_open(true)
        .show(ui, |ui| keypoints(studio, ui));
    egui::CollapsingHeader::new("ROI")
        .default_open(true)
        .show(ui, |ui| roi(studio, ui));
    egui::CollapsingHeader::new("Codebook")
        .default_open(true)
        .show(ui, |ui| codebook(studio, ui));
    let design = studio.design.as_ref().expect("a design");
    let other: Vec<String> = design.problems_at(&["format", "extra"]);
    if !other.is_empty() || design.validation().is_ok() {
        ui.separator();
    }
    for p in other {
        ui.colored_label(ui.visuals().error_fg_color, p.as_str());
    }
    if let Ok(f) = design.validation() {
        for w in f.warnings() {
            ui.colored_label(ui.visuals().warn_fg_color, format!("note: {w}"));
        }
    }
}

fn identity(studio: &mut Studio, ui: &mut Ui) {
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    let mut name = spec.name.clone();
    if text_field(ui, "Name", &mut name).changed() {
        edit_dragged(studio, "identity", "name", Edit::SetName(name));
    }
    let mut title = spec.title.clone();
    if text_field(ui, "Title", &mut title).changed() {
        edit_dragged(studio, "identity", "title", Edit::SetTitle(title));
    }
    let mut description = spec.description.clone();
    let l = ui.label("Description");
    if ui
        .text_edit_multiline(&mut description)
        .labelled_by(l.id)
        .changed()
    {
        edit_dragged(
            studio,
            "identity",
            "description",
            Edit::SetDescription(description),
        );
    }
    let mut source = spec.source.clone();
    if text_field(ui, "Source", &mut source).changed() {
        edit_dragged(studio, "identity", "source", Edit::SetSource(source));
    }
    let mut side = spec.print.marker_side_mm;
    if number(ui, "Print size (mm)", &mut side, 1.0..=2000.0, 0.2).changed() {
        edit_dragged(studio, "identity", "side", Edit::SetMarkerSide(side));
    }
    let mut labels = spec.print.labels;
    if ui
        .checkbox(&mut labels, "Print labels by default")
        .changed()
    {
        edit(studio, "identity", Edit::SetPrintLabels(labels));
    }
    ui.horizontal(|ui| {
        ui.label("Background");
        let mut rgb = parse_hex(&spec.background).unwrap_or([255, 255, 255]);
        if ui.color_edit_button_srgb(&mut rgb).changed() {
            edit_dragged(
                studio,
                "identity",
                "background",
                Edit::SetBackground(hex(rgb)),
            );
        }
    });
    messages(
        ui,
        studio,
        "identity",
        &["name", "title", "source", "background", "print"],
    );
}

fn parse_hex(text: &str) -> Option<[u8; 3]> {
    let c = tagsmith::color::Rgb::parse(text).ok()?;
    Some([c.0, c.1, c.2])
}

fn hex(rgb: [u8; 3]) -> String {
    format!("#{:02x}{:02x}{:02x}", rgb[0], rgb[1], rgb[2])
}

fn fixed_categories(spec: &tagsmith::family::FamilySpec) -> Vec<String> {
    spec.categories
        .iter()
        .filter(|c| c.role == Role::Fixed)
        .map(|c| c.name.clone())
        .collect()
}

fn layout(studio: &mut Studio, ui: &mut Ui) {
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    let fixed = fixed_categories(&spec);
    ui.horizontal(|ui| {
        let is_grid = matches!(spec.layout, Layout::Grid(_));
        if ui.selectable_label(is_grid, "Grid").clicked() && !is_grid {
            match fixed.first() {
                Some(frame) => edit(
                    studio,
                    "layout",
                    Edit::SetGrid {
                        size: 8,
                        border: 1,
                        frame: frame.clone(),
                    },
                ),
                None => {
                    studio.designer.refused = Some((
                        "layout",
                        "a grid's frame needs a fixed category: add one first".into(),
                    ))
                }
            }
        }
        if ui.selectable_label(!is_grid, "Rings").clicked() && is_grid {
            edit(
                studio,
                "layout",
                Edit::SetRings {
                    radii: vec![2.0 / 3.0, 5.0 / 6.0, 1.0],
                    slots: 24,
                    dot_radius_ratio: 0.06,
                    start_angle_deg: -90.0,
                },
            );
        }
    });
    match &spec.layout {
        Layout::Grid(g) => {
            // The frame is whatever fixed category the corner cell shows.
            let corner = g.cells.first().and_then(|r| r.chars().next());
            let frame = corner
                .and_then(|k| g.legend.get(&k.to_string()).cloned())
                .or_else(|| fixed.first().cloned())
                .unwrap_or_default();
            let border = (0..g.size / 2)
                .take_while(|&i| {
                    g.cells
                        .get(i as usize)
                        .and_then(|r| r.chars().nth(i as usize))
                        == corner
                })
                .count() as u32;
            let (mut size, mut new_border) = (g.size, border.max(1));
            let r1 = number(ui, "Grid size", &mut size, 1..=32, 0.05);
            let r2 = number(ui, "Border", &mut new_border, 0..=15, 0.05);
            if (r1.changed() || r2.changed()) && !frame.is_empty() {
                edit_dragged(
                    studio,
                    "layout",
                    "grid",
                    Edit::SetGrid {
                        size,
                        border: new_border,
                        frame,
                    },
                );
            }
            ui.weak("A new grid size redraws the frame and makes every inner cell a code cell.");
            let mut qz = g.quiet_zone;
            if number(ui, "Quiet zone (cells)", &mut qz, 0.0..=8.0, 0.02).changed() {
                edit_dragged(studio, "layout", "quiet", Edit::SetQuietZone(qz));
            }
        }
        Layout::Rings(r) => {
            let mut text = studio.designer.radii_text.clone().unwrap_or_else(|| {
                r.radii
                    .iter()
                    .map(|v| format!("{v:.3}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            });
            let resp = text_field(ui, "Ring radii", &mut text);
            let mut slots = r.slots;
            let mut dot = r.dot_radius_ratio;
            let mut start = r.start_angle_deg;
            let mut changed = number(ui, "Slots per ring", &mut slots, 1..=256, 0.1).changed();
            changed |= number(ui, "Dot radius ratio", &mut dot, 0.005..=0.5, 0.002).changed();
            changed |= number(ui, "Start angle (deg)", &mut start, -360.0..=360.0, 1.0).changed();
            studio.designer.radii_text = Some(text.clone());
            if resp.lost_focus() || changed {
                let radii: Result<Vec<f64>, _> = text
                    .split(',')
                    .map(|s| s.trim())
                    .filter(|s| !s.is_empty())
                    .map(str::parse::<f64>)
                    .collect();
                match radii {
                    Ok(radii) => {
                        edit_dragged(
                            studio,
                            "layout",
                            "rings",
                            Edit::SetRings {
                                radii,
                                slots,
                                dot_radius_ratio: dot,
                                start_angle_deg: start,
                            },
                        );
                        studio.designer.radii_text = None;
                    }
                    Err(_) => {
                        studio.designer.refused = Some((
                            "layout",
                            format!("ring radii {text:?}: give numbers separated by commas"),
                        ))
                    }
                }
            }
            let mut qz = r.quiet_zone;
            if number(ui, "Quiet zone (radius)", &mut qz, 0.0..=2.0, 0.01).changed() {
                edit_dragged(studio, "layout", "quiet", Edit::SetQuietZone(qz));
            }
        }
    }
    ui.separator();
    ui.label(format!("Extra keypoints: {}", spec.extra.len()));
    let mut remove = None;
    for (i, e) in spec.extra.iter().enumerate() {
        ui.horizontal(|ui| {
            ui.label(format!(
                "{}: ({:.2}, {:.2}) size {:.2} {}",
                i + 1,
                e.x,
                e.y,
                e.size,
                e.category
            ));
            if ui.small_button("remove").clicked() {
                remove = Some(i);
            }
        });
    }
    if let Some(i) = remove {
        edit(studio, "layout", Edit::RemoveExtra(i));
    }
    tool_button(studio, ui, Tool::PlaceExtras, "Place extra keypoints");
    if studio.designer.tool == Tool::PlaceExtras {
        let names: Vec<String> = spec.categories.iter().map(|c| c.name.clone()).collect();
        let current = studio
            .designer
            .extra_category
            .clone()
            .filter(|c| names.contains(c))
            .or_else(|| names.first().cloned())
            .unwrap_or_default();
        let mut chosen = current.clone();
        egui::ComboBox::from_label("Extra keypoint category")
            .selected_text(&chosen)
            .show_ui(ui, |ui| {
                for n in &names {
                    ui.selectable_value(&mut chosen, n.clone(), n);
                }
            });
        studio.designer.extra_category = Some(chosen);
        let mut size = studio.designer.extra_size.unwrap_or(1.0);
        number(ui, "Extra keypoint size", &mut size, 0.05..=10.0, 0.01);
        studio.designer.extra_size = Some(size);
        ui.weak("Click on the marker to place one.");
    }
    messages(ui, studio, "layout", &["layout"]);
}

fn tool_button(studio: &mut Studio, ui: &mut Ui, tool: Tool, label: &str) {
    let on = studio.designer.tool == tool;
    if ui.selectable_label(on, label).clicked() {
        studio.designer.tool = if on { Tool::Look } else { tool };
    }
}

fn categories(studio: &mut Studio, ui: &mut Ui) {
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    let family = studio
        .design
        .as_ref()
        .and_then(Design::preview_family)
        .cloned();
    ui.horizontal_wrapped(|ui| {
        for (i, c) in spec.categories.iter().enumerate() {
            let selected = studio.designer.selected_category.as_deref() == Some(&c.name);
            let role = match c.role {
                Role::Symbol(k) => format!("symbol {k}"),
                Role::Fixed => "fixed".into(),
            };
            let text = egui::RichText::new(&c.name).color(category_colour(i));
            if ui
                .selectable_label(selected, text)
                .on_hover_text(role)
                .clicked()
            {
                studio.designer.selected_category = Some(c.name.clone());
                studio.designer.rename_to = c.name.clone();
            }
        }
    });
    ui.horizontal(|ui| {
        let l = ui.label("New category name");
        ui.text_edit_singleline(&mut studio.designer.new_category)
            .labelled_by(l.id);
    });
    if ui.button("Add category").clicked() {
        let name = studio.designer.new_category.trim().to_string();
        if name.is_empty() {
            studio.designer.refused = Some(("categories", "type a name for the category".into()));
        } else {
            edit(
                studio,
                "categories",
                Edit::AddCategory {
                    name: name.clone(),
                    role: Role::Fixed,
                },
            );
            if studio.designer.refused.is_none() {
                studio.designer.selected_category = Some(name.clone());
                studio.designer.rename_to = name;
                studio.designer.new_category.clear();
            }
        }
    }
    let Some(selected) = studio.designer.selected_category.clone() else {
        messages(ui, studio, "categories", &["categories"]);
        return;
    };
    // Read again: an add or rename above has changed the spec this frame.
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    let Some(index) = spec.categories.iter().position(|c| c.name == selected) else {
        studio.designer.selected_category = None;
        return;
    };
    let category = spec.categories[index].clone();
    ui.separator();
    ui.horizontal(|ui| {
        ui.strong(format!("Category {selected}"));
        if let Some(f) = &family {
            if let Some(p) = f.categories().iter().find(|p| p.name == selected) {
                let bg = f.background();
                if let Ok(pixmap) = tagsmith::render::raster::category_swatch(p, bg, 64, 1.6) {
                    let key = format!("swatch-{selected}");
                    let revision = studio.design.as_ref().map_or(0, |d| d.revision);
                    if let Ok(tex) = studio.textures.get_or_make(ui.ctx(), &key, revision, || {
                        Ok(preview::pixmap_image(&pixmap))
                    }) {
                        let r =
                            ui.add(egui::Image::new(&tex).fit_to_exact_size([48.0, 48.0].into()));
                        // The keypoint's own cell, so spill over it is visible.
                        let cell =
                            egui::Rect::from_center_size(r.rect.center(), r.rect.size() / 1.6);
                        ui.painter().rect_stroke(
                            cell,
                            0.0,
                            Stroke::new(1.0, Color32::from_gray(150)),
                            egui::StrokeKind::Middle,
                        );
                    }
                }
            }
        }
    });
    ui.horizontal(|ui| {
        let l = ui.label("Rename to");
        ui.text_edit_singleline(&mut studio.designer.rename_to)
            .labelled_by(l.id);
        if ui.button("Rename").clicked() {
            let to = studio.designer.rename_to.trim().to_string();
            edit(
                studio,
                "categories",
                Edit::RenameCategory {
                    from: selected.clone(),
                    to: to.clone(),
                },
            );
            if studio.designer.refused.is_none() {
                studio.designer.selected_category = Some(to);
            }
        }
    });
    if ui.button("Remove category").clicked() {
        edit(studio, "categories", Edit::RemoveCategory(selected.clone()));
        if studio.designer.refused.is_none() {
            studio.designer.selected_category = None;
        }
    }
    let mut role = category.role;
    ui.horizontal(|ui| {
        ui.radio_value(&mut role, Role::Fixed, "Fixed (border or orientation)");
        let is_symbol = matches!(role, Role::Symbol(_));
        if ui.radio(is_symbol, "Code symbol").clicked() && !is_symbol {
            let used: Vec<u8> = spec
                .categories
                .iter()
                .filter_map(|c| match c.role {
                    Role::Symbol(k) => Some(k),
                    Role::Fixed => None,
                })
                .collect();
            role = Role::Symbol((0..=u8::MAX).find(|k| !used.contains(k)).unwrap_or(0));
        }
    });
    if let Role::Symbol(mut k) = role {
        if number(ui, "Symbol value", &mut k, 0..=15, 0.05).changed() {
            role = Role::Symbol(k);
        }
    }
    if role != category.role {
        edit(
            studio,
            "categories",
            Edit::SetRole {
                category: selected.clone(),
                role,
            },
        );
    }
    ui.label("Shape, built from primitives (cell units, centred on the keypoint):");
    let mut prims = category.primitives.clone();
    let mut changed = false;
    let mut remove = None;
    for (i, p) in prims.iter_mut().enumerate() {
        ui.push_id(i, |ui| {
            egui::Frame::group(ui.style()).show(ui, |ui| {
                changed |= primitive_editor(ui, p);
                if ui.small_button("remove primitive").clicked() {
                    remove = Some(i);
                }
            });
        });
    }
    if let Some(i) = remove {
        prims.remove(i);
        changed = true;
    }
    ui.horizontal_wrapped(|ui| {
        for (label, shape) in new_shapes() {
            if ui.button(label).clicked() {
                prims.push(Primitive {
                    shape,
                    fill: Some("#000000".into()),
                    stroke: None,
                    stroke_width: None,
                });
                changed = true;
            }
        }
    });
    if changed {
        edit_dragged(
            studio,
            "categories",
            &format!("primitives-{selected}"),
            Edit::SetPrimitives {
                category: selected.clone(),
                primitives: prims,
            },
        );
    }
    messages(
        ui,
        studio,
        "categories",
        &[&format!("categories[{index}]"), "categories"],
    );
}

fn new_shapes() -> Vec<(&'static str, Shape)> {
    vec![
        (
            "+ square",
            Shape::Square {
                size: 1.0,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ dot",
            Shape::Dot {
                radius: 0.35,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ ring",
            Shape::Ring {
                radius: 0.35,
                width: 0.1,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ cross",
            Shape::Cross {
                size: 0.8,
                width: 0.2,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ triangle",
            Shape::Triangle {
                size: 0.8,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ bar",
            Shape::Bar {
                width: 0.8,
                height: 0.2,
                angle_deg: 0.0,
                x: 0.0,
                y: 0.0,
            },
        ),
        (
            "+ path",
            Shape::Path {
                d: "M -0.4 -0.4 L 0.4 -0.4 L 0 0.4 Z".into(),
            },
        ),
    ]
}

/// Controls for one primitive; returns whether anything changed.
fn primitive_editor(ui: &mut Ui, p: &mut Primitive) -> bool {
    let mut changed = false;
    let num = |ui: &mut Ui, label: &str, v: &mut f64, lo: f64, hi: f64| {
        number(ui, label, v, lo..=hi, 0.01).changed()
    };
    match &mut p.shape {
        Shape::Square { size, x, y } => {
            ui.label("square");
            changed |= num(ui, "size", size, 0.01, 4.0);
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Dot { radius, x, y } => {
            ui.label("dot");
            changed |= num(ui, "radius", radius, 0.01, 2.0);
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Ring {
            radius,
            width,
            x,
            y,
        } => {
            ui.label("ring");
            changed |= num(ui, "radius", radius, 0.01, 2.0);
            changed |= num(ui, "ring width", width, 0.005, 2.0);
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Cross { size, width, x, y } => {
            ui.label("cross");
            changed |= num(ui, "size", size, 0.01, 4.0);
            changed |= num(ui, "arm width", width, 0.005, 2.0);
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Triangle { size, x, y } => {
            ui.label("triangle");
            changed |= num(ui, "size", size, 0.01, 4.0);
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Bar {
            width,
            height,
            angle_deg,
            x,
            y,
        } => {
            ui.label("bar");
            changed |= num(ui, "bar width", width, 0.005, 4.0);
            changed |= num(ui, "bar height", height, 0.005, 4.0);
            changed |= number(ui, "angle (deg)", angle_deg, -360.0..=360.0, 1.0).changed();
            changed |= num(ui, "x", x, -2.0, 2.0);
            changed |= num(ui, "y", y, -2.0, 2.0);
        }
        Shape::Path { d } => {
            changed |= text_field(ui, "SVG path (cell units)", d).changed();
        }
    }
    changed |= colour_option(ui, "fill", &mut p.fill, "#000000");
    changed |= colour_option(ui, "stroke", &mut p.stroke, "#000000");
    if p.stroke.is_some() {
        let mut w = p.stroke_width.unwrap_or(0.05);
        if number(ui, "stroke width", &mut w, 0.001..=1.0, 0.002).changed() {
            p.stroke_width = Some(w);
            changed = true;
        }
    }
    changed
}

fn colour_option(ui: &mut Ui, label: &str, value: &mut Option<String>, default: &str) -> bool {
    let mut changed = false;
    ui.horizontal(|ui| {
        let mut on = value.is_some();
        if ui.checkbox(&mut on, label).changed() {
            *value = on.then(|| default.to_string());
            changed = true;
        }
        if let Some(v) = value {
            let mut rgb = parse_hex(v).unwrap_or([0, 0, 0]);
            if ui.color_edit_button_srgb(&mut rgb).changed() {
                *v = hex(rgb);
                changed = true;
            }
        }
    });
    changed
}

fn keypoints(studio: &mut Studio, ui: &mut Ui) {
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    let current = spec.keypoint_set.clone();
    let mut chosen = current.clone();
    ui.horizontal(|ui| {
        ui.label("The detector regresses:");
        ui.selectable_value(&mut chosen, KeypointSet::All, "all");
        ui.selectable_value(&mut chosen, KeypointSet::Boundary, "boundary");
        ui.selectable_value(&mut chosen, KeypointSet::Corners, "corners");
        let custom = matches!(chosen, KeypointSet::Custom(_));
        if ui.selectable_label(custom, "custom").clicked() && !custom {
            let all = studio
                .design
                .as_ref()
                .and_then(Design::preview_family)
                .map(|f| f.regressed_keypoints().iter().map(|&k| k as u32).collect())
                .unwrap_or_default();
            chosen = KeypointSet::Custom(all);
        }
    });
    if chosen != current {
        edit(studio, "keypoints", Edit::SetKeypointSet(chosen));
    }
    if let Some(f) = studio.design.as_ref().and_then(Design::preview_family) {
        ui.label(format!(
            "{} of {} keypoints regressed (filled dots on the marker; hollow = not regressed)",
            f.regressed_keypoints().len(),
            f.keypoints().len()
        ));
    }
    tool_button(studio, ui, Tool::PickKeypoints, "Pick keypoints");
    if studio.designer.tool == Tool::PickKeypoints {
        ui.weak("Click a keypoint to add it to or remove it from a custom set.");
    }
    tool_button(studio, ui, Tool::PaintCells, "Paint cells");
    if studio.designer.tool == Tool::PaintCells {
        let mut paint = studio.designer.paint.clone().unwrap_or(CellValue::Symbol);
        ui.horizontal_wrapped(|ui| {
            ui.selectable_value(&mut paint, CellValue::Symbol, "Paint: code symbol");
            ui.selectable_value(&mut paint, CellValue::Empty, "Paint: empty");
            for name in fixed_categories(&spec) {
                let label = format!("Paint: {name}");
                ui.selectable_value(&mut paint, CellValue::Fixed(name), label);
            }
        });
        studio.designer.paint = Some(paint);
        ui.weak("Click grid cells to give them this content.");
    }
    messages(ui, studio, "keypoints", &["keypoint_set"]);
}

fn roi(studio: &mut Studio, ui: &mut Ui) {
    let spec = studio.design.as_ref().expect("a design").spec().clone();
    ui.label(format!(
        "{} ROI points: {}",
        spec.roi.points.len(),
        spec.roi
            .points
            .iter()
            .map(|p| format!("({:.2}, {:.2})", p[0], p[1]))
            .collect::<Vec<_>>()
            .join(" -> ")
    ));
    let mut margin = spec.roi.margin;
    if number(ui, "Template margin a", &mut margin, 0.0..=0.45, 0.005).changed() {
        edit_dragged(studio, "roi", "margin", Edit::SetRoiMargin(margin));
    }
    tool_button(studio, ui, Tool::PickRoi, "Pick ROI points");
    if studio.designer.tool == Tool::PickRoi {
        let draft = studio.designer.roi_draft.clone();
        ui.weak("Click the ROI points in order (clockwise on screen); the first four fix the homography.");
        ui.label(format!("{} point(s) picked", draft.len()));
        // Check the draft as the core would, before it replaces the ROI.
        let mut trial = spec.clone();
        trial.roi.points = draft.clone();
        if draft.len() >= 4 {
            if let Err(e) = Family::from_spec(trial) {
                for p in e.problems.iter().filter(|p| p.path.starts_with("roi")) {
                    ui.colored_label(ui.visuals().warn_fg_color, p.message.as_str());
                }
            }
        }
        ui.horizontal(|ui| {
            if ui
                .add_enabled(draft.len() >= 4, egui::Button::new("Use these ROI points"))
                .clicked()
            {
                edit(studio, "roi", Edit::SetRoi(draft));
                studio.designer.roi_draft.clear();
                studio.designer.tool = Tool::Look;
            }
            if ui.button("Clear picked points").clicked() {
                studio.designer.roi_draft.clear();
            }
        });
    }
    messages(ui, studio, "roi", &["roi"]);
}

fn codebook(studio: &mut Studio, ui: &mut Ui) {
    let design = studio.design.as_ref().expect("a design");
    let spec = design.spec().clone();
    let revision = design.revision;
    let family = design.validation().as_ref().ok().cloned();
    match &family {
        Some(f) => {
            let cached = studio
                .designer
                .min_distance
                .filter(|(rev, _)| *rev == revision);
            let achieved = match cached {
                Some((_, d)) => d,
                None => {
                    let rotations: Vec<Vec<usize>> = f
                        .ambiguous_rotations()
                        .filter_map(|r| r.code_perm.clone())
                        .collect();
                    let d = f.codebook().min_distance(&rotations);
                    studio.designer.min_distance = Some((revision, d));
                    d
                }
            };
            ui.label(format!(
                "{} code(s) of {} symbols over {} values; minimum distance {} (stated {}), \
                 corrects up to {} error(s)",
                f.codebook().len(),
                f.code_len(),
                f.q(),
                achieved.map_or("—".into(), |d| d.to_string()),
                spec.codebook
                    .min_distance
                    .map_or("—".into(), |d| d.to_string()),
                f.codebook().max_correction()
            ));
            ui.weak(&spec.codebook.source);
            let mut correct = f.codebook().max_correction() as u32;
            if number(ui, "Correct up to (errors)", &mut correct, 0..=32, 0.05).changed() {
                let mut cb = spec.codebook.clone();
                cb.max_correction = Some(correct);
                edit_dragged(studio, "codebook", "correction", Edit::SetCodebook(cb));
            }
            let last = f.codebook().len().saturating_sub(1);
            studio.designer.preview_id = studio.designer.preview_id.min(last);
            ui.horizontal(|ui| {
                let l = ui.label("Preview ID");
                ui.add(egui::Slider::new(&mut studio.designer.preview_id, 0..=last))
                    .labelled_by(l.id);
            });
        }
        None => {
            ui.label("The codebook shows once the design validates.");
        }
    }
    ui.separator();
    ui.label("Generate a codebook for this layout:");
    let s = &mut studio.designer.codegen;
    number(ui, "Minimum distance", &mut s.min_distance, 1..=64, 0.05);
    number(ui, "Codes wanted", &mut s.count, 1..=100_000, 1.0);
    number(ui, "Seed", &mut s.seed, 0..=u64::MAX, 1.0);
    let running = studio.designer.job.is_some();
    ui.horizontal(|ui| {
        if ui
            .add_enabled(
                !running && family.is_some(),
                egui::Button::new("Generate codebook"),
            )
            .on_disabled_hover_text("fix the design's problems first")
            .clicked()
        {
            let f = family.as_ref().expect("enabled only when valid");
            let s = &studio.designer.codegen;
            let mut params = GenerateParams::for_family(f, s.min_distance);
            params.max_codes = s.count;
            params.seed = s.seed;
            params.max_candidates = default_budget();
            studio.designer.job = Some(CodegenJob::start(params, revision));
        }
        if let Some(job) = &studio.designer.job {
            let (tried, kept) = job.progress();
            ui.add(
                egui::ProgressBar::new(tried as f32 / job.budget as f32)
                    .text(format!("{kept} codes, {tried} candidates")),
            );
        }
    });
    ui.separator();
    ui.label("Or import a standard table:");
    let matching: Vec<(String, tagsmith::family::spec::CodebookSpec)> = family
        .as_ref()
        .map(|f| {
            studio
                .library
                .entries
                .iter()
                .filter_map(|e| {
                    let other = Family::from_spec(e.spec.clone()).ok()?;
                    (other.q() == f.q()
                        && other.code_len() == f.code_len()
                        && e.spec.name != spec.name)
                        .then(|| (e.spec.name.clone(), e.spec.codebook.clone()))
                })
                .collect()
        })
        .unwrap_or_default();
    ui.horizontal_wrapped(|ui| {
        for (name, cb) in matching {
            if ui
                .button(format!("codes of {name}"))
                .on_hover_text(format!("{} codes", cb.codes.len()))
                .clicked()
            {
                edit(studio, "codebook", Edit::SetCodebook(cb));
            }
        }
    });
    if ui.button("Import table file…").clicked() {
        studio.files.request_open(Purpose::CodeTable);
    }
    messages(ui, studio, "codebook", &["codebook"]);
}

/// A code table file arrived (OpenCV or AprilTag 3 JSON): its codes become the codebook.
pub fn import_table(studio: &mut Studio, name: &str, bytes: &[u8]) {
    let Some(f) = studio
        .design
        .as_ref()
        .and_then(|d| d.validation().as_ref().ok())
        .cloned()
    else {
        studio.error("fix the design's problems before importing a codebook");
        return;
    };
    if f.q() != 2 {
        studio.error(format!(
            "{name}: standard tables are binary, this design has {} symbols",
            f.q()
        ));
        return;
    }
    let text = String::from_utf8_lossy(bytes);
    match tagsmith::codebook::import::import_table(&text, f.code_len()) {
        Ok(t) => {
            let cb = tagsmith::codebook::Codebook::from_codes(
                2,
                f.code_len(),
                t.codes,
                t.min_distance,
                None,
            )
            .to_spec(t.min_distance, &t.source);
            edit(studio, "codebook", Edit::SetCodebook(cb));
            let n = studio
                .design
                .as_ref()
                .map(|d| d.spec().codebook.codes.len());
            studio.info(format!("imported {} codes from {name}", n.unwrap_or(0)));
        }
        Err(e) => studio.error(format!("{name}: {e}")),
    }
}

fn poll_codegen(studio: &mut Studio, ctx: &egui::Context) {
    let Some(job) = &studio.designer.job else {
        return;
    };
    match job.take_result() {
        None => ctx.request_repaint_after(std::time::Duration::from_millis(100)),
        Some(result) => {
            let stale = studio.design.as_ref().map(|d| d.revision) != Some(job.revision);
            studio.designer.job = None;
            match result {
                Ok(_) if stale => studio.error(
                    "the layout changed while the codebook was generated; generate it again",
                ),
                Ok(report) => {
                    let n = report.codebook.len();
                    let cb = report.codebook.to_spec(
                        report.achieved_min_distance,
                        &format!(
                            "generated by Tagsmith (seed {}, {} candidates)",
                            studio.designer.codegen.seed, report.candidates_tried
                        ),
                    );
                    edit(studio, "codebook", Edit::SetCodebook(cb));
                    studio.info(format!(
                        "generated {n} codes with minimum distance {} in {:.1} s ({})",
                        report
                            .achieved_min_distance
                            .map_or("—".into(), |d| d.to_string()),
                        report.seconds,
                        report.stop
                    ));
                }
                Err(e) => studio.error(format!("codebook not generated: {e}")),
            }
        }
    }
}

fn marker_area(studio: &mut Studio, ui: &mut Ui, ctx: &egui::Context) {
    let design = studio.design.as_ref().expect("a design");
    let Some(family) = design.preview_family().cloned() else {
        ui.colored_label(
            ui.visuals().error_fg_color,
            "This design does not validate yet; fix the problems listed on the left.",
        );
        return;
    };
    if design.validation().is_err() {
        ui.colored_label(
            ui.visuals().warn_fg_color,
            "Showing the last valid state; the current one has problems (left).",
        );
    }
    let revision = design.revision;
    let id = studio
        .designer
        .preview_id
        .min(family.codebook().len().saturating_sub(1));
    ui.horizontal_top(|ui| {
        let side = (ui.available_height() - 40.0)
            .min(ui.available_width() * 0.62)
            .max(120.0);
        marker_view(studio, ui, ctx, &family, id, revision, side);
        ui.vertical(|ui| {
            ui.label("Rectified template (what stage 2 sees)");
            let key = "template";
            let tex = studio
                .textures
                .get_or_make(ctx, key, revision * 100_000 + id as u64, || {
                    tagsmith::render::template::rectified_template(&family, id, 256)
                        .map(|g| preview::gray_image(&g))
                        .map_err(|e| e.to_string())
                });
            match tex {
                Ok(t) => {
                    let s = (side * 0.45).max(96.0);
                    ui.add(egui::Image::new(&t).fit_to_exact_size([s, s].into()));
                }
                Err(e) => {
                    ui.colored_label(ui.visuals().error_fg_color, e);
                }
            }
        });
    });
}

#[allow(clippy::too_many_arguments)]
fn marker_view(
    studio: &mut Studio,
    ui: &mut Ui,
    ctx: &egui::Context,
    family: &Family,
    id: usize,
    revision: u64,
    side: f32,
) {
    let scene = match tagsmith::render::marker_scene(family, id, Default::default()) {
        Ok(s) => s,
        Err(e) => {
            ui.colored_label(ui.visuals().error_fg_color, e.to_string());
            return;
        }
    };
    let size = preview::fit(scene.width_mm, scene.height_mm, egui::vec2(side, side));
    let (rect, response) = ui.allocate_exact_size(size, Sense::click());
    response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "marker preview"));
    let tex = studio
        .textures
        .get_or_make(ctx, "marker", revision * 100_000 + id as u64, || {
            let px = (size.x * ctx.pixels_per_point()).round().max(16.0) as u32;
            tagsmith::render::raster::rasterize_width(&scene, px)
                .map(|p| preview::pixmap_image(&p))
                .map_err(|e| e.to_string())
        });
    let Ok(tex) = tex else {
        return;
    };
    let painter = ui.painter_at(rect);
    painter.image(
        tex.id(),
        rect,
        egui::Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
        Color32::WHITE,
    );
    let view = MarkerView { scene, rect };
    // Keypoints, coloured by the category they show for this ID.
    let regressed = family.regressed_keypoints();
    if let Some(cats) = family.keypoint_categories(id) {
        let r = view.scale(family.cell_size()).clamp(2.0, 10.0) * 0.22;
        for (k, kp) in family.keypoints().iter().enumerate() {
            let p = view.to_screen(kp.pos);
            let colour = category_colour(cats[k]);
            if regressed.contains(&k) {
                painter.circle(p, r, colour, Stroke::new(1.0, Color32::WHITE));
            } else {
                painter.circle_stroke(p, r, Stroke::new(1.5, colour));
            }
        }
    }
    let roi: Vec<Pos2> = family
        .roi_points()
        .iter()
        .map(|&p| view.to_screen(p))
        .collect();
    preview::draw_ordered_points(&painter, &roi, Color32::from_rgb(255, 140, 0));
    if studio.designer.tool == Tool::PickRoi {
        let draft: Vec<Pos2> = studio
            .designer
            .roi_draft
            .iter()
            .map(|&p| view.to_screen(p))
            .collect();
        preview::draw_ordered_points(&painter, &draft, Color32::from_rgb(220, 0, 220));
    }
    if let Some(pos) = response
        .interact_pointer_pos()
        .filter(|_| response.clicked())
    {
        click_marker(studio, family, &view, pos);
    }
}

fn snap(v: f64, step: f64) -> f64 {
    (v / step).round() * step
}

fn click_marker(studio: &mut Studio, family: &Family, view: &MarkerView, pos: Pos2) {
    let p = view.to_marker(pos);
    let step = if family.is_grid() { 0.5 } else { 0.05 };
    match studio.designer.tool {
        Tool::Look => {}
        Tool::PaintCells => {
            if !family.is_grid() {
                studio.designer.refused =
                    Some(("keypoints", "ring layouts have no cells to paint".into()));
                return;
            }
            let (col, row) = (p[0].floor(), p[1].floor());
            if col < 0.0 || row < 0.0 {
                return;
            }
            let value = studio.designer.paint.clone().unwrap_or(CellValue::Symbol);
            edit(
                studio,
                "keypoints",
                Edit::SetCell {
                    row: row as u32,
                    col: col as u32,
                    value,
                },
            );
        }
        Tool::PlaceExtras => {
            let category = studio
                .designer
                .extra_category
                .clone()
                .unwrap_or_else(|| family.categories()[0].name.clone());
            edit(
                studio,
                "layout",
                Edit::AddExtra(ExtraKeypointSpec {
                    x: snap(p[0], step),
                    y: snap(p[1], step),
                    size: studio.designer.extra_size.unwrap_or(1.0),
                    category,
                }),
            );
        }
        Tool::PickRoi => studio
            .designer
            .roi_draft
            .push([snap(p[0], step), snap(p[1], step)]),
        Tool::PickKeypoints => {
            let nearest = family
                .keypoints()
                .iter()
                .enumerate()
                .map(|(i, k)| {
                    (
                        i,
                        (k.pos[0] - p[0]).hypot(k.pos[1] - p[1]) / k.size.max(1e-9),
                    )
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let Some((k, d)) = nearest.filter(|(_, d)| *d < 0.75) else {
                return;
            };
            let _ = d;
            let mut set: Vec<u32> = family
                .regressed_keypoints()
                .iter()
                .map(|&i| i as u32)
                .collect();
            match set.iter().position(|&i| i == k as u32) {
                Some(at) => {
                    set.remove(at);
                }
                None => {
                    set.push(k as u32);
                    set.sort_unstable();
                }
            }
            edit(
                studio,
                "keypoints",
                Edit::SetKeypointSet(KeypointSet::Custom(set)),
            );
        }
    }
}
