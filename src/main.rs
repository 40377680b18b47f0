//! The `volcast` command: thin glue over the library (see `cli/`).
//!
//! Exit status: 0 on success (also when the reader of standard output closes it
//! early, as with `volcast check scene.toml | head -3`), 1 for any error, with one
//! message on stderr (an internal error, a panic, included), and 2 for command-line
//! usage errors, which clap reports.

use std::io::Write;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

mod cli;

fn main() -> ExitCode {
    install_panic_hook();
    run_guarded(cli::run)
}

/// Runs the command and turns its outcome into the exit status: an error is one
/// message and status 1, a closed standard output ends quietly with status 0, and a
/// panic (already reported by the hook) is status 1.
fn run_guarded(run: impl FnOnce() -> anyhow::Result<ExitCode>) -> ExitCode {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(run)) {
        Ok(Ok(code)) => code,
        Ok(Err(err)) if cli::is_broken_pipe(&err) => ExitCode::SUCCESS,
        Ok(Err(err)) => {
            let _ = writeln!(std::io::stderr(), "volcast: error: {err:#}");
            ExitCode::FAILURE
        }
        Err(_) => ExitCode::FAILURE,
    }
}

/// Reports a panic as one line on stderr (once per run, whichever thread panicked
/// first). A `println!` into a closed pipe panics in the standard library; that is
/// not an error of volcast, so it ends the process quietly with status 0.
fn install_panic_hook() {
    static REPORTED: AtomicBool = AtomicBool::new(false);
    std::panic::set_hook(Box::new(|info| {
        let message = panic_message(info.payload());
        if message.starts_with("failed printing to stdout") && message.contains("Broken pipe") {
            std::process::exit(0);
        }
        if REPORTED.swap(true, Ordering::SeqCst) {
            return;
        }
        let place = info
            .location()
            .map(|l| format!(" at {}:{}", l.file(), l.line()))
            .unwrap_or_default();
        let _ = writeln!(
            std::io::stderr(),
            "volcast: error: internal error: {message}{place} (a bug in volcast: please report it with the command and scene that caused it)"
        );
    }));
}

/// The text of a panic payload.
fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_string()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "a panic without a message".into()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcomes_become_exit_statuses() {
        assert_eq!(run_guarded(|| Ok(ExitCode::SUCCESS)), ExitCode::SUCCESS);
        assert_eq!(
            run_guarded(|| Err(anyhow::anyhow!("no such scene"))),
            ExitCode::FAILURE
        );
        let pipe = std::io::Error::from(std::io::ErrorKind::BrokenPipe);
        assert_eq!(
            run_guarded(|| Err(anyhow::Error::new(pipe).context("printing the plan"))),
            ExitCode::SUCCESS
        );
        // a panic, also in a worker thread, is status 1
        assert_eq!(run_guarded(|| panic!("boom")), ExitCode::FAILURE);
        assert_eq!(
            run_guarded(|| {
                rayon::scope(|s| s.spawn(|_| panic!("boom in a worker")));
                Ok(ExitCode::SUCCESS)
            }),
            ExitCode::FAILURE
        );
    }

    #[test]
    fn panic_messages() {
        assert_eq!(panic_message(&"x"), "x");
        assert_eq!(panic_message(&String::from("y")), "y");
        assert_eq!(panic_message(&3), "a panic without a message");
    }
}
