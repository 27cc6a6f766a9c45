//! The marker preview: rendered by the core, overlaid with keypoints and ROI, and the target of
//! the designer's click tools; the rectified template beside it.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui, ctx: &egui::Context) {
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
