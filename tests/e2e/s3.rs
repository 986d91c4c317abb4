//! Stores on S3-compatible object storage, against a real S3 server on loopback (moto's, from
//! PyPI, started by tests/python/s3_server.py): a store read from `s3://…` renders, exports and
//! describes itself byte for byte as its folder does; missing buckets, missing stores, damaged
//! objects, malformed locations and a server that went away each end in one line, without a hang.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Duration;

use crate::util::*;

/// The test S3 server, stopped when dropped.
pub(crate) struct S3Server {
    child: Child,
    stdin: Option<ChildStdin>,
    out: BufReader<ChildStdout>,
    pub(crate) endpoint: String,
}

impl S3Server {
    pub(crate) fn start() -> Self {
        let mut child = Command::new(python())
            .arg(repo("tests/python/s3_server.py"))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the S3 server starts");
        let stdin = child.stdin.take();
        let mut out = BufReader::new(child.stdout.take().expect("stdout"));
        let mut line = String::new();
        out.read_line(&mut line).expect("reads");
        let port = line
            .strip_prefix("ready ")
            .and_then(|p| p.trim().parse::<u16>().ok())
            .unwrap_or_else(|| panic!("the S3 server did not start: {line:?}"));
        Self {
            child,
            stdin,
            out,
            endpoint: format!("http://127.0.0.1:{port}"),
        }
    }

    /// Sends one command of s3_server.py and returns its answer.
    pub(crate) fn ask(&mut self, command: &str) -> String {
        let stdin = self.stdin.as_mut().expect("running");
        writeln!(stdin, "{command}").expect("sent");
        stdin.flush().expect("sent");
        let mut line = String::new();
        self.out.read_line(&mut line).expect("answered");
        assert!(line.starts_with("done"), "{command}: {line}");
        line
    }

    /// Uploads every file of `folder` to `s3://bucket/prefix/…`.
    pub(crate) fn put(&mut self, bucket: &str, prefix: &str, folder: &Path) {
        self.ask(&format!("put {bucket} {prefix} {}", s(folder)));
    }

    /// `c` with this server's endpoint and credentials, and nothing of the user's AWS settings.
    pub(crate) fn env<'c>(&self, c: &'c mut Command) -> &'c mut Command {
        for k in [
            "AWS_PROFILE",
            "AWS_SESSION_TOKEN",
            "AWS_ENDPOINT_URL_S3",
            "AWS_CONFIG_FILE",
            "AWS_SHARED_CREDENTIALS_FILE",
        ] {
            c.env_remove(k);
        }
        c.env("AWS_ACCESS_KEY_ID", "sphereclip-test")
            .env("AWS_SECRET_ACCESS_KEY", "sphereclip-test-secret")
            .env("AWS_REGION", "us-east-1")
            .env("AWS_ENDPOINT_URL", &self.endpoint)
            .env("XDG_RUNTIME_DIR", xdg())
    }

    /// The PNG of `render AT --camera CAMERA --size 160x90` into `out`.
    fn render(&self, at: &str, camera: &str, out: &Path) -> Vec<u8> {
        let o = self.run(&[
            "render",
            at,
            "--camera",
            camera,
            "--size",
            "160x90",
            "--out",
            s(out),
        ]);
        ok(&o);
        std::fs::read(out).expect("png")
    }

    /// `sphereclip ARGS` against this server, within two minutes.
    pub(crate) fn run(&self, args: &[&str]) -> std::process::Output {
        let mut c = bin();
        self.env(&mut c).args(args);
        run_within(c, Duration::from_secs(120))
    }
}

