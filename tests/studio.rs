//! The studio driven through its real UI (egui_kittest): widgets are found by their labels and
//! clicked or given values, as a user (or a screen reader) would.

use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tagsmith::family::spec::{Layout, Shape};
use tagsmith_studio::studio::files::FolderFiles;
use tagsmith_studio::studio::{Notice, Panel, Studio};

struct Setup {
    _dir: tempfile::TempDir,
    out: PathBuf,
    user: PathBuf,
}

fn setup() -> Setup {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("exports");
    let user = dir.path().join("families");
    Setup {
        out,
        user,
        _dir: dir,
    }
}

fn studio(s: &Setup) -> Harness<'static, Studio> {
    let mut files = FolderFiles::new(&s.out);
    files.user_folder = Some(s.user.clone());
    let studio = Studio::new(Box::new(files));
    let mut h = Harness::builder()
        // Tall enough that every designer section is on screen without scrolling.
        .with_size(egui::vec2(1400.0, 2400.0))
        .with_max_steps(50)
        .build_ui_state(|ui, s: &mut Studio| s.ui(ui), studio);
    h.run();
    h
}

/// Families panel → select `builtin` → Duplicate as new design.
fn duplicate(h: &mut Harness<'static, Studio>, builtin: &str) {
    h.get_by_label(builtin).click();
    h.run();
    h.get_by_label("Duplicate as new design").click();
    h.run();
    assert_eq!(h.state().panel, Panel::Designer);
}

/// The Train panel's first run folder (beside the user's families).
fn first_run_folder(s: &Setup) -> PathBuf {
    let runs = s.user.with_file_name("runs");
    std::fs::read_dir(&runs)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path()
}

/// A run folder's report.
fn run_report(run_dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(run_dir.join("report.json")).unwrap()).unwrap()
}

/// Frames until `done` holds (background work such as codebook generation).
fn run_until(h: &mut Harness<'static, Studio>, what: &str, done: impl Fn(&Studio) -> bool) {
    let start = Instant::now();
    while !done(h.state()) {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "timed out: {what}"
        );
        h.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    h.run();
}

fn spec(h: &Harness<'static, Studio>) -> tagsmith::family::FamilySpec {
    h.state().design.as_ref().expect("a design").spec().clone()
}

fn grid(h: &Harness<'static, Studio>) -> tagsmith::family::spec::GridLayout {
    match spec(h).layout {
        Layout::Grid(g) => g,
        Layout::Rings(_) => panic!("expected a grid"),
    }
}

fn pdf_pages(path: &Path) -> usize {
    let bytes = std::fs::read(path).unwrap();
    assert!(
        bytes.starts_with(b"%PDF-"),
        "{} is not a PDF",
        path.display()
    );
    let text = String::from_utf8_lossy(&bytes);
    text.matches("/Type /Page").count() - text.matches("/Type /Pages").count()
}

fn error_text(h: &Harness<'static, Studio>) -> String {
    match &h.state().notice {
        Some(Notice::Error(e)) => e.clone(),
        other => panic!("expected an error message, got {other:?}"),
    }
}

/// The scenario: a new family from a built-in, a smaller grid, a cross-shaped category
/// painted into the grid, a generated codebook, saved, printed to PDF.
#[test]
fn design_a_family_from_a_builtin_and_print_it() {
    let s = setup();
    let mut h = studio(&s);

    duplicate(&mut h, "apriltag-36h11");
    assert_eq!(h.state().panel, Panel::Designer);
    assert_eq!(spec(&h).name, "apriltag-36h11-copy");
    assert!(h.query_by_label_contains("(unsaved)").is_some());

    let size_before = grid(&h).size;
    h.get_by_label("Grid size").set_value_accesskit(7.0);
    h.run();
    assert_eq!(grid(&h).size, 7);
    assert_ne!(size_before, 7);

    // Undo and redo, by keyboard.
    h.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::Z);
    h.run();
    assert_eq!(grid(&h).size, size_before, "Ctrl+Z undoes the grid change");
    h.key_press_modifiers(
        egui::Modifiers::COMMAND | egui::Modifiers::SHIFT,
        egui::Key::Z,
    );
    h.run();
    assert_eq!(grid(&h).size, 7, "Ctrl+Shift+Z redoes it");

    h.get_by_label("New category name").click();
    h.run();
    h.get_by_label("New category name").type_text("cross");
    h.run();
    h.get_by_label("Add category").click();
    h.run();
    assert!(
        spec(&h).categories.iter().any(|c| c.name == "cross"),
        "{:?} {:?}",
        h.state().notice,
        h.state().designer.refused
    );
    h.get_by_label("+ cross").click();
    h.run();
    let cross = spec(&h)
        .categories
        .into_iter()
        .find(|c| c.name == "cross")
        .expect("the new category");
    assert!(matches!(cross.primitives[..], [ref p] if matches!(p.shape, Shape::Cross { .. })));

    // Assign it: paint the centre cell of the 7×7 grid with it.
    h.get_by_label("Paint cells").click();
    h.run();
    h.get_by_label("Paint: cross").click();
    h.run();
    h.get_by_label("marker preview").click();
    h.run();
    let g = grid(&h);
    let key = g
        .legend
        .iter()
        .find(|(_, v)| *v == "cross")
        .map(|(k, _)| k.chars().next().unwrap())
        .expect("the cross category is in the legend");
    assert_eq!(g.cells[3].chars().nth(3), Some(key), "{:?}", g.cells);

    h.get_by_label("Minimum distance").set_value_accesskit(5.0);
    h.get_by_label("Codes wanted").set_value_accesskit(30.0);
    h.run();
    h.get_by_label("Generate codebook").click();
    h.run();
    run_until(&mut h, "codebook generation", |s| s.designer.job.is_none());
    assert!(
        matches!(&h.state().notice, Some(Notice::Info(t)) if t.starts_with("generated 30 codes")),
        "{:?}",
        h.state().notice
    );
    let cb = spec(&h).codebook;
    assert_eq!(cb.codes.len(), 30, "{:?}", h.state().notice);
    assert!(cb.min_distance.unwrap() >= 5);
    assert!(h.state().design.as_ref().unwrap().validation().is_ok());

    h.get_by_label("Save").click();
    h.run();
    let saved = s.user.join("apriltag-36h11-copy.json");
    let family = tagsmith::family::load_file(&saved).expect("the saved family validates");
    assert_eq!(family.code_len(), 24, "7×7 with a frame and one cross cell");
    assert!(h.query_by_label_contains("(unsaved)").is_none());
    assert!(
        h.get_all_by_label("apriltag-36h11-copy").count() >= 1,
        "the saved design is listed among the user's families"
    );

    h.get_by_label("Print").click();
    h.run();
    h.get_by_label("IDs").set_text_value_accesskit("0-29");
    h.get_by_label("Marker side (mm)").set_value_accesskit(60.0);
    h.run();
    h.get_by_label("Export PDF…").click();
    h.run();
    let pdf = s.out.join("apriltag-36h11-copy-sheet.pdf");
    let mut params = h.state().print.settings.params(&family).unwrap();
    params.marker_side_mm = 60.0;
    let expected = tagsmith::render::sheet::layout_sheet(&family, &params)
        .unwrap()
        .pages
        .len();
    assert!(expected >= 2, "30 markers of 60 mm take several A4 pages");
    assert_eq!(pdf_pages(&pdf), expected);
}

