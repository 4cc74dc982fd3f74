"""Renders bakes in pyrender (offscreen, OSMesa) and checks the pixels against the bake report.

For the paper's cube (and the Cornell box when fixtures/cornell.gltf exists) this script:

1. bakes the scene with `--shading flat` (the `bake` binary: $BAKE_BIN, default
   target/debug/bake) into a .gltf plus a JSON report;
2. reads the output with pygltflib (COLOR_0 as stored, float) and cross-checks the colours
   trimesh reads from the same file;
3. builds pyrender meshes from those colours (pyrender's own glTF path drops COLOR_0 on
   primitives that have a material) with a white, single-sided material, and renders them
   with RenderFlags.FLAT, which writes base colour × COLOR_0 straight into an 8-bit
   framebuffer: no lighting and no sRGB encoding, so a pixel is round(COLOR_0 × 255);
4. projects the centroid of every report element that faces the camera, is not hidden and
   covers at least a few pixels, and asserts that the pixel there equals the element's
   COLOR_0 × 255 within 2 (of 255);
5. checks colour bleeding: floor pixels near the red wall are redder (R > B, and R − B larger)
   than floor pixels far from it.

The camera is the scene's first perspective camera node, else the framing camera of
`bake preview` (45°, looking down −Z, backed off until the bounding box fits).

Usage: tests/python/.venv/bin/python tests/python/test_render.py [--save DIR]
Exit status 0 when every check passes. Prints the colour differences found.
"""

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "osmesa")

import argparse  # noqa: E402
import base64  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from urllib.parse import unquote  # noqa: E402

import numpy as np  # noqa: E402
import pygltflib  # noqa: E402
import pyrender  # noqa: E402
import trimesh  # noqa: E402
from PIL import Image  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SIZE = 512
YFOV = math.pi / 4
FRAMING_MARGIN = 0.04
TOLERANCE = 2  # of 255
# Pixels at least this far inside an element's projected outline are checked.
EDGE_MARGIN_PX = 2.0
BACKGROUND = [0.0, 0.0, 0.0, 1.0]

COMPONENT_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
                    5125: np.uint32, 5126: np.float32}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


# ---- reading glTF with pygltflib ----

def buffer_bytes(gltf, path):
    """Every buffer's bytes: the GLB chunk, a data: URI, or a file beside `path`."""
    out = []
    for buffer in gltf.buffers:
        if buffer.uri is None:
            out.append(gltf.binary_blob())
        elif buffer.uri.startswith("data:"):
            out.append(base64.b64decode(buffer.uri.split(",", 1)[1]))
        else:
            out.append((path.parent / unquote(buffer.uri)).read_bytes())
    return out


def read_accessor(gltf, buffers, index):
    """An accessor's data as a (count, components) float64 array (normalized ints scaled)."""
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    dtype = np.dtype(COMPONENT_DTYPES[accessor.componentType]).newbyteorder("<")
    components = TYPE_SIZES[accessor.type]
    element_size = dtype.itemsize * components
    stride = view.byteStride or element_size
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    data = buffers[view.buffer]
    rows = [np.frombuffer(data, dtype=dtype, count=components, offset=start + k * stride)
            for k in range(accessor.count)]
    values = np.array(rows, dtype=np.float64).reshape(accessor.count, components)
    if accessor.normalized and dtype.kind in "iu":
        values /= np.iinfo(dtype).max
    return values