impl Drop for S3Server {
    fn drop(&mut self) {
        // closing stdin stops it; a kill makes sure
        drop(self.stdin.take());
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn a_store_on_s3_reads_as_its_folder_and_failures_are_one_line() {
    let store = sample_planet();
    let mut server = S3Server::start();
    server.put("planets", "world/planet.zarr", &store);
    let url = "s3://planets/world/planet.zarr";
    let dir = tempfile::tempdir().expect("tmp");
    // the same picture, pole included
    for (i, camera) in ["46.5,8,300000,0,-30,60", "-89,0,400000,0,-60,60"]
        .iter()
        .enumerate()
    {
        let local = server.render(s(&store), camera, &dir.path().join(format!("local{i}.png")));
        let remote = server.render(url, camera, &dir.path().join(format!("s3-{i}.png")));
        assert!(
            local == remote,
            "camera {camera}: the render from S3 differs from the folder's"
        );
    }
    // the same GeoTIFF, colour and heights
    for layer in ["height", "color"] {
        let local = dir.path().join(format!("local-{layer}.tif"));
        let remote = dir.path().join(format!("s3-{layer}.tif"));
        for (at, out) in [(s(&store), &local), (url, &remote)] {
            ok(&server.run(&["export", at, "--layer", layer, "--level", "2", s(out), "-q"]));
        }
        assert!(
            std::fs::read(&local).expect("tif") == std::fs::read(&remote).expect("tif"),
            "{layer}: the export from S3 differs from the folder's"
        );
    }
    // the same description of its levels
    let local = text(&server.run(&["info", s(&store), "--levels"]).stdout);
    let o = server.run(&["info", url, "--levels"]);
    ok(&o);
    let remote = text(&o.stdout);
    assert!(
        remote
            .lines()
            .next()
            .unwrap_or("")
            .contains("complete, read from object storage"),
        "{remote}"
    );
    // sizes on disk ("1.2 MB") are "-" when read from object storage
    let table = |t: &str| -> Vec<String> {
        t.lines()
            .skip(1)
            .map(|l| {
                let mut words: Vec<&str> = Vec::new();
                for w in l.split_whitespace() {
                    if ["B", "kB", "MB", "GB"].contains(&w.trim_end_matches(',')) {
                        words.pop();
                        words.push("-");
                    } else {
                        words.push(w);
                    }
                }
                words.join(" ")
            })
            .collect()
    };
    assert_eq!(table(&local), table(&remote), "{local}\n{remote}");
    let line = one_line_failure(&server.run(&["info", "--verify", url]), "verify on S3");
    assert!(line.contains("run it where the store lives"), "{line}");

    // what is not there, and what is not an S3 location
    for (at, says) in [
        ("s3://planets/world/none.zarr", "no zarr.json"),
        (
            "s3://no-such-bucket/planet.zarr",
            "s3://no-such-bucket/planet.zarr",
        ),
        ("s3://Bad_Bucket/planet.zarr", "not a valid S3 bucket name"),
        ("s3://planets/world/../planet.zarr", "`..`"),
    ] {
        let line = one_line_failure(&server.run(&["info", at]), at);
        assert!(line.contains(says), "{at}: {line}");
    }
    // a damaged metadata object and a missing shard: one line each, never a panic
    let copy = "world/damaged.zarr";
    server.put("planets", copy, &store);
    server.ask(&format!(
        "write planets {copy}/zarr.json {{\"zarr_format\": 3, \"node"
    ));
    let line = one_line_failure(
        &server.run(&["info", &format!("s3://planets/{copy}")]),
        "damaged zarr.json",
    );
    assert!(line.contains("zarr.json"), "{line}");

    // a server that went away: one line, soon
    drop(server);
    let mut c = bin();
    c.env("AWS_ACCESS_KEY_ID", "x")
        .env("AWS_SECRET_ACCESS_KEY", "y")
        .env("AWS_ENDPOINT_URL", "http://127.0.0.1:9")
        .args(["info", url]);
    let line = one_line_failure(&run_within(c, Duration::from_secs(120)), "server gone");
    assert!(line.contains(url) && line.contains("127.0.0.1:9"), "{line}");
}

#[test]
fn inputs_on_s3_and_over_http_ingest_as_the_same_file_here_does() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    // a Cloud Optimized GeoTIFF, as Copernicus DEM and Landsat publish theirs
    let cog = d.join("n07_w006.tif");
    let o = Command::new("gdal_translate")
        .args(["-q", "-of", "COG", "-co", "COMPRESS=DEFLATE"])
        .arg(sample("n07_w006_3arc_v2.tif"))
        .arg(&cog)
        .output()
        .expect("gdal_translate runs");
    ok(&o);
    let inputs = d.join("inputs");
    std::fs::create_dir(&inputs).expect("mkdir");
    std::fs::copy(&cog, inputs.join("n07_w006.tif")).expect("copy");
    let mut server = S3Server::start();
    server.put("planets", "dem", &inputs);
    server.ask("public planets dem/n07_w006.tif");
    let local = d.join("local.zarr");
    ok(&server.run(&["ingest", s(&local), s(&cog), "-q"]));
    let want = snapshot(&local.join("height"));
    assert!(want.len() > 3, "{} files", want.len());
    let over_http = format!("{}/planets/dem/n07_w006.tif", server.endpoint);
    for input in ["s3://planets/dem/n07_w006.tif", over_http.as_str()] {
        let store = d.join("remote.zarr");
        let _ = std::fs::remove_dir_all(&store);
        let o = server.run(&["ingest", s(&store), input]);
        ok(&o);
        same_files(&want, &snapshot(&store.join("height")), input);
        let meta = std::fs::read_to_string(store.join("zarr.json")).expect("zarr.json");
        assert!(
            meta.contains(input) && meta.contains("etag "),
            "{input}: the store records the input by its version: {meta}"
        );
    }
    // a plan records the input's version; a new upload of it is refused, not mixed in
    let work = d.join("plan");
    std::fs::create_dir(&work).expect("mkdir");
    let mut c = bin();
    server.env(&mut c).current_dir(&work).args([
        "plan",
        "ingest",
        "st.zarr",
        "s3://planets/dem/n07_w006.tif",
        "--tasks",
        "2",
        "--out",
        "p",
    ]);
    ok(&run_within(c, Duration::from_secs(120)));
    server.ask("write planets dem/n07_w006.tif not the raster the plan was made from");
    let mut c = bin();
    server
        .env(&mut c)
        .current_dir(&work)
        .args(["run-task", "p", "--task", "0"]);
    let line = one_line_failure(&run_within(c, Duration::from_secs(120)), "changed input");
    assert!(line.contains("changed since the plan was made"), "{line}");
    // what is not there, and what is not a raster
    for (input, says) in [
        ("s3://planets/dem/none.tif", "no such file"),
        ("s3://planets/dem/n07_w006.tif", "not a raster"),
        ("s3://planets", "names a bucket"),
    ] {
        let line = one_line_failure(&server.run(&["ingest", s(&d.join("x.zarr")), input]), input);
        assert!(
            line.contains(says) && line.contains("s3://planets"),
            "{input}: {line}"
        );
    }
    assert!(!d.join("x.zarr").exists(), "a failed ingest made a store");
}

#[test]
fn push_puts_a_store_on_s3_as_a_commit_resumable_at_every_step_and_one_writer_at_a_time() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let store = d.join("planet.zarr");
    copy_dir(&sample_planet(), &store);
    let mut server = S3Server::start();
    let url = "s3://planets/pushed/planet.zarr";
    let line = one_line_failure(&server.run(&["push", s(&store), url]), "no bucket");
    assert!(line.contains("NoSuchBucket"), "{line}");
    server.ask("bucket planets");
    let o = server.run(&["push", s(&store), url]);
    ok(&o);
    assert!(text(&o.stdout).contains("uploaded"), "{}", text(&o.stdout));
    server.ask(&format!("compare planets pushed/planet.zarr {}", s(&store)));
    let info = |server: &S3Server| text(&server.run(&["info", url]).stdout);
    assert!(info(&server).contains(", complete,"), "{}", info(&server));
    // pushed again unchanged: nothing written
    let o = server.run(&["push", s(&store), url]);
    ok(&o);
    assert!(
        text(&o.stdout).contains(": 0 object(s) uploaded"),
        "{}",
        text(&o.stdout)
    );

