//! Designer section: grid or rings layout, quiet zone, extra keypoints.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
