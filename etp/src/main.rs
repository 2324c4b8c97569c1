//! `etp`: parse the command line, hand over to the library.

use clap::Parser;

fn main() -> std::process::ExitCode {
    etp::run(etp::cli::Cli::parse())
}