#[derive(Debug)]
struct Dropped {
    path: PathBuf,
    bytes: Vec<u8>,
}

impl egui::DroppedFile for Dropped {
    fn path(&self) -> &Path {
        &self.path
    }
    fn bytes(&self) -> Result<Vec<u8>, String> {
        Ok(self.bytes.clone())
    }
}

#[test]
fn a_malformed_family_dropped_on_the_window_is_refused_by_file_and_field() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-4x4_50");
    let before = spec(&h);
    let listed = h.state().library.entries.len();

    let mut json: serde_json::Value =
        serde_json::from_str(&tagsmith::family::to_json_string(&before)).unwrap();
    json["layout"]["size"] = serde_json::json!(40);
    let path = PathBuf::from("/tmp/broken-family.json");
    h.input_mut().dropped_files.push(Arc::new(Dropped {
        path: path.clone(),
        bytes: serde_json::to_vec(&json).unwrap(),
    }));
    h.run();
    let e = error_text(&h);
    assert!(
        e.contains("broken-family.json") && e.contains("layout"),
        "{e}"
    );
    assert_eq!(spec(&h), before, "the design is untouched");
    assert_eq!(
        h.state().library.entries.len(),
        listed,
        "nothing was listed"
    );

    h.input_mut().dropped_files.push(Arc::new(Dropped {
        path: PathBuf::from("/tmp/not-json.json"),
        bytes: b"\xff\xfe garbage".to_vec(),
    }));
    h.run();
    assert!(error_text(&h).contains("not-json.json"));
    assert_eq!(spec(&h), before);

    // A valid family dropped while the design has unsaved changes is listed, not swapped in.
    let good = tagsmith::builtin::get("apriltag-16h5").unwrap().unwrap();
    h.input_mut().dropped_files.push(Arc::new(Dropped {
        path: PathBuf::from("/tmp/mine.json"),
        bytes: tagsmith::family::to_json_string(good.spec()).into_bytes(),
    }));
    h.run();
    assert_eq!(spec(&h), before, "unsaved work is not replaced");
    assert_eq!(h.state().library.entries.len(), listed + 1);
}

#[test]
fn impossible_print_setups_say_why_and_export_nothing() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "apriltag-36h11");
    h.get_by_label("Print").click();
    h.run();

    h.get_by_label("IDs").set_text_value_accesskit("0-5000");
    h.run();
    assert!(
        h.query_by_label_contains("does not exist").is_some(),
        "the out-of-range ID is explained"
    );
    h.get_by_label("Export PDF…").click();
    h.run();

    h.get_by_label("IDs").set_text_value_accesskit("0-3");
    h.get_by_label("Marker side (mm)")
        .set_value_accesskit(500.0);
    h.run();
    assert!(
        h.query_by_label_contains("fit").is_some(),
        "a marker larger than the page is explained"
    );
    h.get_by_label("Export SVG…").click();
    h.run();
    assert!(!s.out.exists(), "nothing was written");

    h.get_by_label("Marker side (mm)").set_value_accesskit(30.0);
    h.run();
    h.get_by_label("Export SVG…").click();
    h.run();
    assert!(s.out.join("apriltag-36h11-copy-sheet.svg").exists());
}

#[test]
fn a_design_survives_a_restart_with_its_unsaved_marker() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-5x5_100");
    h.get_by_label("Quiet zone (cells)")
        .set_value_accesskit(2.0);
    h.run();
    let kept = h.state().persisted();
    let edited = spec(&h);

    // Two designs copied from the same built-in are saved side by side, not over each other.
    h.get_by_label("Save").click();
    h.run();
    h.get_by_label("Families").click();
    h.run();
    duplicate(&mut h, "aruco-5x5_100");
    h.get_by_label("Save").click();
    h.run();
    assert!(s.user.join("aruco-5x5_100-copy.json").exists());
    assert!(s.user.join("aruco-5x5_100-copy-2.json").exists());

    let mut files = FolderFiles::new(&s.out);
    files.user_folder = Some(s.user.clone());
    let mut again = Studio::new(Box::new(files));
    again.restore(serde_json::from_str(&serde_json::to_string(&kept).unwrap()).unwrap());
    assert_eq!(again.design.as_ref().unwrap().spec(), &edited);
    assert!(again.is_dirty(), "still marked unsaved after the restart");
}

