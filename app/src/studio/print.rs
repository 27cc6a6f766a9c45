//! The Print panel: sheet layout (page, margins, marker size, IDs, labels, cut marks) with a live
//! page preview, exported as SVG or PDF by `tagsmith::render` — the same code as `tagsmith sheet`.

use super::preview;
use super::Studio;
use egui::Ui;
use serde::{Deserialize, Serialize};
use tagsmith::family::Family;
use tagsmith::render::sheet::{layout_sheet, parse_ids, PageSize, Sheet, SheetParams, MAX_IDS};

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Page {
    A4,
    A3,
    Letter,
}

/// The print setup, kept across restarts (`serde(default)`: see [`super::Persisted`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct PrintSettings {
    pub page: Page,
    pub landscape: bool,
    pub margin_mm: f64,
    /// `None`: the family's own print size.
    pub marker_side_mm: Option<f64>,
    pub spacing_mm: f64,
    pub ids: String,
    pub labels: bool,
    pub cut_marks: bool,
}

impl Default for PrintSettings {
    fn default() -> Self {
        Self {
            page: Page::A4,
            landscape: false,
            margin_mm: 10.0,
            marker_side_mm: None,
            spacing_mm: 6.0,
            ids: "0-11".into(),
            labels: true,
            cut_marks: false,
        }
    }
}

#[derive(Default)]
pub struct PrintState {
    pub settings: PrintSettings,
    pub preview_page: usize,
    /// The last layout: (design revision, settings) it was made for, and the result.
    layout: Option<(u64, PrintSettings, Result<Sheet, String>)>,
}

impl PrintSettings {
    /// The core's sheet parameters, or what is wrong with the setup.
    pub fn params(&self, family: &Family) -> Result<SheetParams, String> {
        let ids = parse_ids(&self.ids, MAX_IDS).map_err(|e| format!("IDs: {e}"))?;
        if ids.is_empty() {
            return Err("IDs: list at least one ID, e.g. 0-11 or 3,5,8".into());
        }
        let mut p = SheetParams::new(family, ids);
        let page = match self.page {
            Page::A4 => PageSize::A4,
            Page::A3 => PageSize::A3,
            Page::Letter => PageSize::LETTER,
        };
        p.page = if self.landscape {
            page.landscape()
        } else {
            page
        };
        p.margin_mm = self.margin_mm;
        if let Some(side) = self.marker_side_mm {
            p.marker_side_mm = side;
        }
        p.spacing_mm = self.spacing_mm;
        p.labels = self.labels;
        p.cut_marks = self.cut_marks;
        Ok(p)
    }
}

impl PrintState {
    /// Lays the sheet out again when the design or the setup changed.
    pub fn sheet(&mut self, family: &Family, revision: u64) -> &Result<Sheet, String> {
        let fresh =
            matches!(&self.layout, Some((r, s, _)) if *r == revision && *s == self.settings);
        if !fresh {
            let result = self
                .settings
                .params(family)
                .and_then(|p| layout_sheet(family, &p).map_err(|e| e.to_string()));
            self.layout = Some((revision, self.settings.clone(), result));
        }
        &self.layout.as_ref().expect("just laid out").2
    }
}

fn number(ui: &mut Ui, label: &str, value: &mut f64, range: std::ops::RangeInclusive<f64>) -> bool {
    ui.horizontal(|ui| {
        let l = ui.label(label);
        ui.add(egui::DragValue::new(value).range(range).speed(0.5))
            .labelled_by(l.id)
            .changed()
    })
    .inner
}

pub fn show(studio: &mut Studio, ui: &mut Ui, ctx: &egui::Context) {
    let Some(design) = &studio.design else {
        ui.heading("Nothing to print yet");
        ui.label("Go to Families and duplicate a built-in family, or open a family file.");
        return;
    };
    let revision = design.revision;
    let family = match design.validation() {
        Ok(f) => f.clone(),
        Err(e) => {
            ui.colored_label(
                ui.visuals().error_fg_color,
                format!("The design has problems to fix before printing:\n{e}"),
            );
            return;
        }
    };
    egui::Panel::left("print-controls")
        .resizable(true)
        .default_size(300.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| controls(studio, ui, &family, revision));
        });
    egui::CentralPanel::default_margins()
        .show(ui, |ui| page_preview(studio, ui, ctx, &family, revision));
}

