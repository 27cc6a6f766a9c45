//! The Tagsmith studio: design a marker family, see it live, print it. One egui application for
//! the desktop and the browser. It holds no vision logic: every change is a
//! `tagsmith::family::edit::Edit`, every picture and file comes from `tagsmith::render`.

pub mod codegen;
pub mod compare;
pub mod design;
pub mod designer;
pub mod detect;
pub mod families;
pub mod files;
pub mod job;
pub mod offload;
pub mod preview;
pub mod print;
pub mod sequence;
pub mod train;

use design::Design;
use egui::{Key, KeyboardShortcut, Modifiers};
use files::{FileAccess, OpenedFile, Purpose};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;
use tagsmith::family::FamilySpec;

/// The studio's panels. Everything that lists them (the tab bar, the dispatch in
/// [`Studio::ui`], the command line's `--panel` and its help) reads [`Panel::ALL`] and the methods
/// below, so that a new panel is added here and nowhere else.
///
/// The serde names are the variant names, as earlier versions stored them; the command line uses
/// [`Panel::name`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Panel {
    Families,
    Designer,
    Print,
    Train,
    Detect,
    Compare,
}

impl Panel {
    /// In tab order.
    pub const ALL: [Panel; 6] = [
        Panel::Families,
        Panel::Designer,
        Panel::Print,
        Panel::Train,
        Panel::Detect,
        Panel::Compare,
    ];

    /// The tab's text.
    pub fn label(self) -> &'static str {
        match self {
            Panel::Families => "Families",
            Panel::Designer => "Designer",
            Panel::Print => "Print",
            Panel::Train => "Train",
            Panel::Detect => "Detect",
            Panel::Compare => "Compare",
        }
    }

    /// One line on what the panel is for: the tab's hover text and the `--panel` value's help.
    pub fn help(self) -> &'static str {
        match self {
            Panel::Families => "built-in families and your own; start a design from one",
            Panel::Designer => "edit the design: layout, categories, keypoints, ROI, codebook",
            Panel::Print => "lay the design's markers out on pages and export PDF or SVG",
            Panel::Train => "train the detector for the design (desktop)",
            Panel::Detect => "find markers in photographs with the learned detector",
            Panel::Compare => "which design suits my scene: designs read the same rendered scenes",
        }
    }

    /// The stable lowercase name, as typed on the command line (`--panel designer`).
    pub fn name(self) -> &'static str {
        match self {
            Panel::Families => "families",
            Panel::Designer => "designer",
            Panel::Print => "print",
            Panel::Train => "train",
            Panel::Detect => "detect",
            Panel::Compare => "compare",
        }
    }

    pub fn from_name(name: &str) -> Option<Panel> {
        Panel::ALL.into_iter().find(|p| p.name() == name)
    }

    fn show(self, studio: &mut Studio, ui: &mut egui::Ui, ctx: &egui::Context) {
        match self {
            Panel::Families => families::show(studio, ui),
            Panel::Designer => designer::show(studio, ui, ctx),
            Panel::Print => print::show(studio, ui, ctx),
            Panel::Train => train::show(studio, ui, ctx),
            Panel::Detect => detect::show(studio, ui, ctx),
            Panel::Compare => compare::show(studio, ui, ctx),
        }
    }
}

/// Written by hand rather than derived so that the values and their help come from
/// [`Panel::name`] and [`Panel::help`] instead of a second copy in doc comments. clap exists on
/// the desktop only.
#[cfg(not(target_arch = "wasm32"))]
impl clap::ValueEnum for Panel {
    fn value_variants<'a>() -> &'a [Self] {
        &Panel::ALL
    }

    fn to_possible_value(&self) -> Option<clap::builder::PossibleValue> {
        Some(clap::builder::PossibleValue::new(self.name()).help(self.help()))
    }
}

/// The message line at the bottom of the window.
#[derive(Debug, Clone, PartialEq)]
pub enum Notice {
    Info(String),
    Error(String),
}

