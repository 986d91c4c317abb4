//! The `sphereclip` command: one binary, one subcommand per stage (ingest, build, inspect, view,
//! render) plus `info` and `export` for stores. `anyhow` lives only here.

mod cli;
mod cmd;
mod out;
mod progress;

use std::process::ExitCode;

use clap::Parser;

/// mimalloc keeps the pages it has faulted in for its threads' next tiles, where glibc's arenas
/// trimmed them and faulted them in again (a tenth of colour ingest's wall time). Built without
/// transparent huge pages: with them, each first touch of a 2 MiB page could stall on the
/// kernel's compaction and zeroing (a build's system time 0.8-1.6 s instead of 0.3 s).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    // GDAL's spelling of creation options (`-co KEY=VALUE`) is accepted as `--co`
    let args = std::env::args_os().map(|a| if a == "-co" { "--co".into() } else { a });
    let cli = match cli::Cli::try_parse_from(args) {
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
    out::set_quiet(cli.quiet);
    init_logging(cli.quiet, cli.verbose);
    match cmd::run(cli) {
        Ok(code) => code,
        Err(e) => {
            // one line: what failed, with its causes, path last
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Logs (tracing) go to stderr: warnings by default, more with `-v`, none but errors with `-q`;
/// `RUST_LOG` overrides both.
fn init_logging(quiet: bool, verbose: u8) {
    use tracing_subscriber::EnvFilter;
    let default = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, 2) => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .with_target(true)
        .without_time()
        .try_init();
}
