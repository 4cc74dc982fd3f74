"""A room with an authored lightmap UV map, built and exported by Blender: run by
tools/blender-lightmap-room.

    blender -b --factory-startup --python-exit-code 1 --python tools/blender_lightmap_room.py \
        -- OUT.gltf

The room of tools/blender_room.py (floor, ceiling, walls, the table; untextured) and its
500 W point light, every mesh with two UV maps: "UVMap" (planar per face, TEXCOORD_0) and
"Lightmap" (TEXCOORD_1), made by Blender's own Lightmap Pack over all four objects at once
into one shared texture space ("Share Texture Space", margin 0.1), as an artist lays out a
scene-wide lightmap. Exported by Blender's stock exporter (.gltf + .bin). The last line
`BLENDER_LIGHTMAP {...}` is JSON: the output, the Blender version and the objects.
"""

import json
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_room as room  # noqa: E402  (the room's geometry and helpers)


def planar_uv(obj):
    """UVMap: planar on each face, 1 m per unit, u along the face's first edge."""
    mesh = obj.data
    layer = mesh.uv_layers.new(name="UVMap")
    for poly in mesh.polygons:
        corners = [mesh.vertices[mesh.loops[i].vertex_index].co for i in poly.loop_indices]
        u_axis = (corners[1] - corners[0]).normalized()
        v_axis = poly.normal.cross(u_axis)
        for i, co in zip(poly.loop_indices, corners):
            d = co - corners[0]
            layer.data[i].uv = (d.dot(u_axis), d.dot(v_axis))


def lightmap_pack(objects):
    """Lightmap: Blender's Lightmap Pack of every face of `objects` into one texture space."""
    for obj in objects:
        obj.data.uv_layers.new(name="Lightmap")
        obj.data.uv_layers.active = obj.data.uv_layers["Lightmap"]
    bpy.ops.object.select_all(action="DESELECT")
    for obj in objects:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = objects[0]
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    result = bpy.ops.uv.lightmap_pack(PREF_CONTEXT="ALL_FACES", PREF_PACK_IN_ONE=True,
                                      PREF_NEW_UVLAYER=False, PREF_BOX_DIV=12,
                                      PREF_MARGIN_DIV=0.1)
    bpy.ops.object.mode_set(mode="OBJECT")
    if "FINISHED" not in result:
        raise RuntimeError(f"lightmap pack failed: {result}")
    for obj in objects:
        obj.data.uv_layers.active = obj.data.uv_layers["UVMap"]


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: tools/blender-lightmap-room OUT.gltf")
    out = os.path.abspath(argv[0])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    inside = (room.ROOM_LO + room.ROOM_HI) / 2
    lo, hi = room.ROOM_LO, room.ROOM_HI
    objects = [
        room.mesh_object("Floor", [room.box_quads(lo, hi, ["-z"], inward=True)],
                         room.material("floor"), inside),
        room.mesh_object("Ceiling", [room.box_quads(lo, hi, ["+z"], inward=True)],
                         room.material("ceiling"), inside),
        room.mesh_object("Walls", [room.box_quads(lo, hi, ["-x", "+x", "-y", "+y"], inward=True)],
                         room.material("walls"), inside),
        room.mesh_object("Table", room.table_parts(), room.material("table")),
    ]
    for obj in objects:
        planar_uv(obj)
    lightmap_pack(objects)
    room.light("Point", "POINT", 500.0, (1.5, -1.0, 2.2))
    bpy.context.view_layer.update()
    result = bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE",
                                       export_lights=True, export_apply=True)
    if "FINISHED" not in result:
        raise RuntimeError(f"the glTF exporter failed on {out}: {result}")
    report = {
        "output": out,
        "blender": bpy.app.version_string,
        "objects": [obj.name for obj in objects],
        "faces": sum(len(obj.data.polygons) for obj in objects),
    }
    print("BLENDER_LIGHTMAP " + json.dumps(report, sort_keys=True))


main()
