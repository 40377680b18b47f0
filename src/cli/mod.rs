//! Command-line parsing and the three subcommands. Library code never prints;
//! everything the user sees on the terminal is printed here.

mod args;
mod bench;
mod check;
mod info;
mod render;

use std::process::ExitCode;

use clap::Parser;

pub use args::{Cli, Command};

/// Parses the command line and runs the subcommand.
pub fn run() -> anyhow::Result<ExitCode> {
    let cli = Cli::parse();
    match cli.command {
        Command::Render(a) => render::run(a),
        Command::Check(a) => check::run(a),
        Command::Info(a) => info::run(a),
        Command::Bench(args::BenchCommand::Accuracy(a)) => bench::accuracy(a),
        Command::Bench(args::BenchCommand::Speed(a)) => bench::speed(a),
    }
}