def local_matrix(node):
    """A node's local matrix (4×4, row-major numpy, column vectors)."""
    if node.matrix:
        return np.array(node.matrix, dtype=np.float64).reshape(4, 4).T
    t = np.eye(4)
    if node.translation:
        t[:3, 3] = node.translation
    r = np.eye(4)
    if node.rotation:
        x, y, z, w = node.rotation
        r[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    s = np.eye(4)
    if node.scale:
        s[0, 0], s[1, 1], s[2, 2] = node.scale
    return t @ r @ s


def load_scene(path):
    """World-space triangles (positions, COLOR_0 per corner) and camera nodes of a bake."""
    gltf = pygltflib.GLTF2().load(str(path))
    buffers = buffer_bytes(gltf, path)
    scene = gltf.scenes[gltf.scene if gltf.scene is not None else 0]
    primitives = []  # (world positions (n, 3), COLOR_0 (n, 3), triangle indices (m, 3))
    cameras = []  # (world matrix, yfov, znear)
    stack = [(index, np.eye(4)) for index in reversed(scene.nodes)]
    while stack:
        index, parent = stack.pop()
        node = gltf.nodes[index]
        world = parent @ local_matrix(node)
        if node.camera is not None:
            camera = gltf.cameras[node.camera]
            if camera.type == "perspective":
                cameras.append((world, camera.perspective.yfov, camera.perspective.znear))
        if node.mesh is not None:
            for primitive in gltf.meshes[node.mesh].primitives:
                if primitive.mode not in (None, 4):
                    raise AssertionError(f"{path.name}: unexpected primitive mode {primitive.mode}")
                local = read_accessor(gltf, buffers, primitive.attributes.POSITION)
                positions = (world[:3, :3] @ local.T).T + world[:3, 3]
                colors = read_accessor(gltf, buffers, primitive.attributes.COLOR_0)[:, :3]
                indices = read_accessor(gltf, buffers, primitive.indices).astype(np.int64)
                triangles = indices.reshape(-1, 3)
                if np.linalg.det(world[:3, :3]) < 0:
                    triangles = triangles[:, [0, 2, 1]]
                primitives.append((positions, colors, triangles))
        for child in reversed(node.children or []):
            stack.append((child, world))
    return primitives, cameras


def trimesh_colors(geometry):
    """COLOR_0 as trimesh read it: float, kept as a vertex attribute when the primitive has a
    material (TextureVisuals), else 8-bit vertex colours."""
    visual = geometry.visual
    if "color" in getattr(visual, "vertex_attributes", {}):
        return np.asarray(visual.vertex_attributes["color"], dtype=np.float64)[:, :3]
    return np.asarray(visual.vertex_colors, dtype=np.float64)[:, :3] / 255


def check_trimesh_agrees(path, primitives):
    """trimesh reads the same COLOR_0 values and vertex count as pygltflib. Returns the largest
    difference (0…1)."""
    scene = trimesh.load(str(path), force="scene", process=False)
    ours = np.concatenate([colors for _, colors, _ in primitives])
    theirs = np.concatenate([trimesh_colors(g) for g in scene.geometry.values()])
    assert ours.shape == theirs.shape, \
        f"{path.name}: trimesh reads {theirs.shape} colours, pygltflib {ours.shape}"
    # Geometry order may differ: compare the sorted colour multisets.
    ours = ours[np.lexsort(ours.T[::-1])]
    theirs = theirs[np.lexsort(theirs.T[::-1])]
    difference = float(np.abs(ours - theirs).max())
    assert difference <= 0.5 / 255, f"{path.name}: trimesh's COLOR_0 differs by {difference}"
    return difference


# ---- camera ----

class Camera:
    """A pinhole: eye, orthonormal right/up/forward, vertical field of view, near plane."""

    def __init__(self, eye, right, up, forward, yfov, znear):
        self.eye, self.right, self.up, self.forward = eye, right, up, forward
        self.yfov, self.znear = yfov, znear

    @staticmethod
    def framing(points):
        """`bake preview`'s framing camera looking down −Z at `points`' bounding box."""
        lo, hi = points.min(axis=0), points.max(axis=0)
        centre = (lo + hi) / 2
        forward = np.array([0.0, 0.0, -1.0])
        right = np.array([1.0, 0.0, 0.0])
        up = np.array([0.0, 1.0, 0.0])
        tan_y = math.tan(YFOV / 2) * (1 - FRAMING_MARGIN)
        tan_x = tan_y  # square image
        distance, nearest = 0.0, math.inf
        for corner in range(8):
            p = np.array([hi[a] if corner >> a & 1 else lo[a] for a in range(3)])
            offset = p - centre
            x, y = offset @ right, offset @ up
            towards_eye = -(offset @ forward)
            distance = max(distance, towards_eye + max(abs(x) / tan_x, abs(y) / tan_y))
            nearest = min(nearest, -towards_eye)
        eye = centre - forward * distance
        return Camera(eye, right, up, forward, YFOV, max((distance + nearest) * 0.5, 1e-6))

    @staticmethod
    def from_node(world, yfov, znear):
        forward = -world[:3, 2] / np.linalg.norm(world[:3, 2])
        right = np.cross(forward, world[:3, 1])
        right /= np.linalg.norm(right)
        return Camera(world[:3, 3].copy(), right, np.cross(right, forward), forward, yfov, znear)

    def pose(self):
        """The camera-to-world matrix pyrender wants (camera looks down its −Z, +Y up)."""
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2] = self.right, self.up, -self.forward
        pose[:3, 3] = self.eye
        return pose

    def depth_on_plane(self, pixel, point, normal):
        """The view depth at which the ray through `pixel` meets the plane (point, normal)."""
        t = math.tan(self.yfov / 2)
        ndc_x = pixel[0] / SIZE * 2 - 1
        ndc_y = 1 - pixel[1] / SIZE * 2
        ray = self.forward + ndc_x * t * self.right + ndc_y * t * self.up
        return float(((point - self.eye) @ normal) / (ray @ normal))

    def project(self, points):
        """(n, 3) world points → (n, 2) pixel coordinates (x right, y down) and view depth."""
        d = points - self.eye
        x, y, z = d @ self.right, d @ self.up, d @ self.forward
        t = math.tan(self.yfov / 2)
        px = (x / (z * t) + 1) * 0.5 * SIZE
        py = (1 - y / (z * t)) * 0.5 * SIZE
        return np.stack([px, py], axis=1), z


