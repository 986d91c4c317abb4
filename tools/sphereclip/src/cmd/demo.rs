//! `sphereclip demo`: runs what exists so far on the bundled samples.

use std::process::ExitCode;

use anyhow::Result;

use crate::cli::DemoArgs;

/// Runs `demo`.
pub fn run(a: &DemoArgs) -> Result<ExitCode> {
    let _ = a;
    eprintln!("sphereclip demo: not implemented yet");
    Ok(ExitCode::from(2))
}
