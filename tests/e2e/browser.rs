//! The web viewer in headless Chromium: `serve` on a loopback port, the page loaded with a view
//! in its URL fragment, its canvas read back through the page once the view is complete, and
//! compared with native `render` of the same camera and size: space, a pole, the antimeridian
//! and a ground view unlit (mean ≤ 2/255, ≤ 0.5 % of pixels off by more than 30/255), lit with
//! the atmosphere within the golden pictures' tolerance; on WebGPU and on the WebGL2 fallback. The browser is driven through the
//! DevTools protocol (a WebSocket); a failing page says why on the page and to the test.

use std::io::Read;
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use base64::Engine;
use serde_json::{Value, json};

use crate::serve::Served;
use crate::util::*;

/// Chromium's flags for a WebGPU canvas headless on a machine without a GPU: SwiftShader's
/// Vulkan under WebGPU (Dawn) and ANGLE.
const WEBGPU: &[&str] = &[
    "--enable-unsafe-webgpu",
    "--enable-features=Vulkan",
    "--use-vulkan=swiftshader",
    "--use-angle=vulkan",
];

/// Longest a page may take to complete a view.
const VIEW_LIMIT: Duration = Duration::from_secs(300);

/// Headless Chromium with one page, driven over the DevTools protocol; killed when dropped.
struct Chromium {
    child: Child,
    ws: tungstenite::WebSocket<TcpStream>,
    next: u64,
    _profile: tempfile::TempDir,
}

impl Chromium {
    fn start(flags: &[&str]) -> Self {
        let profile = tempfile::tempdir().expect("tmp");
        let child = Command::new("chromium")
            .args([
                "--headless=new",
                "--no-sandbox",
                "--no-first-run",
                "--no-default-browser-check",
                "--hide-scrollbars",
                "--remote-debugging-port=0",
            ])
            .arg(format!("--user-data-dir={}", profile.path().display()))
            // its own temporary folders (org.chromium.Chromium.*) go with the profile
            .env("TMPDIR", profile.path())
            .args(flags)
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromium runs (scripts/deps.sh installs it)");
        let active = profile.path().join("DevToolsActivePort");
        let start = Instant::now();
        let port = loop {
            if let Some(p) = std::fs::read_to_string(&active)
                .ok()
                .and_then(|t| t.lines().next().and_then(|l| l.trim().parse::<u16>().ok()))
            {
                break p;
            }
            assert!(
                start.elapsed() < Duration::from_secs(60),
                "chromium opened no DevTools port"
            );
            std::thread::sleep(Duration::from_millis(50));
        };
        let list: Value = serde_json::from_str(
            &ureq::get(&format!("http://127.0.0.1:{port}/json/list"))
                .call()
                .expect("the DevTools list")
                .body_mut()
                .read_to_string()
                .expect("text"),
        )
        .expect("JSON");
        let url = list
            .as_array()
            .and_then(|l| l.iter().find(|t| t["type"] == "page"))
            .and_then(|t| t["webSocketDebuggerUrl"].as_str())
            .expect("a page")
            .to_string();
        let stream = TcpStream::connect(("127.0.0.1", port)).expect("connects");
        stream
            .set_read_timeout(Some(VIEW_LIMIT + Duration::from_secs(60)))
            .expect("timeout");
        let (ws, _) = tungstenite::client(url.as_str(), stream).expect("a WebSocket");
        let mut c = Self {
            child,
            ws,
            next: 0,
            _profile: profile,
        };
        c.call("Runtime.enable", json!({}));
        c.call("Page.enable", json!({}));
        c
    }

    /// The next message from the browser.
    fn message(&mut self) -> Value {
        loop {
            let m = self.ws.read().expect("a message from chromium");
            if let Ok(t) = m.to_text()
                && !t.is_empty()
            {
                return serde_json::from_str(t).expect("JSON");
            }
        }
    }

