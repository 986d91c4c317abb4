//! The writing commands on a store on object storage (`ingest s3://…`, `build s3://…`): the
//! store pulled into its working copy on this machine, the command run there as on any folder,
//! the folder pushed back as a commit over the commit pulled. Another writer's commit in between
//! is never written over: the work is done again over it.

use std::path::Path;

use anyhow::{Context, Result, bail};

use crate::progress::Progress;

/// Times a command's work is done again while other writers keep committing first.
const ATTEMPTS: usize = 3;

/// The store location a writing command was given: `Some(url)` for a store on object storage;
/// `None` for a folder; an error for a URL the command cannot write.
pub fn s3_store(store: &Path, command: &str) -> Result<Option<String>> {
    let Some(s) = store.to_str() else {
        return Ok(None);
    };
    if sc_store::is_s3_url(s) {
        return Ok(Some(s.trim_end_matches('/').to_string()));
    }
    if sc_store::is_url(s) {
        bail!(
            "{}: {command} writes a store folder or one on object storage (s3://BUCKET/…); a store over HTTP is read-only",
            s.escape_debug()
        );
    }
    Ok(None)
}

/// Runs `work` on the working copy of the store at `url` and commits it there.
pub fn write_through<T>(
    url: &str,
    command: &str,
    mut work: impl FnMut(&Path) -> Result<T>,
) -> Result<T> {
    for attempt in 1..=ATTEMPTS {
        let progress = Progress::new("pull", 0);
        let (mut copy, pulled) = sc_store::WorkingCopy::open(url, &|done, total| {
            progress.set_total(total);
            progress.set(done);
        })
        .with_context(|| format!("cannot {command} {url}"))?;
        progress.finish();
        if let Some(p) = pulled {
            crate::cmd::info_line(format_args!(
                "pulled {url} into {}: {} object(s) downloaded ({}), {} already there, {} removed",
                copy.root().display(),
                p.downloaded,
                crate::cmd::human_bytes(p.bytes),
                p.kept,
                p.removed
            ));
        }
        let out = work(copy.root())?;
        sc_store::fault::pause("work-done");
        let progress = Progress::new("push", 0);
        let pushed = copy
            .commit(&|done, total| {
                progress.set_total(total);
                progress.set(done);
            })
            .with_context(|| format!("{command} of {url} stopped; run it again to finish"))?;
        progress.finish();
        match pushed {
            Ok(s) => {
                crate::cmd::info_line(format_args!(
                    "committed to {url}: {} object(s) uploaded ({}), {} unchanged, {} removed",
                    s.uploaded,
                    crate::cmd::human_bytes(s.bytes),
                    s.unchanged,
                    s.removed
                ));
                return Ok(out);
            }
            Err(why) if attempt < ATTEMPTS => {
                eprintln!("{url}: {why}: the {command} is done again over it");
            }
            Err(why) => bail!("{url}: {why} ({ATTEMPTS} times): run the {command} again"),
        }
    }
    bail!("{url}: no attempt left")
}