/// What survives a restart (eframe persistence): the design, saved or not, and the print setup.
///
/// Every stored struct is `serde(default)`: state written by an older or newer studio (a field
/// added or removed since) must still restore, or the unsaved design it carries would be lost.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(default)]
pub struct Persisted {
    pub panel: Option<Panel>,
    pub design: Option<FamilySpec>,
    pub saved: Option<FamilySpec>,
    pub path: Option<PathBuf>,
    pub print: print::PrintSettings,
}

/// A design change that would drop unsaved work, waiting for the user's confirmation.
struct PendingReplace {
    spec: FamilySpec,
    path: Option<PathBuf>,
    saved: bool,
}

pub struct Studio {
    pub panel: Panel,
    pub library: families::Library,
    pub design: Option<Design>,
    pub notice: Option<Notice>,
    pub files: Box<dyn FileAccess>,
    pub designer: designer::DesignerState,
    pub print: print::PrintState,
    pub detect: detect::DetectState,
    pub train: train::TrainState,
    pub compare: compare::CompareState,
    textures: preview::Textures,
    pending_replace: Option<PendingReplace>,
    /// The window was asked to close with unsaved changes; the confirmation is showing.
    pub quit_prompt: bool,
    quit_confirmed: bool,
    /// The previous frame's CPU time (ms) as eframe measured it, when running in eframe: the
    /// Train panel shows it, so the UI's cost while training is visible.
    pub frame_ms: Option<f32>,
}

impl Studio {
    pub fn new(files: Box<dyn FileAccess>) -> Self {
        let mut studio = Self {
            panel: Panel::Families,
            library: families::Library::default(),
            design: None,
            notice: None,
            files,
            designer: designer::DesignerState::default(),
            print: print::PrintState::default(),
            detect: detect::DetectState::default(),
            train: train::TrainState::default(),
            compare: compare::CompareState::default(),
            textures: preview::Textures::default(),
            pending_replace: None,
            quit_prompt: false,
            quit_confirmed: false,
            frame_ms: None,
        };
        studio.reload_library();
        studio
    }

    pub fn reload_library(&mut self) {
        let problems = self.library.reload(&*self.files);
        if !problems.is_empty() {
            self.error(problems.join("\n"));
        }
    }

    pub fn restore(&mut self, saved: Persisted) {
        if let Some(spec) = saved.design {
            self.design = Some(Design::restore(spec, saved.path, saved.saved));
        }
        if let Some(panel) = saved.panel {
            self.panel = panel;
        }
        self.print.settings = saved.print;
    }

    /// Restores the state kept by [`Studio::store`], as the app does at startup.
    pub fn restore_from(&mut self, storage: &dyn eframe::Storage) {
        match eframe::get_value::<Persisted>(storage, eframe::APP_KEY) {
            Some(saved) => self.restore(saved),
            // eframe only logs this at debug level, yet it may have just lost an unsaved design.
            None if storage.get_string(eframe::APP_KEY).is_some() => {
                log::warn!("the state kept from the last session could not be read; starting fresh")
            }
            None => {}
        }
    }

    /// Keeps the state for the next start, in eframe's storage under its app key.
    pub fn store(&self, storage: &mut dyn eframe::Storage) {
        eframe::set_value(storage, eframe::APP_KEY, &self.persisted());
    }

    pub fn persisted(&self) -> Persisted {
        Persisted {
            panel: Some(self.panel),
            design: self.design.as_ref().map(|d| d.spec().clone()),
            saved: self.design.as_ref().and_then(|d| d.saved_spec().cloned()),
            path: self.design.as_ref().and_then(|d| d.path.clone()),
            print: self.print.settings.clone(),
        }
    }

    pub fn info(&mut self, text: impl Into<String>) {
        self.notice = Some(Notice::Info(text.into()));
    }

    pub fn error(&mut self, text: impl Into<String>) {
        self.notice = Some(Notice::Error(text.into()));
    }

    pub fn is_dirty(&self) -> bool {
        self.design.as_ref().is_some_and(Design::is_dirty)
    }

