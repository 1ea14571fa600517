"""Blender script: import a USD layer and describe what arrived, as JSON.

Run by ``tests/export/test_blender.py`` with Blender's Python (``bpy``):
``python inspect_usd.py LAYER OUT_DIR``. Writes ``OUT_DIR/scene.json`` (objects, the mesh's
counts and UV maps, every material's nodes and links) and ``OUT_DIR/world.npy`` (the mesh's
vertices in world coordinates, in file order) and ``OUT_DIR/loops.npz``: per face corner
(loop) its vertex and Blender's tangent space on the UV map ``st`` (MikkTSpace tangent,
bitangent and normal, object coordinates), the frame of a tangent-space Vector
Displacement node (which reads an image's R, G, B along tangent, normal, bitangent: the
channel order of the vector map files).
"""

import json
import sys
from pathlib import Path

import bpy
import numpy as np


def describe_material(material) -> dict:
    nodes, links = [], []
    if material.node_tree is not None:
        for n in material.node_tree.nodes:
            d = {"name": n.name, "type": n.type}
            if n.type == "TEX_IMAGE" and n.image is not None:
                d |= {
                    "file": n.image.filepath,
                    "source": n.image.source,
                    "tiles": [t.number for t in n.image.tiles],
                    "colorspace": n.image.colorspace_settings.name,
                }
            if n.type == "UVMAP":
                d["uv_map"] = n.uv_map
            if n.type == "DISPLACEMENT":
                d["space"] = n.space
                d |= {s.name: s.default_value for s in n.inputs if s.name in ("Midlevel", "Scale")}
            nodes.append(d)
        for link in material.node_tree.links:
            links.append(
                [link.from_node.name, link.from_socket.name, link.to_node.name, link.to_socket.name]
            )
    return {"name": material.name, "nodes": nodes, "links": links}


def loops(me) -> dict:
    me.calc_tangents(uvmap="st")
    n = len(me.loops)
    out = {"vertex": np.zeros(n, dtype=np.int64)}
    me.loops.foreach_get("vertex_index", out["vertex"])
    for name in ("tangent", "bitangent", "normal"):
        a = np.zeros(3 * n)
        me.loops.foreach_get(name, a)
        out[name] = a.reshape(n, 3)
    return out


def main(layer: str, out: Path) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if bpy.ops.wm.usd_import(filepath=layer) != {"FINISHED"}:
        raise SystemExit(f"USD import of {layer} failed")
    objects = []
    for o in bpy.data.objects:
        d = {"name": o.name, "type": o.type, "dimensions": list(o.dimensions)}
        if o.type == "MESH":
            me = o.data
            d |= {
                "vertices": len(me.vertices),
                "faces": len(me.polygons),
                "triangles": sum(len(p.vertices) == 3 for p in me.polygons),
                "uv_maps": [uv.name for uv in me.uv_layers],
                "materials": [m.name for m in me.materials if m is not None],
                "modifiers": [m.type for m in o.modifiers],
            }
            co = np.array([v.co[:] for v in me.vertices], dtype=np.float64)
            M = np.array(o.matrix_world, dtype=np.float64)
            np.save(out / "world.npy", co @ M[:3, :3].T + M[:3, 3])
            np.savez(out / "loops.npz", **loops(me))
        objects.append(d)
    scene = {
        "objects": objects,
        "materials": [describe_material(m) for m in bpy.data.materials],
        "unit_scale": bpy.context.scene.unit_settings.scale_length,
    }
    (out / "scene.json").write_text(json.dumps(scene, indent=1))


if __name__ == "__main__":
    main(sys.argv[1], Path(sys.argv[2]))