    /// Calls `method`; its result (events meanwhile are skipped).
    fn call(&mut self, method: &str, params: Value) -> Value {
        self.next += 1;
        let id = self.next;
        let msg = json!({"id": id, "method": method, "params": params}).to_string();
        self.ws.send(msg.into()).expect("sends");
        loop {
            let v = self.message();
            if v["id"] == id {
                assert!(v.get("error").is_none(), "{method}: {v}");
                return v["result"].clone();
            }
        }
    }

    /// Loads `url` as a new document and waits for its load event.
    fn navigate(&mut self, url: &str) {
        self.call("Page.navigate", json!({"url": url}));
        while self.message()["method"] != "Page.loadEventFired" {}
    }

    /// Evaluates `expr` in the page (a promise waited for); its value.
    fn eval(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "awaitPromise": true, "returnByValue": true}),
        );
        assert!(
            r.get("exceptionDetails").is_none(),
            "{expr}: {}",
            r["exceptionDetails"]
        );
        r["result"]["value"].clone()
    }

    /// Loads `url` in a `w × h` viewport (device pixels) and waits for the viewer to complete
    /// its view; the canvas's picture and the viewer's status, or what the page said went wrong.
    fn view(&mut self, url: &str, (w, h): (u32, u32)) -> Result<(image::RgbaImage, Value), String> {
        self.call(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": w, "height": h, "deviceScaleFactor": 1, "mobile": false}),
        );
        // a new document each time (another fragment alone would not load the page again)
        self.navigate("about:blank");
        self.navigate(url);
        let limit = VIEW_LIMIT.as_millis();
        let said = self.eval(&format!(
            "new Promise((done) => {{ const t0 = performance.now(); const look = () => {{
                if (window.sphereclipError) done('error: ' + window.sphereclipError);
                else if (window.sphereclip && window.sphereclip.complete()) done('complete');
                else if (performance.now() - t0 > {limit}) done('timeout: ' + (window.sphereclip ? window.sphereclip.status() : 'never started'));
                else setTimeout(look, 50); }}; look(); }})"
        ));
        let said = said.as_str().unwrap_or_default().to_string();
        if said != "complete" {
            return Err(said);
        }
        let status = self.status();
        Ok((self.snapshot(), status))
    }

    /// The viewer's status, as JSON.
    fn status(&mut self) -> Value {
        serde_json::from_str(
            self.eval("window.sphereclip.status()")
                .as_str()
                .expect("text"),
        )
        .expect("status JSON")
    }

    /// The view drawn again and read back from the canvas.
    fn snapshot(&mut self) -> image::RgbaImage {
        let png = self.eval("window.sphereclip.snapshot()");
        let png = png
            .as_str()
            .and_then(|u| u.strip_prefix("data:image/png;base64,"))
            .expect("a PNG data URL");
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(png)
            .expect("base64");
        image::load_from_memory(&bytes).expect("PNG").to_rgba8()
    }
}

impl Drop for Chromium {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Native `render` of `store` from `camera` at `size` with `look` (e.g. `--shading none`).
fn native(
    store: &str,
    camera: &str,
    (w, h): (u32, u32),
    look: &[&str],
    out: &Path,
) -> image::RgbaImage {
    let mut c = bin();
    c.env("XDG_RUNTIME_DIR", xdg())
        .args(["render", store, &format!("--camera={camera}")])
        .args(["--size", &format!("{w}x{h}"), "--out", s(out)])
        .args(look);
    ok(&run_within(c, Duration::from_secs(300)));
    image::open(out).expect("png").to_rgba8()
}

/// Mean absolute difference per channel (0–255), the share of pixels with a channel off by more
/// than 30, and the 99th percentile of the channel differences.
fn difference(a: &image::RgbaImage, b: &image::RgbaImage) -> (f64, f64, u8) {
    assert_eq!(a.dimensions(), b.dimensions());
    let mut diffs = Vec::new();
    let mut far = 0usize;
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d: Vec<u8> = (0..3).map(|i| p[i].abs_diff(q[i])).collect();
        far += usize::from(d.iter().any(|&x| x > 30));
        diffs.extend(d);
    }
    let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / diffs.len() as f64;
    diffs.sort_unstable();
    let p99 = diffs[diffs.len() * 99 / 100];
    (mean, far as f64 / a.pixels().len() as f64, p99)
}

