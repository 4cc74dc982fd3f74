"""Headless Chromium (software WebGL) on a page served with three.js: shared by
tools/threejs_check.py and tools/probe_viewer_check.py.

`run_page(routes, path, timeout)` serves `routes` (a function from a URL path to a file path or
`(bytes, content type)`, or None for 404) and three.js from tools/.three at /three/ on a local
port, opens `path` in headless Chromium and returns the JSON object the page POSTs to /result
(with "error" set when it posted nothing within `timeout` seconds). `serve(routes, posted)`
starts that server alone (for a person's browser) and returns it.
"""

import http.server
import json
import os
import shutil
import subprocess
import tempfile
import threading

TOOLS = os.path.dirname(os.path.abspath(__file__))
THREE = os.path.join(TOOLS, ".three", "node_modules", "three")
KINDS = {".js": "text/javascript", ".json": "application/json", ".png": "image/png",
         ".html": "text/html", ".gltf": "model/gltf+json"}


def chromium():
    """The Chromium executable, or None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def available():
    """Whether Chromium and three.js (tools/.three) are here."""
    return chromium() is not None and os.path.isdir(THREE)


def serve(routes, posted):
    """A server of `routes` and /three/ on a free local port, in a thread; `posted(dict)` gets
    what a page POSTs."""

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            url = self.path.split("?")[0]
            if url.startswith("/three/"):
                found = os.path.join(THREE, url[len("/three/"):])
            else:
                found = routes(url)
            if isinstance(found, tuple):
                body, kind = found
            elif found is not None and os.path.isfile(found):
                with open(found, "rb") as f:
                    body = f.read()
                kind = KINDS.get(os.path.splitext(found)[1], "application/octet-stream")
            else:
                self.send_error(404)
                return
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def do_POST(self):
            length = int(self.headers.get("Content-Length", 0))
            body = json.loads(self.rfile.read(length))
            self.send_response(204)
            self.end_headers()
            posted(body)

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    return server


def run_page(routes, path, timeout=300):
    done = threading.Event()
    result = {}

    def posted(body):
        result.update(body)
        done.set()

    server = serve(routes, posted)
    url = f"http://127.0.0.1:{server.server_address[1]}{path}"
    profile = tempfile.mkdtemp(prefix="headless-three-")
    process = subprocess.Popen(
        [chromium(), "--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
         f"--user-data-dir={profile}", url],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        finished = done.wait(timeout=timeout)
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
        server.shutdown()
        shutil.rmtree(profile, ignore_errors=True)
    if not finished:
        result["error"] = f"Chromium posted no result within {timeout} s"
    return result