/// A click at `p` marker units on the marker preview (the view maps units to screen points).
fn click_marker(h: &mut Harness<'static, Studio>, p: [f64; 2]) {
    let rect = h.get_by_label("marker preview").rect();
    let family = h
        .state()
        .design
        .as_ref()
        .unwrap()
        .preview_family()
        .unwrap()
        .clone();
    let view = tagsmith_studio::studio::preview::MarkerView::new(&family, 0, rect).unwrap();
    let pos = view.to_screen(p);
    for pressed in [true, false] {
        h.event(egui::Event::PointerButton {
            pos,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
        h.step();
    }
    h.run();
}

#[test]
fn roi_points_picked_by_clicking_are_checked_before_they_are_used() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-4x4_50");
    let before = spec(&h).roi.points;
    let side = grid(&h).size as f64;

    h.get_by_label("Pick ROI points").click();
    h.run();
    // Counter-clockwise on screen: refused with the core's reason, before anything changes.
    for p in [[0.0, 0.0], [0.0, side], [side, side], [side, 0.0]] {
        click_marker(&mut h, p);
    }
    assert_eq!(h.state().designer.roi_draft.len(), 4);
    assert!(h.query_by_label_contains("counter-clockwise").is_some());
    assert_eq!(spec(&h).roi.points, before);

    h.get_by_label("Clear picked points").click();
    h.run();
    // Clockwise, starting from the top-right corner: a valid, rotated ROI.
    let clockwise = [[side, 0.0], [side, side], [0.0, side], [0.0, 0.0]];
    for p in clockwise {
        click_marker(&mut h, p);
    }
    assert!(h.query_by_label_contains("counter-clockwise").is_none());
    h.get_by_label("Use these ROI points").click();
    h.run();
    assert_eq!(
        spec(&h).roi.points,
        clockwise.to_vec(),
        "clicks snap to the grid"
    );
    assert!(h.state().design.as_ref().unwrap().validation().is_ok());

    // Undo brings the old ROI back.
    h.get_by_label("Undo").click();
    h.run();
    assert_eq!(spec(&h).roi.points, before);
}

/// The desktop window under Xvfb with software GL, one frame written to a PNG. Needs Debian's
/// `xvfb libgl1-mesa-dri libegl1` and the screenshot feature:
/// `cargo test -p tagsmith-studio --features screenshot --test studio -- --ignored desktop`
#[test]
#[ignore = "needs Xvfb and --features screenshot"]
fn desktop_screenshot_under_xvfb() {
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("designer.png");
    let out = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1400x900x24"])
        .arg(env!("CARGO_BIN_EXE_tagsmith"))
        .args([
            "studio",
            "apriltag-xo-36h11",
            "--panel",
            "designer",
            "--fresh",
        ])
        .env("EFRAME_SCREENSHOT_TO", &shot)
        .env("XDG_DATA_HOME", dir.path())
        .output()
        .expect("xvfb-run is installed");
    assert!(
        shot.exists(),
        "no screenshot: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let image = tagsmith::image::read(&shot, &Default::default()).unwrap();
    assert!(image.width >= 1000 && image.height >= 700);
    // A drawn window, not a blank frame: dark panels and a white marker preview.
    let (dark, light) = image.pixels.iter().fold((0, 0), |(d, l), &p| {
        (d + usize::from(p < 60), l + usize::from(p > 200))
    });
    let n = image.pixels.len();
    assert!(
        dark > n / 10 && light > n / 20,
        "dark {dark}, light {light} of {n}"
    );
}

#[test]
fn the_tabs_and_the_command_line_name_every_panel_from_one_list() {
    use clap::ValueEnum;
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-4x4_50");
    for panel in Panel::ALL {
        h.get_by_label(panel.label()).click();
        h.run();
        assert_eq!(h.state().panel, panel);
    }
    let names: Vec<String> = Panel::value_variants()
        .iter()
        .map(|p| p.to_possible_value().unwrap().get_name().to_string())
        .collect();
    assert_eq!(
        names,
        ["families", "designer", "print", "train", "detect", "compare"]
    );
    for panel in Panel::ALL {
        assert_eq!(Panel::from_str(panel.name(), false), Ok(panel));
        assert_eq!(Panel::from_name(panel.name()), Some(panel));
        let value = panel.to_possible_value().unwrap();
        assert_eq!(
            value.get_help().map(|h| h.to_string()).as_deref(),
            Some(panel.help())
        );
    }
    assert!(
        Panel::from_str("Designer", false).is_err(),
        "names are lowercase"
    );

    // As `tagsmith studio --panel` will declare it.
    #[derive(clap::Parser)]
    struct Args {
        #[arg(long, value_enum)]
        panel: Option<Panel>,
    }
    let parse = |args: &[&str]| <Args as clap::Parser>::try_parse_from(args).map(|a| a.panel);
    assert_eq!(
        parse(&["studio", "--panel", "print"]).unwrap(),
        Some(Panel::Print)
    );
    assert_eq!(parse(&["studio"]).unwrap(), None);
    let refused = parse(&["studio", "--panel", "training"])
        .unwrap_err()
        .to_string();
    assert!(refused.contains("families, designer, print"), "{refused}");
}

/// eframe's storage, in memory.
#[derive(Default)]
struct Storage(std::collections::HashMap<String, String>);

impl eframe::Storage for Storage {
    fn get_string(&self, key: &str) -> Option<String> {
        self.0.get(key).cloned()
    }
    fn set_string(&mut self, key: &str, value: String) {
        self.0.insert(key.to_string(), value);
    }
    fn remove_string(&mut self, key: &str) {
        self.0.remove(key);
    }
    fn flush(&mut self) {}
}

/// State written by another version of the studio (one that lacked a field this one has, and had
/// one this one does not know) still brings back the unsaved design and the print setup.
#[test]
fn state_kept_by_another_version_still_restores_the_design_and_print_setup() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-5x5_100");
    h.get_by_label("Quiet zone (cells)")
        .set_value_accesskit(2.0);
    h.run();
    let edited = spec(&h);
    {
        let p = &mut h.state_mut().print.settings;
        p.page = tagsmith_studio::studio::print::Page::A3;
        p.landscape = true;
        p.margin_mm = 15.0;
        p.ids = "3-7".into();
        p.cut_marks = true;
    }
    let mut storage = Storage::default();
    h.state().store(&mut storage);
    let ours = eframe::Storage::get_string(&storage, eframe::APP_KEY).expect("stored");

    let fresh = || {
        let mut files = FolderFiles::new(&s.out);
        files.user_folder = Some(s.user.clone());
        Studio::new(Box::new(files))
    };
    let restored = |text: String| {
        let mut storage = Storage::default();
        eframe::Storage::set_string(&mut storage, eframe::APP_KEY, text);
        let mut again = fresh();
        again.restore_from(&storage);
        again
    };

    // The same version: everything comes back.
    let again = restored(ours.clone());
    assert_eq!(again.design.as_ref().unwrap().spec(), &edited);
    assert_eq!(again.print.settings, h.state().print.settings);

    // An older version had no cut marks; a newer one keeps a zoom and a theme.
    let print_field = ",cut_marks:true)";
    assert!(ours.contains(print_field), "{ours}");
    let other = ours.replacen(print_field, ",zoom:2.5)", 1);
    let other = format!("{},theme:\"dark\")", other.strip_suffix(')').unwrap());
    let again = restored(other);
    let design = again.design.as_ref().expect("the design is restored");
    assert_eq!(design.spec(), &edited);
    assert!(again.is_dirty(), "still marked unsaved");
    assert_eq!(again.panel, Panel::Designer);
    let p = &again.print.settings;
    assert_eq!(p.page, tagsmith_studio::studio::print::Page::A3);
    assert!(p.landscape);
    assert_eq!((p.margin_mm, p.ids.as_str()), (15.0, "3-7"));
    assert!(!p.cut_marks, "the missing field takes its default");

    // A version from before printing kept no print setup at all. (The family has a `print` of
    // its own; the studio's is the last field.)
    let start = ours.rfind(",print:(").expect("a print field");
    let end = start + ours[start..].find(')').unwrap() + 1;
    let older = format!("{}{}", &ours[..start], &ours[end..]);
    assert!(!older.contains("margin_mm"), "{older}");
    let again = restored(older);
    assert_eq!(again.design.as_ref().unwrap().spec(), &edited);
    assert_eq!(
        again.print.settings,
        tagsmith_studio::studio::print::PrintSettings::default()
    );
}

#[test]
fn the_families_panel_shows_each_family_drawn_with_its_numbers() {
    let s = setup();
    let mut h = studio(&s);
    for name in tagsmith::builtin::names() {
        let f = tagsmith::builtin::get(name).unwrap().unwrap();
        let numbers = format!(
            "{} keypoints · {} codes · minimum distance {}",
            f.keypoints().len(),
            f.codebook().len(),
            f.spec().codebook.min_distance.expect("built-ins state it")
        );
        // Variants of one family (apriltag-36h11, -xo-, -xa-) share their numbers.
        assert!(
            h.query_all_by_label(&numbers).next().is_some(),
            "{name}: {numbers}"
        );
        h.get_by_label(&format!("{name} marker"));
    }
    // Thumbnails are uploaded once, not every frame: a new upload would get a new id.
    let ctx = h.ctx.clone();
    let textures = || {
        let mut ids: Vec<egui::TextureId> = (ctx.tex_manager().read().allocated())
            .filter(|(_, meta)| meta.name.starts_with("family-thumbnail-"))
            .map(|(id, _)| *id)
            .collect();
        ids.sort_by_key(|id| format!("{id:?}"));
        ids
    };
    let before = textures();
    assert_eq!(before.len(), h.state().library.entries.len());
    for _ in 0..3 {
        h.step();
    }
    assert_eq!(textures(), before);

    // A click on a thumbnail selects its family.
    h.get_by_label("aruco-6x6_250 marker").click();
    h.run();
    h.get_by_label("Duplicate as new design").click();
    h.run();
    assert_eq!(spec(&h).name, "aruco-6x6_250-copy");
}

#[test]
fn every_builtin_family_is_on_the_first_screen_with_whether_it_detects() {
    let s = setup();
    let mut files = FolderFiles::new(&s.out);
    files.user_folder = Some(s.user.clone());
    let window = egui::vec2(1400.0, 900.0);
    let mut h = Harness::builder()
        .with_size(window)
        .with_max_steps(50)
        .build_ui_state(|ui, s: &mut Studio| s.ui(ui), Studio::new(Box::new(files)));
    h.run();
    let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, window);
    for name in tagsmith::builtin::names() {
        let marker = h.get_by_label(&format!("{name} marker")).rect();
        assert!(
            screen.contains_rect(marker),
            "{name}'s marker at {marker:?}"
        );
        assert!(marker.width() >= 80.0, "{name}'s marker is {marker:?}");
        let label = h.get_by_label(name).rect();
        assert!(screen.contains_rect(label), "{name}'s name at {label:?}");
        assert!(label.height() < 28.0, "{name}'s name wraps: {label:?}");
    }
    let shipped = tagsmith::detect::stage2::shipped_families().count();
    assert_eq!(
        h.query_all_by_label("detects: shipped weights").count(),
        shipped
    );
    assert_eq!(
        h.query_all_by_label("no shipped weights: train them in Train")
            .count(),
        tagsmith::builtin::names().count() - shipped
    );
}

