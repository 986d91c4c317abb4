//! Store fuzz: seeded random damage to shards (data and index), array metadata and group
//! metadata of a small two-layer store. For every case the reader and `verify` must not panic
//! (an abort or a hang fails the run too), and whatever changes what a reader returns must be
//! reported: the store is refused at open, a tile read is an error, or `verify` lists a problem.
//!
//! `SPHERECLIP_FUZZ_CASES` sets the number of random cases (default 400, run by `make test`);
//! seeds that ever failed are listed in `store_fuzz_regressions.txt` and always run first.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rand::{Rng, SeedableRng, rngs::StdRng};
use sc_core::{GridSpec, LevelId, ShardId, TileId};
use sc_store::{LayerKind, StoreConfig, StoreReader, StoreWriter, TileRead};

const T: usize = 16;

fn make_store(root: &Path) {
    let w = StoreWriter::create(
        root,
        StoreConfig {
            grid: GridSpec::new(T as u32).expect("grid"),
            shard_tiles: 2,
            ..StoreConfig::default()
        },
    )
    .expect("create");
    let mut rng = StdRng::seed_from_u64(7);
    for level in [LevelId::iso(0), LevelId::iso(1), LevelId::new(1, 1)] {
        let level = level.expect("level");
        let m = w.meta();
        let (sx, sy) = ShardId::counts(m.grid, level, m.shard_tiles);
        for y in 0..sy {
            for x in 0..sx {
                let mut sw = w
                    .shard_writer::<f32>(ShardId { level, x, y })
                    .expect("claim");
                let tiles: Vec<TileId> = sw.tiles().collect();
                for t in tiles {
                    let v: Vec<f32> = (0..T * T)
                        .map(|_| rng.random_range(-500.0..500.0))
                        .collect();
                    sw.put_tile(t, &v).expect("put");
                }
                sw.finish().expect("finish");
            }
        }
    }
    let level = LevelId::iso(1).expect("level");
    let mut sw = w
        .shard_writer::<u8>(ShardId { level, x: 0, y: 0 })
        .expect("claim");
    let tiles: Vec<TileId> = sw.tiles().collect();
    for t in tiles {
        let v: Vec<u8> = (0..T * T * 4).map(|_| rng.random()).collect();
        sw.put_tile(t, &v).expect("put");
    }
    sw.finish().expect("finish");
    w.commit(None).expect("commit");
}

/// What a reader returns for every tile of every level the pristine store lists: the bytes, or
/// `None` for a missing tile.
type Contents = BTreeMap<(LayerKind, LevelId, u64, u64), Option<Vec<u8>>>;

fn read_all(r: &StoreReader, levels: &[(LayerKind, LevelId)]) -> Result<Contents, String> {
    let g = r.meta().grid;
    let mut out = Contents::new();
    for &(kind, level) in levels {
        for y in 0..g.tiles_y(level) {
            for x in 0..g.tiles_x(level) {
                let tile = TileId::new(g, level, x, y).map_err(|e| e.to_string())?;
                let got = match kind {
                    LayerKind::Height => {
                        let mut b = vec![0f32; T * T];
                        r.read_tile(tile, &mut b)
                            .map_err(|e| e.to_string())?
                            .eq(&TileRead::Present)
                            .then(|| b.iter().flat_map(|v| v.to_le_bytes()).collect())
                    }
                    LayerKind::Color => {
                        let mut b = vec![0u8; T * T * 4];
                        r.read_tile(tile, &mut b)
                            .map_err(|e| e.to_string())?
                            .eq(&TileRead::Present)
                            .then_some(b)
                    }
                };
                out.insert((kind, level, x, y), got);
            }
        }
    }
    Ok(out)
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
        let p = e.path();
        if p.is_dir() {
            files(&p, out);
        } else if e.file_name() != ".lock" {
            out.push(p);
        }
    }
}

