//! `fogtemp-cal`: the calibration command for lab technicians (thin glue over `fogtemp-cal`).

mod args;
mod commands;
mod diagnose;
mod output;
mod simulate;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let cli = args::Cli::parse();
    match commands::run(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // One paragraph: the error and its causes.
            let mut message = format!("error: {e}");
            for cause in e.chain().skip(1) {
                message.push_str(&format!("\n  caused by: {cause}"));
            }
            eprintln!("{message}");
            std::process::ExitCode::FAILURE
        }
    }
}
