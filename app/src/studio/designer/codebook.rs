//! Designer section: the codebook (statistics, ID browser, generation in the background, import of
//! a built-in family's codes or a standard table file).

use super::*;

pub(super) fn show(studio: &mut Studio, ui: &mut Ui) {
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
            let mut params = f.generate_params(s.min_distance);
            params.max_codes = s.count;
            params.seed = s.seed;
            params.max_candidates = default_budget();
            studio.designer.job = Some(CodegenJob::start(params, revision));
        }
        if let Some(job) = &studio.designer.job {
            let progress = job.progress();
            ui.add(egui::ProgressBar::new(progress.fraction).text(progress.message));
            if ui.button("Cancel generation").clicked() {
                job.cancel();
                studio.designer.job = None;
                studio.info("codebook generation cancelled");
            }
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
                .filter(|e| e.q == f.q() && e.code_len == f.code_len() && e.spec.name != spec.name)
                .map(|e| (e.spec.name.clone(), e.spec.codebook.clone()))
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

pub(super) fn poll(studio: &mut Studio, ctx: &egui::Context) {
    let Some(job) = &mut studio.designer.job else {
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