    // the store changes (a regional ingest and its pyramid); from the old store on S3, its push
    // killed after each of its durable steps in turn (a fresh start each time), then run again:
    // the old store stays complete until the new root is marked INCOMPLETE, a rerun takes over
    // the dead push's lock and ends with the new store, object by object
    let old = d.join("old.zarr");
    copy_dir(&store, &old);
    ok(&run(&[
        "ingest",
        s(&store),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "3",
        "-q",
    ]));
    ok(&run(&["build", s(&store), "-q"]));
    let mut killed = 0;
    for n in 1.. {
        ok(&server.run(&["push", s(&old), url]));
        let mut c = bin();
        server
            .env(&mut c)
            .env("SPHERECLIP_FAULT_AFTER", n.to_string())
            .args(["push", s(&store), url]);
        let o = run_within(c, Duration::from_secs(120));
        if o.status.success() {
            break;
        }
        assert_eq!(
            o.status.code(),
            Some(sc_store::fault::FAULT_EXIT),
            "step {n}: {}",
            text(&o.stderr)
        );
        killed += 1;
        let first = info(&server).lines().next().unwrap_or("").to_string();
        match n {
            1 => assert!(first.contains(", complete,"), "after the lock: {first}"),
            2 => assert!(first.contains("INCOMPLETE"), "after the root: {first}"),
            _ => assert!(
                first.contains(", complete,") || first.contains("INCOMPLETE"),
                "after step {n}: {first}"
            ),
        }
        ok(&server.run(&["push", s(&store), url]));
        server.ask(&format!("compare planets pushed/planet.zarr {}", s(&store)));
        assert!(n < 300, "the push never ends");
    }
    assert!(killed >= 5, "only {killed} durable steps");
    assert!(info(&server).contains(", complete,"), "{}", info(&server));