fn controls(studio: &mut Studio, ui: &mut Ui, family: &Family, revision: u64) {
    let s = &mut studio.print.settings;
    ui.horizontal(|ui| {
        ui.label("Page");
        ui.selectable_value(&mut s.page, Page::A4, "A4");
        ui.selectable_value(&mut s.page, Page::A3, "A3");
        ui.selectable_value(&mut s.page, Page::Letter, "Letter");
    });
    ui.checkbox(&mut s.landscape, "Landscape");
    number(ui, "Margin (mm)", &mut s.margin_mm, 0.0..=100.0);
    let mut side = s
        .marker_side_mm
        .unwrap_or(family.spec().print.marker_side_mm);
    if number(ui, "Marker side (mm)", &mut side, 1.0..=2000.0) {
        s.marker_side_mm = Some(side);
    }
    number(ui, "Spacing (mm)", &mut s.spacing_mm, 0.0..=200.0);
    ui.horizontal(|ui| {
        let l = ui.label("IDs");
        ui.text_edit_singleline(&mut s.ids)
            .labelled_by(l.id)
            .on_hover_text("ranges and lists, e.g. 0-11 or 3,5,8");
    });
    ui.weak(format!(
        "{} has IDs 0 to {}",
        family.name(),
        family.codebook().len().saturating_sub(1)
    ));
    ui.checkbox(&mut s.labels, "Labels");
    ui.checkbox(&mut s.cut_marks, "Cut marks");
    ui.separator();
    let sheet = studio.print.sheet(family, revision).clone();
    match &sheet {
        Ok(sheet) => {
            ui.label(format!(
                "{} page(s), {} marker(s) per page",
                sheet.pages.len(),
                sheet.markers_per_page
            ));
            for w in &sheet.warnings {
                ui.colored_label(ui.visuals().warn_fg_color, format!("note: {w}"));
            }
        }
        Err(e) => {
            ui.colored_label(ui.visuals().error_fg_color, e.as_str());
        }
    }
    ui.horizontal(|ui| {
        let ok = sheet.is_ok();
        if ui
            .add_enabled(ok, egui::Button::new("Export PDF…"))
            .clicked()
        {
            export(studio, family, true);
        }
        if ui
            .add_enabled(ok, egui::Button::new("Export SVG…"))
            .clicked()
        {
            export(studio, family, false);
        }
    });
}

/// Writes the sheet; an SVG sheet of several pages is one file per page, as `tagsmith sheet` does.
pub fn export(studio: &mut Studio, family: &Family, pdf: bool) {
    let revision = studio.design.as_ref().map_or(0, |d| d.revision);
    let sheet = match studio.print.sheet(family, revision) {
        Ok(s) => s.clone(),
        Err(e) => {
            let e = e.clone();
            studio.error(format!("nothing exported: {e}"));
            return;
        }
    };
    let stem = format!("{}-sheet", family.name());
    let mut written = Vec::new();
    if pdf {
        let bytes = match tagsmith::render::pdf::sheet_pdf(&sheet) {
            Ok(b) => b,
            Err(e) => {
                studio.error(format!("PDF not made: {e}"));
                return;
            }
        };
        match studio.files.save_as(&format!("{stem}.pdf"), &bytes) {
            Ok(Some(place)) => written.push(place),
            Ok(None) => return,
            Err(e) => {
                studio.error(format!("PDF not saved: {e}"));
                return;
            }
        }
    } else {
        let n = sheet.pages.len();
        for (i, page) in sheet.pages.iter().enumerate() {
            let name = if n == 1 {
                format!("{stem}.svg")
            } else {
                format!("{stem}-{}.svg", i + 1)
            };
            match studio.files.save_as(&name, page.as_bytes()) {
                Ok(Some(place)) => written.push(place),
                Ok(None) => return,
                Err(e) => {
                    studio.error(format!("SVG not saved: {e}"));
                    return;
                }
            }
        }
    }
    studio.info(format!(
        "exported {} page(s): {}",
        sheet.pages.len(),
        written.join(", ")
    ));
}

fn page_preview(
    studio: &mut Studio,
    ui: &mut Ui,
    ctx: &egui::Context,
    family: &Family,
    revision: u64,
) {
    let Ok(sheet) = studio.print.sheet(family, revision).clone() else {
        ui.label("No preview: the setup on the left has a problem.");
        return;
    };
    let pages = sheet.pages.len();
    let page = studio.print.preview_page.min(pages - 1);
    ui.horizontal(|ui| {
        if ui
            .add_enabled(page > 0, egui::Button::new("< Previous page"))
            .clicked()
        {
            studio.print.preview_page = page - 1;
        }
        ui.label(format!("page {} of {pages}", page + 1));
        if ui
            .add_enabled(page + 1 < pages, egui::Button::new("Next page >"))
            .clicked()
        {
            studio.print.preview_page = page + 1;
        }
    });
    let page = studio.print.preview_page.min(pages - 1);
    let avail = ui.available_size();
    let aspect = (sheet.page.height_mm / sheet.page.width_mm) as f32;
    let w = avail.x.min(avail.y / aspect).max(100.0);
    // The settings are part of the key so that any change re-renders.
    let key = format!("page-{page}-{:?}", studio.print.settings);
    let px = (w * ctx.pixels_per_point()).round() as u32;
    let svg = &sheet.pages[page];
    let tex = studio.textures.get_or_make(ctx, &key, revision, || {
        tagsmith::render::raster::rasterize_svg(svg, px)
            .map(|p| preview::pixmap_image(&p))
            .map_err(|e| e.to_string())
    });
    match tex {
        Ok(t) => {
            let r = ui.add(egui::Image::new(&t).fit_to_exact_size([w, w * aspect].into()));
            ui.painter().rect_stroke(
                r.rect,
                0.0,
                egui::Stroke::new(1.0, egui::Color32::GRAY),
                egui::StrokeKind::Outside,
            );
        }
        Err(e) => {
            ui.colored_label(ui.visuals().error_fg_color, e);
        }
    }
}
