"""Cycles renders of a bake, compared with the bake's numbers: run by tools/blender-cycles-check.

    blender -b --factory-startup --python-exit-code 1 --python tools/blender_cycles_check.py \
        -- BAKED.gltf REPORT.json [--lightmap [--exr] | --baked-texture [--expected E.json]]
        [--png OUT.png] [--width W]

Imports BAKED (a vertex bake written with --shading flat, or with --lightmap the lightmap bake
beside it, BAKED being the .lightmap.gltf) with Blender's stock importer and replaces every
material by emission-only shading, so each pixel is exactly what the node set-up computes:

  vertex bake:    Emission = base-colour texture(UVMap) × baseColorFactor × colour attribute
                  (COLOR_0), strength 1
  lightmap bake:  Emission = base-colour texture(UV map 0) × baseColorFactor
                  × lightmap PNG(UV map 1, sRGB → linear) × png_scale × exposure, strength 1
                  (png_scale is MOZ_lightmap's intensity; exposure the report's); with
                  --exr the lightmap EXR (UV map 1, Linear) × exposure instead, the README's
                  set-up (no 8-bit quantisation)

With --baked-texture (a bake written with --target baked-texture) the materials stay as
Blender's importer makes them from KHR_materials_unlit (its emission-like set-up of the
base-colour texture on the second UV map): nothing is set up, as for any user.

It then renders with Cycles from an orthographic camera looking straight down (a black world, no
lights, 16 samples, a 0.01-pixel filter, the "Standard" view transform: 8-bit sRGB of the
linear value). At the centre of every upward-facing element the camera sees unobstructed
(a ray cast finds its own surface there) and that lies at least a quarter texel from a texel
border, the pixel is compared with the bake's own numbers from REPORT:

  expected = baseColorFactor × texture(uv) × clamp(H × exposure, 0, 1)   (textured)
  expected = clamp(b × exposure, 0, 1)                                     (untextured, vertex)
  expected = baseColorFactor × clamp(H × exposure, 0, 1)                   (untextured, lightmap)
  expected = clamp((ρ × H + e) × exposure, 0, 1)                         (--baked-texture)

(--baked-texture compares with the element's ρ, the mean of a base-colour texture over it:
meant for scenes without base-colour textures, whose ρ is the same at every point. For a
textured scene, --expected E.json gives the displayed linear value at chosen elements,
{"ELEMENT INDEX": [r, g, b], ...}, computed by the caller from the input's texture at the
element's centre: only those elements are compared, against those values.)

with H and b the element's `h` and `b`. Prints `CYCLES_CHECK {...}` (JSON: elements compared,
the largest and mean difference in 8-bit levels) and exits 1 when the largest exceeds
--tolerance (default 2 levels).
"""

import json
import math
import os
import sys
import warnings

import bpy
import numpy
from mathutils import Vector
from mathutils.interpolate import poly_3d_calc

with warnings.catch_warnings():
    warnings.simplefilter("ignore", FutureWarning)
    if not hasattr(numpy, "bool"):
        numpy.bool = bool  # Debian's Blender 3.4 importer uses the removed alias


def srgb_to_linear(v):
    return v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4


def linear_to_srgb8(v):
    v = min(max(v, 0.0), 1.0)
    s = v * 12.92 if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return s * 255


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    args = {"lightmap": False, "exr": False, "baked_texture": False, "png": None,
            "width": 1200, "tolerance": 2.0, "expected": None}
    positional = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a == "--lightmap":
            args["lightmap"] = True
        elif a == "--exr":
            args["exr"] = True
        elif a == "--baked-texture":
            args["baked_texture"] = True
        elif a in ("--png", "--width", "--tolerance", "--expected"):
            i += 1
            args[a[2:]] = argv[i] if a in ("--png", "--expected") else float(argv[i])
        else:
            positional.append(a)
        i += 1
    if len(positional) != 2:
        raise SystemExit(__doc__)
    args["gltf"], args["report"] = positional
    return args


def image_node_image(material):
    """The image of the importer's base-colour Image Texture node, if any."""
    if not material or not material.use_nodes:
        return None
    for node in material.node_tree.nodes:
        if node.type == "TEX_IMAGE" and node.image is not None:
            return node.image
    return None


