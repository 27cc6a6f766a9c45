//! `tagsmith`: the Tagsmith studio (no subcommand) and its command-line interface.

mod cli;
mod cli_detect;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let args = cli::Cli::parse();
    match args.command {
        Some(command) => match cli::run(command) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                eprintln!("error: {e:#}");
                ExitCode::from(e.exit_code())
            }
        },
        None => studio(),
    }
}

/// The studio GUI lands in a later release; until then, say so and point at the commands.
fn studio() -> ExitCode {
    println!(
        "Tagsmith {} — the studio window is not built yet; use the command line:\n  \
         tagsmith families                      list the built-in marker families\n  \
         tagsmith render apriltag-36h11 --id 0 -o tag.svg\n  \
         tagsmith sheet apriltag-36h11 --ids 0-23 --labels --cut-marks -o sheet.pdf\n  \
         tagsmith --help                        every command",
        env!("CARGO_PKG_VERSION")
    );
    ExitCode::SUCCESS
}