    // one push at a time: a second one meets the first's lock and changes nothing
    let other = d.join("other.zarr");
    copy_dir(&sample_planet(), &other);
    let mut c = bin();
    server.env(&mut c).args(["push", s(&other), url]);
    let go = pause_at(&mut c, "push-locked", d);
    let first = std::thread::spawn(move || run_within(c, Duration::from_secs(300)));
    wait_until_paused("push-locked", d);
    let line = one_line_failure(&server.run(&["push", s(&store), url]), "second push");
    assert!(line.contains("another push holds the store"), "{line}");
    std::fs::write(&go, b"").expect("go");
    ok(&first.join().expect("first push"));
    server.ask(&format!("compare planets pushed/planet.zarr {}", s(&other)));
    // a lock another machine left is broken only when asked
    server.ask("write planets pushed/planet.zarr/.sphereclip/push.lock {\"host\": \"elsewhere\", \"pid\": 7}");
    let line = one_line_failure(&server.run(&["push", s(&store), url]), "foreign lock");
    assert!(
        line.contains("host elsewhere") && line.contains("--break-lock"),
        "{line}"
    );
    ok(&server.run(&["push", s(&store), url, "--break-lock"]));
    server.ask(&format!("compare planets pushed/planet.zarr {}", s(&store)));

    // what push refuses: a location holding other objects, an incomplete store, not S3
    server.ask("write planets mixed/notes.txt not a store");
    let line = one_line_failure(
        &server.run(&["push", s(&store), "s3://planets/mixed"]),
        "mixed",
    );
    assert!(
        line.contains("no store: push to an empty location"),
        "{line}"
    );
    let line = one_line_failure(&server.run(&["push", s(&store), "/tmp/x"]), "not s3");
    assert!(line.contains("s3://BUCKET/PREFIX"), "{line}");
}