    /// Makes `spec` the design, asking first when that would drop unsaved changes.
    pub fn start_design(&mut self, spec: FamilySpec, path: Option<PathBuf>, saved: bool) {
        if self.is_dirty() {
            self.pending_replace = Some(PendingReplace { spec, path, saved });
            return;
        }
        self.replace_design(spec, path, saved);
    }

    fn replace_design(&mut self, spec: FamilySpec, path: Option<PathBuf>, saved: bool) {
        self.designer = designer::DesignerState::default();
        self.design = Some(Design::new(spec, path, saved));
        self.panel = Panel::Designer;
    }

    /// A family file opened or dropped: listed in the library and, when that loses nothing,
    /// opened in the designer. A file that does not parse changes nothing and says why.
    pub fn open_file(&mut self, file: OpenedFile) {
        match self.library.add_opened(&file) {
            Ok(spec) => {
                let name = spec.name.clone();
                if self.is_dirty() {
                    self.info(format!(
                        "opened {name} from {}; it is in the families list (the current design \
                         has unsaved changes)",
                        file.name
                    ));
                } else {
                    self.replace_design(spec, file.path.clone(), true);
                    self.info(format!("opened {name} from {}", file.name));
                }
            }
            Err(e) => self.error(e),
        }
    }

    /// Saves the design where it lives, or asks where (first save, built-in duplicates).
    pub fn save(&mut self) {
        let Some(design) = &self.design else {
            return;
        };
        let json = tagsmith::family::to_json_string(design.spec());
        // A first save goes to the user's folder under a name no other file has there, so two
        // copies of the same built-in never overwrite each other.
        let target = design.path.clone().or_else(|| {
            let dir = self.files.user_folder()?;
            let stem = design.spec().name.clone();
            (1..)
                .map(|n| match n {
                    1 => dir.join(format!("{stem}.json")),
                    n => dir.join(format!("{stem}-{n}.json")),
                })
                .find(|p| !p.exists())
        });
        let result = match &target {
            Some(path) => self.files.save_to(path, json.as_bytes()).map(Some),
            None => self.files.save_as(&design.file_name(), json.as_bytes()),
        };
        self.finish_save(result, target);
    }

    pub fn save_as(&mut self) {
        let Some(design) = &self.design else {
            return;
        };
        let json = tagsmith::family::to_json_string(design.spec());
        let result = self.files.save_as(&design.file_name(), json.as_bytes());
        // A dialog may rename the file; on the desktop the returned location is its path.
        let path = match &result {
            Ok(Some(place)) if !cfg!(target_arch = "wasm32") => Some(PathBuf::from(place)),
            _ => None,
        };
        self.finish_save(result, path);
    }

    fn finish_save(&mut self, result: Result<Option<String>, String>, path: Option<PathBuf>) {
        match result {
            Ok(Some(place)) => {
                let design = self.design.as_mut().expect("saving a design");
                let problems = design.validation().as_ref().err().map(|e| e.problems.len());
                design.mark_saved(path);
                let warning = match problems {
                    Some(n) => format!(" — it has {n} validation problem(s) still to fix"),
                    None => String::new(),
                };
                self.info(format!("saved {place}{warning}"));
                self.reload_library();
            }
            Ok(None) => {}
            Err(e) => self.error(format!("not saved: {e}")),
        }
    }

    pub fn undo(&mut self) {
        if let Some(d) = &mut self.design {
            if !d.undo() {
                self.info("nothing to undo");
            }
        }
    }

