//! `serve` and stores read over HTTP: a served store renders byte for byte as the folder does;
//! Range requests (single, open-ended, suffix, several, unsatisfiable) and conditional requests
//! answer as RFC 9110 says; nothing outside the store's data is ever served (hidden files,
//! `..`, symlinks, temp files); INCOMPLETE, vanished and missing stores are answered clearly;
//! a loopback load is answered in full with bounded memory.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::Duration;

use crate::util::*;

/// `sphereclip serve STORE --addr 127.0.0.1:0`, stopped (SIGTERM) when dropped.
pub(crate) struct Served {
    child: Child,
    pub(crate) addr: SocketAddr,
    pub(crate) url: String,
}

impl Served {
    pub(crate) fn start(store: &Path) -> Self {
        let mut c = bin();
        c.args(["serve", s(store), "--addr", "127.0.0.1:0"]);
        Self::start_with(c)
    }

    /// `c`, a `sphereclip serve` command, started.
    pub(crate) fn start_with(mut c: std::process::Command) -> Self {
        let mut child = c
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("serve starts");
        let mut out = child.stdout.take().expect("stdout");
        // the first line: "serving STORE at URL"
        let mut line = Vec::new();
        let mut b = [0u8; 1];
        while out.read(&mut b).expect("reads") == 1 && b[0] != b'\n' {
            line.push(b[0]);
        }
        let line = text(&line);
        let url = line
            .rsplit(' ')
            .next()
            .filter(|u| u.starts_with("http://"))
            .unwrap_or_else(|| panic!("serve printed no URL: {line:?}"))
            .to_string();
        let addr = url
            .trim_start_matches("http://")
            .split('/')
            .next()
            .and_then(|a| a.parse().ok())
            .expect("an address in the URL");
        // the rest of its output is not read: keep the pipe from filling
        std::thread::spawn(move || std::io::copy(&mut out, &mut std::io::sink()));
        Self { child, addr, url }
    }

    /// The server's peak resident memory, kB.
    fn peak_rss_kb(&self) -> u64 {
        let status =
            std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).expect("status");
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmHWM:"))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
            .expect("VmHWM")
    }
}

impl Drop for Served {
    fn drop(&mut self) {
        // SIGTERM: the server's graceful stop
        let _ = std::process::Command::new("kill")
            .arg(self.child.id().to_string())
            .status();
        for _ in 0..100 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One answer: status, headers (lower-case names), body.
pub(crate) struct Answer {
    pub(crate) status: u16,
    pub(crate) headers: HashMap<String, String>,
    pub(crate) body: Vec<u8>,
}

impl Answer {
    pub(crate) fn header(&self, name: &str) -> &str {
        self.headers.get(name).map_or("", String::as_str)
    }
}

/// A raw HTTP/1.1 request (the path sent exactly as given), `Connection: close`.
pub(crate) fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
) -> Answer {
    let mut t = TcpStream::connect(addr).expect("connects");
    t.set_read_timeout(Some(Duration::from_secs(30)))
        .expect("timeout");
    let mut req = format!("{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for (k, v) in headers {
        req.push_str(&format!("{k}: {v}\r\n"));
    }
    req.push_str("\r\n");
    t.write_all(req.as_bytes()).expect("writes");
    let mut raw = Vec::new();
    t.read_to_end(&mut raw).expect("reads the answer");
    let split = raw
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .expect("a header block");
    let head = text(&raw[..split]);
    let mut lines = head.lines();
    let status = lines
        .next()
        .and_then(|l| l.split(' ').nth(1))
        .and_then(|c| c.parse().ok())
        .expect("a status line");
    let headers = lines
        .filter_map(|l| l.split_once(':'))
        .map(|(k, v)| (k.trim().to_ascii_lowercase(), v.trim().to_string()))
        .collect();
    Answer {
        status,
        headers,
        body: raw[split + 4..].to_vec(),
    }
}

pub(crate) fn get(addr: SocketAddr, path: &str, headers: &[(&str, &str)]) -> Answer {
    request(addr, "GET", path, headers)
}

/// The first shard file of the store's finest height level, its key inside the store.
pub(crate) fn a_shard(store: &Path) -> String {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).expect("read_dir").flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.components().any(|c| c.as_os_str() == "c") {
                out.push(p);
            }
        }
    }
    let mut shards = Vec::new();
    walk(&store.join("height"), &mut shards);
    shards.sort_by_key(|p| std::cmp::Reverse(std::fs::metadata(p).map_or(0, |m| m.len())));
    let p = shards.first().expect("a shard");
    p.strip_prefix(store)
        .expect("inside")
        .to_string_lossy()
        .into_owned()
}