/// Where a failing comparison leaves its pictures.
fn keep(name: &str, page: &image::RgbaImage) -> PathBuf {
    let dir = std::env::temp_dir().join("sphereclip-browser");
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(format!("{name}.page.png"));
    let _ = page.save(&path);
    path
}

#[test]
fn the_web_viewer_draws_the_views_of_native_render_on_webgpu_and_webgl2() {
    let store = sample_planet();
    let server = Served::start(&store);
    let page = format!("http://{}/", server.addr);
    let dir = tempfile::tempdir().expect("tmp");
    // at most 200 rows: the height windows stay at 512 texels, a quarter of the fill at 270
    let size = (320, 180);
    // (name, camera, lit with air): space, a pole, the antimeridian, the ground
    let views = [
        ("space", "30,10,12000000", false),
        ("pole", "90,0,3000000,0,-90,50", false),
        ("antimeridian", "-17,179.9,20000,270,-15,60", false),
        ("ground", "46.5,8.0,300,30,-4,60", false),
        ("lit", "46.5,8,300000,0,-30,60", true),
    ];
    let look = |lit: bool| -> &'static [&'static str] {
        if lit {
            &["--shading", "lit", "--atmosphere", "on"]
        } else {
            &["--shading", "none"]
        }
    };
    let natives: Vec<image::RgbaImage> = views
        .iter()
        .map(|(name, camera, lit)| {
            native(
                s(&store),
                camera,
                size,
                look(*lit),
                &dir.path().join(format!("{name}.png")),
            )
        })
        .collect();
    let mut report = String::new();
    let mut failed = false;
    // WebGPU (SwiftShader's Vulkan under Dawn), and the WebGL2 fallback the page asks for
    for (backend, flags, query, adapter) in [
        ("WebGPU", WEBGPU, "", "BrowserWebGpu"),
        ("WebGL2", &[][..], "?gpu=webgl2", "(Gl,"),
    ] {
        let mut chromium = Chromium::start(flags);
        for ((name, camera, lit), want) in views.iter().zip(&natives) {
            let fragment = format!(
                "#camera={camera}&shading={}&atmosphere=on",
                if *lit { "lit" } else { "none" }
            );
            let (got, status) = chromium
                .view(&format!("{page}{query}{fragment}"), size)
                .unwrap_or_else(|e| panic!("{backend} {name}: the page did not complete: {e}"));
            assert_eq!(
                status["failed"], 0,
                "{backend} {name}: failed requests: {status}"
            );
            assert!(
                status["adapter"].as_str().unwrap_or("").contains(adapter),
                "{backend} {name}: not on {backend}: {status}"
            );
            let (mean, far, p99) = difference(&got, want);
            let good = if *lit {
                mean <= 3.0 && p99 <= 40
            } else {
                mean <= 2.0 && far <= 0.005
            };
            report += &format!(
                "{backend} {name}: mean {mean:.3}, {:.3} % off by > 30, p99 {p99}; levels {}..{}, {} requests, {} bytes{}\n",
                far * 100.0,
                status["level_lo"],
                status["level_hi"],
                status["requests"],
                status["bytes"],
                if good {
                    String::new()
                } else {
                    format!(
                        " — page: {}",
                        keep(&format!("{backend}-{name}"), &got).display()
                    )
                }
            );
            failed |= !good;
        }
    }
    eprint!("{report}");
    assert!(!failed, "the page differs from native render:\n{report}");
}

#[test]
fn a_page_whose_store_is_not_there_says_so() {
    let store = sample_planet();
    let server = Served::start(&store);
    let mut chromium = Chromium::start(WEBGPU);
    // a store name nothing answers, and a link the viewer cannot read
    let page = format!(
        "http://{}/?store=nothing.zarr#camera=30,10,1e7",
        server.addr
    );
    let said = chromium.view(&page, (160, 90)).expect_err("no store");
    assert!(
        said.contains("cannot read store") && said.contains("nothing.zarr"),
        "{said}"
    );
    let page = format!("http://{}/#camera=95,10,1e7", server.addr);
    let said = chromium.view(&page, (160, 90)).expect_err("a bad link");
    assert!(said.contains("camera"), "{said}");
    let shown = chromium.eval("document.getElementById('status').textContent");
    assert_eq!(shown.as_str(), Some(said.trim_start_matches("error: ")));
}

