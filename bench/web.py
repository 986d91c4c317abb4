"""The web viewer in headless Chromium, driven over the DevTools protocol: for each view, the time
from asking for the page to its complete view (the wasm fetched and compiled, the store's tiles
fetched and made), the requests and bytes the page fetched, and then the steady frame time
(requestAnimationFrame intervals over 120 frames flying sideways from the complete view, D held:
a still view is not drawn again). One line of JSON a view.

With PAGE_URL `cesium:URL`, the page is bench/cesium/index.html (CesiumJS), which measures
itself: the same numbers from its `window.bench`.

With FLY=0 in the environment, only the complete view is measured (no frames flying: nothing
fetched after it).

Usage: python bench/web.py PAGE_URL WxH FLAGS NAME=CAMERA...   (FLAGS: Chromium's, space-separated)
"""
import json, os, subprocess, sys, tempfile, time, urllib.request

import websocket

page, size, flags = sys.argv[1], sys.argv[2], sys.argv[3].split()
w, h = (int(v) for v in size.split("x"))
profile = tempfile.mkdtemp()
chrome = subprocess.Popen(
    ["chromium", "--headless=new", "--no-sandbox", "--no-first-run", "--hide-scrollbars",
     "--remote-debugging-port=0", f"--user-data-dir={profile}", *flags, "about:blank"],
    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
try:
    port_file = os.path.join(profile, "DevToolsActivePort")
    for _ in range(600):
        if os.path.exists(port_file) and open(port_file).read().strip():
            break
        time.sleep(0.1)
    port = open(port_file).read().split()[0]
    targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
    ws = websocket.create_connection(
        next(t for t in targets if t["type"] == "page")["webSocketDebuggerUrl"], max_size=None)
    next_id = [0]

    def call(method, wait_event=None, **params):
        next_id[0] += 1
        ws.send(json.dumps({"id": next_id[0], "method": method, "params": params}))
        result = None
        while True:
            m = json.loads(ws.recv())
            if m.get("id") == next_id[0]:
                result = m.get("result")
                if wait_event is None:
                    return result
            elif wait_event is not None and m.get("method") == wait_event and result is not None:
                return result

    def js(expr):
        r = call("Runtime.evaluate", expression=expr, awaitPromise=True, returnByValue=True)
        return r["result"].get("value")

    call("Page.enable")
    call("Emulation.setDeviceMetricsOverride", width=w, height=h, deviceScaleFactor=1, mobile=False)
    for view in sys.argv[4:]:
        name, camera = view.split("=", 1)
        call("Page.navigate", "Page.loadEventFired", url="about:blank")
        if page.startswith("cesium:"):
            call("Page.navigate", "Page.loadEventFired", url=f"{page[7:]}#camera={camera}")
            print(json.dumps({"view": name, **js("window.bench")}), flush=True)
            continue
        t0 = time.monotonic()
        call("Page.navigate", url=f"{page}#camera={camera}&shading=lit&atmosphere=on")
        said = js("""new Promise((done) => { const look = () => {
            if (window.sphereclipError) done('error: ' + window.sphereclipError);
            else if (window.sphereclip && window.sphereclip.complete()) done('complete');
            else setTimeout(look, 20); }; look(); })""")
        complete_ms = (time.monotonic() - t0) * 1e3
        if said != "complete":
            print(json.dumps({"view": name, "error": said}), flush=True)
            continue
        status = json.loads(js("window.sphereclip.status()"))
        if os.environ.get("FLY") == "0":
            print(json.dumps({"view": name, "complete_ms": round(complete_ms),
                              "bytes": status["bytes"], "requests": status["requests"]}), flush=True)
            continue
        # a still, complete view is not drawn again: fly sideways (D held) while measuring
        key = dict(key="d", code="KeyD", windowsVirtualKeyCode=68)
        call("Input.dispatchKeyEvent", type="keyDown", **key)
        frames = js("""new Promise((done) => { const t = []; const tick = (now) => { t.push(now);
            if (t.length > 120) done(t.slice(1).map((v, i) => v - t[i])); else requestAnimationFrame(tick); };
            requestAnimationFrame(tick); })""")
        call("Input.dispatchKeyEvent", type="keyUp", **key)
        frames.sort()
        print(json.dumps({
            "view": name, "complete_ms": round(complete_ms), "bytes": status["bytes"],
            "requests": status["requests"], "frame_median_ms": round(frames[len(frames) // 2], 1),
            "frame_p95_ms": round(frames[int(len(frames) * 0.95)], 1), "adapter": status["adapter"],
        }), flush=True)
finally:
    chrome.kill()