/// Detect panel → a shipped sample photograph (the first click also loads the models).
fn detect_sample(h: &mut Harness<'static, Studio>, sample: &str) {
    h.get_by_label("Detect").click();
    h.run();
    assert_eq!(h.state().panel, Panel::Detect);
    h.get_by_label(sample).click();
    h.run();
    wait_for_detection(h);
}

/// Until the Detect panel's background detection is back.
fn wait_for_detection(h: &mut Harness<'static, Studio>) {
    run_until(h, "the detection", |s| {
        !s.detect.is_detecting() && s.detect.result.is_some()
    });
}

/// `tagsmith detect SAMPLE ARGS… --json` of this build: the detections file.
/// How many markers the Detect panel lists.
fn listed_count(h: &Harness<'static, Studio>) -> usize {
    h.state().detect.result.as_ref().unwrap().markers.len()
}

/// How many markers `tagsmith detect SAMPLE ARGS` reports.
fn cli_count(sample: &str, args: &[&str]) -> usize {
    cli_detect(sample, args)["images"][0]["detections"]
        .as_array()
        .unwrap()
        .len()
}

fn cli_detect(sample: &str, args: &[&str]) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let image = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/samples/")
        .join(sample);
    let out = dir.path().join("cli.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .arg("detect")
        .arg(&image)
        .args(args)
        .arg("--json")
        .arg(&out)
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap()
}

