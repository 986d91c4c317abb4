//! The `sphereclip` command: one binary, one subcommand per stage (ingest, build, inspect, view,
//! render) plus `info` and `export` for stores. `anyhow` lives only here.

mod cli;
mod cmd;
mod out;
mod progress;

use std::process::ExitCode;

use clap::Parser;

fn main() -> ExitCode {
    let cli = match cli::Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        Err(e) => {
            // clap's message, its hints joined onto the same line
            let text = e.render().to_string();
            let parts: Vec<&str> = text
                .lines()
                .map(str::trim)
                .filter(|l| !l.is_empty() && !l.starts_with("For more information"))
                .collect();
            eprintln!("{}", parts.join(" "));
            return ExitCode::from(2);
        }
    };
    match cmd::run(cli) {
        Ok(code) => code,
        Err(e) => {
            // one line: what failed, with its causes, path last
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
