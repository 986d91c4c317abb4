//! `sphereclip demo`: runs what exists so far on the bundled samples.
//!
//! Today that is checking the samples are there; it grows with each capability
//! (ingest → build → render/view).

use std::process::ExitCode;

use anyhow::{Result, bail};

use crate::cli::DemoArgs;

/// The bundled samples the demo uses.
const SAMPLES: [&str; 3] = [
    "etopo5.cdf.gz",
    "bluemarble_5400x2700.jpg",
    "N57E011.hgt.zip",
];

/// Runs `demo`.
pub fn run(a: &DemoArgs) -> Result<ExitCode> {
    for s in SAMPLES {
        let p = a.samples.join(s);
        if !p.is_file() {
            bail!(
                "sample missing: {} (run from the repository root or pass --samples)",
                p.display()
            );
        }
    }
    eprintln!(
        "demo: samples found in {}; ingest, build and the viewer are not implemented yet, so there is nothing more to show",
        a.samples.display()
    );
    Ok(ExitCode::SUCCESS)
}