def chain_multiply(tree, inputs):
    """Multiplies colour sockets/values left to right with MixRGB MULTIPLY nodes."""
    nodes, links = tree.nodes, tree.links
    current = inputs[0]
    for nxt in inputs[1:]:
        mix = nodes.new("ShaderNodeMixRGB")
        mix.blend_type = "MULTIPLY"
        mix.inputs["Fac"].default_value = 1.0
        for k, value in ((1, current), (2, nxt)):
            if isinstance(value, bpy.types.NodeSocket):
                links.new(value, mix.inputs[k])
            else:
                mix.inputs[k].default_value = value
        current = mix.outputs["Color"]
    return current


def emission_material(obj, gltf_material, lightmap):
    """Replaces obj's material by the documented emission-only set-up; returns what the
    expected value needs: (texture image or None, factor rgb, texture uv map name)."""
    original = obj.active_material
    image = image_node_image(original) if gltf_material.get("textured") else None
    factor = gltf_material["factor"]
    mat = bpy.data.materials.new(f"emission-{obj.name}")
    mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    factors = []
    uv_names = [uv.name for uv in obj.data.uv_layers]
    if image is not None:
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Closest"
        uv = tree.nodes.new("ShaderNodeUVMap")
        uv.uv_map = uv_names[0]
        tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
        factors.append(tex.outputs["Color"])
    factors.append((*factor, 1.0))
    if lightmap:
        lm = tree.nodes.new("ShaderNodeTexImage")
        lm.image = lightmap["image"]
        lm.interpolation = "Linear"
        lm.extension = "EXTEND"
        uv1 = tree.nodes.new("ShaderNodeUVMap")
        uv1.uv_map = uv_names[1]
        tree.links.new(uv1.outputs["UV"], lm.inputs["Vector"])
        factors.append(lm.outputs["Color"])
        scale = lightmap["scale"] * lightmap["exposure"]
        factors.append((scale, scale, scale, 1.0))
    else:
        attribute = tree.nodes.new("ShaderNodeAttribute")
        attribute.attribute_name = obj.data.color_attributes[0].name
        factors.append(attribute.outputs["Color"])
    tree.links.new(chain_multiply(tree, factors), emission.inputs["Color"])
    tree.links.new(emission.outputs["Emission"], out.inputs["Surface"])
    obj.data.materials.clear()
    obj.data.materials.append(mat)
    return image, factor


def sample_nearest(image, uv):
    """Linear RGB of `image` (sRGB-encoded 8-bit) at Blender uv, nearest texel, repeat;
    and the distance from the texel's border in texels."""
    w, h = image.size
    x, y = (uv[0] % 1.0) * w, (uv[1] % 1.0) * h
    border = min(x - math.floor(x), math.ceil(x) - x, y - math.floor(y), math.ceil(y) - y)
    i, j = int(x) % w, int(y) % h
    k = 4 * (j * w + i)
    px = image.pixels[k:k + 3]
    return [srgb_to_linear(c) for c in px], border


