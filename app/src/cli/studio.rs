//! `studio` (and no command at all): the studio window.

use super::common::load_family;
use super::error::{failure, Result};
use tagsmith_studio::studio::Panel;

#[derive(clap::Args, Debug, Default)]
pub struct StudioArgs {
    /// Start designing from this family: a built-in (duplicated) or a family JSON file (edited).
    pub family: Option<String>,
    /// The panel to show first.
    #[arg(long, value_enum)]
    pub panel: Option<Panel>,
    /// Start from a clean slate instead of the design kept from the last session.
    #[arg(long)]
    pub fresh: bool,
}

impl StudioArgs {
    /// Opens the studio window; a family given on the command line starts the designer with it.
    pub fn run(self) -> Result<()> {
        use tagsmith_studio::studio::{files::NativeFiles, StudioApp};
        let start = match &self.family {
            Some(name) => Some(load_family(name)?),
            None => None,
        };
        let builtin = self
            .family
            .as_deref()
            .is_some_and(|n| tagsmith::builtin::get(n).is_some());
        let path = self
            .family
            .as_ref()
            .filter(|_| !builtin)
            .map(std::path::PathBuf::from);
        let options = eframe::NativeOptions {
            viewport: egui::ViewportBuilder::default()
                .with_title("Tagsmith studio")
                .with_inner_size([1360.0, 860.0])
                .with_drag_and_drop(true),
            ..Default::default()
        };
        let user_folder = eframe::storage_dir("Tagsmith").map(|d| d.join("families"));
        eframe::run_native(
            "Tagsmith",
            options,
            Box::new(move |cc| {
                let mut app = StudioApp::new(cc, Box::new(NativeFiles::new(user_folder)));
                if self.fresh {
                    app.studio.design = None;
                    app.studio.panel = Panel::Families;
                }
                if let Some(f) = start {
                    let mut spec = f.spec().clone();
                    if builtin {
                        spec.name = format!("{}-copy", spec.name);
                    }
                    app.studio.start_design(spec, path, !builtin);
                }
                if let Some(panel) = self.panel {
                    app.studio.panel = panel;
                }
                Ok(Box::new(app))
            }),
        )
        .map_err(|e| {
            failure!(
                "the studio window could not open ({e}); on a machine without a display use the \
                 command line: tagsmith --help"
            )
        })
    }
}