/// A random JSON value of any kind.
fn random_value(rng: &mut StdRng) -> serde_json::Value {
    use serde_json::json;
    match rng.random_range(0..9) {
        0 => json!(null),
        1 => json!(rng.random_range(-3i64..70)),
        2 => json!(u64::MAX),
        3 => json!(-1e300),
        4 => json!("big"),
        5 => json!(""),
        6 => json!([]),
        7 => json!({}),
        _ => json!(rng.random::<bool>()),
    }
}

/// Replaces, removes or renames one random node of a JSON tree.
fn mutate_json(v: &mut serde_json::Value, rng: &mut StdRng, depth: usize) {
    let stop = depth > 0 && rng.random_range(0..4) == 0;
    match v {
        serde_json::Value::Object(m) if !m.is_empty() && !stop => {
            let keys: Vec<String> = m.keys().cloned().collect();
            let k = &keys[rng.random_range(0..keys.len())];
            match rng.random_range(0..6) {
                0 => {
                    m.remove(k);
                }
                1 => {
                    if let Some(x) = m.remove(k) {
                        m.insert(format!("{k}x"), x);
                    }
                }
                _ => mutate_json(m.get_mut(k).expect("key"), rng, depth + 1),
            }
        }
        serde_json::Value::Array(a) if !a.is_empty() && !stop => {
            let i = rng.random_range(0..a.len());
            match rng.random_range(0..5) {
                0 => {
                    a.remove(i);
                }
                1 => a.push(a[i].clone()),
                _ => mutate_json(&mut a[i], rng, depth + 1),
            }
        }
        serde_json::Value::Number(n) if rng.random_bool(0.7) => {
            let x = n.as_f64().unwrap_or(0.0);
            *v = serde_json::json!(match rng.random_range(0..4) {
                0 => x + 1.0,
                1 => x * 2.0,
                2 => 0.0,
                _ => -x,
            });
        }
        _ => *v = random_value(rng),
    }
}

/// Whether sphereclip's reader reads `p`: the root metadata and the data arrays
/// (`LAYER/LEVEL/LAYER/…`). Level and layer groups, coordinates and grid mappings are there for
/// other readers (their damage changes nothing this reader returns).
fn read_by_sphereclip(root: &Path, p: &Path) -> bool {
    let rel: Vec<String> = p
        .strip_prefix(root)
        .expect("in")
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    rel == ["zarr.json"] || (rel.len() > 3 && rel[2] == rel[0])
}

/// Damages one file of the store that sphereclip reads; returns what was done.
fn damage(root: &Path, rng: &mut StdRng) -> String {
    let mut all = Vec::new();
    files(root, &mut all);
    all.retain(|p| read_by_sphereclip(root, p));
    all.sort();
    let json: Vec<&PathBuf> = all.iter().filter(|p| p.ends_with("zarr.json")).collect();
    let shards: Vec<&PathBuf> = all
        .iter()
        .filter(|p| p.components().any(|c| c.as_os_str() == "c"))
        .collect();
    if rng.random_bool(0.4) {
        let p = json[rng.random_range(0..json.len())];
        let mut v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(p).expect("read")).expect("json");
        let before = v.clone();
        mutate_json(&mut v, rng, 0);
        if v == before {
            mutate_json(&mut v, rng, 0);
        }
        std::fs::write(p, serde_json::to_vec(&v).expect("json")).expect("write");
        return format!("json {}", p.strip_prefix(root).expect("in").display());
    }
    let p = shards[rng.random_range(0..shards.len())];
    let mut b = std::fs::read(p).expect("read");
    let len = b.len();
    // the index (4 tiles × 16 bytes + crc) sits at the end: damage it as often as the data
    let index_start = len.saturating_sub(4 * 16 + 4);
    let at = if rng.random_bool(0.5) {
        rng.random_range(index_start..len)
    } else {
        rng.random_range(0..len)
    };
    let what = match rng.random_range(0..5) {
        0 => {
            b[at] ^= 1 << rng.random_range(0..8);
            "flip bit"
        }
        1 => {
            b.truncate(at);
            "truncate"
        }
        2 => {
            let end = (at + rng.random_range(1..64)).min(len);
            b[at..end].fill(0);
            "zero"
        }
        3 => {
            let end = (at + 8).min(len);
            b[at..end].fill(0xff);
            "ones"
        }
        _ => {
            b.extend((0..rng.random_range(1..100)).map(|_| rng.random::<u8>()));
            "append"
        }
    };
    std::fs::write(p, b).expect("write");
    format!(
        "{what} at {at} of {}",
        p.strip_prefix(root).expect("in").display()
    )
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read_dir").flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else {
            std::fs::copy(&p, to.join(e.file_name())).expect("copy");
        }
    }
}

