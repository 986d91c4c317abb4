//! `sphereclip push`.

use std::process::ExitCode;

use anyhow::Result;

use crate::cli::PushArgs;
use crate::progress::Progress;

/// Runs `push`.
pub fn run(a: &PushArgs) -> Result<ExitCode> {
    if crate::cmd::remote::s3_store(&a.store, "push")?.is_some() {
        anyhow::bail!(
            "{}: push puts a store folder of this machine on object storage",
            a.store.display()
        );
    }
    if !sc_store::is_s3_url(&a.to) {
        anyhow::bail!(
            "{}: push writes to S3-compatible object storage, s3://BUCKET/PREFIX",
            a.to.escape_debug()
        );
    }
    let start = std::time::Instant::now();
    let progress = Progress::new("push", 0);
    let pushed = sc_store::push(
        &a.store,
        &a.to,
        a.break_lock,
        sc_store::Over::Anything,
        &|done, total| {
            progress.set_total(total);
            progress.set(done);
        },
    )
    .map_err(|e| anyhow::anyhow!("push of {} stopped: {e}", a.store.display()))?;
    let sc_store::Pushed::Done(summary) = pushed else {
        anyhow::bail!(
            "push of {} stopped: the store there moved",
            a.store.display()
        );
    };
    progress.finish();
    crate::outln!(
        "pushed {} to {}: {} object(s) uploaded ({}), {} already there, {} removed, {:.1} s",
        a.store.display(),
        a.to.trim_end_matches('/'),
        summary.uploaded,
        crate::cmd::human_bytes(summary.bytes),
        summary.unchanged,
        summary.removed,
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