#[test]
fn a_failing_s3_is_retried_and_a_full_bucket_ends_in_one_line() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let store = sample_planet();
    let mut server = S3Server::start();
    server.put("planets", "world/planet.zarr", &store);
    let url = "s3://planets/world/planet.zarr";
    let camera = "46.5,8,300000,0,-30,60";
    let render = |server: &S3Server, at: &str, out: &Path| server.render(at, camera, out);
    let want = render(&server, s(&store), &d.join("local.png"));
    // every fifth request refused (503 SlowDown, S3's throttling), then every fourth a 500:
    // the reads and a push are retried to the same bytes
    server.ask("faults every 5 503");
    assert!(
        render(&server, url, &d.join("slow.png")) == want,
        "the render through throttling differs"
    );
    server.ask("faults every 4 500");
    ok(&server.run(&["push", s(&store), "s3://planets/retried/planet.zarr"]));
    server.ask("faults none");
    server.ask(&format!(
        "compare planets retried/planet.zarr {}",
        s(&store)
    ));
    // the server away for two seconds (a restart): waited out
    server.ask("faults down 2");
    ok(&server.run(&["info", url]));
    // a bucket whose quota runs out mid-push: one line; a new store is not there yet (no root),
    // a store pushed over reads as it was, marked INCOMPLETE; a push once there is room
    // finishes either
    let changed = d.join("changed.zarr");
    copy_dir(&store, &changed);
    ok(&run(&[
        "ingest",
        s(&changed),
        s(&sample("n07_w006_3arc_v2.tif")),
        "--level",
        "3",
        "-q",
    ]));
    ok(&run(&["build", s(&changed), "-q"]));
    let root = std::fs::metadata(store.join("zarr.json"))
        .expect("root")
        .len();
    let fresh = "s3://planets/full/planet.zarr";
    for (folder, at, reads) in [(&store, fresh, false), (&changed, url, true)] {
        server.ask(&format!("faults quota {}", 2 * root + 100_000));
        let line = one_line_failure(&server.run(&["push", s(folder), at]), "quota");
        assert!(line.contains("QuotaExceeded"), "{line}");
        server.ask("faults none");
        let o = server.run(&["info", at]);
        if reads {
            ok(&o);
            assert!(
                text(&o.stdout).contains("INCOMPLETE"),
                "{}",
                text(&o.stdout)
            );
            assert!(
                render(&server, at, &d.join("incomplete.png")).len() > 100,
                "an incomplete store renders"
            );
        } else {
            let line = one_line_failure(&o, "a store half pushed");
            assert!(line.contains("no store there"), "{line}");
        }
        ok(&server.run(&["push", s(folder), at]));
        let prefix = at.trim_start_matches("s3://planets/");
        server.ask(&format!("compare planets {prefix} {}", s(folder)));
    }

    // ingest and build through a working copy: throttled, they finish with the folder's
    // objects; out of quota, one line and the store readable; once there is room a rerun
    // finishes
    let work = d.join("work");
    let on = |server: &S3Server, args: &[&str]| {
        let mut c = bin();
        server
            .env(&mut c)
            .env("SPHERECLIP_WORK_DIR", &work)
            .args(args);
        run_within(c, Duration::from_secs(300))
    };
    let srtm = sample("n07_w006_3arc_v2.tif");
    for (at, fault) in [
        (
            "s3://planets/throttled/planet.zarr",
            "every 5 503".to_string(),
        ),
        (
            "s3://planets/quota/planet.zarr",
            format!("quota {}", 2 * root + 100_000),
        ),
    ] {
        ok(&server.run(&["push", s(&store), at]));
        server.ask(&format!("faults {fault}"));
        let o = on(&server, &["ingest", at, s(&srtm), "--level", "3", "-q"]);
        if fault.starts_with("quota") {
            let line = one_line_failure(&o, "quota during an ingest");
            assert!(line.contains("QuotaExceeded"), "{line}");
            server.ask("faults none");
            let o = server.run(&["info", at]);
            ok(&o);
            assert!(
                text(&o.stdout).contains("INCOMPLETE"),
                "{}",
                text(&o.stdout)
            );
            ok(&on(
                &server,
                &["ingest", at, s(&srtm), "--level", "3", "-q"],
            ));
        } else {
            ok(&o);
        }
        ok(&on(&server, &["build", at, "-q"]));
        server.ask("faults none");
        let prefix = at.trim_start_matches("s3://planets/");
        server.ask(&format!("compare planets {prefix} {}", s(&changed)));
    }
}