# ---- rendering ----

def render(primitives, camera):
    material = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                                  metallicFactor=0.0, roughnessFactor=1.0,
                                                  doubleSided=False)
    meshes = [pyrender.Primitive(positions=positions.astype(np.float32),
                                 color_0=colors.astype(np.float32),
                                 indices=triangles.astype(np.uint32),
                                 material=material, mode=pyrender.GLTF.TRIANGLES)
              for positions, colors, triangles in primitives]
    scene = pyrender.Scene(bg_color=BACKGROUND, ambient_light=[1.0, 1.0, 1.0])
    scene.add(pyrender.Mesh(primitives=meshes))
    scene.add(pyrender.PerspectiveCamera(yfov=camera.yfov, aspectRatio=1.0,
                                         znear=camera.znear, zfar=camera.znear * 1e5),
              pose=camera.pose())
    renderer = pyrender.OffscreenRenderer(SIZE, SIZE)
    try:
        color, depth = renderer.render(scene, flags=pyrender.RenderFlags.FLAT)
    finally:
        renderer.delete()
    return color, depth


# ---- checks ----

def triangles_containing(point, normal, corners):
    """Indices of the triangles (corners: (m, 3, 3)) in the plane of `point` containing it."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    size = np.linalg.norm(b - a, axis=1) + np.linalg.norm(c - a, axis=1)
    n = np.cross(b - a, c - a)
    in_plane = np.abs(np.einsum("ij,ij->i", point - a, n)) <= 1e-6 * size * np.linalg.norm(n, axis=1)
    facing = n @ normal > 0
    inside = np.ones(len(corners), dtype=bool)
    for p, q in ((a, b), (b, c), (c, a)):
        inside &= np.einsum("ij,ij->i", np.cross(q - p, point - p), n) >= -1e-9 * size ** 2 * np.linalg.norm(n, axis=1)
    return np.nonzero(in_plane & facing & inside)[0]


def inside_margin(pixel, outline):
    """Distance from `pixel` to the boundary of the convex hull of `outline` (2D), negative
    when outside."""
    hull = convex_hull(outline)
    if len(hull) < 3:
        return -math.inf
    distance = math.inf
    for k in range(len(hull)):
        p, q = hull[k], hull[(k + 1) % len(hull)]
        edge = q - p
        length = math.hypot(*edge)
        if length == 0:
            continue
        # The hull is counter-clockwise in (x, y-down) coordinates as built below.
        cross = edge[0] * (pixel[1] - p[1]) - edge[1] * (pixel[0] - p[0])
        distance = min(distance, cross / length)
    return distance


def convex_hull(points):
    """Andrew's monotone chain; counter-clockwise for a y-up reading, i.e. the sign that makes
    `inside_margin` positive inside."""
    pts = sorted(set(map(tuple, np.round(points, 9))))
    if len(pts) < 3:
        return [np.array(p) for p in pts]

    def turn(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower, upper = [], []
    for p in pts:
        while len(lower) >= 2 and turn(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(pts):
        while len(upper) >= 2 and turn(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return [np.array(p) for p in lower[:-1] + upper[:-1]]


def check_elements(name, report, primitives, camera, color, depth):
    """Pixel at each usable element's projected centroid vs its COLOR_0. Returns the
    differences (in 1/255) and the per-element pixel colours (by element index)."""
    corners = np.concatenate([positions[triangles] for positions, _, triangles in primitives])
    corner_colors = np.concatenate([colors[triangles] for _, colors, triangles in primitives])
    differences, pixels, skipped = [], {}, {"back": 0, "hidden": 0, "small": 0}
    for k, element in enumerate(report["elements"]):
        centroid = np.array(element["centroid"])
        normal = np.array(element["normal"])
        if normal @ (camera.eye - centroid) <= 0:
            skipped["back"] += 1
            continue
        found = triangles_containing(centroid, normal, corners)
        assert len(found) > 0, f"{name}: element {k} at {centroid} has no triangle in the file"
        # Flat shading: every triangle of an element carries the element's one COLOR_0.
        element_colors = corner_colors[found].reshape(-1, 3)
        assert np.ptp(element_colors, axis=0).max() == 0, f"{name}: element {k} is not flat"
        expected = element_colors[0] * 255
        outline, z = camera.project(corners[found].reshape(-1, 3))
        (pixel,), _ = camera.project(centroid[None, :])
        if min(z) < camera.znear:
            skipped["hidden"] += 1
            continue
        column, row = int(math.floor(pixel[0])), int(math.floor(pixel[1]))
        if not (0 <= column < SIZE and 0 <= row < SIZE):
            skipped["hidden"] += 1
            continue
        centre = np.array([column + 0.5, row + 0.5])
        if inside_margin(centre, outline) < EDGE_MARGIN_PX:
            skipped["small"] += 1
            continue
        # pyrender's depth is the distance along the view axis (0 where nothing was drawn):
        # the element is what the pixel shows when that is the depth of its plane there.
        seen = depth[row, column]
        expected_depth = camera.depth_on_plane(centre, centroid, normal)
        if seen == 0 or abs(seen - expected_depth) > 1e-4 * expected_depth:
            skipped["hidden"] += 1
            continue
        got = color[row, column, :3].astype(np.float64)
        difference = np.abs(got - expected).max()
        differences.append(difference)
        pixels[k] = got
        assert difference <= TOLERANCE, (
            f"{name}: element {k} at {centroid.tolist()}: pixel ({column}, {row}) = "
            f"{got.tolist()}, COLOR_0 × 255 = {expected.round(3).tolist()}")
    return np.array(differences), pixels, skipped


def check_bleeding(name, report, pixels):
    """Floor pixels near the red wall are redder than those far from it."""
    elements = report["elements"]
    red = [e for e in elements
           if e["rho"][0] > 2 * e["rho"][2] and abs(e["normal"][1]) < 0.5]
    assert red, f"{name}: no red wall in the report"
    red_point = np.mean([e["centroid"] for e in red], axis=0)
    red_normal = np.array(red[0]["normal"])
    floor_y = min(e["centroid"][1] for e in elements if e["normal"][1] > 0.9)
    floor = [(k, e) for k, e in enumerate(elements)
             if e["normal"][1] > 0.9 and abs(e["centroid"][1] - floor_y) < 1e-6 and k in pixels]
    assert len(floor) >= 4, f"{name}: only {len(floor)} floor elements checked"
    distance = {k: float((np.array(e["centroid"]) - red_point) @ red_normal) for k, e in floor}
    ordered = sorted(floor, key=lambda item: distance[item[0]])
    quarter = max(1, len(ordered) // 4)
    near = np.array([pixels[k] for k, _ in ordered[:quarter]])
    far = np.array([pixels[k] for k, _ in ordered[-quarter:]])
    near_excess = float((near[:, 0] - near[:, 2]).mean())
    far_excess = float((far[:, 0] - far[:, 2]).mean())
    print(f"  bleeding: floor near the red wall R−B = {near_excess:+.1f}/255 "
          f"(mean of {len(near)} elements), far from it {far_excess:+.1f}/255")
    assert (near[:, 0] > near[:, 2]).all(), f"{name}: floor near the red wall is not red: {near}"
    assert near_excess > far_excess, f"{name}: no red bleeding on the floor"


def bake(bake_bin, source, out_dir, subdiv):
    output = out_dir / f"{source.stem}-flat.gltf"
    report = out_dir / f"{source.stem}-flat.json"
    # The uniform grid the check is sized for (refinement would make most elements too small
    # to sample away from their edges).
    subprocess.run([str(bake_bin), "--quiet", "--shading", "flat", "--subdiv", str(subdiv),
                    "--refine", "off", "--report", str(report), str(source), str(output)],
                   check=True)
    return output, json.loads(report.read_text())


def run_scene(name, source, subdiv, bake_bin, out_dir, save):
    started = time.monotonic()
    output, report = bake(bake_bin, source, out_dir, subdiv)
    primitives, cameras = load_scene(output)
    trimesh_difference = check_trimesh_agrees(output, primitives)
    if cameras:
        camera = Camera.from_node(*cameras[0])
    else:
        camera = Camera.framing(np.concatenate([p for p, _, _ in primitives]))
    color, depth = render(primitives, camera)
    if save:
        save.mkdir(parents=True, exist_ok=True)
        Image.fromarray(color[:, :, :3]).save(save / f"{name}-pyrender.png")
    differences, pixels, skipped = check_elements(name, report, primitives, camera, color, depth)
    print(f"{name}: {len(report['elements'])} elements, {len(differences)} checked "
          f"(skipped: {skipped['back']} facing away, {skipped['hidden']} hidden, "
          f"{skipped['small']} under {EDGE_MARGIN_PX:g} px from an edge); "
          f"|pixel − COLOR_0×255|: max {differences.max():.3f}, mean {differences.mean():.3f} "
          f"(of 255); trimesh vs pygltflib COLOR_0: max {trimesh_difference:.1e}; "
          f"{time.monotonic() - started:.1f} s")
    assert len(differences) >= 0.5 * (len(report["elements"]) - skipped["back"]), \
        f"{name}: too few elements checked"
    if name == "cube":
        # The Cornell box's fixed camera sees its floor at too grazing an angle for the
        # per-element pixel test; its colours are checked above, the bleeding on the cube.
        check_bleeding(name, report, pixels)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--save", type=Path, help="also write the pyrender images here")
    args = parser.parse_args()
    bake_bin = Path(os.environ.get("BAKE_BIN", ROOT / "target" / "debug" / "bake"))
    if not bake_bin.is_file():
        sys.exit(f"test_render.py: no bake binary at {bake_bin} (set BAKE_BIN or cargo build)")
    scenes = [("cube", ROOT / "fixtures" / "cube.gltf", 4)]
    cornell = ROOT / "fixtures" / "cornell.gltf"
    if cornell.is_file():
        scenes.append(("cornell", cornell, 4))
    else:
        print("cornell: skipped (fixtures/cornell.gltf not there yet)")
    print(f"pyrender {pyrender.__version__}, trimesh {trimesh.__version__}, "
          f"pygltflib {pygltflib.__version__ if hasattr(pygltflib, '__version__') else '?'}, "
          f"PYOPENGL_PLATFORM={os.environ['PYOPENGL_PLATFORM']}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, source, subdiv in scenes:
            run_scene(name, source, subdiv, bake_bin, Path(tmp), args.save)
    print("ok")


if __name__ == "__main__":
    main()
