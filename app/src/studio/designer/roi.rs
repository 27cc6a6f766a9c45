//! Designer section: the ROI, picked by clicking on the marker and checked by the core before it
//! replaces the old one; the template margin a.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