#[test]
fn a_served_store_renders_byte_for_byte_as_its_folder_and_info_reads_it() {
    let store = sample_planet();
    let server = Served::start(&store);
    let dir = tempfile::tempdir().expect("tmp");
    for (i, camera) in ["46.5,8,300000,0,-30,60", "-89,0,400000,0,-60,60"]
        .iter()
        .enumerate()
    {
        let local = dir.path().join(format!("local{i}.png"));
        let remote = dir.path().join(format!("remote{i}.png"));
        let mut said = String::new();
        for (at, out) in [(s(&store), &local), (server.url.as_str(), &remote)] {
            let mut c = bin();
            c.env("XDG_RUNTIME_DIR", xdg()).args([
                "render",
                at,
                "--camera",
                camera,
                "--size",
                "160x90",
                "--out",
                s(out),
            ]);
            let o = run_within(c, Duration::from_secs(300));
            ok(&o);
            said += &format!("{at}: {}{}", text(&o.stdout), text(&o.stderr));
        }
        assert!(
            std::fs::read(&local).expect("png") == std::fs::read(&remote).expect("png"),
            "camera {camera}: the render over HTTP differs from the folder's\n{said}"
        );
    }
    let o = run(&["info", &server.url]);
    ok(&o);
    let t = text(&o.stdout);
    assert!(
        t.contains("read over HTTP") && t.contains("complete"),
        "{t}"
    );
    let line = one_line_failure(&run(&["info", "--verify", &server.url]), "verify remote");
    assert!(line.contains("run it where the store lives"), "{line}");
    // a URL nothing answers: one line, no hang
    let mut c = bin();
    c.args(["info", "http://127.0.0.1:9/planet.zarr"]);
    let line = one_line_failure(&run_within(c, Duration::from_secs(120)), "nothing there");
    assert!(line.contains("127.0.0.1:9"), "{line}");
}

#[test]
fn ranges_and_conditional_requests_answer_as_http_says() {
    let store = sample_planet();
    let server = Served::start(&store);
    let key = a_shard(&store);
    let bytes = std::fs::read(store.join(&key)).expect("shard");
    let n = bytes.len();
    assert!(n > 1000, "a shard of {n} bytes");
    let path = format!("/planet.zarr/{key}");
    let a = server.addr;

    let whole = get(a, &path, &[]);
    assert_eq!(whole.status, 200);
    assert_eq!(whole.body, bytes);
    assert_eq!(whole.header("accept-ranges"), "bytes");
    assert_eq!(whole.header("content-type"), "application/octet-stream");

    let single = get(a, &path, &[("Range", "bytes=100-199")]);
    assert_eq!(single.status, 206);
    assert_eq!(single.body, &bytes[100..200]);
    assert_eq!(single.header("content-range"), format!("bytes 100-199/{n}"));

    let open = get(a, &path, &[("Range", &format!("bytes={}-", n - 50))]);
    assert_eq!(open.status, 206);
    assert_eq!(open.body, &bytes[n - 50..]);

    let suffix = get(a, &path, &[("Range", "bytes=-20")]);
    assert_eq!(suffix.status, 206);
    assert_eq!(suffix.body, &bytes[n - 20..]);

    let multi = get(a, &path, &[("Range", "bytes=0-9,500-519")]);
    assert_eq!(multi.status, 206);
    let ct = multi.header("content-type").to_string();
    let boundary = ct
        .strip_prefix("multipart/byteranges; boundary=")
        .unwrap_or_else(|| panic!("{ct}"));
    let parts = split_parts(&multi.body, boundary);
    assert_eq!(parts.len(), 2, "two parts");
    assert_eq!(parts[0], &bytes[0..10]);
    assert_eq!(parts[1], &bytes[500..520]);

    for bad in [
        format!("bytes={n}-"),
        "bytes=9-3".into(),
        "bytes=0-99,50-60".into(),
    ] {
        let r = get(a, &path, &[("Range", &bad)]);
        assert_eq!(r.status, 416, "{bad}");
        assert_eq!(r.header("content-range"), format!("bytes */{n}"), "{bad}");
    }

    let head = request(a, "HEAD", &path, &[]);
    assert_eq!(head.status, 200);
    assert_eq!(head.header("content-length"), n.to_string());
    assert!(head.body.is_empty());

    let tag = whole.header("etag").to_string();
    assert!(tag.starts_with('"'), "{tag}");
    assert_eq!(get(a, &path, &[("If-None-Match", &tag)]).status, 304);
    let lm = whole.header("last-modified").to_string();
    assert_eq!(get(a, &path, &[("If-Modified-Since", &lm)]).status, 304);
    // If-Range with an old validator: the whole file, not the range
    let stale = get(
        a,
        &path,
        &[("Range", "bytes=0-9"), ("If-Range", "\"not-this\"")],
    );
    assert_eq!(stale.status, 200);
    assert_eq!(stale.body.len(), n);

    // metadata gzipped when asked, the same bytes once inflated
    let meta = std::fs::read(store.join("zarr.json")).expect("meta");
    let gz = get(a, "/planet.zarr/zarr.json", &[("Accept-Encoding", "gzip")]);
    assert_eq!(gz.status, 200);
    assert_eq!(gz.header("content-encoding"), "gzip");
    assert_eq!(gz.header("content-type"), "application/json");
    let mut inflated = Vec::new();
    flate2::read::GzDecoder::new(&gz.body[..])
        .read_to_end(&mut inflated)
        .expect("gzip");
    assert_eq!(inflated, meta);
    assert!(gz.body.len() * 3 < meta.len(), "gzip saves little");
    assert_eq!(request(a, "POST", &path, &[]).status, 405);
}