#[test]
fn serve_passes_a_store_on_s3_on_as_its_folder_and_never_a_half_written_one() {
    use crate::serve::{Served, a_shard, get, split_parts};
    let store = sample_planet();
    let mut server = S3Server::start();
    let prefix = "served/planet.zarr";
    server.put("planets", prefix, &store);
    let mut c = bin();
    server.env(&mut c).args([
        "serve",
        &format!("s3://planets/{prefix}"),
        "--addr",
        "127.0.0.1:0",
    ]);
    let served = Served::start_with(c);
    let a = served.addr;
    assert!(served.url.ends_with("/planet.zarr"), "{}", served.url);
    let dir = tempfile::tempdir().expect("tmp");

    // the viewer's reads: the same picture as the folder's
    let camera = "46.5,8,300000,0,-30,60";
    let local = server.render(s(&store), camera, &dir.path().join("local.png"));
    let remote = server.render(&served.url, camera, &dir.path().join("served.png"));
    assert!(local == remote, "the render through serve s3:// differs");

    // a shard whole, a range, a suffix, two ranges: the folder's bytes, with the object's ETag
    let key = a_shard(&store);
    let bytes = std::fs::read(store.join(&key)).expect("shard");
    let path = format!("/planet.zarr/{key}");
    let whole = get(a, &path, &[]);
    assert_eq!(whole.status, 200);
    assert!(whole.body == bytes, "the whole shard differs");
    let tag = whole.header("etag").to_string();
    assert!(tag.starts_with('"') && tag.len() > 2, "{tag}");
    let r = get(a, &path, &[("Range", "bytes=10-109")]);
    assert_eq!(r.status, 206);
    assert_eq!(r.body, bytes[10..110]);
    assert_eq!(
        r.header("content-range"),
        format!("bytes 10-109/{}", bytes.len())
    );
    let r = get(a, &path, &[("Range", "bytes=-64")]);
    assert_eq!(r.body, bytes[bytes.len() - 64..]);
    let r = get(a, &path, &[("Range", "bytes=0-9,100-199")]);
    assert_eq!(r.status, 206);
    let boundary = r
        .header("content-type")
        .strip_prefix("multipart/byteranges; boundary=")
        .expect("multipart")
        .to_string();
    let parts = split_parts(&r.body, &boundary);
    assert_eq!(parts, [&bytes[0..10], &bytes[100..200]]);
    assert_eq!(
        get(a, &path, &[("Range", &format!("bytes={}-", bytes.len()))]).status,
        416
    );
    assert_eq!(get(a, &path, &[("If-None-Match", &tag)]).status, 304);
    // metadata gzipped when asked
    let z = get(a, "/planet.zarr/zarr.json", &[("Accept-Encoding", "gzip")]);
    assert_eq!(z.header("content-encoding"), "gzip");
    let mut json = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&z.body[..]), &mut json)
        .expect("gzip");
    assert!(json == std::fs::read(store.join("zarr.json")).expect("json"));
    // what serve never passes on, on object storage too
    server.ask(&format!(
        "write planets {prefix}/.sphereclip/push.lock secret"
    ));
    for hidden in [
        "/planet.zarr/.sphereclip/push.lock",
        "/planet.zarr/../x",
        "/planet.zarr/height/no-such",
    ] {
        assert_eq!(get(a, hidden, &[]).status, 404, "{hidden}");
    }

    // an object written again behind the root's back: refused, never mixed in
    let other = tempfile::NamedTempFile::new().expect("tmp");
    let mut changed = bytes.clone();
    changed[0] ^= 1;
    std::fs::write(other.path(), &changed).expect("write");
    let r = get(a, &path, &[("Range", "bytes=0-9")]);
    assert_eq!(r.body, bytes[..10]);
    server.ask(&format!(
        "upload planets {prefix}/{key} {}",
        s(other.path())
    ));
    let r = get(a, &path, &[("Range", "bytes=0-9")]);
    assert_eq!(r.status, 503, "{}", text(&r.body));
    assert!(text(&r.body).contains("changed while"), "{}", text(&r.body));
    server.ask(&format!(
        "upload planets {prefix}/{key} {}",
        s(&store.join(&key))
    ));

    // a writer marks the root INCOMPLETE first: the data is refused within a second
    let mut root: serde_json::Value =
        serde_json::from_slice(&std::fs::read(store.join("zarr.json")).expect("json"))
            .expect("json");
    root["attributes"]["sphereclip"]["complete"] = false.into();
    server.ask(&format!("write planets {prefix}/zarr.json {root}"));
    let refused = |p: &str| {
        (0..50).any(|_| {
            let r = get(a, p, &[]);
            if r.status == 503 && text(&r.body).contains("INCOMPLETE") {
                return true;
            }
            std::thread::sleep(Duration::from_millis(100));
            false
        })
    };
    assert!(
        refused(&path) && refused("/"),
        "an INCOMPLETE store was served"
    );
    // gone: said so
    server.ask(&format!("delete planets {prefix}/zarr.json"));
    let gone = (0..50).any(|_| {
        let r = get(a, &path, &[]);
        std::thread::sleep(Duration::from_millis(100));
        r.status == 404 && text(&r.body).contains("no store here")
    });
    assert!(gone, "a store gone from S3 was served");
    drop(served);

    // nothing to serve: one line
    let line = one_line_failure(
        &server.run(&["serve", "s3://planets/none.zarr", "--addr", "127.0.0.1:0"]),
        "serve a missing store",
    );
    assert!(line.contains("s3://planets/none.zarr"), "{line}");
}

