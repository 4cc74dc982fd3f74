// The probe viewer (tools/probe-viewer.html): a sphere lit only by a bake's light probes
// (the `BAKE_irradiance_probes` scene extension, docs/probes.md), interpolated here, in the
// page, rather than by three.js' LightProbeGrid: moved probes and validity flags do not fit
// a regular grid. See docs/probes.md, "Viewing probes".
//
//   probe-viewer.html?bake=URL&at=X,Y,Z[&from=X,Y,Z][&rho=R,G,B][&radius=R][&size=N][&room=0][&post=1]
//
// `post=1` renders once and POSTs the numbers (and the canvas as a PNG data URL) to /result,
// for tools/probe-viewer-check; otherwise the page stays interactive: drag to orbit, the
// arrow keys move the sphere in x and z, PageUp/PageDown in y.
import * as THREE from "three";
import { GLTFLoader } from "three/addons/loaders/GLTFLoader.js";
import { OrbitControls } from "three/addons/controls/OrbitControls.js";

export const EXTENSION = "BAKE_irradiance_probes";

/// The probes of the loaded glTF's scene: the extension's grid and its accessors' arrays.
export async function readProbes(gltf) {
  const parser = gltf.parser;
  const json = parser.json;
  const scene = (json.scenes || [])[json.scene ?? 0] || {};
  const ext = (scene.extensions || {})[EXTENSION];
  if (!ext) throw new Error(`the bake has no ${EXTENSION} extension (bake with --probes)`);
  const array = async (key) =>
    ext[key] === undefined ? new Float32Array(0) : (await parser.getDependency("accessor", ext[key])).array;
  return {
    origin: ext.grid.origin,
    spacing: ext.grid.spacing,
    counts: ext.grid.counts,
    count: ext.count,
    exposure: ext.exposure ?? 1,
    positions: await array("positions"),
    coefficients: await array("coefficients"),
    valid: await array("valid"),
  };
}

/// Whether something in `occluders` (meshes, raycast on both sides) crosses the segment
/// from `a` to `b`.
function blocked(raycaster, occluders, a, b) {
  const d = new THREE.Vector3().subVectors(b, a);
  const length = d.length();
  if (length === 0) return false;
  raycaster.set(a, d.divideScalar(length));
  raycaster.near = 0;
  raycaster.far = length * (1 - 1e-6);
  return raycaster.intersectObjects(occluders, false).length > 0;
}

/// The probes that light `point` and their weights: the trilinear weights of the eight grid
/// probes of the cell containing `point` (clamped to the grid), less the invalid ones and
/// those whose segment to `point` crosses an occluder (no light through walls); the weights
/// of the others renormalised to sum 1. Probes after the grid's (marked in the input) are
/// not interpolated.
export function probeWeights(probes, point, occluders) {
  const raycaster = new THREE.Raycaster();
  const corner = [];
  const fraction = [];
  for (let a = 0; a < 3; a++) {
    const n = probes.counts[a];
    const t = (point.getComponent(a) - probes.origin[a]) / probes.spacing;
    const i = Math.min(Math.max(Math.floor(t), 0), Math.max(n - 2, 0));
    corner.push(i);
    fraction.push(n < 2 ? 0 : Math.min(Math.max(t - i, 0), 1));
  }
  const used = [];
  const dropped = { invalid: [], blocked: [] };
  for (let c = 0; c < 8; c++) {
    const ijk = [c & 1, (c >> 1) & 1, (c >> 2) & 1];
    let weight = 1;
    for (let a = 0; a < 3; a++) weight *= ijk[a] ? fraction[a] : 1 - fraction[a];
    if (weight === 0) continue;
    const [i, j, k] = ijk.map((o, a) => corner[a] + o);
    if (i >= probes.counts[0] || j >= probes.counts[1] || k >= probes.counts[2]) continue;
    const index = i + probes.counts[0] * (j + probes.counts[1] * k);
    const at = new THREE.Vector3().fromArray(probes.positions, 3 * index);
    if (!probes.valid[index]) {
      dropped.invalid.push(index);
    } else if (blocked(raycaster, occluders, point, at)) {
      dropped.blocked.push(index);
    } else {
      used.push({ index, weight });
    }
  }
  const total = used.reduce((s, u) => s + u.weight, 0);
  for (const u of used) u.weight /= total;
  return { used, dropped };
}

/// The weighted sum of the used probes' coefficients times `scale`, as three.js
/// `SphericalHarmonics3`.
export function blend(probes, used, scale) {
  const sh = new THREE.SphericalHarmonics3();
  for (const { index, weight } of used) {
    for (let k = 0; k < 9; k++) {
      const base = 27 * index + 3 * k;
      const c = probes.coefficients;
      sh.coefficients[k].x += scale * weight * c[base];
      sh.coefficients[k].y += scale * weight * c[base + 1];
      sh.coefficients[k].z += scale * weight * c[base + 2];
    }
  }
  return sh;
}