#[test]
fn the_page_and_its_files_are_served_with_their_types() {
    let store = sample_planet();
    let server = Served::start(&store);
    let base = format!("http://{}", server.addr);
    let mut r = ureq::get(&format!("{base}/")).call().expect("the page");
    let page = r.body_mut().read_to_string().expect("text");
    assert!(
        page.contains(r#"<meta name="sphereclip-store" content="planet.zarr">"#),
        "{page}"
    );
    let wasm = ureq::get(&format!("{base}/sc_view_web_bg.wasm"))
        .header("Accept-Encoding", "identity")
        .call()
        .expect("the wasm");
    assert_eq!(wasm.headers()["content-type"], "application/wasm");
    let mut head = [0u8; 4];
    wasm.into_body()
        .into_reader()
        .read_exact(&mut head)
        .expect("bytes");
    assert_eq!(&head, b"\0asm");
    let js = ureq::get(&format!("{base}/main.js"))
        .call()
        .expect("main.js");
    assert!(
        js.headers()["content-type"]
            .to_str()
            .unwrap_or("")
            .starts_with("text/javascript")
    );
}

/// A plain static host (Python's, which ignores Range and sends whole files) serving what
/// `sphereclip web --out` wrote beside a copy of the store; stopped when dropped.
struct StaticHost {
    child: Child,
    port: u16,
}

impl StaticHost {
    fn start(dir: &Path) -> Self {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let child = Command::new("python3")
            .args([
                "-m",
                "http.server",
                "--bind",
                "127.0.0.1",
                &port.to_string(),
            ])
            .current_dir(dir)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("python3 runs");
        let start = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(start.elapsed() < Duration::from_secs(30), "no static host");
            std::thread::sleep(Duration::from_millis(50));
        }
        Self { child, port }
    }
}

