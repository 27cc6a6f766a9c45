//! `studio` (and no command at all): the studio window.

use super::common::load_family;
use super::error::{failure, CliError, Result};
use tagsmith_studio::studio::files::MAX_IMAGE_BYTES;
use tagsmith_studio::studio::{detect, Panel};

/// A bare name of one of the shipped samples (`--image aruco-6x6_250-tutorial.jpg`).
fn is_sample(path: &std::path::Path) -> bool {
    let name = path.to_string_lossy();
    detect::samples().any(|(n, _)| n == name)
}

/// The file `--image` names: a regular file of at most [`MAX_IMAGE_BYTES`] (a FIFO would block
/// before the window opens, a device never end).
fn read_image(path: &std::path::Path) -> Result<Vec<u8>> {
    tagsmith::io::read_input(path, MAX_IMAGE_BYTES).map_err(|e| {
        CliError::reading(
            format_args!("--image {}: cannot read the image", path.display()),
            e,
        )
    })
}

#[derive(clap::Args, Debug, Default)]
pub struct StudioArgs {
    /// Start designing from this family: a built-in (duplicated) or a family JSON file of at most
    /// 64 MB (edited).
    pub family: Option<String>,
    /// The panel to show first.
    #[arg(long, value_enum)]
    pub panel: Option<Panel>,
    /// Start from a clean slate instead of the design kept from the last session.
    #[arg(long)]
    pub fresh: bool,
    /// Open this image in the Detect panel (a file of at most 512 MB, or a shipped sample by its
    /// name in assets/samples/).
    #[arg(long, value_name = "IMAGE")]
    pub image: Option<std::path::PathBuf>,
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
        // Read before the window opens, so a wrong path is an error on the command line.
        let image = match &self.image {
            Some(path) if !path.exists() && is_sample(path) => Some((path.clone(), None)),
            Some(path) => {
                let bytes = read_image(path)?;
                Some((path.clone(), Some(bytes)))
            }
            None => None,
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
                match image {
                    Some((path, Some(bytes))) => {
                        use tagsmith_studio::studio::files::{OpenedFile, Purpose};
                        let file = OpenedFile {
                            purpose: Purpose::Image,
                            name: path.display().to_string(),
                            path: Some(path),
                            bytes,
                        };
                        detect::open_image(&mut app.studio, file);
                    }
                    Some((path, None)) => {
                        detect::open_sample(&mut app.studio, &path.to_string_lossy());
                    }
                    None => {}
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_image_limit_in_the_help_is_the_one_applied() {
        use clap::Args as _;
        let help = StudioArgs::augment_args(clap::Command::new("studio"))
            .render_long_help()
            .to_string();
        let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            help.contains(&format!("at most {} MB, or", MAX_IMAGE_BYTES >> 20)),
            "{help}"
        );
        let text = tagsmith::io::MAX_TEXT_BYTES >> 20;
        assert!(help.contains(&format!("at most {text} MB")), "{help}");
    }

    #[cfg(unix)]
    #[test]
    fn an_image_that_is_not_a_regular_file_is_bad_input_naming_the_option() {
        let dir = tempfile::tempdir().unwrap();
        let err = read_image(dir.path()).unwrap_err();
        assert_eq!(err.exit_code(), 2);
        assert!(err.to_string().starts_with("--image "), "{err}");
        if std::path::Path::new("/dev/zero").exists() {
            let err = read_image(std::path::Path::new("/dev/zero")).unwrap_err();
            assert_eq!(err.exit_code(), 2);
            assert!(err.to_string().contains("/dev/zero"), "{err}");
        }
    }
}