/// Detect panel → a sample photograph: the panel lists what `tagsmith detect` reports on the
/// same image, and saves it in the CLI's format.
#[test]
fn the_detect_panel_lists_what_the_cli_detects_on_a_sample() {
    let s = setup();
    let mut h = studio(&s);
    detect_sample(&mut h, "aruco-6x6_250-tutorial.jpg");
    let listed: Vec<(String, usize, [[f64; 2]; 4])> = h
        .state()
        .detect
        .result
        .as_ref()
        .expect("detected on the sample")
        .markers
        .iter()
        .map(|m| {
            let d = &m.detection;
            (d.family.clone().unwrap(), d.id, d.corners.0)
        })
        .collect();
    assert!(!listed.is_empty(), "the sample shows six ArUco markers");
    // Each marker's pose is drawn as axes from its centre (where its diagonals cross).
    let result = h.state().detect.result.as_ref().unwrap();
    for m in &result.markers {
        let [origin, ..] = m.axes.expect("every marker of the sample has a pose");
        let centre = m.detection.corners.diagonal_crossing().unwrap();
        let off = (origin[0] - centre[0]).hypot(origin[1] - centre[1]);
        assert!(off < 1.5, "axes {off:.2} px from the marker's centre");
    }

    let cli = cli_detect("aruco-6x6_250-tutorial.jpg", &[]);
    let cli: Vec<(String, usize, [[f64; 2]; 4])> = cli["images"][0]["detections"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| {
            let c = |i: usize, j: usize| d["corners"][i][j].as_f64().unwrap();
            (
                d["family"].as_str().unwrap().to_string(),
                d["id"].as_u64().unwrap() as usize,
                std::array::from_fn(|i| [c(i, 0), c(i, 1)]),
            )
        })
        .collect();
    assert_eq!(listed.len(), cli.len());
    for ((f1, id1, c1), (f2, id2, c2)) in listed.iter().zip(&cli) {
        assert_eq!((f1, id1), (f2, id2));
        for (a, b) in c1.iter().zip(c2) {
            assert!((a[0] - b[0]).abs() < 1e-6 && (a[1] - b[1]).abs() < 1e-6);
        }
    }

    h.get_by_label("Save detections (JSON)…").click();
    h.run();
    let saved = s.out.join("aruco-6x6_250-tutorial.detections.json");
    let saved: serde_json::Value = serde_json::from_slice(&std::fs::read(&saved).unwrap()).unwrap();
    assert_eq!(
        saved["images"][0]["detections"].as_array().unwrap().len(),
        listed.len()
    );
}

/// Detect panel: the detection runs in the background. The frame that starts it comes back
/// at once and says it is detecting; the window keeps drawing until the result is in.
#[test]
fn the_window_keeps_drawing_while_the_detector_runs() {
    const SAMPLE: &str = "apriltag-36h11-swarmathon.jpg";
    let s = setup();
    let mut h = studio(&s);
    h.get_by_label("Detect").click();
    h.run();
    h.get_by_label(SAMPLE).click();
    let clock = Instant::now();
    h.step();
    let frame_ms = clock.elapsed().as_secs_f64() * 1e3;
    assert!(h.state().detect.is_detecting());
    h.step();
    if h.state().detect.is_detecting() {
        h.get_by_label("detecting…");
    }
    let mut frames = 0;
    while h.state().detect.is_detecting() {
        h.step();
        frames += 1;
        std::thread::sleep(Duration::from_millis(5));
    }
    h.run();
    let detection_ms = h.state().detect.result.as_ref().unwrap().time_ms;
    assert!(
        frame_ms < 0.5 * detection_ms,
        "the frame that started it took {frame_ms:.0} ms, the detection {detection_ms:.0} ms"
    );
    assert!(frames > 1, "frames drew while it ran: {frames}");
    assert!(h.query_by_label_contains("detecting…").is_none());
    assert!(listed_count(&h) > 0);
}

/// Detect panel → "tiny markers": the detector runs again with stage 1 also on the image
/// enlarged twice, and lists what `tagsmith detect --upsample` finds on the same photograph.
#[test]
fn the_tiny_markers_switch_searches_as_detect_upsample_does() {
    const SAMPLE: &str = "apriltag-36h11-swarmathon.jpg";
    let s = setup();
    let mut h = studio(&s);
    detect_sample(&mut h, SAMPLE);
    let default = listed_count(&h);
    h.get_by_label("tiny markers").click();
    h.run();
    wait_for_detection(&mut h);
    assert!(h.state().detect.options().propose.upsample);
    let upsampled = listed_count(&h);
    assert!(upsampled >= default, "{upsampled} with, {default} without");
    assert_eq!(cli_count(SAMPLE, &["--upsample"]), upsampled);
}

