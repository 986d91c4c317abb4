//! Ingest input fuzz: seeded mutations (flipped bytes, extreme numbers, zeroed ranges,
//! truncation) of a GeoTIFF in a projected CRS, a small GeoTIFF with nodata, a raw SRTM `.hgt`
//! and a classic NetCDF, concentrated on their headers. Each mutated file is ingested into a copy
//! of an existing store: the process must end within a minute with exit 0 (then the store
//! verifies) or exit 1 with one error line (then the store is byte-identical to before) — never a
//! panic, an abort, a signal or a hang.
//!
//! `SPHERECLIP_FUZZ_CASES` sets the number of random cases per format (default 30, run by
//! `make test`); `format seed` pairs that ever failed are listed in `input_fuzz_regressions.txt`
//! and always run first.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;

use crate::util::{bin, copy_dir, run, run_within, s, same_files, sample, snapshot_with, text};

/// SplitMix64: a seeded stream of numbers, enough to pick mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// One input format: a valid file and the ingest arguments for it.
struct Format {
    name: &'static str,
    file: PathBuf,
    args: &'static [&'static str],
}

/// The valid inputs (made once) and the store every case starts from.
struct Fixture {
    _dir: tempfile::TempDir,
    formats: Vec<Format>,
    store: PathBuf,
}

fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = tempfile::tempdir().expect("tempdir");
        // a raw SRTM tile: its name says where it is, its size how fine it is
        let hgt = dir.path().join("N57E011.hgt");
        let o = Command::new("gdal_translate")
            .args(["-q", "-of", "SRTMHGT"])
            .arg(format!(
                "/vsizip/{}/N57E011.hgt",
                sample("N57E011.hgt.zip").display()
            ))
            .arg(&hgt)
            .output()
            .expect("gdal_translate runs");
        assert!(o.status.success(), "{}", text(&o.stderr));
        let store = dir.path().join("base.zarr");
        let o = run(&[
            "ingest",
            s(&store),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "2",
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let formats = vec![
            Format {
                name: "geotiff-lv95",
                file: sample("aletsch_dhm200_lv95.tif"),
                args: &["--level", "6"],
            },
            Format {
                name: "geotiff-nodata",
                file: sample("terra_elev_luxembourg.tif"),
                args: &["--level", "6"],
            },
            Format {
                name: "hgt",
                file: hgt,
                args: &["--level", "6"],
            },
            Format {
                name: "netcdf",
                file: sample("etopo20.cdf"),
                args: &["--level", "2"],
            },
        ];
        Fixture {
            _dir: dir,
            formats,
            store,
        }
    })
}

/// The file mutated by `seed`: damage lands in the first and last 4 KiB (headers, TIFF
/// directories) three times out of four.
fn mutate(bytes: &[u8], seed: u64) -> Vec<u8> {
    let mut rng = Rng(seed);
    let mut b = bytes.to_vec();
    let n = b.len();
    let pos = |rng: &mut Rng| -> usize {
        match rng.below(4) {
            0 => rng.below(n),
            1 => n - 1 - rng.below(n.min(4096)),
            _ => rng.below(n.min(4096)),
        }
    };
    for _ in 0..1 + rng.below(3) {
        match rng.below(5) {
            0 | 1 => {
                for _ in 0..1 + rng.below(8) {
                    let p = pos(&mut rng);
                    b[p] ^= 1 << rng.below(8);
                }
            }
            2 => {
                // an extreme number where a size, an offset or a count may be
                let p = pos(&mut rng).min(n.saturating_sub(4));
                let v: [u8; 4] = match rng.below(4) {
                    0 => [0xff; 4],
                    1 => [0x7f, 0xff, 0xff, 0xff],
                    2 => [0; 4],
                    _ => [0xff, 0xff, 0xff, 0x7f],
                };
                b[p..p + 4].copy_from_slice(&v);
            }
            3 => {
                let p = pos(&mut rng);
                let len = (1 + rng.below(64)).min(n - p);
                b[p..p + len].fill(0);
            }
            _ => {
                let keep = rng.below(n);
                b.truncate(keep);
                return b;
            }
        }
    }
    b
}

/// Ingests `format` mutated by `seed` into a fresh copy of the base store; `Err` says what broke
/// the contract.
fn case(f: &Fixture, format: &Format, seed: u64, work: &Path) -> Result<bool, String> {
    let _ = std::fs::remove_dir_all(work);
    std::fs::create_dir_all(work).map_err(|e| e.to_string())?;
    let store = work.join("s.zarr");
    copy_dir(&f.store, &store);
    let before = snapshot_with(&store, true);
    let input = work.join(format.file.file_name().expect("file name"));
    let original = std::fs::read(&format.file).map_err(|e| e.to_string())?;
    std::fs::write(&input, mutate(&original, seed)).map_err(|e| e.to_string())?;
    let mut c = bin();
    c.arg("ingest")
        .arg(&store)
        .arg(&input)
        .args(format.args)
        .env("RAYON_NUM_THREADS", "2");
    let o = run_within(c, Duration::from_secs(60));
    let err = text(&o.stderr);
    match o.status.code() {
        Some(0) => {
            let v = run(&["info", "--verify", s(&store)]);
            if v.status.success() {
                Ok(true)
            } else {
                Err(format!(
                    "ingest succeeded but the store does not verify: {}",
                    text(&v.stderr)
                ))
            }
        }
        Some(1) => {
            let lines = err.lines().filter(|l| l.starts_with("error:")).count();
            if lines != 1 || err.contains("panicked") {
                return Err(format!("not one error line: {err}"));
            }
            let after = snapshot_with(&store, true);
            if after != before {
                same_files(&before, &after, "");
            }
            Ok(false)
        }
        code => Err(format!("exit {code:?} (a panic or a signal): {err}")),
    }
}

#[test]
fn mutated_inputs_never_crash_hang_or_touch_the_store() {
    let f = fixture();
    let work = tempfile::tempdir().expect("tempdir");
    let regressions: Vec<(String, u64)> = include_str!("input_fuzz_regressions.txt")
        .lines()
        .filter_map(|l| {
            let mut it = l.split('#').next()?.split_whitespace();
            Some((it.next()?.to_string(), it.next()?.parse().ok()?))
        })
        .collect();
    let n: u64 = std::env::var("SPHERECLIP_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(30);
    let mut failures = Vec::new();
    let mut accepted = 0;
    for format in &f.formats {
        let seeds = regressions
            .iter()
            .filter(|(name, _)| name == format.name)
            .map(|(_, seed)| *seed)
            .chain((0..n).map(|k| 1000 + k));
        for seed in seeds {
            match std::panic::catch_unwind(|| case(f, format, seed, work.path())) {
                Ok(Ok(ok)) => accepted += usize::from(ok),
                Ok(Err(e)) => failures.push(format!("{} {seed}: {e}", format.name)),
                Err(_) => failures.push(format!("{} {seed}: the store changed", format.name)),
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} failing case(s) (add them to input_fuzz_regressions.txt):\n{}",
        failures.len(),
        failures.join("\n")
    );
    // the mutations must reach both outcomes, or they test nothing
    let total = f.formats.len() as u64 * n;
    assert!(
        accepted > 0 && (accepted as u64) < total,
        "{accepted} of {total} accepted"
    );
}