impl Drop for StaticHost {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Copies the store folder `from` to `to` as a user publishing it would: without the lock and
/// `.sphereclip/`.
fn publish(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for e in std::fs::read_dir(from).expect("store") {
        let e = e.expect("entry");
        let name = e.file_name();
        if name.to_string_lossy().starts_with('.') {
            continue;
        }
        if e.file_type().expect("type").is_dir() {
            publish(&e.path(), &to.join(&name));
        } else {
            std::fs::copy(e.path(), to.join(&name)).expect("copy");
        }
    }
}

#[test]
fn web_writes_a_site_that_a_static_host_serves_with_the_store() {
    let store = sample_planet();
    let site = tempfile::tempdir().expect("tmp");
    let out = site.path().join("site");
    ok(&run(&["web", "--out", s(&out)]));
    let page = std::fs::read_to_string(out.join("index.html")).expect("index.html");
    assert!(page.contains(r#"content="planet.zarr""#), "{page}");
    for f in [
        "main.js",
        "worker.js",
        "sc_view_web.js",
        "sc_view_web_bg.wasm",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // written again over itself: the same files
    ok(&run(&["web", "--out", s(&out), "--store", "planet.zarr"]));
    // a file, or a symlink, where the folder or a file should be: refused, nothing written
    let file = site.path().join("a-file");
    std::fs::write(&file, "mine").expect("write");
    one_line_failure(&run(&["web", "--out", s(&file)]), "a file as --out");
    assert_eq!(std::fs::read_to_string(&file).expect("read"), "mine");
    let other = site.path().join("other");
    std::fs::create_dir(&other).expect("mkdir");
    std::os::unix::fs::symlink(&file, other.join("main.js")).expect("symlink");
    one_line_failure(&run(&["web", "--out", s(&other)]), "a symlink in --out");
    assert_eq!(std::fs::read_to_string(&file).expect("read"), "mine");
    // the site and the store on a host that ignores Range
    publish(&store, &out.join("planet.zarr"));
    let host = StaticHost::start(&out);
    let mut chromium = Chromium::start(WEBGPU);
    let (img, status) = chromium
        .view(
            &format!(
                "http://127.0.0.1:{}/#camera=30,10,12000000&shading=none",
                host.port
            ),
            (160, 90),
        )
        .unwrap_or_else(|e| panic!("the static site did not complete its view: {e}"));
    assert_eq!(status["failed"], 0, "{status}");
    let want = native(
        s(&store),
        "30,10,12000000",
        (160, 90),
        &["--shading", "none"],
        &site.path().join("native.png"),
    );
    let (mean, far, _) = difference(&img, &want);
    assert!(mean <= 2.0 && far <= 0.005, "mean {mean}, {far} off");
}

#[test]
fn a_server_that_goes_away_is_counted_and_shown_and_the_page_keeps_drawing() {
    let store = sample_planet();
    let server = Served::start(&store);
    let page = format!("http://{}/#camera=30,10,12000000&shading=none", server.addr);
    let mut chromium = Chromium::start(WEBGPU);
    let (_, before) = chromium.view(&page, (320, 180)).expect("the first view");
    assert_eq!(before["failed"], 0, "{before}");
    drop(server);
    // zoom in (the wheel on the canvas): finer levels, whose tiles can no longer be fetched
    for _ in 0..8 {
        chromium.call(
            "Input.dispatchMouseEvent",
            json!({"type": "mouseWheel", "x": 160, "y": 90, "deltaX": 0, "deltaY": -400}),
        );
    }
    let said = chromium.eval(
        "new Promise((done) => { const t0 = performance.now(); const look = () => {
            const s = JSON.parse(window.sphereclip.status());
            if (s.failed > 0 && window.sphereclip.complete()) done(s);
            else if (performance.now() - t0 > 120000) done({timeout: s});
            else setTimeout(look, 50); }; look(); })",
    );
    assert!(
        said.get("timeout").is_none(),
        "the page did not settle: {said}"
    );
    assert!(
        said["level_wanted"].as_u64() > before["level_wanted"].as_u64(),
        "the wheel did not zoom: {said}"
    );
    // shown on the page, and the page still draws when the view moves
    let line = chromium.eval("document.getElementById('status').textContent");
    assert!(line.as_str().unwrap_or("").contains("FAILED"), "{line}");
    let frames = |c: &mut Chromium| c.status()["frames"].as_u64().expect("frames");
    let n = frames(&mut chromium);
    chromium.call(
        "Input.dispatchMouseEvent",
        json!({"type": "mouseWheel", "x": 160, "y": 90, "deltaX": 0, "deltaY": 400}),
    );
    chromium.eval("new Promise((done) => setTimeout(done, 1000))");
    assert!(frames(&mut chromium) > n, "the page stopped drawing");
    // the address holds the new view
    let link = chromium.eval("location.hash");
    assert!(
        link.as_str().unwrap_or("").starts_with("#camera=")
            && !link.as_str().unwrap_or("").contains("12000000"),
        "{link}"
    );
}

/// A server in front of `serve` that answers the page, its files and the store's metadata, and
/// takes every request for a shard (a `/c/` key) without ever answering it: a server that hangs.
/// Its listener and the connections it holds close when it is dropped.
struct Silent {
    addr: std::net::SocketAddr,
    held: std::sync::Arc<std::sync::Mutex<Vec<TcpStream>>>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
}

impl Silent {
    fn start(upstream: std::net::SocketAddr) -> Self {
        use std::io::Write;
        use std::sync::atomic::{AtomicBool, Ordering};
        use std::sync::{Arc, Mutex};
        let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("binds");
        let addr = listener.local_addr().expect("addr");
        let held: Arc<Mutex<Vec<TcpStream>>> = Arc::default();
        let stop = Arc::new(AtomicBool::new(false));
        let (h, st) = (held.clone(), stop.clone());
        std::thread::spawn(move || {
            for conn in listener.incoming() {
                if st.load(Ordering::SeqCst) {
                    return;
                }
                let Ok(mut conn) = conn else { continue };
                let h = h.clone();
                std::thread::spawn(move || {
                    // one request per connection: its head, up to the empty line
                    let mut head = Vec::new();
                    let mut b = [0u8; 1];
                    while !head.ends_with(b"\r\n\r\n") && head.len() < 65536 {
                        if conn.read(&mut b).unwrap_or(0) == 0 {
                            return;
                        }
                        head.push(b[0]);
                    }
                    let head = String::from_utf8_lossy(&head).into_owned();
                    let path = head.split(' ').nth(1).unwrap_or("");
                    if path.contains("/c/") {
                        h.lock().expect("lock").push(conn);
                        return;
                    }
                    let mut lines: Vec<&str> = head
                        .trim_end()
                        .lines()
                        .filter(|l| !l.to_ascii_lowercase().starts_with("connection:"))
                        .collect();
                    lines.push("Connection: close");
                    let Ok(mut up) = TcpStream::connect(upstream) else {
                        return;
                    };
                    let mut answer = Vec::new();
                    if up
                        .write_all(format!("{}\r\n\r\n", lines.join("\r\n")).as_bytes())
                        .is_ok()
                        && up.read_to_end(&mut answer).is_ok()
                    {
                        let _ = conn.write_all(&answer);
                    }
                });
            }
        });
        Self { addr, held, stop }
    }

