"""Blender script: import USD layers and render them with Cycles.

This file is run BY Blender's Python interpreter (the one that imports ``bpy``, in a
virtualenv of its own), in a subprocess: ``python report_blender.py SPEC.json``. meshfit
never imports it, and it imports nothing from meshfit (Blender's Python has no meshfit). It
ships in the package as a resource for :func:`meshfit.report.blender_renders`, the report's
renders of the USD deliverable; the tests run it too.

The spec (JSON) gives the output folder ``out``, the image ``size`` and ``samples``, the
camera's ``view`` direction and, optionally, its ``up`` direction (both in the layer's own
coordinates, turned and scaled as the import places the mesh; default up: Blender's +Z), a
``subdivision`` level (a Simple Subdivision Surface modifier; 0 for none), optional
model-space ``probes`` and ``renders``: ``[name, layer, variant]`` triples, each rendered
into a fresh scene as ``out/<name>.png``, where the variant is

- ``displaced``: the material as imported, Displacement method "Displacement Only";
- ``plain``: nothing connected to the material's displacement (or no material);
- ``vector``: the image read again, its Color straight into a Vector Displacement node in
  tangent space, as :func:`meshfit.export.export_usd` documents;
- ``mask``: white emission where the displacement texture is non-zero, no lights.

With ``probes``, ``out/render.json`` holds their pixel positions ``(column, row from the
top)`` in the first render. Every render uses the first one's camera (orthographic, round
the bounding sphere of its mesh), CPU Cycles with a fixed seed and no bounces, so two
renders of the same geometry agree pixel for pixel. A failure exits non-zero with the reason
on stderr.
"""

import json
import sys
from pathlib import Path

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Matrix, Vector


def import_layer(layer: str):
    """A fresh, empty Blender with ``layer`` imported; its (first) mesh object."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    if bpy.ops.wm.usd_import(filepath=layer) != {"FINISHED"}:
        raise SystemExit(f"USD import of {layer} failed")
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    if not meshes:
        raise SystemExit(f"{layer} holds no mesh")
    return meshes[0]


def world_vertices(obj) -> np.ndarray:
    M = np.array(obj.matrix_world)
    return np.array([v.co[:] for v in obj.data.vertices]) @ M[:3, :3].T + M[:3, 3]


def to_world(obj, direction) -> np.ndarray:
    """A direction in the layer's coordinates as a unit vector in Blender's world (the
    import's turn of a Y-up stage and its unit scale are in the object's matrix)."""
    M = np.array(obj.matrix_world)[:3, :3]
    d = M @ np.asarray(direction, dtype=np.float64)
    return d / np.linalg.norm(d)


def frame(obj, view, up=None) -> dict:
    """The camera: orthographic, along ``view``, ``up`` upwards (None: world +Z), round the
    object's bounding sphere."""
    co = world_vertices(obj)
    centre = (co.min(0) + co.max(0)) / 2
    radius = float(np.linalg.norm(co - centre, axis=1).max())
    return {
        "centre": centre,
        "radius": radius,
        "view": to_world(obj, view),
        "up": None if up is None else to_world(obj, up),
    }


def look(view: np.ndarray, up) -> Matrix:
    """The rotation of a camera (it looks along its local -Z, local +Y up) looking along
    ``view`` with ``up`` shown upwards; Blender's +Z up where ``up`` is None or along
    ``view``."""
    right = np.cross(view, up) if up is not None else np.zeros(3)
    if np.linalg.norm(right) < 1e-6:
        return Vector(view).to_track_quat("-Z", "Y").to_matrix()
    right /= np.linalg.norm(right)
    return Matrix(np.stack([right, np.cross(right, view), -view], axis=1).tolist())


