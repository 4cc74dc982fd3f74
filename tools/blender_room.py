"""A lit test room built and exported by Blender: run by tools/blender-room inside Blender.

    blender -b --factory-startup --python-exit-code 1 --python tools/blender_room.py -- OUT.gltf

Builds, in an empty scene (Blender z-up, metres), a closed 6 × 5 × 2.8 m room (x −3..3,
y −2.5..2.5, z 0..2.8; floor, ceiling and the four walls one quad each, facing into the room),
a table (top 1.2 × 0.8 × 0.05 m, upper surface at 0.75 m, centred at (−1, 0.5); four
0.05 × 0.05 m legs), a 500 W point light at (1.5, −1, 2.2) and an 800 W spot at (1.5, 1.2, 2.6)
pointing straight down (60° cone, blend 0.2) so that its foot lands on the bare floor. Exports
it with Blender's stock exporter (.gltf + .bin, KHR_lights_punctual) and prints a last line
`BLENDER_ROOM {...}` (JSON, glTF y-up coordinates) for tests: the spot's foot on the floor, the
radius of its outer cone there, and each light's position, power and expected glTF values.

The baker treats faces as single-sided (the front is where the normal points), so the
winding is built explicitly and checked before export.
"""

import json
import math
import sys

import bpy
from mathutils import Vector

# Blender's exporter: candela = watts × 683 / (4π) for point and spot lights.
WATTS_TO_CANDELA = 683 / (4 * math.pi)

ROOM_LO, ROOM_HI = Vector((-3.0, -2.5, 0.0)), Vector((3.0, 2.5, 2.8))
TABLE_CENTRE, TABLE_TOP_Z = Vector((-1.0, 0.5)), 0.75
TABLE_SIZE, TABLE_THICKNESS, LEG, LEG_INSET = Vector((1.2, 0.8)), 0.05, 0.05, 0.05

COLOURS = {
    "floor": (0.6, 0.5, 0.4),
    "walls": (0.8, 0.8, 0.8),
    "ceiling": (0.9, 0.9, 0.9),
    "table": (0.5, 0.3, 0.2),
}

# Faces of the box lo..hi as corner bit masks (bit 0: x, 1: y, 2: z at hi), wound
# counter-clockwise seen from outside: the normals point out.
BOX_FACES = {
    "-z": (0, 2, 3, 1), "+z": (4, 5, 7, 6),
    "-y": (0, 1, 5, 4), "+y": (2, 6, 7, 3),
    "-x": (0, 4, 6, 2), "+x": (1, 3, 7, 5),
}


def to_gltf(v):
    """Blender (x, y, z) → glTF (x, z, −y), as the exporter converts node transforms."""
    return [round(c, 6) + 0.0 for c in (v[0], v[2], -v[1])]  # + 0.0: no -0.0 in the JSON


def box_quads(lo, hi, sides, inward=False):
    """Vertices and quads of the named sides of box lo..hi; inward flips the winding."""
    corners = [Vector([hi[a] if c >> a & 1 else lo[a] for a in range(3)]) for c in range(8)]
    verts, faces = [], []
    for side in sides:
        quad = BOX_FACES[side][::-1] if inward else BOX_FACES[side]
        faces.append(tuple(range(len(verts), len(verts) + 4)))
        verts.extend(corners[c] for c in quad)
    return verts, faces