/// One case: `Ok(true)` when the damage was reported, `Ok(false)` when it changed nothing a
/// reader returns; `Err` describes a panic or an unreported change.
fn case(pristine: &Path, work: &Path, seed: u64, want: &Contents) -> Result<bool, String> {
    let _ = std::fs::remove_dir_all(work);
    copy_dir(pristine, work);
    let mut rng = StdRng::seed_from_u64(seed);
    let what = damage(work, &mut rng);
    let levels: Vec<(LayerKind, LevelId)> = want
        .keys()
        .map(|&(k, l, _, _)| (k, l))
        .collect::<std::collections::BTreeSet<_>>()
        .into_iter()
        .collect();
    let outcome = std::panic::catch_unwind(|| {
        let reader = match StoreReader::open(work) {
            Ok(r) => r,
            Err(_) => return Ok(true),
        };
        let read = read_all(&reader, &levels);
        let verify = StoreReader::open(work)
            .and_then(|r| r.verify(&|| {}))
            .map_err(|e| e.to_string());
        let reported = match &verify {
            Err(_) => true,
            Ok(v) => !v.problems.is_empty(),
        };
        match read {
            Ok(got) if got == *want => Ok(reported),
            Ok(_) if !reported => Err("tiles changed but verify reports nothing".to_string()),
            Err(e) if !reported => Err(format!("a read failed ({e}) but verify reports nothing")),
            _ => Ok(true),
        }
    });
    match outcome {
        Ok(Ok(r)) => Ok(r),
        Ok(Err(e)) => Err(format!("seed {seed} ({what}): {e}")),
        Err(p) => {
            let msg = p
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(format!("seed {seed} ({what}): panicked: {msg}"))
        }
    }
}

#[test]
fn random_damage_never_panics_and_every_change_is_reported() {
    let dir = tempfile::tempdir().expect("tempdir");
    let pristine = dir.path().join("pristine.zarr");
    make_store(&pristine);
    let r = StoreReader::open(&pristine).expect("open");
    let levels: Vec<(LayerKind, LevelId)> = [LayerKind::Height, LayerKind::Color]
        .into_iter()
        .flat_map(|k| r.meta().levels(k).into_iter().map(move |l| (k, l)))
        .collect();
    let want = read_all(&r, &levels).expect("pristine reads");
    assert!(r.verify(&|| {}).expect("verify").problems.is_empty());
    let regressions: Vec<u64> = include_str!("store_fuzz_regressions.txt")
        .lines()
        .filter_map(|l| l.split('#').next()?.trim().parse().ok())
        .collect();
    let n: u64 = std::env::var("SPHERECLIP_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(400);
    let work = dir.path().join("case.zarr");
    let mut reported = 0;
    let mut failures = Vec::new();
    for seed in regressions.iter().copied().chain(0..n) {
        match case(&pristine, &work, seed, &want) {
            Ok(r) => reported += u64::from(r),
            Err(e) => failures.push(e),
        }
    }
    assert!(
        failures.is_empty(),
        "{} failing cases:\n{}",
        failures.len(),
        failures.join("\n")
    );
    // the harness damages for real: most cases are caught, few change nothing a reader sees
    assert!(
        reported * 10 >= n * 6,
        "only {reported} of {n} cases reported"
    );
}

/// What takes a file's place in [`swapped_files_never_hang_reach_outside_or_pass_verify`].
const SWAPS: [&str; 7] = [
    "fifo",
    "symlink to a copy outside",
    "dangling symlink",
    "symlink to /dev/zero",
    "symlink to /dev/null",
    "folder",
    "deleted",
];

/// Replaces `p` by what `swap` names; `outside` holds the copies symlinks point to.
fn swap_file(p: &Path, swap: &str, outside: &Path, n: u64) {
    let copy = outside.join(format!("copy-{n}"));
    if p.exists() {
        std::fs::copy(p, &copy).expect("copy");
    }
    let _ = std::fs::remove_file(p);
    match swap {
        "fifo" => {
            let ok = std::process::Command::new("mkfifo")
                .arg(p)
                .status()
                .expect("mkfifo");
            assert!(ok.success());
        }
        "symlink to a copy outside" => std::os::unix::fs::symlink(&copy, p).expect("symlink"),
        "dangling symlink" => {
            std::os::unix::fs::symlink(outside.join("nothing"), p).expect("symlink")
        }
        "symlink to /dev/zero" => std::os::unix::fs::symlink("/dev/zero", p).expect("symlink"),
        "symlink to /dev/null" => std::os::unix::fs::symlink("/dev/null", p).expect("symlink"),
        "folder" => std::fs::create_dir(p).expect("mkdir"),
        _ => {}
    }
}

/// Every file below `dir` (symlinks not followed) with its bytes.
fn outside_state(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
        out.insert(e.path(), std::fs::read(e.path()).unwrap_or_default());
    }
    out
}