#[test]
fn ingest_and_build_write_a_store_on_s3_as_its_folder_resumable_at_every_step_and_racing() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = dir.path();
    let mut server = S3Server::start();
    let url = "s3://planets/made/planet.zarr";
    // `sphereclip ARGS` on a machine whose working copies are under `machine`
    let on = |server: &S3Server, machine: &str, args: &[&str]| {
        let mut c = bin();
        server
            .env(&mut c)
            .env("SPHERECLIP_WORK_DIR", d.join(machine))
            .args(args);
        c
    };
    let run_on = |server: &S3Server, machine: &str, args: &[&str]| {
        run_within(on(server, machine, args), Duration::from_secs(300))
    };
    let start = d.join("start.zarr");
    copy_dir(&sample_planet(), &start);
    let srtm = sample("n07_w006_3arc_v2.tif");
    let ingest_srtm = ["ingest", url, s(&srtm), "--level", "3", "-q"];
    // the folder the same commands make
    let expect = |name: &str, steps: &[&[&str]]| {
        let f = d.join(name);
        copy_dir(&start, &f);
        for args in steps {
            let args: Vec<&str> = args
                .iter()
                .map(|a| if *a == url { s(&f) } else { *a })
                .collect();
            ok(&run(&args));
        }
        f
    };
    let ingested = expect("ingested.zarr", &[&ingest_srtm]);
    let built = expect("built.zarr", &[&ingest_srtm, &["build", url, "-q"]]);

    // a new location: nothing to pull; then over a store there: pulled, written, committed
    server.ask("bucket planets");
    ok(&server.run(&["push", s(&start), url]));
    let o = run_on(&server, "a", &ingest_srtm);
    ok(&o);
    server.ask(&format!(
        "compare planets made/planet.zarr {}",
        s(&ingested)
    ));
    // a build on machine a, then on machine b (the whole store pulled, nothing to do, nothing
    // written): what each says, and the folder's objects after each
    for (machine, says) in [
        ("a", "committed to s3://planets/made/planet.zarr"),
        ("b", ": 0 object(s) uploaded"),
    ] {
        let o = run_on(&server, machine, &["build", url]);
        ok(&o);
        assert!(text(&o.stderr).contains(says), "{}", text(&o.stderr));
        server.ask(&format!("compare planets made/planet.zarr {}", s(&built)));
    }

    // killed after a durable step (pull, ingest, push) and run again: the store on S3 is
    // readable all along and ends as the folder's, object by object. Every step of the pull and
    // of the push, every sixth of the ingest between (its resumes are the ingest tests')
    let kill_at = |server: &S3Server, n: u64| -> bool {
        ok(&server.run(&["push", s(&start), url]));
        let mut c = on(server, "k", &ingest_srtm);
        c.env("SPHERECLIP_FAULT_AFTER", n.to_string());
        let o = run_within(c, Duration::from_secs(300));
        if o.status.success() {
            return false;
        }
        assert_eq!(
            o.status.code(),
            Some(sc_store::fault::FAULT_EXIT),
            "step {n}: {}",
            text(&o.stderr)
        );
        ok(&server.run(&["info", url]));
        ok(&run_on(server, "k", &ingest_srtm));
        true
    };
    let (mut n, mut last) = (1, 0);
    while kill_at(&server, n) {
        server.ask(&format!(
            "compare planets made/planet.zarr {}",
            s(&ingested)
        ));
        last = n;
        n += if n < 12 { 1 } else { 6 };
        assert!(n < 1000, "the ingest never ends");
    }
    for m in last.saturating_sub(12).max(12) + 1..n {
        if m % 6 != 0 && kill_at(&server, m) {
            server.ask(&format!(
                "compare planets made/planet.zarr {}",
                s(&ingested)
            ));
        }
    }
    assert!(last >= 30, "only {last} durable steps");

    // two machines racing: the one that commits second finds the other's commit and does its
    // ingest again over it; both inputs are in the store, as ingested one after the other
    ok(&server.run(&["push", s(&start), url]));
    let aletsch = sample("aletsch_dhm200_lv95.tif");
    let hgt = sample("N57E011.hgt.zip");
    for m in ["a", "b"] {
        ok(&run_on(&server, m, &["build", url, "-q"]));
    }
    let mut c = on(&server, "a", &["ingest", url, s(&hgt), "--level", "3"]);
    let go = pause_at(&mut c, "work-done", d);
    let first = std::thread::spawn(move || run_within(c, Duration::from_secs(300)));
    wait_until_paused("work-done", d);
    ok(&run_on(
        &server,
        "b",
        &["ingest", url, s(&aletsch), "--level", "3", "-q"],
    ));
    std::fs::write(&go, b"").expect("go");
    let o = first.join().expect("first ingest");
    ok(&o);
    assert!(
        text(&o.stderr).contains("the ingest is done again over it"),
        "{}",
        text(&o.stderr)
    );
    let both = expect(
        "both.zarr",
        &[
            &["build", url, "-q"],
            &["ingest", url, s(&aletsch), "--level", "3", "-q"],
            &["ingest", url, s(&hgt), "--level", "3", "-q"],
        ],
    );
    server.ask(&format!("compare planets made/planet.zarr {}", s(&both)));

    // what cannot be written: a store over HTTP, a plan's store, a location holding other things
    for (args, says) in [
        (
            vec!["ingest", "http://127.0.0.1:9/planet.zarr", s(&srtm)],
            "read-only",
        ),
        (
            vec![
                "plan",
                "build",
                url,
                "--tasks",
                "2",
                "--out",
                s(&d.join("p.json")),
            ],
            "a plan's tasks write a store folder",
        ),
    ] {
        let line = one_line_failure(&run_on(&server, "a", &args), says);
        assert!(line.contains(says), "{line}");
    }
    server.ask("write planets other/notes.txt not a store");
    let line = one_line_failure(
        &run_on(&server, "a", &["build", "s3://planets/other"]),
        "other objects",
    );
    assert!(line.contains("but no store"), "{line}");
}
