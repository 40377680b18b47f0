//! Command-line parsing and the subcommands. Library code never prints;
//! everything the user sees on the terminal is printed here.

mod args;
mod bench;
mod check;
mod histogram;
mod info;
mod render;

use std::process::ExitCode;

use clap::Parser;

pub use args::{Cli, Command};

use std::io::Write;

/// Writes `text` to standard output. A closed output (`volcast check s.toml | head`)
/// is a `BrokenPipe` error, which `main` turns into a quiet exit.
pub fn print(text: &str) -> std::io::Result<()> {
    let mut out = std::io::stdout().lock();
    out.write_all(text.as_bytes())?;
    out.flush()
}

/// Writes one line to standard error, ignoring a closed stderr (messages are never
/// worth a crash).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}
pub(crate) use say;

/// Whether `err` comes from writing into a closed pipe.
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|e| {
        e.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Parses the command line and runs the subcommand.
pub fn run() -> anyhow::Result<ExitCode> {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Check(a) => check::run(a),
        Command::Info(a) => info::run(a),
        Command::Histogram(a) => histogram::run(a),
        Command::Bench(args::BenchCommand::Accuracy(a)) => bench::accuracy(a),
        Command::Bench(args::BenchCommand::Speed(a)) => bench::speed(a),
    }
}