/// Detect panel → "steep views" (on by default): switched off, the detector runs again without
/// the quads the image outlines and lists what `tagsmith detect --no-outline` finds on the same
/// photograph; switched on it lists what plain `tagsmith detect` finds.
#[test]
fn the_steep_views_switch_searches_as_detect_no_outline_does() {
    const SAMPLE: &str = "apriltag-36h11-swarmathon.jpg";
    let s = setup();
    let mut h = studio(&s);
    detect_sample(&mut h, SAMPLE);
    assert!(h.state().detect.options().propose.image_searches());
    assert_eq!(listed_count(&h), cli_count(SAMPLE, &[]));
    h.get_by_label("steep views").click();
    h.run();
    wait_for_detection(&mut h);
    assert!(!h.state().detect.options().propose.image_searches());
    assert_eq!(listed_count(&h), cli_count(SAMPLE, &["--no-outline"]));
}

/// Detect panel → "Play as video": the opened photograph plays as a moving sequence; Pause
/// stops it, Step reads one frame more, each with tracking (the whole detector on the first
/// frame only here), the same markers as on the photograph, and Stop ends it.
#[test]
fn a_photograph_plays_as_video_with_tracking_paused_and_stepped() {
    const SAMPLE: &str = "aruco-6x6_250-tutorial.jpg";
    let s = setup();
    let mut h = studio(&s);
    detect_sample(&mut h, SAMPLE);
    let on_the_photo = listed_count(&h);
    h.get_by_label("Play as video").click();
    // Playing repaints frame after frame: a few of them, then pause.
    h.run_steps(4);
    h.get_by_label("Pause").click();
    h.run();
    let shown = |h: &Harness<'static, Studio>| h.state().detect.sequence.as_ref().unwrap().shown;
    let paused_at = shown(&h).expect("a frame was read before the pause");
    h.run();
    assert_eq!(
        shown(&h),
        Some(paused_at),
        "a paused video stays on its frame"
    );
    for _ in 0..3 {
        h.get_by_label("Step").click();
        h.run();
    }
    assert_eq!(shown(&h), Some(paused_at + 3));
    let sequence = h.state().detect.sequence.as_ref().unwrap();
    let wholes: Vec<bool> = sequence.times.iter().map(|(_, full)| *full).collect();
    assert!(wholes[0], "the first frame runs the whole detector");
    assert!(
        wholes[1..].iter().filter(|full| !**full).count() >= wholes.len() / 2,
        "{wholes:?}"
    );
    assert_eq!(listed_count(&h), on_the_photo);
    h.get_by_label("Stop").click();
    h.run();
    assert!(h.state().detect.sequence.is_none());
}

/// Train panel: an unsaved design is refused in words; once saved, a run starts in the
/// background, shows progress and writes checkpoints while the window keeps drawing; Stop leaves
/// a resumable run, Resume finishes it and the model is attached next to the family file.
#[test]
fn the_train_panel_trains_stops_resumes_and_attaches_the_model() {
    use tagsmith_studio::studio::train::{attached_model, Settings};
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "apriltag-16h5");
    h.get_by_label("Train").click();
    h.run();
    assert_eq!(h.state().panel, Panel::Train);
    assert!(h.query_by_label_contains("Save the design first").is_some());
    h.state_mut().save();
    h.run();
    assert!(h.query_by_label_contains("Save the design first").is_none());
    h.state_mut().train.settings = Settings {
        steps: 2000,
        batch: 2,
        width: 8,
        ..Settings::default()
    };
    // From fresh weights (the panel would otherwise start a 16h5 design from the grid model).
    h.state_mut().train.fine_tune_chosen = true;
    h.run();
    h.get_by_label("Start").click();
    h.run();
    let mut frames = Vec::new();
    let start = Instant::now();
    while h
        .state()
        .train
        .live()
        .and_then(|l| l.last_checkpoint)
        .is_none()
    {
        assert!(start.elapsed() < Duration::from_secs(120), "no checkpoint");
        let frame = Instant::now();
        h.step();
        frames.push(frame.elapsed().as_secs_f64() * 1e3);
        std::thread::sleep(Duration::from_millis(10));
    }
    frames.sort_by(f64::total_cmp);
    println!(
        "frame time while training: median {:.1} ms over {} frames",
        frames[frames.len() / 2],
        frames.len()
    );
    // One more frame, to draw what the run reported since the last one.
    h.step();
    assert!(h.query_by_label_contains("samples/s").is_some());
    // The first checkpoint comes with a validation, and with it the pictures: the batch's
    // samples with their truth and validation patches with the network's keypoints.
    let pictures = h.state().train.live().unwrap().pictures.unwrap();
    assert_eq!(
        pictures.samples.len(),
        2,
        "one per sample of the batch of 2"
    );
    assert_eq!(pictures.predictions.len(), 6);
    assert!(pictures.samples.iter().all(|p| !p.keypoints.is_empty()));
    assert!(h
        .query_by_label_contains("Training samples with their truth")
        .is_some());
    h.get_by_label("Stop").click();
    run_until(&mut h, "the run to stop", |st| !st.train.is_running());
    h.run();
    let live = h.state().train.live().unwrap();
    let stopped_at = live.step;
    assert!(stopped_at < 2000);
    // A stopped run is offered for resuming, and listed as such.
    assert!(h.query_by_label_contains("An unfinished run").is_some());
    h.get_by_label("Runs").click();
    h.run();
    assert!(h.query_by_label("unfinished (resumable)").is_some());
    // Start on an unfinished run asks before it replaces the checkpoint; Cancel keeps it.
    h.get_by_label("Start").click();
    h.run();
    assert!(!h.state().train.is_running());
    h.get_by_label("Cancel").click();
    h.run();
    assert!(h.query_by_label("Start over").is_none());
    let design_file = h.state().design.as_ref().unwrap().path.clone().unwrap();
    let run_dir = first_run_folder(&s);
    assert!(run_dir.join("checkpoint.bin").exists());
    // Finish a few steps past the checkpoint.
    h.state_mut().train.settings.steps = stopped_at + 3;
    h.run();
    h.get_by_label("Resume").click();
    h.run();
    run_until(&mut h, "the resumed run", |st| {
        !st.train.is_running() && st.train.outcome.is_some()
    });
    h.run();
    let outcome = h.state().train.outcome.clone().unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
    assert!(attached_model(&design_file).exists(), "{outcome:?}");
    let report = run_report(&run_dir);
    assert!(report["resumed_from"].as_u64().is_some());
}