    pub fn redo(&mut self) {
        if let Some(d) = &mut self.design {
            if !d.redo() {
                self.info("nothing to redo");
            }
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let save = KeyboardShortcut::new(Modifiers::COMMAND, Key::S);
        let undo = KeyboardShortcut::new(Modifiers::COMMAND, Key::Z);
        let redo = KeyboardShortcut::new(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
        let redo_y = KeyboardShortcut::new(Modifiers::COMMAND, Key::Y);
        if ctx.input_mut(|i| i.consume_shortcut(&save)) {
            self.save();
        }
        // A focused text field keeps its own undo.
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        // Redo first: Ctrl+Shift+Z also matches Ctrl+Z's logical shortcut.
        if ctx.input_mut(|i| i.consume_shortcut(&redo) || i.consume_shortcut(&redo_y)) {
            self.redo();
        } else if ctx.input_mut(|i| i.consume_shortcut(&undo)) {
            self.undo();
        }
    }

    fn take_dropped_and_opened(&mut self, ctx: &egui::Context) {
        let dropped = ctx.input_mut(|i| std::mem::take(&mut i.raw.dropped_files));
        for file in dropped {
            if let Err(e) = self.files.accept_dropped(file) {
                self.error(e);
            }
        }
        // A pasted file path (or file:// address, as file managers copy files) of an image
        // opens it in Detect, as a drop would. Not while a text field takes the paste.
        if !ctx.egui_wants_keyboard_input() {
            let pasted: Vec<String> = ctx.input(|i| {
                i.events
                    .iter()
                    .filter_map(|e| match e {
                        egui::Event::Paste(text) => Some(text.clone()),
                        _ => None,
                    })
                    .collect()
            });
            for text in pasted {
                detect::open_pasted(self, &text);
            }
        }
        for file in self.files.take_opened() {
            match file.purpose {
                // A dropped image goes to the Detect panel.
                Purpose::Family if files::is_image_name(&file.name) => {
                    detect::open_image(self, file)
                }
                Purpose::Family => self.open_file(file),
                Purpose::CodeTable => designer::import_table(self, &file.name, &file.bytes),
                Purpose::Image => detect::open_image(self, file),
            }
        }
    }

    /// The whole window.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        self.take_dropped_and_opened(&ctx);
        self.shortcuts(&ctx);
        self.handle_close_request(&ctx);

        egui::Panel::top("studio-top").show(ui, |ui| self.top_bar(ui));
        egui::Panel::bottom("studio-notice").show(ui, |ui| self.notice_bar(ui));
        egui::CentralPanel::default_margins().show(ui, |ui| self.panel.show(self, ui, &ctx));
        self.confirm_replace(&ctx);
        self.confirm_quit(&ctx);
    }

    fn top_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            ui.heading("Tagsmith");
            ui.separator();
            for panel in Panel::ALL {
                ui.selectable_value(&mut self.panel, panel, panel.label())
                    .on_hover_text(panel.help());
            }
            ui.separator();
            if ui.button("Open family file…").clicked() {
                self.files.request_open(Purpose::Family);
            }
            let has_design = self.design.is_some();
            if ui
                .add_enabled(has_design, egui::Button::new("Save"))
                .on_hover_text("Ctrl+S")
                .clicked()
            {
                self.save();
            }
            if ui
                .add_enabled(has_design, egui::Button::new("Save as…"))
                .clicked()
            {
                self.save_as();
            }
            let (undo, redo) = self
                .design
                .as_ref()
                .map_or((0, 0), |d| (d.undo_steps(), d.redo_steps()));
            if ui
                .add_enabled(undo > 0, egui::Button::new("Undo"))
                .on_hover_text(format!("Ctrl+Z ({undo} step(s))"))
                .clicked()
            {
                self.undo();
            }
            if ui
                .add_enabled(redo > 0, egui::Button::new("Redo"))
                .on_hover_text(format!("Ctrl+Shift+Z ({redo} step(s))"))
                .clicked()
            {
                self.redo();
            }
            if let Some(d) = &self.design {
                ui.separator();
                let name = &d.spec().name;
                if d.is_dirty() {
                    ui.label(egui::RichText::new(format!("{name} (unsaved)")).strong())
                        .on_hover_text("this design has changes that are not saved to a file");
                } else {
                    ui.label(name.as_str());
                }
            }
        });
    }

    fn notice_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| match &self.notice {
            Some(Notice::Error(text)) => {
                ui.colored_label(ui.visuals().error_fg_color, format!("error: {text}"));
            }
            Some(Notice::Info(text)) => {
                ui.label(text.as_str());
            }
            None => {
                ui.weak("Drop a family file (.json) on the window to open it, or an image to detect on.");
            }
        });
    }

    fn confirm_replace(&mut self, ctx: &egui::Context) {
        let Some(pending) = &self.pending_replace else {
            return;
        };
        let name = self
            .design
            .as_ref()
            .map(|d| d.spec().name.clone())
            .unwrap_or_default();
        let next = pending.spec.name.clone();
        let choice = unsaved_prompt(
            ctx,
            "replace-design",
            "Unsaved changes",
            &format!("{name} has unsaved changes. Open {next} and discard them?"),
            ["Save, then open", "Discard changes and open", "Cancel"],
        );
        match choice {
            Some(Unsaved::SaveFirst) => {
                self.save();
                if !self.is_dirty() {
                    let p = self.pending_replace.take().expect("pending");
                    self.replace_design(p.spec, p.path, p.saved);
                }
            }
            Some(Unsaved::Discard) => {
                let p = self.pending_replace.take().expect("pending");
                self.replace_design(p.spec, p.path, p.saved);
            }
            Some(Unsaved::Cancel) => self.pending_replace = None,
            None => {}
        }
    }

    fn handle_close_request(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested()) && self.is_dirty() && !self.quit_confirmed
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.quit_prompt = true;
        }
    }

    fn confirm_quit(&mut self, ctx: &egui::Context) {
        if !self.quit_prompt {
            return;
        }
        let choice = unsaved_prompt(
            ctx,
            "quit",
            "Quit with unsaved changes?",
            "The design is also kept for the next start, but it is not in a family file yet.",
            ["Save and quit", "Quit without saving", "Keep editing"],
        );
        match choice {
            Some(Unsaved::SaveFirst) => {
                self.save();
                if !self.is_dirty() {
                    self.quit(ctx);
                }
            }
            Some(Unsaved::Discard) => self.quit(ctx),
            Some(Unsaved::Cancel) => self.quit_prompt = false,
            None => {}
        }
    }

    fn quit(&mut self, ctx: &egui::Context) {
        self.quit_prompt = false;
        self.quit_confirmed = true;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }
}

