//! The Designer panel: every part of a family spec, edited through `family::edit::Edit`, with the
//! marker, its keypoints and ROI, and the rectified template drawn live beside the controls.

use super::codegen::{default_budget, CodegenJob};
use super::design::Design;
use super::files::Purpose;
use super::preview::{self, category_colour, MarkerView};
use super::Studio;
use egui::{Color32, Pos2, Sense, Stroke, Ui};
use tagsmith::family::edit::{CellValue, Edit};
use tagsmith::family::spec::ExtraKeypoint as ExtraKeypointSpec;
use tagsmith::family::spec::{KeypointSet, Layout, Primitive, Role, Shape};
use tagsmith::family::Family;

mod categories;
mod codebook;
mod identity;
mod keypoints;
mod layout;
mod marker;
mod roi;

pub use codebook::import_table;

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
    codebook::poll(studio, ctx);
    egui::Panel::left("designer-controls")
        .resizable(true)
        .default_size(380.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| controls(studio, ui));
        });
    egui::CentralPanel::default_margins().show(ui, |ui| marker::show(studio, ui, ctx));
}

/// A designer section's body.
type Section = fn(&mut Studio, &mut Ui);

fn controls(studio: &mut Studio, ui: &mut Ui) {
    let sections: [(&str, Section); 6] = [
        ("Identity", identity::show),
        ("Layout", layout::show),
        ("Pattern categories", categories::show),
        ("Keypoints", keypoints::show),
        ("ROI", roi::show),
        ("Codebook", codebook::show),
    ];
    for (title, show) in sections {
        egui::CollapsingHeader::new(title)
            .default_open(true)
            .show(ui, |ui| show(studio, ui));
    }
    let design = studio.design.as_ref().expect("a design");
    let other: Vec<String> = design.problems_at(&["format", "extra"]);
    if !other.is_empty() || design.validation().is_ok() {
        ui.separator();
    }
    for p in other {
        ui.colored_label(ui.visuals().error_fg_color, p.as_str());
    }
    if let Ok(f) = design.validation() {
        for w in tagsmith::render::readback::warnings(f) {
            ui.colored_label(ui.visuals().warn_fg_color, format!("note: {w}"));
        }
    }
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

fn tool_button(studio: &mut Studio, ui: &mut Ui, tool: Tool, label: &str) {
    let on = studio.designer.tool == tool;
    if ui.selectable_label(on, label).clicked() {
        studio.designer.tool = if on { Tool::Look } else { tool };
    }
}