/// The parts of a `multipart/byteranges` body.
pub(crate) fn split_parts<'a>(body: &'a [u8], boundary: &str) -> Vec<&'a [u8]> {
    let sep = format!("\r\n--{boundary}");
    let mut out = Vec::new();
    let mut rest = body;
    while let Some(i) = find(rest, sep.as_bytes()) {
        rest = &rest[i + sep.len()..];
        if rest.starts_with(b"--") {
            break;
        }
        let Some(h) = find(rest, b"\r\n\r\n") else {
            break;
        };
        let start = h + 4;
        let end = find(&rest[start..], sep.as_bytes()).map_or(rest.len(), |e| start + e);
        out.push(&rest[start..end]);
        rest = &rest[end..];
    }
    out
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

#[test]
fn nothing_outside_the_store_data_is_ever_served() {
    let dir = tempfile::tempdir().expect("tmp");
    let store = dir.path().join("planet.zarr");
    copy_dir(&sample_planet(), &store);
    let secret = dir.path().join("secret.txt");
    std::fs::write(&secret, b"SECRET-OUTSIDE").expect("secret");
    std::fs::write(store.join(".lock"), b"").expect("lock");
    std::fs::create_dir_all(store.join(".sphereclip")).expect("mkdir");
    std::fs::write(
        store.join(".sphereclip").join("journal-1.json"),
        b"SECRET-BOOK",
    )
    .expect("journal");
    std::fs::write(store.join("zarr.json.tmp.77.88"), b"SECRET-TMP").expect("tmp");
    let before = snapshot_with(&store, true);
    let outside = file_names(dir.path());
    let (leak, up) = (
        store.join("height").join("leak.json"),
        store.join("color").join("up"),
    );
    std::os::unix::fs::symlink(&secret, &leak).expect("link");
    std::os::unix::fs::symlink(dir.path(), &up).expect("link");
    let server = Served::start(&store);
    let a = server.addr;
    for path in [
        "/planet.zarr/height/leak.json",
        "/planet.zarr/color/up/secret.txt",
        "/planet.zarr/.lock",
        "/planet.zarr/.sphereclip/journal-1.json",
        "/planet.zarr/zarr.json.tmp.77.88",
        "/planet.zarr/../secret.txt",
        "/planet.zarr/height/../../secret.txt",
        "/planet.zarr/%2e%2e/secret.txt",
        "/planet.zarr/height/%2E%2E/%2E%2E/secret.txt",
        "/planet.zarr//etc/passwd",
        "/../secret.txt",
        "/secret.txt",
        "/planet.zarr/height",
        "/etc/passwd",
    ] {
        let r = get(a, path, &[]);
        assert!(
            r.status == 404 || r.status == 400,
            "{path}: {} {}",
            r.status,
            text(&r.body)
        );
        let body = text(&r.body);
        assert!(
            !body.contains("SECRET") && !body.contains("root:"),
            "{path} leaked: {body}"
        );
    }
    // the data is served, and serving wrote nothing into the store
    assert_eq!(get(a, "/planet.zarr/zarr.json", &[]).status, 200);
    drop(server);
    std::fs::remove_file(&leak).expect("unlink");
    std::fs::remove_file(&up).expect("unlink");
    same_files(
        &before,
        &snapshot_with(&store, true),
        "serve wrote into the store",
    );
    assert_eq!(
        file_names(dir.path()),
        outside,
        "serve wrote beside the store"
    );
}

