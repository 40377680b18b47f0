//! The `volcast` command: thin glue over the library (see `cli/`).

use std::process::ExitCode;

mod cli;

fn main() -> ExitCode {
    match cli::run() {
        Ok(code) => code,
        Err(err) => {
            eprintln!("volcast: error: {err:#}");
            ExitCode::FAILURE
        }
    }
}
