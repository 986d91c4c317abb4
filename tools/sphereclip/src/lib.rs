//! The `sphereclip` command line: one subcommand per stage (ingest, build, inspect, view, render)
//! plus `info` and `export` for stores. `anyhow` lives only here.
//!
//! Two executables run it. `sphereclip-gdal` runs every command. `sphereclip`, the one users
//! call, runs the commands that never open a raster through GDAL (build, info, view, render,
//! upgrade, completions) itself and hands the others to `sphereclip-gdal` beside it, with the
//! same arguments. It does not link GDAL: loading GDAL's hundred-odd shared libraries costs every
//! process 40–50 ms before `main`, a twentieth of a one-second build.

pub mod cli;
pub mod cmd;
pub mod out;
pub mod progress;

use std::ffi::OsString;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};

/// mimalloc keeps the pages it has faulted in for its threads' next tiles, where glibc's arenas
/// trimmed them and faulted them in again (a tenth of colour ingest's wall time). Built without
/// transparent huge pages: with them, each first touch of a 2 MiB page could stall on the
/// kernel's compaction and zeroing (a build's system time 0.8-1.6 s instead of 0.3 s).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// The executable that runs the commands needing GDAL, installed beside `sphereclip`.
pub const GDAL_EXE: &str = "sphereclip-gdal";

/// Both executables' `main`: parses the command line, sets up output and logging, runs the
/// command with `run` and prints its error, if any, as one line.
pub fn main(run: fn(cli::Cli) -> Result<ExitCode>) -> ExitCode {
    let cli = match cli::parse_from(args()) {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => e.exit(), // --help, --version
        Err(e) if e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            // bare `sphereclip`: the help as clap lays it out
            eprint!("{}", e.render());
            return ExitCode::from(2);
        }
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
    match run(cli) {
        Ok(code) => code,
        Err(e) => {
            // one line: what failed, with its causes, path last
            eprintln!("error: {}", one_line(&chain(&e)));
            ExitCode::FAILURE
        }
    }
}

/// The error and its causes joined by `: `, leaving out a cause whose text the line already holds
/// (errors that quote their OS error in their own message).
fn chain(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.is_empty() {
            line = text;
        } else if !line.contains(&text) {
            line = format!("{line}: {text}");
        }
    }
    line
}

/// The longest error line printed: messages quote untrusted values (a plan's fields, paths).
const ERROR_MAX_CHARS: usize = 4000;

/// `message` as one line of bounded length: control characters (a newline in a path or a
/// plan's field) escaped, the tail past [`ERROR_MAX_CHARS`] cut.
fn one_line(message: &str) -> String {
    let mut out = String::new();
    for (n, c) in message.chars().enumerate() {
        if n == ERROR_MAX_CHARS {
            out += &format!(" … ({} more characters)", message.chars().count() - n);
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// The process's arguments, GDAL's spelling of creation options (`-co KEY=VALUE`) accepted as
/// `--co`.
fn args() -> impl Iterator<Item = OsString> {
    std::env::args_os().map(|a| if a == "-co" { "--co".into() } else { a })
}

/// Replaces this process by `sphereclip-gdal` with the same arguments; returns only when it
/// cannot be started.
pub fn hand_over() -> Result<ExitCode> {
    let exe = gdal_exe()?;
    let mut argv = std::env::args_os();
    let argv0 = argv.next().unwrap_or_else(|| "sphereclip".into());
    let mut command = std::process::Command::new(&exe);
    command.args(argv);
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt;
        let e = command.arg0(argv0).exec();
        Err(e).with_context(|| format!("cannot run {}", exe.display()))
    }
    #[cfg(not(unix))]
    {
        let _ = argv0;
        let status = command
            .status()
            .with_context(|| format!("cannot run {}", exe.display()))?;
        Ok(ExitCode::from(
            status.code().map_or(1, |c| c.clamp(0, 255) as u8),
        ))
    }
}

/// `sphereclip-gdal` beside this executable; an error naming where it was looked for when it is
/// not there.
fn gdal_exe() -> Result<PathBuf> {
    let me = std::env::current_exe().context("cannot find the sphereclip executable")?;
    let exe = me.with_file_name(format!("{GDAL_EXE}{}", std::env::consts::EXE_SUFFIX));
    if !exe.is_file() {
        anyhow::bail!(
            "this command needs {GDAL_EXE}, which is not installed beside sphereclip: {}",
            exe.display()
        );
    }
    Ok(exe)
}

/// The `sphereclip` executable users call, for scripts that run it again: this one, or the one
/// beside it when this is `sphereclip-gdal`.
pub fn user_exe() -> Result<PathBuf> {
    let me = std::env::current_exe().context("cannot find the sphereclip executable")?;
    let front = me.with_file_name(format!("sphereclip{}", std::env::consts::EXE_SUFFIX));
    Ok(if front.is_file() { front } else { me })
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
