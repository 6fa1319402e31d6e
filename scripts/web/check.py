"""Runs the web check page in headless Chromium over the DevTools protocol: prints the page's
warnings and errors, waits for the app's verdict line (`web_check: PASS ...` or
`web_check: FAIL ...`), saves a screenshot of the page, and exits 0 only for a PASS on the
backend expected.

    python3 check.py URL BACKEND SCREENSHOT [SECONDS]

BACKEND is GPU or CPU (the backend the verdict must name); SECONDS bounds the wait (180)."""
import base64
import json
import socket
import subprocess
import sys
import time
import urllib.request

import websocket

url, backend, screenshot = sys.argv[1], sys.argv[2], sys.argv[3]
seconds = float(sys.argv[4]) if len(sys.argv) > 4 else 180.0
# A free port for the DevTools protocol, so that no other Chromium answers.
with socket.socket() as probe:
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
chrome = subprocess.Popen(
    [
        "chromium", "--headless=new", "--no-sandbox", "--enable-unsafe-webgpu", "--enable-unsafe-swiftshader",
        "--use-webgpu-adapter=swiftshader", "--use-angle=swiftshader", "--ignore-gpu-blocklist",
        "--window-size=1280,720", f"--remote-debugging-port={port}", "about:blank",
    ],
    stdout=subprocess.DEVNULL,
    stderr=subprocess.DEVNULL,
)
verdict = None
try:
    page = None
    for _ in range(150):
        try:
            targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json"))
            page = next(t for t in targets if t["type"] == "page")
            break
        except Exception:
            time.sleep(0.2)
    if page is None:
        sys.exit("web check: Chromium did not open its DevTools port")
    ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=2)
    ids = iter(range(1, 10**9))

    def send(method, **params):
        i = next(ids)
        ws.send(json.dumps({"id": i, "method": method, "params": params}))
        return i

    def reply(i):
        while True:
            msg = json.loads(ws.recv())
            if msg.get("id") == i:
                return msg.get("result", {})

    send("Runtime.enable")
    send("Page.enable")
    send("Page.navigate", url=url)
    start = time.time()
    while verdict is None and time.time() - start < seconds:
        try:
            msg = json.loads(ws.recv())
        except websocket.WebSocketTimeoutException:
            continue
        if msg.get("method") == "Runtime.consoleAPICalled":
            params = msg["params"]
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in params["args"])
            # Bevy's browser logger styles its lines: the first argument is the message, the
            # rest are CSS.
            first = str(params["args"][0].get("value", "")) if params["args"] else ""
            if "web_check: " in first:
                verdict = first[first.index("web_check: "):]
            elif params["type"] in ("warning", "error"):
                print(f"{time.time() - start:6.1f} s {params['type']}: {text[:400]}", flush=True)
        elif msg.get("method") == "Runtime.exceptionThrown":
            details = msg["params"]["exceptionDetails"]
            print("exception:", details.get("exception", {}).get("description", details.get("text"))[:400], flush=True)
    # Let the page show the verdict before the picture.
    time.sleep(0.5)
    shot = reply(send("Page.captureScreenshot", format="png"))
    if "data" in shot:
        with open(screenshot, "wb") as out:
            out.write(base64.b64decode(shot["data"]))
finally:
    chrome.kill()

if verdict is None:
    sys.exit(f"web check: no verdict within {seconds:.0f} s ({url}); screenshot in {screenshot}")
print(verdict)
if not verdict.startswith("web_check: PASS") or f"backend={backend} " not in verdict:
    sys.exit(f"web check: expected a PASS on the {backend} backend ({url}); screenshot in {screenshot}")
