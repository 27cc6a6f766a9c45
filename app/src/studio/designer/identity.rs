//! Designer section: name, title, description, source, print defaults, background.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
