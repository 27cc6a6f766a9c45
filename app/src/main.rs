//! `tagsmith`: the Tagsmith studio (no subcommand, or `studio`) and its command-line interface.

#[cfg(not(target_arch = "wasm32"))]
mod cli;
#[cfg(not(target_arch = "wasm32"))]
mod cli_detect;

#[cfg(not(target_arch = "wasm32"))]
fn main() -> std::process::ExitCode {
    use clap::Parser;
    let args = cli::Cli::parse();
    let command = args
        .command
        .unwrap_or(cli::Command::Studio(cli::StudioArgs::default()));
    match cli::run(command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::from(e.exit_code())
        }
    }
}

/// Opens the studio window; a family given on the command line starts the designer with it.
#[cfg(not(target_arch = "wasm32"))]
fn studio(args: cli::StudioArgs) -> Result<(), cli::CliError> {
    use tagsmith_studio::studio::{files::NativeFiles, Panel, StudioApp};
    let start = match &args.family {
        Some(name) => Some(cli::load_family(name)?),
        None => None,
    };
    let builtin = args
        .family
        .as_deref()
        .is_some_and(|n| tagsmith::builtin::get(n).is_some());
    let path = args
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
            if args.fresh {
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
            match args.panel.as_deref() {
                Some("families") => app.studio.panel = Panel::Families,
                Some("designer") => app.studio.panel = Panel::Designer,
                Some("print") => app.studio.panel = Panel::Print,
                _ => {}
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| {
        cli::CliError::Failed(anyhow::anyhow!(
            "the studio window could not open ({e}); on a machine without a display use the \
             command line: tagsmith --help"
        ))
    })
}

#[cfg(target_arch = "wasm32")]
fn main() {
    tagsmith_studio::web::start();
}
