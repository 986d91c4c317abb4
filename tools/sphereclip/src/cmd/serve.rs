//! `sphereclip serve`.

use std::process::ExitCode;

use anyhow::{Context, Result};

use crate::cli::ServeArgs;

/// Runs `serve` until SIGINT or SIGTERM.
pub fn run(a: &ServeArgs) -> Result<ExitCode> {
    let server = sc_serve::start(&a.store, a.addr, true)
        .with_context(|| format!("cannot serve {}", a.store.display()))?;
    let page = format!("http://{}/", server.addr);
    crate::outln!("serving {} at {}", a.store.display(), server.store_url);
    if sc_serve::site::has_viewer() {
        crate::outln!("page: {page}  (the web viewer; Ctrl-C stops)");
    } else {
        crate::outln!("page: {page}  (Ctrl-C stops)");
        eprintln!("warning: {}", sc_serve::site::NOT_BUILT);
    }
    if !server.addr.ip().is_loopback() {
        eprintln!(
            "warning: listening on {}: every machine that can reach it can read the store",
            server.addr
        );
    }
    if a.open
        && let Err(e) = std::process::Command::new("xdg-open")
            .arg(&page)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
    {
        eprintln!("warning: cannot open a browser (xdg-open: {e}); open {page}");
    }
    let counts = server.counts.clone();
    server.wait().context("the server stopped")?;
    use std::sync::atomic::Ordering::Relaxed;
    crate::outln!(
        "served {} requests, {}",
        counts.requests.load(Relaxed),
        super::human_bytes(counts.bytes.load(Relaxed))
    );
    Ok(ExitCode::SUCCESS)
}