def material(name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    # Else the exporter writes doubleSided: true and the baker bakes both sides of every face.
    mat.use_backface_culling = True
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = \
        (*COLOURS[name], 1.0)
    return mat


def mesh_object(name, parts, mat, inside=None):
    """One object from (verts, faces) parts. Checks every normal: towards `inside` (a point)
    when given, else away from the centre of its own part (a convex box or box side)."""
    verts, faces, centres = [], [], []
    for part_verts, part_faces in parts:
        centre = sum(part_verts, Vector()) / len(part_verts)
        faces.extend(tuple(i + len(verts) for i in f) for f in part_faces)
        centres.extend([centre] * len(part_faces))
        verts.extend(part_verts)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    mesh.validate()
    mesh.materials.append(mat)
    for poly, centre in zip(mesh.polygons, centres):
        towards = (inside - poly.center) if inside is not None else (poly.center - centre)
        if poly.normal.dot(towards) <= 0:
            raise RuntimeError(f"{name}: face {poly.index} faces the wrong way ({poly.normal})")
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def table_parts():
    half = TABLE_SIZE / 2
    lo = Vector((*(TABLE_CENTRE - half), TABLE_TOP_Z - TABLE_THICKNESS))
    hi = Vector((*(TABLE_CENTRE + half), TABLE_TOP_Z))
    parts = [box_quads(lo, hi, BOX_FACES)]
    for ix in (0, 1):
        for iy in (0, 1):
            x = lo.x + LEG_INSET if ix == 0 else hi.x - LEG_INSET - LEG
            y = lo.y + LEG_INSET if iy == 0 else hi.y - LEG_INSET - LEG
            # No top or bottom cap: they would lie flush against the table top's underside
            # and the floor, hidden faces whose zero distance to their neighbour only
            # troubles the form factors.
            parts.append(box_quads(Vector((x, y, 0.0)), Vector((x + LEG, y + LEG, lo.z)),
                                   ("-x", "+x", "-y", "+y")))
    return parts


def light(name, kind, watts, location, **settings):
    data = bpy.data.lights.new(name, kind)
    data.energy = watts
    data.color = (1.0, 1.0, 1.0)
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    obj.location = location  # default rotation: shining down Blender's −Z
    bpy.context.scene.collection.objects.link(obj)
    return obj


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: tools/blender-room OUT.gltf")
    out = argv[0]
    bpy.ops.wm.read_factory_settings(use_empty=True)  # no default cube, camera or light

    inside = (ROOM_LO + ROOM_HI) / 2
    mesh_object("Floor", [box_quads(ROOM_LO, ROOM_HI, ["-z"], inward=True)],
                material("floor"), inside)
    mesh_object("Ceiling", [box_quads(ROOM_LO, ROOM_HI, ["+z"], inward=True)],
                material("ceiling"), inside)
    mesh_object("Walls", [box_quads(ROOM_LO, ROOM_HI, ["-x", "+x", "-y", "+y"], inward=True)],
                material("walls"), inside)
    mesh_object("Table", table_parts(), material("table"))

    point = light("Point", "POINT", 500.0, (1.5, -1.0, 2.2))
    spot = light("Spot", "SPOT", 800.0, (1.5, 1.2, 2.6),
                 spot_size=math.radians(60), spot_blend=0.2)
    bpy.context.view_layer.update()  # matrix_world of the new objects

    # Where the spot's axis meets the floor plane z = 0.
    origin = spot.matrix_world.translation
    axis = (spot.matrix_world.to_3x3() @ Vector((0, 0, -1))).normalized()
    foot = origin + axis * ((ROOM_LO.z - origin.z) / axis.z)
    outer = spot.data.spot_size / 2

    result = bpy.ops.export_scene.gltf(filepath=out, export_format="GLTF_SEPARATE",
                                       export_lights=True, export_apply=True)
    if "FINISHED" not in result:
        raise RuntimeError(f"the glTF exporter failed on {out}: {result}")

    def describe(obj):
        entry = {"type": obj.data.type.lower(), "watts": obj.data.energy,
                 "position": to_gltf(obj.matrix_world.translation),
                 "direction": to_gltf(obj.matrix_world.to_3x3() @ Vector((0, 0, -1))),
                 "candela": round(obj.data.energy * WATTS_TO_CANDELA, 4)}
        if obj.data.type == "SPOT":
            half = obj.data.spot_size / 2
            entry["outer_cone_angle"] = round(half, 6)
            entry["inner_cone_angle"] = round(half * (1 - obj.data.spot_blend), 6)
        return entry

    report = {
        "output": out,
        "blender": bpy.app.version_string,
        "spot_foot": to_gltf(foot),
        "spot_foot_radius": round((origin - foot).length * math.tan(outer), 6),
        "lights": {obj.name: describe(obj) for obj in (point, spot)},
    }
    print("BLENDER_ROOM " + json.dumps(report, sort_keys=True))


if __name__ == "__main__":  # also imported by blender_textured_room.py
    main()
