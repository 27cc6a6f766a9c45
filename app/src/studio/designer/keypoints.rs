//! Designer section: the keypoints the detector regresses (drawn on the marker), and painting grid
//! cells with a code symbol, nothing, or a fixed category.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
