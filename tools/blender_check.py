"""What Blender sees in a baked glTF: run by tools/blender-check inside Blender.

    blender -b --factory-startup --python-exit-code 1 --python tools/blender_check.py -- \
        OUT.gltf [PNG] [--width W] [--height H] [--view X,Y,Z] [--json]

Imports OUT with Blender's stock glTF importer into an empty scene and prints every object:
type, vertex and face counts, colour attributes (domain, storage, min/max/mean of the linear
values per channel), UV maps, other attributes, and each material's node types. With --json,
a last line `BLENDER_CHECK_JSON {...}` holds the same as JSON (for tests).

With PNG, renders the scene with Workbench (flat lighting, vertex colours, back faces culled,
"Standard" view transform: the stored colour, sRGB-encoded) from the same camera as
`bake preview`: the file's first camera, else a 45° camera looking down glTF's −Z (Blender's
+Y), backed off until the bounding box fits. The background is the preview's dark grey.

Debian's Blender 3.4 glTF importer still uses `numpy.bool`, removed in numpy 1.24: the alias
is restored before importing.
"""

import json
import math
import sys
import warnings

import bpy
import numpy
from mathutils import Matrix, Vector

with warnings.catch_warnings():
    # numpy 1.24 warns on the very lookup of the removed alias.
    warnings.simplefilter("ignore", FutureWarning)
    if not hasattr(numpy, "bool"):
        numpy.bool = bool  # the importer's removed alias (numpy >= 1.24)

YFOV = math.pi / 4
FRAMING_MARGIN = 0.04
BACKGROUND = (0.02, 0.02, 0.02)


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    options = {"input": None, "png": None, "width": 512, "height": 512, "view": None,
               "json": False}
    positional = []
    k = 0
    while k < len(argv):
        arg = argv[k]
        if arg in ("--width", "--height") and k + 1 < len(argv):
            options[arg[2:]] = int(argv[k + 1])
            k += 2
        elif arg == "--json":
            options["json"] = True
            k += 1
        elif arg == "--view" and k + 1 < len(argv):
            options["view"] = [float(v) for v in argv[k + 1].split(",")]
            k += 2
        else:
            positional.append(arg)
            k += 1
    if not 1 <= len(positional) <= 2:
        raise SystemExit("usage: tools/blender-check OUT.gltf [PNG] [--width W] [--height H] "
                         "[--view X,Y,Z] [--json]")
    options["input"] = positional[0]
    options["png"] = positional[1] if len(positional) == 2 else None
    return options


def stats(values, channels):
    """min/max/mean per channel of a flat array of `channels`-tuples."""
    if len(values) == 0:
        return None
    table = numpy.asarray(values, dtype=numpy.float64).reshape(-1, channels)
    return {
        "min": [round(float(v), 6) for v in table.min(axis=0)],
        "max": [round(float(v), 6) for v in table.max(axis=0)],
        "mean": [round(float(v), 6) for v in table.mean(axis=0)],
    }


def describe_mesh(obj):
    mesh = obj.data
    colors = []
    for attribute in mesh.color_attributes:
        values = numpy.zeros(len(attribute.data) * 4, dtype=numpy.float32)
        attribute.data.foreach_get("color", values)
        colors.append({
            "name": attribute.name,
            "domain": attribute.domain,
            "data_type": attribute.data_type,
            "count": len(attribute.data),
            "rgba": stats(values, 4),
        })
    color_names = {c["name"] for c in colors}
    others = [{"name": a.name, "domain": a.domain, "data_type": a.data_type}
              for a in mesh.attributes
              if a.name not in color_names and not a.name.startswith(".")
              and a.name not in ("position", "sharp_face", "material_index")]
    return {
        "vertices": len(mesh.vertices),
        "faces": len(mesh.polygons),
        "color_attributes": colors,
        "uv_maps": [uv.name for uv in mesh.uv_layers],
        "other_attributes": others,
        "materials": [slot.material.name for slot in obj.material_slots if slot.material],
    }


def describe_material(material):
    nodes = sorted(n.bl_idname for n in material.node_tree.nodes) if material.use_nodes else []
    return {
        "name": material.name,
        "node_types": nodes,
        "backface_culling": material.use_backface_culling,
        "blend_method": material.blend_method,
    }


