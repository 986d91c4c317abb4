//! Helpers every CLI test file shares: running the binary (with a hang limit), the samples,
//! byte snapshots of a store, and the one-line error contract.
#![allow(dead_code)] // each module uses its own subset

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use sc_core::{GridSpec, LevelId, TileId};
use sc_store::{StoreReader, TileRead};

/// The binary, with a fixed clock for provenance and no inherited fault points or stdin.
pub fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_sphereclip"));
    c.env("SOURCE_DATE_EPOCH", "1790000000")
        .env_remove("SPHERECLIP_FAULT_AFTER")
        .env_remove("SPHERECLIP_PAUSE")
        .stdin(Stdio::null());
    c
}

/// A path inside the repository.
pub fn repo(p: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(p)
}

/// A file of `samples/`.
pub fn sample(name: &str) -> PathBuf {
    repo("samples").join(name)
}

pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Runs the command to its end, or fails the test after `limit` (a hang).
pub fn run_within(mut c: Command, limit: Duration) -> Output {
    use std::io::Read;
    let mut child = c
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawns");
    // the pipes are drained while it runs: a child writing more than a pipe holds would
    // otherwise wait on us forever
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut b = Vec::new();
            let _ = r.read_to_end(&mut b);
            b
        })
    };
    let out = drain(Box::new(child.stdout.take().expect("stdout")));
    let err = drain(Box::new(child.stderr.take().expect("stderr")));
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("wait") {
            return Output {
                status,
                stdout: out.join().expect("stdout"),
                stderr: err.join().expect("stderr"),
            };
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "hung for {limit:?}: {:?}\n{}{}",
                c,
                text(&out.join().expect("stdout")),
                text(&err.join().expect("stderr"))
            );
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// `sphereclip ARGS…`, failing the test if it runs longer than five minutes.
pub fn run(args: &[&str]) -> Output {
    let mut c = bin();
    c.args(args);
    run_within(c, Duration::from_secs(300))
}

pub fn ok(o: &Output) {
    assert!(o.status.success(), "{}{}", text(&o.stdout), text(&o.stderr));
}

/// A failure the contract allows: exit code 1 (not a panic's 101, not a signal), one line.
pub fn one_line_failure(o: &Output, what: &str) -> String {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{what}: {err}");
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("error:") || l.contains("panicked"))
        .collect();
    assert_eq!(lines.len(), 1, "{what}: one error line expected: {err}");
    lines[0].to_string()
}

/// The one line of a usage error (exit 2: clap's line naming the option and the value).
pub fn usage_failure(o: &Output, what: &str) -> String {
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{what}: {err}");
    let lines: Vec<&str> = err.lines().filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(lines.len(), 1, "{what}: one line expected: {err}");
    assert!(lines[0].starts_with("error: "), "{what}: {err}");
    lines[0].to_string()
}

/// Every file below `root` but the lock, with its bytes; `.sphereclip/` (journals, undo,
/// provenance) too when `bookkeeping`.
pub fn snapshot_with(root: &Path, bookkeeping: bool) -> BTreeMap<PathBuf, Vec<u8>> {
    fn walk(dir: &Path, root: &Path, bk: bool, out: &mut BTreeMap<PathBuf, Vec<u8>>) {
        for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).expect("inside").to_path_buf();
            if rel == Path::new(".lock") || (!bk && rel.starts_with(".sphereclip")) {
                continue;
            }
            if p.is_dir() {
                walk(&p, root, bk, out);
            } else {
                out.insert(rel, std::fs::read(&p).expect("read"));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(root, root, bookkeeping, &mut out);
    out
}

/// The store's data: every file but the lock and the bookkeeping.
pub fn snapshot(root: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    snapshot_with(root, false)
}

pub fn same_files(a: &BTreeMap<PathBuf, Vec<u8>>, b: &BTreeMap<PathBuf, Vec<u8>>, what: &str) {
    let ka: Vec<_> = a.keys().collect();
    let kb: Vec<_> = b.keys().collect();
    assert_eq!(ka, kb, "{what}: different files");
    for (k, v) in a {
        assert!(b[k] == *v, "{what}: {} differs", k.display());
    }
}

/// Copies a store (without its lock).
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("read_dir").flatten() {
        let p = e.path();
        if p.is_dir() {
            copy_dir(&p, &to.join(e.file_name()));
        } else if e.file_name() != ".lock" {
            std::fs::copy(&p, to.join(e.file_name())).expect("copy");
        }
    }
}

