"""A textured test room built and exported by Blender: run by tools/blender-textured-room.

    blender -b --factory-startup --python-exit-code 1 --python tools/blender_textured_room.py \
        -- OUT.gltf

The room of tools/blender_room.py (6 × 5 × 2.8 m, faces facing in, the same table) with a
generated 64 × 64 PNG texture (a coloured grid: brick-like rows, no black texels) on the floor
and the walls through an Image Texture node (closest filter: glTF NEAREST) into the
Principled BSDF's Base Color, each mesh with two UV maps — "UVMap" (planar, 1 m per texture
repeat, TEXCOORD_0) and an authored "Lightmap" (each face its own cell, TEXCOORD_1) — an
untextured table, and a 500 W point light. Exported by Blender's stock exporter (.gltf + .bin +
the PNG beside it, KHR_lights_punctual). The last line `BLENDER_TEXTURED {...}` is JSON: the
output, the Blender version, the image file and the expected texel values (sRGB bytes).
"""

import json
import os
import sys

import bpy
from mathutils import Vector

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_room as room  # noqa: E402  (the room's geometry and helpers)

SIZE = 64


def texel(x, y):
    """sRGB bytes of texel (x, y) (y = 0 the bottom row, as Blender stores it): bricks of
    16 × 8 texels, mortar lines lighter, every second brick row shifted by half a brick."""
    row = y // 8
    shifted = (x + 8 * (row % 2)) % SIZE
    mortar = y % 8 == 0 or shifted % 16 == 0
    if mortar:
        return (210, 205, 195)
    brick = (shifted // 16 + row) % 3
    return [(170, 80, 60), (150, 95, 70), (185, 110, 80)][brick]


def grid_image(path):
    image = bpy.data.images.new("bricks", SIZE, SIZE, alpha=False)
    pixels = []
    for y in range(SIZE):
        for x in range(SIZE):
            r, g, b = texel(x, y)
            pixels.extend((r / 255, g / 255, b / 255, 1.0))
    image.pixels = pixels
    image.filepath_raw = path
    image.file_format = "PNG"
    image.save()
    return image


def textured_material(name, image):
    mat = room.material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    tex = nodes.new("ShaderNodeTexImage")
    tex.image = image
    tex.interpolation = "Closest"
    links.new(tex.outputs["Color"], nodes["Principled BSDF"].inputs["Base Color"])
    return mat


def add_uv_maps(obj):
    """UVMap: planar on each face (1 m = one texture repeat, u along the face's first edge);
    Lightmap: face k in cell k of an 8 × 8 grid."""
    mesh = obj.data
    planar = mesh.uv_layers.new(name="UVMap")
    second = mesh.uv_layers.new(name="Lightmap")
    for poly in mesh.polygons:
        corners = [mesh.vertices[mesh.loops[i].vertex_index].co for i in poly.loop_indices]
        origin = corners[0]
        u_axis = (corners[1] - corners[0]).normalized()
        v_axis = poly.normal.cross(u_axis)
        cell = Vector((poly.index % 8, poly.index // 8)) / 8
        for i, co in zip(poly.loop_indices, corners):
            d = co - origin
            planar.data[i].uv = (d.dot(u_axis), d.dot(v_axis))
        # The second map: the face's planar UVs squeezed into its cell.
        extent = Vector((max(planar.data[i].uv.x for i in poly.loop_indices),
                         max(planar.data[i].uv.y for i in poly.loop_indices)))
        for i in poly.loop_indices:
            uv = planar.data[i].uv
            second.data[i].uv = (cell.x + 0.1 * uv.x / extent.x, cell.y + 0.1 * uv.y / extent.y)
    mesh.uv_layers.active = planar
    return obj


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: tools/blender-textured-room OUT.gltf")
    out = os.path.abspath(argv[0])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    image_path = os.path.join(os.path.dirname(out), "bricks.png")
    image = grid_image(image_path)

    inside = (room.ROOM_LO + room.ROOM_HI) / 2
    lo, hi = room.ROOM_LO, room.ROOM_HI
    floor = room.mesh_object("Floor", [room.box_quads(lo, hi, ["-z"], inward=True)],
                             textured_material("floor", image), inside)
    walls = room.mesh_object("Walls",
                             [room.box_quads(lo, hi, ["-x", "+x", "-y", "+y"], inward=True)],
                             textured_material("walls", image), inside)
    room.mesh_object("Ceiling", [room.box_quads(lo, hi, ["+z"], inward=True)],
                     room.material("ceiling"), inside)
    room.mesh_object("Table", room.table_parts(), room.material("table"))
    add_uv_maps(floor)
    add_uv_maps(walls)
    room.light("Point", "POINT", 500.0, (1.5, -1.0, 2.2))
    bpy.context.view_layer.update()

    result = bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE",
                                       export_lights=True, export_apply=True)
    if "FINISHED" not in result:
        raise RuntimeError(f"the glTF exporter failed on {out}: {result}")
    report = {
        "output": out,
        "blender": bpy.app.version_string,
        "image": image_path,
        "size": SIZE,
        "texels": {f"{x},{y}": texel(x, y) for (x, y) in [(0, 0), (5, 3), (20, 12), (40, 50)]},
    }
    print("BLENDER_TEXTURED " + json.dumps(report, sort_keys=True))


main()