/// Detect panel → Test scene: both families' synthetic scenes under the same conditions, each
/// detected and its error against the truth listed.
#[test]
fn the_test_scene_lists_each_familys_detection_with_its_error() {
    let s = setup();
    let mut h = studio(&s);
    h.get_by_label("Detect").click();
    h.run();
    h.get_by_label("Test scene").click();
    h.run();
    h.get_by_label("Render test scene").click();
    h.run();
    let scenes = &h.state().detect.scenes;
    assert_eq!(scenes.len(), 2, "two families compared");
    for scene in scenes {
        let (corners, position, rotation) = scene
            .errors
            .unwrap_or_else(|| panic!("{} not found", scene.family));
        assert!(corners < 1.0, "{}: {corners} px", scene.family);
        assert!(position < 5.0, "{}: {position} mm", scene.family);
        assert!(rotation < 2.0, "{}: {rotation}°", scene.family);
    }
    assert_eq!(
        h.query_all_by_label_contains("px RMS, position").count(),
        2,
        "each scene's errors are listed"
    );
}

/// Detection latency in the Detect panel against `tagsmith detect` on the same sample, both
/// from this build: the panel's time from the click to the result (image decoded, detected in
/// the background, drawn) and the
/// detector's own time, against the CLI's per-image time (process start and model loading
/// excluded, as they are in the app after its first run). A benchmark (BENCHMARKS.md "Studio"):
/// `cargo test --release -p tagsmith-studio --test studio -- --ignored latency --nocapture`.
#[test]
#[ignore = "a benchmark: run it on an idle machine"]
fn detect_latency_in_the_app_is_the_clis() {
    const RUNS: usize = 15;
    const SAMPLE: &str = "aruco-6x6_250-tutorial.jpg";
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let s = setup();
    let mut h = studio(&s);
    detect_sample(&mut h, SAMPLE);
    let (mut frames, mut detector) = (Vec::new(), Vec::new());
    for _ in 0..RUNS {
        let clock = Instant::now();
        h.get_by_label(SAMPLE).click();
        h.run();
        wait_for_detection(&mut h);
        frames.push(clock.elapsed().as_secs_f64() * 1e3);
        detector.push(h.state().detect.result.as_ref().unwrap().time_ms);
    }
    let image = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/samples/")
        .join(SAMPLE);
    let images: Vec<&Path> = std::iter::repeat_n(image.as_path(), RUNS + 1).collect();
    let out = s.out.with_file_name("cli.json");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .arg("detect")
        .args(&images)
        .args(["--sequential", "--json", out.to_str().unwrap()])
        .stdout(std::process::Stdio::null())
        .status()
        .unwrap();
    assert!(status.success());
    let cli: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let cli: Vec<f64> = cli["images"].as_array().unwrap()[1..]
        .iter()
        .map(|i| i["time_ms"].as_f64().unwrap())
        .collect();
    let (frame, detector, cli) = (median(frames), median(detector), median(cli));
    println!(
        "{SAMPLE}: app frame {frame:.1} ms, app detector {detector:.1} ms, CLI {cli:.1} ms \
         (medians of {RUNS}); app/CLI {:.2}× (detector), {:.2}× (frame)",
        detector / cli,
        frame / cli
    );
    assert!(
        detector < 1.1 * cli,
        "the app's detector is slower than the CLI's"
    );
}

/// The web build detects in a real browser: scripts/web-detect.sh serves app/dist, opens the
/// Detect panel on the ArUco sample in headless Chromium and prints the detector's line, which
/// must list the sample's six markers. Needs the built page (scripts/build-web.sh), Debian's
/// chromium and Node.js: `cargo test -p tagsmith-studio --test studio -- --ignored browser`.
#[test]
#[ignore = "needs scripts/build-web.sh's output, chromium and node"]
fn the_browser_build_detects_the_samples_markers() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let dir = tempfile::tempdir().unwrap();
    let shot = dir.path().join("web.png");
    let out = std::process::Command::new(root.join("scripts/web-detect.sh"))
        .arg(&shot)
        .arg("aruco-6x6_250-tutorial.jpg")
        .output()
        .expect("scripts/web-detect.sh runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("detected 6 marker(s) in aruco-6x6_250-tutorial.jpg (640×480)"),
        "{stdout}"
    );
    assert!(shot.exists(), "no screenshot");
}