/// A private runtime folder for the windowing stack.
pub fn xdg() -> PathBuf {
    let d = std::env::temp_dir().join("sphereclip-xdg");
    std::fs::create_dir_all(&d).expect("mkdir");
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&d, std::fs::Permissions::from_mode(0o700)).expect("chmod");
    d
}

/// A whole height level, row-major.
pub fn read_level(r: &StoreReader, id: LevelId) -> (usize, usize, Vec<f32>) {
    let g: GridSpec = r.meta().grid;
    let t = g.tile_size() as usize;
    let (w, h) = (g.width(id) as usize, g.height(id) as usize);
    let mut out = vec![f32::NAN; w * h];
    let mut buf = vec![0f32; t * t];
    for ty in 0..g.tiles_y(id) {
        for tx in 0..g.tiles_x(id) {
            let tile = TileId::new(g, id, tx, ty).expect("tile");
            if r.read_tile(tile, &mut buf).expect("read") == TileRead::Missing {
                continue;
            }
            for rr in 0..t {
                let o = (ty as usize * t + rr) * w + tx as usize * t;
                out[o..o + t].copy_from_slice(&buf[rr * t..(rr + 1) * t]);
            }
        }
    }
    (w, h, out)
}

/// A folder made by `make` once per build of the executables and shared by every test of a run
/// (the other test processes too, when a runner starts one per test): kept under cargo's target
/// tmpdir, keyed by both executables' sizes and times, made under a file lock into a `.part`
/// folder and renamed when complete. Treat it as read-only: copy it before changing anything.
pub fn fixture(name: &str, make: impl FnOnce(&Path)) -> PathBuf {
    let key = [
        env!("CARGO_BIN_EXE_sphereclip"),
        env!("CARGO_BIN_EXE_sphereclip-gdal"),
    ]
    .map(|exe| {
        let m = std::fs::metadata(exe).expect("the executable");
        let time = m
            .modified()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos());
        format!("{}-{time}", m.len())
    })
    .join("-");
    let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fixtures");
    std::fs::create_dir_all(&root).expect("mkdir");
    let lock = std::fs::File::create(root.join(format!("{name}.lock"))).expect("lock file");
    lock.lock().expect("lock");
    let dir = root.join(format!("{name}-{key}"));
    if !dir.is_dir() {
        // fixtures of earlier builds and a half-made one (all made here) go
        for e in std::fs::read_dir(&root).expect("read_dir").flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            if n.starts_with(&format!("{name}-")) && e.path().is_dir() {
                std::fs::remove_dir_all(e.path()).expect("remove an old fixture");
            }
        }
        let part = root.join(format!("{name}-{key}.part"));
        std::fs::create_dir_all(&part).expect("mkdir");
        make(&part);
        std::fs::rename(&part, &dir).expect("rename");
    }
    dir
}

/// ETOPO5 ingested at level 4 (8192×4096, 256² tiles), no pyramid.
pub fn etopo5_level4() -> PathBuf {
    fixture("etopo5-l4", |d| {
        ok(&run(&[
            "ingest",
            s(&d.join("s.zarr")),
            s(&sample("etopo5.cdf.gz")),
            "--level",
            "4",
        ]));
    })
    .join("s.zarr")
}