def setup(spec: dict, layer: str, camera: dict | None = None):
    """A fresh scene with ``layer`` imported, lit, and a camera (``camera``, else framed
    on this object)."""
    obj = import_layer(layer)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = spec["samples"]
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 0
    scene.cycles.max_bounces = 0
    scene.render.threads_mode = "FIXED"
    scene.render.threads = 2
    scene.render.resolution_x = scene.render.resolution_y = spec["size"]
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = "PNG"
    scene.render.image_settings.color_mode = "RGBA"
    scene.view_settings.view_transform = "Standard"
    if spec.get("subdivision", 0):
        mod = obj.modifiers.new("subdivide", "SUBSURF")
        mod.subdivision_type = "SIMPLE"
        mod.levels = mod.render_levels = spec["subdivision"]
    camera = camera or frame(obj, spec["view"], spec.get("up"))
    centre, radius, view = camera["centre"], camera["radius"], camera["view"]
    cam_data = bpy.data.cameras.new("camera")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.6 * radius
    cam_data.clip_start = 0.01 * radius
    cam_data.clip_end = 10 * radius
    cam = bpy.data.objects.new("camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = Vector(centre - 4 * radius * view)
    cam.rotation_euler = look(view, camera["up"]).to_euler()
    scene.camera = cam
    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = 3.0
    sun = bpy.data.objects.new("sun", sun_data)
    scene.collection.objects.link(sun)
    light = view + np.array([0.3, 0.3, -0.5])
    sun.rotation_euler = Vector(light).to_track_quat("-Z", "Y").to_euler()
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.2
    scene.world = world
    bpy.context.view_layer.update()
    return scene, obj, cam, camera


def render(scene, path: Path) -> None:
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)


def displacement_link(tree):
    out = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    return out, next((lk for lk in tree.links if lk.to_socket == out.inputs["Displacement"]), None)


def vector_wiring(material) -> None:
    """The documented wiring: the image's Color straight into a tangent-space Vector
    Displacement node (the map files hold T, N, B, the order that node reads)."""
    tree = material.node_tree
    image = next(n for n in tree.nodes if n.type == "TEX_IMAGE")
    uv = tree.nodes.new("ShaderNodeUVMap")
    uv.uv_map = "st"
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image.image
    tex.interpolation = image.interpolation
    vd = tree.nodes.new("ShaderNodeVectorDisplacement")
    vd.space = "TANGENT"
    vd.inputs["Midlevel"].default_value = 0.0
    vd.inputs["Scale"].default_value = 1.0
    out, link = displacement_link(tree)
    if link is not None:
        tree.links.remove(link)
    tree.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], vd.inputs["Vector"])
    tree.links.new(vd.outputs["Displacement"], out.inputs["Displacement"])


def mask_material(material):
    """White emission where the displacement texture's value is non-zero, else black."""
    tree = material.node_tree
    out, link = displacement_link(tree)
    height = link.from_node.inputs["Height"].links[0].from_socket
    tree.links.remove(link)
    absolute = tree.nodes.new("ShaderNodeMath")
    absolute.operation = "ABSOLUTE"
    above = tree.nodes.new("ShaderNodeMath")
    above.operation = "GREATER_THAN"
    above.inputs[1].default_value = 1e-9
    emit = tree.nodes.new("ShaderNodeEmission")
    tree.links.new(height, absolute.inputs[0])
    tree.links.new(absolute.outputs[0], above.inputs[0])
    tree.links.new(above.outputs[0], emit.inputs["Strength"])
    tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])


def displaced(scene, material) -> None:
    if material is not None:
        material.displacement_method = "DISPLACEMENT"


def plain(scene, material) -> None:
    if material is None:
        return
    tree = material.node_tree
    link = displacement_link(tree)[1]
    if link is not None:
        tree.links.remove(link)


def vector(scene, material) -> None:
    material.displacement_method = "DISPLACEMENT"
    vector_wiring(material)


def mask(scene, material) -> None:
    mask_material(material)
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    bpy.data.objects["sun"].hide_render = True


VARIANTS = {"displaced": displaced, "plain": plain, "vector": vector, "mask": mask}


def main(spec: dict) -> None:
    out = Path(spec["out"])
    camera = None
    pixels = []
    for k, (name, layer, variant) in enumerate(spec["renders"]):
        scene, obj, cam, camera = setup(spec, layer, camera)
        if k == 0:
            M = np.array(obj.matrix_world)
            for p in spec.get("probes", ()):
                w = M[:3, :3] @ np.asarray(p, dtype=np.float64) + M[:3, 3]
                c = world_to_camera_view(scene, cam, Vector(w))
                pixels.append([c.x * spec["size"], (1.0 - c.y) * spec["size"]])
        VARIANTS[variant](scene, obj.data.materials[0] if obj.data.materials else None)
        render(scene, out / f"{name}.png")
    if "probes" in spec:
        (out / "render.json").write_text(json.dumps({"probes": pixels}))


if __name__ == "__main__":
    main(json.loads(Path(sys.argv[1]).read_text()))