#[test]
fn swapped_files_never_hang_reach_outside_or_pass_verify() {
    let dir = tempfile::tempdir().expect("tempdir");
    let pristine = dir.path().join("pristine.zarr");
    make_store(&pristine);
    let outside = dir.path().join("outside");
    std::fs::create_dir_all(&outside).expect("mkdir");
    let work = dir.path().join("case.zarr");
    let mut targets = Vec::new();
    files(&pristine, &mut targets);
    targets.sort();
    let n: u64 = std::env::var("SPHERECLIP_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .map_or(120, |v: u64| v.div_ceil(3));
    let mut failures = Vec::new();
    for seed in 0..n {
        let _ = std::fs::remove_dir_all(&work);
        copy_dir(&pristine, &work);
        let mut rng = StdRng::seed_from_u64(seed);
        // the lock one case in eight, else any file of the store
        let rel: PathBuf = if seed % 8 == 0 {
            PathBuf::from(".lock")
        } else {
            targets[rng.random_range(0..targets.len())]
                .strip_prefix(&pristine)
                .expect("in")
                .to_path_buf()
        };
        let swap = SWAPS[rng.random_range(0..SWAPS.len())];
        swap_file(&work.join(&rel), swap, &outside, seed);
        let what = format!("seed {seed}: {} replaced by {swap}", rel.display());
        let before = outside_state(&outside);
        let w = work.clone();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let r = std::panic::catch_unwind(|| {
                let verified = StoreReader::open(&w).map(|r| r.verify(&|| {}));
                let reported = match verified {
                    Err(_) => true,
                    Ok(Err(_)) => true,
                    Ok(Ok(v)) => !v.problems.is_empty(),
                };
                let writer = StoreWriter::open(&w).map(|_| ());
                (reported, writer.map_err(|e| e.to_string()))
            });
            let _ = tx.send(r.map_err(|_| "panicked".to_string()));
        });
        let (reported, writer) = match rx.recv_timeout(std::time::Duration::from_secs(60)) {
            Ok(Ok(r)) => r,
            Ok(Err(e)) => {
                failures.push(format!("{what}: {e}"));
                continue;
            }
            Err(_) => {
                failures.push(format!("{what}: hung for a minute"));
                continue;
            }
        };
        if rel == Path::new(".lock") {
            if swap != "deleted" && writer.is_ok() {
                failures.push(format!(
                    "{what}: a writer took a lock that is no regular file"
                ));
            }
        } else if !reported {
            failures.push(format!("{what}: open and verify reported nothing"));
        }
        if outside_state(&outside) != before || outside.join("nothing").exists() {
            failures.push(format!("{what}: something outside the store changed"));
        }
    }
    assert!(
        failures.is_empty(),
        "{} failing cases:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
