//! `sphereclip upgrade STORE`: a store of an older format converted in place.

use std::process::ExitCode;

use anyhow::Result;

use crate::cli::UpgradeArgs;
use crate::progress::Progress;

/// Runs `upgrade`.
pub fn run(a: &UpgradeArgs) -> Result<ExitCode> {
    if let Some(url) = crate::cmd::remote::s3_store(&a.store, "upgrade")? {
        anyhow::bail!("{url}: upgrade a store folder, then push it");
    }
    let p = Progress::new("upgrade", 0);
    let report = sc_store::upgrade(&a.store, &|done, total| {
        p.set_total(total as u64);
        p.set(done as u64);
    })
    .map_err(|e| {
        // a file system failure mid-way (a full disk) is overcome by running it again
        let hint = if matches!(e, sc_store::StoreError::Io { .. }) {
            " (the store reads as being upgraded until it is done: run `sphereclip upgrade` again to finish it)"
        } else {
            ""
        };
        anyhow::anyhow!("cannot upgrade {}{hint}: {e}", a.store.display())
    })?;
    p.finish();
    let now = format!("{}.{}", sc_store::FORMAT_MAJOR, sc_store::FORMAT_MINOR);
    if report.from == now {
        crate::outln!("{} is already format {now}", a.store.display());
    } else {
        crate::outln!(
            "upgraded {} from format {} to {now}: {} level(s) converted, {} without data removed",
            a.store.display(),
            report.from,
            report.converted,
            report.pruned
        );
    }
    Ok(ExitCode::SUCCESS)
}