#[test]
fn incomplete_vanished_and_missing_stores_are_answered_clearly() {
    let dir = tempfile::tempdir().expect("tmp");
    let line = one_line_failure(
        &run(&[
            "serve",
            s(&dir.path().join("none.zarr")),
            "--addr",
            "127.0.0.1:0",
        ]),
        "no store",
    );
    assert!(line.contains("does not exist"), "{line}");

    let store = dir.path().join("planet.zarr");
    copy_dir(&sample_planet(), &store);
    let server = Served::start(&store);
    let a = server.addr;
    assert_eq!(get(a, "/", &[]).status, 200);
    assert_eq!(get(a, "/planet.zarr/zarr.json", &[]).status, 200);
    edit_json(&store.join("zarr.json"), |v| {
        v["attributes"]["sphereclip"]["complete"] = false.into();
    });
    for path in ["/", "/planet.zarr/zarr.json"] {
        let r = get(a, path, &[]);
        assert_eq!(r.status, 503, "{path}");
        assert!(text(&r.body).contains("INCOMPLETE"), "{}", text(&r.body));
    }
    let png = dir.path().join("x.png");
    let o = run(&[
        "render",
        &server.url,
        "--camera",
        "0,0,9000000",
        "--size",
        "16x16",
        "--out",
        s(&png),
    ]);
    let line = one_line_failure(&o, "incomplete over HTTP");
    assert!(line.contains("INCOMPLETE"), "{line}");
    std::fs::remove_dir_all(&store).expect("rm");
    let r = get(a, "/planet.zarr/zarr.json", &[]);
    assert_eq!(r.status, 404);
    assert!(text(&r.body).contains("no store here"), "{}", text(&r.body));
}

#[test]
fn a_server_that_goes_away_mid_render_ends_the_render_with_what_it_has() {
    let dir = tempfile::tempdir().expect("tmp");
    let server = Served::start(&sample_planet());
    let mut c = bin();
    let go = pause_at(&mut c, "render-opened", dir.path());
    c.env("XDG_RUNTIME_DIR", xdg()).args([
        "render",
        &server.url,
        "--camera",
        "46.5,8,300000,0,-30,60",
        "--size",
        "64x36",
        "--out",
        s(&dir.path().join("gone.png")),
    ]);
    let child = std::thread::spawn(move || run_within(c, Duration::from_secs(120)));
    wait_until_paused("render-opened", dir.path());
    drop(server);
    std::fs::write(&go, b"").expect("go");
    let o = child.join().expect("render ran");
    let err = text(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("not answering") || err.contains("onnection"),
        "{err}"
    );
    assert!(
        !err.contains("corrupt"),
        "a network failure called damage: {err}"
    );
}

#[test]
fn a_loopback_load_is_answered_in_full_with_bounded_memory() {
    const CLIENTS: usize = 50;
    const REQUESTS: usize = 2000;
    let store = sample_planet();
    let server = Served::start(&store);
    let key = a_shard(&store);
    let bytes = std::sync::Arc::new(std::fs::read(store.join(&key)).expect("shard"));
    let url = format!("{}/{key}", server.url);
    let threads: Vec<_> = (0..CLIENTS)
        .map(|c| {
            let (url, bytes) = (url.clone(), bytes.clone());
            std::thread::spawn(move || {
                let agent: ureq::Agent = ureq::Agent::config_builder()
                    .timeout_global(Some(Duration::from_secs(60)))
                    .build()
                    .into();
                let n = bytes.len();
                for i in 0..REQUESTS {
                    let start = (c * 7919 + i * 104_729) % (n - 4096);
                    let len = 1 + (i * 31 + c) % 4096;
                    let mut r = agent
                        .get(&url)
                        .header("Range", format!("bytes={start}-{}", start + len - 1))
                        .call()
                        .expect("answered");
                    assert_eq!(r.status(), 206);
                    let body = r.body_mut().read_to_vec().expect("body");
                    assert_eq!(body, &bytes[start..start + len], "client {c} request {i}");
                }
            })
        })
        .collect();
    for t in threads {
        t.join().expect("a client failed");
    }
    let kb = server.peak_rss_kb();
    assert!(kb < 200_000, "the server peaked at {kb} kB");
}