def framing_camera(view):
    """The `bake preview` framing camera, in Blender's coordinates (glTF (x, y, z) is Blender
    (x, −z, y))."""
    points = [obj.matrix_world @ v.co for obj in bpy.context.scene.objects
              if obj.type == "MESH" for v in obj.data.vertices]
    lo = Vector([min(p[a] for p in points) for a in range(3)])
    hi = Vector([max(p[a] for p in points) for a in range(3)])
    centre = (lo + hi) / 2
    gx, gy, gz = view or (0.0, 0.0, -1.0)
    forward = Vector((gx, -gz, gy)).normalized()
    world_up = Vector((0.0, 0.0, 1.0))
    if abs(forward.z) > 0.999:
        world_up = Vector((0.0, forward.z / abs(forward.z), 0.0))
    right = forward.cross(world_up).normalized()
    up = right.cross(forward)
    aspect = bpy.context.scene.render.resolution_x / bpy.context.scene.render.resolution_y
    tan_y = math.tan(YFOV / 2) * (1 - FRAMING_MARGIN)
    tan_x = tan_y * aspect
    distance, nearest = 0.0, math.inf
    for corner in range(8):
        p = Vector([hi[a] if corner >> a & 1 else lo[a] for a in range(3)])
        offset = p - centre
        towards_eye = -offset.dot(forward)
        distance = max(distance, towards_eye + max(abs(offset.dot(right)) / tan_x,
                                                   abs(offset.dot(up)) / tan_y))
        nearest = min(nearest, -towards_eye)
    data = bpy.data.cameras.new("preview")
    data.sensor_fit = "VERTICAL"
    data.angle_y = YFOV
    data.clip_start = max((distance + nearest) * 0.5, 1e-6)
    data.clip_end = distance * 100 + (hi - lo).length * 10
    camera = bpy.data.objects.new("preview", data)
    bpy.context.scene.collection.objects.link(camera)
    camera.location = centre - forward * distance
    # The camera looks down its local −Z with +Y up: columns right, up, −forward.
    camera.rotation_mode = "QUATERNION"
    camera.rotation_quaternion = Matrix((right, up, -forward)).transposed().to_quaternion()
    return camera


def render(png, width, height, view):
    scene = bpy.context.scene
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    cameras = [obj for obj in scene.objects if obj.type == "CAMERA"]
    if view is None and cameras:
        scene.camera = cameras[0]
        if scene.camera.data.sensor_fit != "VERTICAL":
            scene.camera.data.sensor_fit = "VERTICAL"
        source = f"camera {scene.camera.name!r}"
    else:
        scene.camera = framing_camera(view)
        source = "framing camera"
    scene.render.engine = "BLENDER_WORKBENCH"
    shading = scene.display.shading
    shading.light = "FLAT"
    shading.color_type = "VERTEX"
    shading.show_backface_culling = True
    shading.show_cavity = False
    shading.show_object_outline = False
    shading.show_specular_highlight = False
    shading.show_shadows = False
    shading.show_xray = False
    scene.display.render_aa = "8"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    world = scene.world or bpy.data.worlds.new("background")
    scene.world = world
    world.color = BACKGROUND
    scene.render.film_transparent = False
    scene.render.dither_intensity = 0.0  # exact colours, not noise
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGB"
    scene.render.image_settings.color_depth = "8"
    scene.render.filepath = png
    bpy.ops.render.render(write_still=True)
    return {"png": png, "engine": "BLENDER_WORKBENCH", "camera": source,
            "width": width, "height": height}


def main():
    options = parse_args()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.gltf(filepath=options["input"])
    if "FINISHED" not in result:
        raise RuntimeError(f"the glTF importer failed on {options['input']}: {result}")
    objects = []
    for obj in sorted(bpy.context.scene.objects, key=lambda o: o.name):
        entry = {"name": obj.name, "type": obj.type}
        if obj.type == "MESH":
            entry.update(describe_mesh(obj))
        objects.append(entry)
    materials = [describe_material(m) for m in sorted(bpy.data.materials, key=lambda m: m.name)]
    report = {
        "input": options["input"],
        "blender": bpy.app.version_string,
        "objects": objects,
        "materials": materials,
    }

    print(f"blender-check: {options['input']} in Blender {bpy.app.version_string}")
    print(f"blender-check: {len(objects)} objects, {len(materials)} materials")
    for entry in objects:
        if entry["type"] != "MESH":
            print(f"  {entry['name']}: {entry['type']}")
            continue
        print(f"  {entry['name']}: MESH, {entry['vertices']} vertices, {entry['faces']} faces, "
              f"UV maps {entry['uv_maps'] or 'none'}, materials {entry['materials']}")
        for color in entry["color_attributes"]:
            rgba = color["rgba"]
            fmt = lambda v: "/".join(f"{x:.4f}" for x in v[:3])  # noqa: E731
            print(f"    colour attribute {color['name']!r} ({color['data_type']}, "
                  f"{color['domain']}, {color['count']} values): linear RGB min {fmt(rgba['min'])}"
                  f" max {fmt(rgba['max'])} mean {fmt(rgba['mean'])}")
        for other in entry["other_attributes"]:
            print(f"    attribute {other['name']!r} ({other['data_type']}, {other['domain']})")
    for material in materials:
        print(f"  material {material['name']!r}: nodes {', '.join(material['node_types'])}; "
              f"backface culling {material['backface_culling']}, blend {material['blend_method']}")
    if options["png"]:
        report["render"] = render(options["png"], options["width"], options["height"],
                                  options["view"])
        print(f"blender-check: rendered {options['png']} ({options['width']}×{options['height']}, "
              f"Workbench flat vertex colours, {report['render']['camera']})")
    if options["json"]:
        print("BLENDER_CHECK_JSON " + json.dumps(report, sort_keys=True))


main()
