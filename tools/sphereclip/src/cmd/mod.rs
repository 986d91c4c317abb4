//! One module per subcommand; [`run`] dispatches.

mod build;
mod demo;
mod export;
mod flight;
mod info;
mod ingest;
mod inspect;
mod render;
mod view;

use std::process::ExitCode;

use anyhow::Result;

use crate::cli::{Cli, Command};

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Info(a) => info::run(&a),
        Command::Export(a) => export::run(&a),
        Command::Demo(a) => demo::run(&a),
        Command::Ingest(a) => ingest::run(&a),
        Command::Build(a) => build::run(&a),
        Command::Inspect(a) => inspect::run(&a),
        Command::View(a) => view::run(&a),
        Command::Render(a) => render::run(&a),
    }
}

/// Parses a layer name into its kind, with the list of valid names in the error.
pub fn parse_layer(name: &str) -> Result<sc_store::LayerKind> {
    sc_store::LayerKind::from_name(name)
        .ok_or_else(|| anyhow::anyhow!("unknown layer `{name}` (expected one of: height, color)"))
}
