//! Designer section: pattern categories (add, rename, remove, role) and their primitives, with a
//! live swatch.

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
    // Every shape but a path is placed by a centre, edited after its own fields.
    let centre = match &mut p.shape {
        Shape::Square { size, x, y } => {
            ui.label("square");
            changed |= num(ui, "size", size, 0.01, 4.0);
            Some((x, y))
        }
        Shape::Dot { radius, x, y } => {
            ui.label("dot");
            changed |= num(ui, "radius", radius, 0.01, 2.0);
            Some((x, y))
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
            Some((x, y))
        }
        Shape::Cross { size, width, x, y } => {
            ui.label("cross");
            changed |= num(ui, "size", size, 0.01, 4.0);
            changed |= num(ui, "arm width", width, 0.005, 2.0);
            Some((x, y))
        }
        Shape::Triangle { size, x, y } => {
            ui.label("triangle");
            changed |= num(ui, "size", size, 0.01, 4.0);
            Some((x, y))
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
            Some((x, y))
        }
        Shape::Path { d } => {
            changed |= text_field(ui, "SVG path (cell units)", d).changed();
            None
        }
    };
    if let Some((x, y)) = centre {
        changed |= num(ui, "x", x, -2.0, 2.0);
        changed |= num(ui, "y", y, -2.0, 2.0);
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