    /// Shard requests taken and never answered so far.
    fn hanging(&self) -> usize {
        self.held.lock().expect("lock").len()
    }
}

impl Drop for Silent {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::SeqCst);
        // wakes the listener, which then stops
        let _ = TcpStream::connect(self.addr);
        self.held.lock().expect("lock").clear();
    }
}

#[test]
fn a_server_that_never_answers_slows_the_view_not_the_page() {
    let store = sample_planet();
    let server = Served::start(&store);
    let silent = Silent::start(server.addr);
    let mut chromium = Chromium::start(WEBGPU);
    chromium.call(
        "Emulation.setDeviceMetricsOverride",
        json!({"width": 160, "height": 90, "deviceScaleFactor": 1, "mobile": false}),
    );
    // each request given up after 2 s
    chromium.navigate(&format!(
        "http://{}/?timeout=2#camera=30,10,12000000&shading=none",
        silent.addr
    ));
    let opened = chromium.eval(
        "new Promise((done) => { const t0 = performance.now(); const look = () => {
            if (window.sphereclip || window.sphereclipError) done(window.sphereclipError ?? 'open');
            else if (performance.now() - t0 > 60000) done('never opened');
            else setTimeout(look, 20); }; look(); })",
    );
    assert_eq!(opened, "open", "the store's metadata is answered");
    // while the shards' requests hang, the page draws frames and answers at once
    let start = Instant::now();
    while silent.hanging() == 0 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "no shard asked for"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    // animation frames go on (none would while the page's thread waited on the network)
    let frames = chromium.eval(
        "new Promise((done) => { let n = 0; const t0 = performance.now(); const tick = () => {
            n += 1; if (n < 5 && performance.now() - t0 < 30000) requestAnimationFrame(tick);
            else done(n); }; requestAnimationFrame(tick); })",
    );
    assert!(silent.hanging() > 0);
    assert_eq!(frames, 5, "animation frames while the server hangs");
    // the silent requests are given up, counted and shown
    let said = chromium.eval(
        "new Promise((done) => { const t0 = performance.now(); const look = () => {
            const s = JSON.parse(window.sphereclip.status());
            const line = document.getElementById('status').textContent;
            if (s.failed > 0 && s.errors > 0 && line.includes('FAILED')) done(s);
            else if (performance.now() - t0 > 120000) done({timeout: s, line});
            else setTimeout(look, 50); }; look(); })",
    );
    assert!(said.get("timeout").is_none(), "no failure shown: {said}");
    let why = said["last_error"].as_str().unwrap_or("");
    assert!(
        why.contains("/c/") && why.contains("no answer (none in 2 s)"),
        "{said}"
    );
}

