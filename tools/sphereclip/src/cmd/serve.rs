//! `sphereclip serve` and `sphereclip web`.

use std::process::ExitCode;

use anyhow::{Context, Result};

use crate::cli::{ServeArgs, WebArgs};

/// Runs `serve` until SIGINT or SIGTERM.
pub fn run(a: &ServeArgs) -> Result<ExitCode> {
    let server = sc_serve::start(&a.store, a.addr, true)
        .with_context(|| format!("cannot serve {}", a.store))?;
    let page = format!("http://{}/", server.addr);
    crate::outln!("serving {} at {}", a.store, server.store_url);
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

/// Runs `web`: the viewer's files into `--out`.
pub fn web(a: &WebArgs) -> Result<ExitCode> {
    if a.store.is_empty() || a.store.chars().any(char::is_control) {
        anyhow::bail!("--store must be a URL or a path, found {:?}", a.store);
    }
    let written = sc_serve::site::write_site(&a.out, &a.store)
        .with_context(|| format!("cannot write the web viewer into {}", a.out.display()))?;
    crate::outln!(
        "wrote the web viewer ({} files) into {}; the page opens {} (relative to the page unless a URL).",
        written.len(),
        a.out.display(),
        a.store
    );
    crate::outln!(
        "Serve the folder with the store beside it from any static host, e.g. python3 -m http.server -d {}",
        a.out.display()
    );
    Ok(ExitCode::SUCCESS)
}