/// `ingest` options that place the Blue Marble (it has no georeference) as global colour at
/// level 3.
pub const BLUE_MARBLE_L3: [&str; 6] = [
    "--layer",
    "color",
    "--level",
    "3",
    "--bounds",
    "-180,-90,180,90",
];

/// ETOPO5 ingested into `store` at level 3 (4096×2048 with 256² tiles, its own resolution).
pub fn etopo5_at_level_3(store: &Path) {
    ok(&run(&[
        "ingest",
        s(store),
        s(&sample("etopo5.cdf.gz")),
        "--level",
        "3",
    ]));
}

/// The sample planet: ETOPO5 heights and Blue Marble colour at level 3, pyramid built.
pub fn sample_planet() -> PathBuf {
    fixture("planet-l3", |d| {
        let store = d.join("planet.zarr");
        etopo5_at_level_3(&store);
        let bm = sample("bluemarble_5400x2700.jpg");
        ok(&run(
            &[&["ingest", s(&store), s(&bm)][..], &BLUE_MARBLE_L3].concat()
        ));
        ok(&run(&["build", s(&store)]));
    })
    .join("planet.zarr")
}

/// ETOPO20 at level 5 with 32² tiles (32 shards) and its pyramid, built on one thread.
pub fn etopo20_level5_small_tiles() -> PathBuf {
    fixture("etopo20-l5-t32", |d| {
        let p = d.join("base.zarr");
        let mut c = bin();
        c.args([
            "ingest",
            s(&p),
            s(&sample("etopo20.cdf")),
            "--tile-size",
            "32",
            "--level",
            "5",
        ])
        .env("RAYON_NUM_THREADS", "1");
        ok(&run_within(c, Duration::from_secs(300)));
        ok(&run(&["build", s(&p), "--threads", "1"]));
    })
    .join("base.zarr")
}

/// `sphereclip ingest STORE ARGS…`, to its end.
pub fn ingest(store: &Path, args: &[&str]) -> Output {
    bin()
        .arg("ingest")
        .arg(store)
        .args(args)
        .output()
        .expect("runs")
}

/// `gdal_create -q ARGS… DST`.
pub fn gdal_create(dst: &Path, args: &[&str]) {
    let o = Command::new("gdal_create")
        .arg("-q")
        .args(args)
        .arg(dst)
        .output()
        .expect("gdal_create runs");
    assert!(o.status.success(), "{}", text(&o.stderr));
}

/// A whole-globe lon/lat raster of 360×180 one-degree pixels, each band one value:
/// `gdal_create` with `args` (bands, type, `-burn` values).
pub fn global_raster(dst: &Path, args: &[&str]) {
    let mut a = vec!["-outsize", "360", "180"];
    a.extend_from_slice(args);
    a.extend_from_slice(&["-a_srs", "EPSG:4326", "-a_ullr", "-180", "90", "180", "-90"]);
    gdal_create(dst, &a);
}

/// `sphereclip render STORE --camera CAMERA --size SIZE --out OUT --clear 1,0,1 --atmosphere off
/// --detail off EXTRA…` (space magenta, the terrain not seen through air, the data alone), the
/// picture read back.
pub fn render_png(
    store: &Path,
    out: &Path,
    camera: &str,
    size: &str,
    extra: &[&str],
) -> image::RgbaImage {
    let mut args = vec![
        "render",
        s(store),
        "--camera",
        camera,
        "--size",
        size,
        "--out",
        s(out),
        "--clear",
        "1,0,1",
        "--atmosphere",
        "off",
        "--detail",
        "off",
    ];
    args.extend_from_slice(extra);
    ok(&run(&args));
    image::open(out).expect("a PNG").to_rgba8()
}

/// A planet of flat heights (0 m at level 2) painted with the Blue Marble at level 4 (its own
/// resolution: 5400 pixels round the equator, 8192 texels), pyramid built: what the renderer
/// draws is then the stored colour alone, to compare with the CPU reference.
pub fn flat_blue_marble() -> PathBuf {
    fixture("flat-bluemarble-l4", |d| {
        flat_planet(
            &d.join("flat.zarr"),
            &sample("bluemarble_5400x2700.jpg"),
            &[],
        );
    })
    .join("flat.zarr")
}