#[test]
fn the_panel_edits_the_view_by_the_windows_rules() {
    let store = sample_planet();
    let server = Served::start(&store);
    let dir = tempfile::tempdir().expect("tmp");
    let mut chromium = Chromium::start(WEBGPU);
    let size = (160, 90);
    let camera = "46.5,8,300000,0,-30,60";
    let (lit, _) = chromium
        .view(&format!("http://{}/#camera={camera}", server.addr), size)
        .unwrap_or_else(|e| panic!("the lit view: {e}"));
    let settle = |c: &mut Chromium| {
        let said = c.eval(
            "new Promise((done) => { const t0 = performance.now(); const look = () => {
                if (window.sphereclip.complete()) done('complete');
                else if (performance.now() - t0 > 120000) done(window.sphereclip.status());
                else setTimeout(look, 50); }; look(); })",
        );
        assert_eq!(said, "complete");
        c.snapshot()
    };
    // the panel's "lit" switched off, as a user clicks it: the colour as stored, and no air
    let clicked = chromium.eval(
        "(() => { const l = [...document.querySelectorAll('#panel label')]
            .find((l) => l.textContent.startsWith(' lit'));
          l.querySelector('input').click(); return l.querySelector('input').checked; })()",
    );
    assert_eq!(clicked, false);
    let unlit = settle(&mut chromium);
    let want = native(
        s(&store),
        camera,
        size,
        &["--shading", "none"],
        &dir.path().join("none.png"),
    );
    let (mean, far, _) = difference(&unlit, &want);
    assert!(mean <= 2.0 && far <= 0.005, "unlit: mean {mean}, {far} off");
    assert!(
        difference(&unlit, &lit).0 > 2.0,
        "the switch changed nothing"
    );
    let panel: Value = serde_json::from_str(
        chromium
            .eval("window.sphereclip.panel()")
            .as_str()
            .expect("text"),
    )
    .expect("JSON");
    assert_eq!(
        panel["atmosphere"], false,
        "air only over a lit planet: {panel}"
    );
    let link = chromium.eval("location.hash");
    assert!(
        link.as_str().unwrap_or("").contains("shading=none"),
        "{link}"
    );
    // the colour filter's brightness slider: tiles made again by the workers, brighter
    chromium.eval(
        "(() => { const r = [...document.querySelectorAll('#panel label')]
            .find((l) => l.textContent.includes('brightness')).querySelector('input');
          r.value = 650; r.dispatchEvent(new Event('input')); })()",
    );
    let bright = settle(&mut chromium);
    let sum = |img: &image::RgbaImage| {
        img.pixels()
            .map(|p| f64::from(p.0[0]) + f64::from(p.0[1]) + f64::from(p.0[2]))
            .sum::<f64>()
            / (3.0 * f64::from(img.width() * img.height()))
    };
    assert!(
        sum(&bright) > sum(&unlit) + 40.0,
        "brightness 0.3: {} then {}",
        sum(&unlit),
        sum(&bright)
    );
}

/// The ground the page grabs and zooms towards under canvas point `at` (the sphere raised by
/// the ground under its camera, as its status reports them), planet frame.
fn page_ground(status: &Value, size: (u32, u32), at: (f64, f64)) -> glam::DVec3 {
    use sc_view_space::camera::{ViewFrame, hit_sphere};
    let c = page_camera(status);
    let r = sc_core::EARTH_RADIUS_M + status["ground"].as_f64().expect("ground");
    let f = ViewFrame::new(&c, r);
    let d = f.ray(c.fov, size, at);
    let t = hit_sphere(f.eye, d, r).expect("the pointer is on the ground");
    f.eye + d * t
}

/// The page's camera, from its status.
fn page_camera(status: &Value) -> sc_view_space::camera::Camera {
    let v = |k: &str| {
        status[k]
            .as_f64()
            .unwrap_or_else(|| panic!("{k} in {status}"))
    };
    sc_view_space::camera::Camera {
        lat_deg: v("lat"),
        lon_deg: v("lon"),
        alt: v("alt"),
        heading: v("heading"),
        pitch: v("pitch"),
        fov: v("fov"),
    }
}