/// Compare panel → a tiny sweep of two shipped designs: the verdict, the plots and the table
/// fill in, and `tagsmith eval compare-designs` on the same scenario writes the same rows.
#[test]
fn the_compare_panel_runs_a_sweep_and_the_command_line_agrees() {
    let s = setup();
    let mut h = studio(&s);
    h.get_by_label("Compare").click();
    h.run();
    assert_eq!(h.state().panel, Panel::Compare);
    {
        let c = &mut h.state_mut().compare;
        c.scenario.camera.width = 320;
        c.scenario.camera.height = 240;
        c.scenario.scenes = 2;
        c.sweep_values = "0.2, 0.5".into();
    }
    h.get_by_label("Run comparison").click();
    h.run();
    assert!(
        h.state().compare.is_running(),
        "the run goes on in the background"
    );
    run_until(&mut h, "the comparison", |s| !s.compare.is_running());
    let panel = h.state().compare.result.clone().expect("a report");
    assert_eq!(panel.report.scenes_done, 4);
    assert_eq!(panel.report.rows.len(), 2 * 2, "a row per design and value");
    for what in ["recall (%)", "Verdict", "Worst reads", "Export CSV"] {
        h.get_by_label_contains(what);
    }
    assert!(
        h.query_all_by_label_contains("% of 2").count() >= 4,
        "the table lists each row's recall"
    );
    h.get_by_label("Export CSV").click();
    h.run();
    h.get_by_label("Export plots (PNG)").click();
    h.run();
    let exported = std::fs::read_to_string(s.out.join("designs.csv")).unwrap();
    assert_eq!(exported, panel.report.csv());
    for what in ["recall", "position", "rotation"] {
        let png = s.out.join(format!("distance-{what}.png"));
        let decoded = tagsmith::image::read(&png, &Default::default()).expect("a PNG");
        assert!(decoded.width >= 480, "{what}: {} px", decoded.width);
    }
    let scenario = h.state().compare.scenario().unwrap();
    let file = s.out.with_file_name("scene.json");
    scenario.save(&file).unwrap();
    let out = s.out.with_file_name("designs");
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_tagsmith"))
        .args(["eval", "compare-designs"])
        .arg(&file)
        .args(["apriltag-36h11", "apriltag-xo-36h11", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    // Every column but the time per image, which is the machine's.
    let without_time = |csv: &str| -> Vec<String> {
        csv.lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string())
            .collect()
    };
    let cli = std::fs::read_to_string(out.join("designs.csv")).unwrap();
    assert_eq!(without_time(&cli), without_time(&panel.report.csv()));
    for plot in ["distance-recall.svg", "distance-rotation.svg", "report.md"] {
        assert!(out.join(plot).is_file(), "{plot}");
    }
}

/// Train panel: a design of two categories starts from the shipped grid model (a fine-tune at
/// its own steps and learning rate, the model's width), and says so; a quaternary design from
/// its trunk with a fresh class head; a ring design from the ring model, whole or its trunk;
/// unticking goes back to the fresh defaults.
#[test]
fn the_train_panel_fine_tunes_a_design_from_the_shipped_model_that_fits_it() {
    use tagsmith_studio::studio::train::{Settings, FINE_TUNE_STEPS};
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "apriltag-16h5");
    h.get_by_label("Train").click();
    h.run();
    h.state_mut().save();
    h.run();
    let settings = h.state().train.settings.clone();
    assert!(settings.fine_tune);
    assert_eq!(settings.steps, FINE_TUNE_STEPS);
    h.get_by_label("grid-8-bw: the same number of categories as this design");
    // Fresh weights when asked, with the fresh defaults; and back.
    h.get_by_label("a shipped model (fine-tune)").click();
    h.run();
    assert_eq!(h.state().train.settings, Settings::default());
    h.get_by_label("a shipped model (fine-tune)").click();
    h.run();
    assert!(h.state().train.settings.fine_tune);
    h.state_mut().train.settings.steps = 3;
    h.state_mut().train.settings.batch = 2;
    h.run();
    h.get_by_label("Start").click();
    h.run();
    run_until(&mut h, "the fine-tune", |st| {
        !st.train.is_running() && st.train.outcome.is_some()
    });
    let outcome = h.state().train.outcome.clone().unwrap();
    assert!(outcome.is_ok(), "{outcome:?}");
    let run_dir = first_run_folder(&s);
    let report = run_report(&run_dir);
    let started = report["started_from"].as_str().unwrap_or_default();
    assert!(started.contains("grid-8-bw.stage2.bin"), "{report}");

    // Four categories: the grid model's trunk, a fresh class head.
    h.get_by_label("Families").click();
    h.run();
    duplicate(&mut h, "quaternary-6x6");
    h.get_by_label("Train").click();
    h.run();
    assert!(h.state().train.settings.fine_tune);
    h.get_by_label("grid-8-bw, its trunk; the class head learns this design's categories afresh");
    h.state_mut().save();
    h.run();

    // Rings: the ring model, whole for a design of RuneTag's categories, its trunk for one with
    // orientation marks (a third category).
    h.get_by_label("Families").click();
    h.run();
    duplicate(&mut h, "runetag");
    h.get_by_label("Train").click();
    h.run();
    assert!(h.state().train.settings.fine_tune);
    h.get_by_label("runetag: the same number of categories as this design");
    h.state_mut().save();
    h.run();
    h.get_by_label("Families").click();
    h.run();
    duplicate(&mut h, "runetag-plus");
    h.get_by_label("Train").click();
    h.run();
    assert!(h.state().train.settings.fine_tune);
    h.get_by_label("runetag, its trunk; the class head learns this design's categories afresh");
}

/// A design duplicated from a built-in, with the layout a shipped model learned, detects with no
/// training: the Detect panel offers it with that model, it reads the tutorial photograph's
/// markers under its own name, and its gallery card says how it detects.
#[test]
fn a_design_on_a_shipped_layout_detects_without_training() {
    let s = setup();
    let mut h = studio(&s);
    duplicate(&mut h, "aruco-6x6_250");
    h.state_mut().save();
    h.run();
    let name = h.state().design.as_ref().unwrap().spec().name.clone();
    h.get_by_label("Detect").click();
    h.run();
    for builtin in ["apriltag-36h11", "apriltag-xo-36h11", "aruco-6x6_250"] {
        h.get_by_label(builtin).click();
        h.run();
    }
    h.get_by_label(&format!("{name} (the shipped model of its layout)"));
    h.get_by_label("aruco-6x6_250-tutorial.jpg").click();
    h.run();
    wait_for_detection(&mut h);
    let result = h.state().detect.result.as_ref().unwrap();
    assert!(
        result.markers.len() >= 5,
        "{} markers",
        result.markers.len()
    );
    assert!(
        (result.markers.iter()).all(|m| m.detection.family.as_deref() == Some(name.as_str())),
        "every read is the design's"
    );
    h.get_by_label("Families").click();
    h.run();
    assert!(h
        .query_all_by_label("detects: the shipped model of its layout")
        .next()
        .is_some());
}
