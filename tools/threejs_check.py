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

import json
import os
import sys

import headless_three

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
    if not headless_three.available():
        print("threejs-check: chromium or tools/.three missing (tools/threejs-check installs "
              "three; apt-get install chromium)", file=sys.stderr)
        sys.exit(2)
    folder, name = os.path.split(baked)
    page = PAGE.replace("NAME", name).encode()

    def routes(path):
        if path == "/":
            return page, "text/html"
        if path == "/report.json":
            return report
        if path.startswith("/bake/"):
            return os.path.join(folder, path[len("/bake/"):])
        return None

    result = headless_three.run_page(routes, "/")
    result["file"] = baked
    print("THREEJS_CHECK " + json.dumps(result, sort_keys=True))
    if "error" in result or not result.get("compared") or result["max_levels"] > tolerance:
        sys.exit(1)


main()