def main():
    args = parse_args()
    with open(args["report"]) as f:
        report = json.load(f)
    with open(args["gltf"]) as f:
        doc = json.load(f)
    exposure = report["options"]["exposure"]
    given = None
    if args["expected"]:
        with open(args["expected"]) as f:
            given = {int(k): v for k, v in json.load(f).items()}
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=os.path.abspath(args["gltf"]))

    lightmap = None
    if args["lightmap"]:
        extras = doc["extras"]["bake_lightmap"]
        folder = os.path.dirname(os.path.abspath(args["gltf"]))
        if args["exr"]:
            image = bpy.data.images.load(os.path.join(folder, extras["exr"]))
            image.colorspace_settings.name = "Linear"
            scale = 1.0
        else:
            image = bpy.data.images.load(os.path.join(folder, extras["png"]))
            image.colorspace_settings.name = "sRGB"
            scale = extras["png_scale"]
        lightmap = {"image": image, "scale": scale, "exposure": exposure}

    # glTF materials by name: factor and whether they carry a base-colour texture.
    gltf_materials = {}
    for m in doc.get("materials", []):
        pbr = m.get("pbrMetallicRoughness", {})
        gltf_materials[m.get("name")] = {
            "factor": pbr.get("baseColorFactor", [1, 1, 1, 1])[:3],
            "textured": "baseColorTexture" in pbr,
        }
    shading = {}
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH" or obj.active_material is None:
            continue
        if args["baked_texture"]:
            shading[obj.name] = (None, [1.0, 1.0, 1.0], False)
            continue
        name = obj.active_material.name
        gm = gltf_materials.get(name) or gltf_materials.get(name.split(".")[0])
        if gm is None:
            raise RuntimeError(f"{obj.name}: material {name} is not in the file")
        shading[obj.name] = (*emission_material(obj, gm, lightmap), gm["textured"])

    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.filter_width = 0.01
    scene.cycles.max_bounces = 0
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world

    # Orthographic, straight down over the bounding box of the mesh objects (Blender z-up).
    points = [obj.matrix_world @ Vector(c) for obj in scene.objects if obj.type == "MESH"
              for c in obj.bound_box]
    lo = Vector([min(p[a] for p in points) for a in range(3)])
    hi = Vector([max(p[a] for p in points) for a in range(3)])
    size = hi - lo
    camera_data = bpy.data.cameras.new("top")
    camera_data.type = "ORTHO"
    camera_data.ortho_scale = max(size.x, size.y) * 1.02
    camera_data.clip_start = 0.001
    camera_data.clip_end = size.z + 10
    camera = bpy.data.objects.new("top", camera_data)
    # Just below the top of the box: a closed room's ceiling faces down, away from it.
    camera.location = ((lo.x + hi.x) / 2, (lo.y + hi.y) / 2, hi.z - 0.01)
    scene.collection.objects.link(camera)
    scene.camera = camera
    width = int(args["width"])
    scene.render.resolution_x = width
    scene.render.resolution_y = max(1, int(width * size.y / size.x)) if size.x >= size.y \
        else width
    if size.x < size.y:
        scene.render.resolution_x = max(1, int(width * size.x / size.y))
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_depth = "8"
    png = args["png"] or os.path.join(bpy.app.tempdir, "cycles.png")
    scene.render.filepath = png
    bpy.ops.render.render(write_still=True)
    rendered = bpy.data.images.load(png)
    W, H = rendered.size
    pixels = numpy.array(rendered.pixels[:]).reshape(H, W, 4)

    from bpy_extras.object_utils import world_to_camera_view
    depsgraph = bpy.context.evaluated_depsgraph_get()
    diffs = []
    for element, e in enumerate(report["elements"]):
        if given is not None and element not in given:
            continue
        n = e["normal"]
        if n[1] < 0.99:  # glTF +y: Blender +z, facing the camera
            continue
        c = e["centroid"]
        point = Vector((c[0], -c[2], c[1]))
        hit, location, _, index, obj, _ = scene.ray_cast(
            depsgraph, Vector((point.x, point.y, camera.location.z)), Vector((0, 0, -1)))
        if not hit or abs(location.z - point.z) > 1e-4:
            continue
        texture, factor, textured = shading[obj.name][0], shading[obj.name][1], \
            shading[obj.name][2]
        if textured:
            mesh = obj.data
            poly = mesh.polygons[index]
            corners = [obj.matrix_world @ mesh.vertices[v].co for v in poly.vertices]
            weights = poly_3d_calc(corners, location)
            uv_layer = mesh.uv_layers[0].data
            uv = sum((uv_layer[li].uv * w for li, w in zip(poly.loop_indices, weights)),
                     Vector((0, 0)))
            tex, border = sample_nearest(texture, uv)
            if border < 0.25:
                continue
        else:
            tex = [1.0, 1.0, 1.0]
        if given is not None:
            expected = [min(max(given[element][k], 0.0), 1.0) for k in range(3)]
        elif args["baked_texture"]:
            expected = [min(max((e["rho"][k] * e["h"][k] + e["e"][k]) * exposure, 0.0), 1.0)
                        for k in range(3)]
        elif args["lightmap"] or textured:
            value = [min(max(h * exposure, 0.0), 1.0) for h in e["h"]]
            expected = [factor[k] * tex[k] * value[k] for k in range(3)]
        else:
            expected = [min(max(b * exposure, 0.0), 1.0) for b in e["b"]]
        p = world_to_camera_view(scene, camera, point)
        x, y = int(p.x * W), int(p.y * H)
        if not (0 <= x < W and 0 <= y < H):
            continue
        got = pixels[y, x, :3] * 255
        diffs.append(float(max(abs(got[k] - linear_to_srgb8(expected[k])) for k in range(3))))
    result = {
        "file": args["gltf"],
        "lightmap": args["lightmap"],
        "image": ("exr" if args["exr"] else "png") if args["lightmap"] else None,
        "baked_texture": args["baked_texture"],
        "compared": len(diffs),
        "max_levels": round(max(diffs), 3) if diffs else None,
        "mean_levels": round(sum(diffs) / len(diffs), 3) if diffs else None,
        "within_2": int(sum(d <= 2 for d in diffs)),
        "render": png,
        "size": [W, H],
    }
    print("CYCLES_CHECK " + json.dumps(result, sort_keys=True))
    if not diffs or max(diffs) > args["tolerance"]:
        sys.exit(1)


main()
