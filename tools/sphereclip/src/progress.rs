//! Progress reporting: an indicatif bar with ETA on a terminal, a plain line per 10 % elsewhere (CI).

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};

use indicatif::{ProgressBar, ProgressStyle};

/// A progress reporter for `total` steps of `what`; shareable between threads.
#[derive(Debug)]
pub struct Progress {
    bar: Option<ProgressBar>,
    what: String,
    total: AtomicU64,
    done: AtomicU64,
    last_decile: AtomicU64,
    quiet: bool,
}

impl Progress {
    /// A bar on a terminal (stderr), plain lines at every 10 % elsewhere.
    pub fn new(what: &str, total: u64) -> Self {
        let quiet = crate::out::quiet();
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let b = ProgressBar::new(total);
            if let Ok(style) = ProgressStyle::with_template(
                "{msg:>10} [{elapsed_precise}] {wide_bar} {pos}/{len} ETA {eta}",
            ) {
                b.set_style(style);
            }
            b.set_message(what.to_string());
            b
        });
        Self {
            bar,
            what: what.to_string(),
            total: AtomicU64::new(total),
            done: AtomicU64::new(0),
            last_decile: AtomicU64::new(0),
            quiet,
        }
    }

    /// Sets the number of steps done.
    pub fn set(&self, done: u64) {
        self.done.store(done, Ordering::Relaxed);
        match &self.bar {
            Some(b) => b.set_position(done),
            None if self.quiet => {}
            None => {
                let decile = done * 10 / self.total.load(Ordering::Relaxed).max(1);
                if self.last_decile.fetch_max(decile, Ordering::Relaxed) < decile {
                    eprintln!("{}: {}%", self.what, decile * 10);
                }
            }
        }
    }

    /// Sets the number of steps (when it is known only once the work started).
    pub fn set_total(&self, total: u64) {
        self.total.store(total, Ordering::Relaxed);
        if let Some(b) = &self.bar {
            b.set_length(total);
        }
    }

    /// Advances by one step.
    pub fn inc(&self) {
        let done = self.done.fetch_add(1, Ordering::Relaxed) + 1;
        self.set(done);
    }

    /// Finishes the bar.
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