/// A store of flat heights (0 m at level 2) painted with the global picture `colour` at level 4,
/// then `build STORE BUILD_ARGS…`; scratch files go beside the store.
pub fn flat_planet(store: &Path, colour: &Path, build_args: &[&str]) {
    let flat = store.with_extension("heights.tif");
    global_raster(&flat, &["-bands", "1", "-ot", "Float32", "-burn", "0"]);
    ok(&run(&["ingest", s(store), s(&flat), "--level", "2"]));
    ok(&run(&[
        "ingest",
        s(store),
        s(colour),
        "--layer",
        "color",
        "--level",
        "4",
        "--bounds",
        "-180,-90,180,90",
    ]));
    let mut build = vec!["build", s(store)];
    build.extend_from_slice(build_args);
    ok(&run(&build));
}

/// The names of the entries of a folder, sorted.
pub fn file_names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read_dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// `sphereclip ARGS…` under a file-size limit of `kib` KiB: writes beyond it fail with EFBIG
/// (SIGXFSZ ignored), the way they fail on a full disk, deterministically.
pub fn run_with_file_limit(kib: u64, args: &[&str]) -> Output {
    let mut c = Command::new("bash");
    c.arg("-c")
        .arg(format!(
            "trap '' XFSZ; ulimit -f {kib}; exec {} \"$@\"",
            env!("CARGO_BIN_EXE_sphereclip")
        ))
        .arg("sphereclip")
        .args(args)
        .env("SOURCE_DATE_EPOCH", "1790000000")
        .env("XDG_RUNTIME_DIR", xdg())
        .stdin(Stdio::null());
    run_within(c, Duration::from_secs(300))
}

/// Edits a JSON file (a store's metadata, a plan) in place.
pub fn edit_json(path: &Path, f: impl FnOnce(&mut serde_json::Value)) {
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(path).expect("read")).expect("json");
    f(&mut v);
    std::fs::write(path, serde_json::to_vec_pretty(&v).expect("json")).expect("write");
}

/// Starts `c` with `SPHERECLIP_PAUSE=POINT:DIR/go` and returns once it waits at `point`; it goes
/// on when `DIR/go` exists (the returned path).
pub fn spawn_paused(mut c: Command, point: &str, dir: &Path) -> (std::process::Child, PathBuf) {
    let go = pause_at(&mut c, point, dir);
    c.stdout(Stdio::null()).stderr(Stdio::null());
    let child = c.spawn().expect("spawn");
    wait_until_paused(point, dir);
    (child, go)
}

/// Makes `c` wait at pause point `point` until `DIR/go` (the returned path) exists.
pub fn pause_at(c: &mut Command, point: &str, dir: &Path) -> PathBuf {
    let go = dir.join("go");
    c.env("SPHERECLIP_PAUSE", format!("{point}:{}", s(&go)));
    go
}

/// Returns once a process made with [`pause_at`] waits at `point`; fails the test after 120 s.
pub fn wait_until_paused(point: &str, dir: &Path) {
    let waiting = dir.join("go.waiting");
    let start = Instant::now();
    while !waiting.exists() {
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "the process did not pause at {point}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The Python of scripts/pyenv.sh (made once under target/): zarr-python, xarray, rioxarray,
/// shapely, pyproj.
pub fn python() -> PathBuf {
    let o = run_within(
        {
            let mut c = Command::new("bash");
            c.arg(repo("scripts/pyenv.sh"));
            c
        },
        Duration::from_secs(900),
    );
    assert!(
        o.status.success(),
        "scripts/pyenv.sh failed: {}",
        text(&o.stderr)
    );
    PathBuf::from(text(&o.stdout).trim())
}