/// Meshes with the same geometry and world matrices as `root`'s, raycast on both sides.
function occludersOf(root) {
  const material = new THREE.MeshBasicMaterial({ side: THREE.DoubleSide });
  const out = [];
  root.updateMatrixWorld(true);
  root.traverse((o) => {
    if (!o.isMesh) return;
    const m = new THREE.Mesh(o.geometry, material);
    m.matrixAutoUpdate = false;
    m.matrixWorld.copy(o.matrixWorld);
    out.push(m);
  });
  return out;
}

const vector = (text) => (text ? text.split(",").map(Number) : null);

/// The page: loads the bake, places the sphere, lights it, renders; posts with `post=1`.
export async function main() {
  const params = new URLSearchParams(location.search);
  const post = params.get("post") === "1";
  const size = Number(params.get("size") || (post ? 129 : 512));
  const radius = Number(params.get("radius") || 0.25);
  const rho = vector(params.get("rho")) || [1, 1, 1];
  const gltf = await new GLTFLoader().loadAsync(params.get("bake"));
  const probes = await readProbes(gltf);
  const occluders = occludersOf(gltf.scene);

  const renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
  renderer.setPixelRatio(1);
  renderer.setSize(size, size, false);
  renderer.toneMapping = THREE.NoToneMapping;
  renderer.outputColorSpace = THREE.SRGBColorSpace;
  document.body.appendChild(renderer.domElement);

  const scene = new THREE.Scene();
  if (params.get("room") !== "0") scene.add(gltf.scene); // unlit (KHR_materials_unlit): no probe light on it
  const material = new THREE.MeshStandardMaterial({ roughness: 1, metalness: 0 });
  material.color.setRGB(rho[0], rho[1], rho[2], THREE.LinearSRGBColorSpace);
  const sphere = new THREE.Mesh(new THREE.SphereGeometry(radius, 256, 128), material);
  scene.add(sphere);
  const light = new THREE.LightProbe();
  scene.add(light);

  const at = new THREE.Vector3(...(vector(params.get("at")) || [0, 0, 0]));
  const middle = new THREE.Vector3(...probes.origin).addScaledVector(
    new THREE.Vector3(...probes.counts).subScalar(1), probes.spacing / 2);
  const from = vector(params.get("from"));
  const camera = new THREE.PerspectiveCamera(40, 1, radius / 100, 1000);
  if (from) {
    camera.position.set(...from);
  } else {
    const toward = middle.clone().sub(at);
    if (toward.lengthSq() < 1e-12) toward.set(0, 0, 1);
    camera.position.copy(at).addScaledVector(toward.normalize(), 5 * radius);
  }
  camera.lookAt(at);

  // The coefficients are those of the radiance b/π, unscaled: × exposure to match the file's
  // COLOR_0, and × π so that the sphere shows ρ E(n) × exposure, the radiosity it would have,
  // as the bake's surfaces show their radiosity b × exposure (three.js lights a standard
  // material to ρ E / π).
  const scale = probes.exposure * Math.PI;
  let lit;
  const place = () => {
    sphere.position.copy(at);
    lit = probeWeights(probes, at, occluders);
    light.sh.copy(blend(probes, lit.used, scale));
    renderer.render(scene, camera);
  };
  place();

  if (!post) {
    const controls = new OrbitControls(camera, renderer.domElement);
    controls.target.copy(at);
    controls.addEventListener("change", () => renderer.render(scene, camera));
    const step = probes.spacing / 4;
    addEventListener("keydown", (e) => {
      const move = { ArrowLeft: [-step, 0, 0], ArrowRight: [step, 0, 0], ArrowUp: [0, 0, -step],
        ArrowDown: [0, 0, step], PageUp: [0, step, 0], PageDown: [0, -step, 0] }[e.key];
      if (!move) return;
      at.add(new THREE.Vector3(...move));
      camera.position.add(new THREE.Vector3(...move));
      controls.target.copy(at);
      place();
    });
    return;
  }
  // The pixel at the canvas centre (size odd: its centre ray passes through the sphere's
  // centre, where the sphere's normal points at the camera) and the normal there.
  const gl = renderer.getContext();
  const pixel = new Uint8Array(4);
  const c = (size - 1) / 2;
  gl.readPixels(c, c, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, pixel);
  const normal = camera.position.clone().sub(at).normalize();
  await fetch("/result", {
    method: "POST",
    body: JSON.stringify({
      three: THREE.REVISION,
      at: at.toArray(),
      camera: camera.position.toArray(),
      normal: normal.toArray(),
      rho,
      scale,
      used: lit.used,
      dropped: lit.dropped,
      sh: light.sh.coefficients.map((v) => v.toArray()),
      centre_pixel: Array.from(pixel.slice(0, 3)),
      png: renderer.domElement.toDataURL("image/png"),
    }),
  });
}
