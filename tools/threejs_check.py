"""three.js in headless Chromium, compared with the bake's numbers: run by tools/threejs-check.

    python3 tools/threejs_check.py BAKED.gltf REPORT.json [--tolerance LEVELS]

BAKED is a bake written with --target baked-texture (and --shading flat, so that an element's
centre shows the element's own H). A local HTTP server serves three.js (tools/.three), BAKED's
folder and REPORT; headless Chromium (software WebGL, SwiftShader) loads BAKED with three.js'
stock GLTFLoader (KHR_materials_unlit → MeshBasicMaterial, the base-colour texture on its
TEXCOORD_1 channel, sRGB) and renders it with no set-up beyond what the glTF says: no tone
mapping, sRGB output. For every element of REPORT an orthographic camera 1 mm in front of its
centre, looking at it along its normal, renders one pixel (a frustum a quarter texel wide, so
the texture is magnified: level 0), read back as 8 bits, and compared with

    expected = 8-bit sRGB of clamp((ρ × H + e) × exposure, 0, 1)

from REPORT (ρ, H, e per element; the exposure from BAKED's extras). Prints `THREEJS_CHECK {...}`
(JSON: elements compared, within 2 levels, largest and mean difference in 8-bit levels) and
exits 1 when the largest exceeds --tolerance (default 2 levels), 2 when a client is missing.
"""

import http.server
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading

TOOLS = os.path.dirname(os.path.abspath(__file__))
THREE = os.path.join(TOOLS, ".three", "node_modules", "three")

PAGE = """<!doctype html>
<html><body>
<script type="importmap">
{"imports": {"three": "/three/build/three.module.js", "three/addons/": "/three/examples/jsm/"}}
</script>
<script type="module">
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
const post = (result) => fetch("/result", { method: "POST", body: JSON.stringify(result) });
const level = (v) => {
  v = Math.min(Math.max(v, 0), 1);
  return 255 * (v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055);
};
try {
  const report = await (await fetch("/report.json")).json();
  const doc = await (await fetch("/bake/NAME")).json();
  const extras = doc.extras.bake_baked_texture;
  const gltf = await new GLTFLoader().loadAsync("/bake/NAME");
  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(1, 1, false);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  const scene = gltf.scene;
  scene.updateMatrixWorld(true);
  const s = extras.texel_size / 8;
  const camera = new THREE.OrthographicCamera(-s, s, s, -s, 1e-5, 100);
  const gl = renderer.getContext();
  const pixel = new Uint8Array(4);
  const diffs = [];
  const unlit = [];
  scene.traverse((o) => { if (o.isMesh) unlit.push(o.material.type); });
  for (const e of report.elements) {
    const c = new THREE.Vector3(...e.centroid);
    const n = new THREE.Vector3(...e.normal);
    camera.position.copy(c).addScaledVector(n, 1e-3);
    camera.up.set(...(Math.abs(n.y) < 0.9 ? [0, 1, 0] : [1, 0, 0]));
    camera.lookAt(c);
    camera.updateMatrixWorld();
    renderer.render(scene, camera);
    gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
    let worst = 0;
    for (let k = 0; k < 3; k++) {
      const want = level((e.rho[k] * e.h[k] + e.e[k]) * extras.exposure);
      worst = Math.max(worst, Math.abs(pixel[k] - want));
    }
    diffs.push(worst);
  }
  const n = diffs.length;
  await post({
    three: THREE.REVISION,
    materials: [...new Set(unlit)],
    compared: n,
    within_2: diffs.filter((d) => d <= 2).length,
    max_levels: n ? Math.round(1000 * Math.max(...diffs)) / 1000 : null,
    mean_levels: n ? Math.round(1000 * diffs.reduce((a, b) => a + b, 0) / n) / 1000 : null,
  });
} catch (err) {
  await post({ error: String(err && err.stack || err) });
}
</script>
</body></html>
"""


def chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    return None


def main():
    argv = sys.argv[1:]
    tolerance = 2.0
    if "--tolerance" in argv:
        i = argv.index("--tolerance")
        tolerance = float(argv[i + 1])
        del argv[i:i + 2]
    if len(argv) != 2:
        raise SystemExit(__doc__)
    baked, report = (os.path.abspath(a) for a in argv)
    browser = chromium()
    if browser is None or not os.path.isdir(THREE):
        print("threejs-check: chromium or tools/.three missing (tools/threejs-check installs "
              "three; apt-get install chromium)", file=sys.stderr)
        sys.exit(2)
    folder, name = os.path.split(baked)
    page = PAGE.replace("NAME", name).encode()
    done = threading.Event()
    result = {}

    class Handler(http.server.BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            path = self.path.split("?")[0]
            if path == "/":
                body, kind = page, "text/html"
            else:
                if path == "/report.json":
                    file = report
                elif path.startswith("/three/"):
                    file = os.path.join(THREE, path[len("/three/"):])
                elif path.startswith("/bake/"):
                    file = os.path.join(folder, path[len("/bake/"):])
                else:
                    file = None
                if file is None or not os.path.isfile(file):
                    self.send_error(404)
                    return
                with open(file, "rb") as f:
                    body = f.read()
                kind = {".js": "text/javascript", ".json": "application/json",
                        ".png": "image/png", ".gltf": "model/gltf+json"}.get(
                    os.path.splitext(file)[1], "application/octet-stream")
            self.send_response(200)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def do_POST(self):
            length = int(self.headers.get("Content-Length", 0))
            result.update(json.loads(self.rfile.read(length)))
            self.send_response(204)
            self.end_headers()
            done.set()

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}/"
    profile = tempfile.mkdtemp(prefix="threejs-check-")
    process = subprocess.Popen(
        [browser, "--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
         f"--user-data-dir={profile}", url],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        finished = done.wait(timeout=300)
    finally:
        process.terminate()
        try:
            process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            process.kill()
        server.shutdown()
        shutil.rmtree(profile, ignore_errors=True)
    if not finished:
        result["error"] = "Chromium posted no result within 300 s"
    result["file"] = baked
    print("THREEJS_CHECK " + json.dumps(result, sort_keys=True))
    if "error" in result or not result.get("compared") or result["max_levels"] > tolerance:
        sys.exit(1)


main()