/// Pixels between where the page's camera in `status` (over the ground `ground` it zoomed with)
/// shows `p` and `at`.
fn page_off(status: &Value, ground: f64, size: (u32, u32), p: glam::DVec3, at: (f64, f64)) -> f64 {
    let c = page_camera(status);
    let f = sc_view_space::camera::ViewFrame::new(&c, sc_core::EARTH_RADIUS_M + ground);
    let (x, y) = f.project(c.fov, size, p).expect("in front");
    (x - at.0).hypot(y - at.1)
}

#[test]
fn the_pages_wheel_and_drag_keep_the_ground_under_the_pointer() {
    let store = sample_planet();
    let server = Served::start(&store);
    let page = format!("http://{}/#camera=30,10,8000000&shading=none", server.addr);
    let mut chromium = Chromium::start(WEBGPU);
    let size = (320, 180);
    chromium.view(&page, size).expect("the view");
    let panel = |c: &mut Chromium| -> Value {
        serde_json::from_str(c.eval("window.sphereclip.panel()").as_str().expect("text"))
            .expect("JSON")
    };
    let before = panel(&mut chromium);
    // the pixel under the pointer at CSS (200, 70): its centre
    let at = (200.5, 70.5);
    let p = page_ground(&before, size, at);
    let ground = before["ground"].as_f64().expect("ground");
    let moved = |c: &mut Chromium, from: &Value| -> Value {
        let alt = from["alt"].clone();
        let lat = from["lat"].clone();
        let v = c.eval(&format!(
            "new Promise((done) => {{ const t0 = performance.now(); const look = () => {{
                const s = JSON.parse(window.sphereclip.panel());
                if (s.alt !== {alt} || s.lat !== {lat}) done(s);
                else if (performance.now() - t0 > 30000) done({{timeout: s}});
                else setTimeout(look, 20); }}; look(); }})"
        ));
        assert!(v.get("timeout").is_none(), "the camera did not move: {v}");
        v
    };
    // three notches in, towards the point under the pointer
    chromium.call(
        "Input.dispatchMouseEvent",
        json!({"type": "mouseWheel", "x": 200, "y": 70, "deltaX": 0, "deltaY": -300}),
    );
    let after = moved(&mut chromium, &before);
    // and the page draws the new view
    let drawn = chromium.eval(&format!(
        "new Promise((done) => {{ const t0 = performance.now(); const look = () => {{
            const s = JSON.parse(window.sphereclip.status());
            if (s.frames > {}) done(true);
            else if (performance.now() - t0 > 30000) done(false);
            else setTimeout(look, 20); }}; look(); }})",
        after["frames"]
    ));
    assert_eq!(drawn, json!(true), "the page did not draw the zoomed view");
    let off = page_off(&after, ground, size, p, at);
    assert!(
        after["alt"].as_f64() < before["alt"].as_f64() && off < 0.5,
        "the wheel left the point {off} px from the pointer: {after}"
    );
    // grab the ground there and drag it 40 px left and 30 px down
    let ground = after["ground"].as_f64().expect("ground");
    let p = page_ground(&after, size, at);
    for (kind, x, y, buttons) in [
        ("mousePressed", 200, 70, 1),
        ("mouseMoved", 180, 85, 1),
        ("mouseMoved", 160, 100, 1),
    ] {
        chromium.call(
            "Input.dispatchMouseEvent",
            json!({"type": kind, "x": x, "y": y, "button": "left", "buttons": buttons, "clickCount": 1}),
        );
    }
    let dragged = moved(&mut chromium, &after);
    // the last move may land a frame later: wait for the page to settle
    chromium.eval("new Promise((done) => setTimeout(done, 500))");
    let dragged = {
        let s = panel(&mut chromium);
        if s["lat"] == dragged["lat"] {
            dragged
        } else {
            s
        }
    };
    chromium.call(
        "Input.dispatchMouseEvent",
        json!({"type": "mouseReleased", "x": 160, "y": 100, "button": "left", "buttons": 0, "clickCount": 1}),
    );
    let off = page_off(&dragged, ground, size, p, (160.5, 100.5));
    assert!(
        off < 0.5,
        "the drag left the grabbed point {off} px from the pointer: {dragged}"
    );
}
