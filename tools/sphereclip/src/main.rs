//! The `sphereclip` command: one binary, one subcommand per stage (ingest, build, inspect, view,
//! render) plus `info` and `export` for stores. `anyhow` lives only here.

mod cli;
mod cmd;
mod progress;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    match cmd::run(cli) {
        Ok(code) => code,
        Err(e) => {
            // one line: what failed, with its causes, path last
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