/// The answer to a prompt about unsaved work, in the order its buttons are shown.
enum Unsaved {
    SaveFirst,
    Discard,
    Cancel,
}

/// A modal asking what to do with unsaved work before going on; `labels` name the three answers
/// in [`Unsaved`]'s order. None while the user has not answered.
fn unsaved_prompt(
    ctx: &egui::Context,
    id: &str,
    heading: &str,
    text: &str,
    labels: [&str; 3],
) -> Option<Unsaved> {
    let mut choice = None;
    egui::Modal::new(egui::Id::unique(id)).show(ctx, |ui| {
        ui.heading(heading);
        ui.label(text);
        ui.horizontal(|ui| {
            for (label, answer) in
                labels
                    .into_iter()
                    .zip([Unsaved::SaveFirst, Unsaved::Discard, Unsaved::Cancel])
            {
                if ui.button(label).clicked() {
                    choice = Some(answer);
                }
            }
        });
    });
    choice
}

/// The eframe application around [`Studio`], with persistence.
pub struct StudioApp {
    pub studio: Studio,
}

impl StudioApp {
    pub fn new(cc: &eframe::CreationContext<'_>, files: Box<dyn FileAccess>) -> Self {
        let mut studio = Studio::new(files);
        if let Some(storage) = cc.storage {
            studio.restore_from(storage);
        }
        Self { studio }
    }
}

impl eframe::App for StudioApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        self.studio.frame_ms = frame.info().cpu_usage.map(|s| 1e3 * s);
        self.studio.ui(ui);
    }

    fn save(&mut self, storage: &mut dyn eframe::Storage) {
        self.studio.store(storage);
    }

    /// Unsaved designs are written to storage often, so a crash loses little.
    fn auto_save_interval(&self) -> std::time::Duration {
        std::time::Duration::from_secs(5)
    }
}
