"""Blender Cycles side of ``benchmarks/cycles_compare.py``: runs under a Python that has ``bpy``.

Reads the renderer-agnostic scene and configurations that ``cycles_compare.py`` wrote (JSON:
meshes, materials, tag textures, lights, camera intrinsics; per configuration the rail-frame
transforms of ``simgap.render.scene.pose_transforms`` and simgap's crop), builds the scene once,
renders each configuration's crop on the CPU at each sample count and writes, per render, the
linear RGB pixels (``.npy``, H x W x 3, top row first) and a JSON of seconds.

Physical conventions, Mitsuba -> Cycles: a diffuse BSDF is Cycles' diffuse BSDF; a rough metal
or plastic is the Principled BSDF with roughness sqrt(alpha); an area light of radiance L and
area A has power pi L A (W), a point or spot of intensity I has power 4 pi I (W, radius 0); the
constant environment is the world colour. Mitsuba's ``max_depth`` d is Cycles' ``max_bounces``
d - 2 (d = 2: direct light only). The film is Mitsuba's box filter of 1 px; adaptive sampling and
denoising are off, so a sample count means the same work as in Mitsuba.

Usage (not by hand): ``python cycles_worker.py SCENE.json OUT_DIR``
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

#: OpenCV camera frame (x right, y down, z forward) to Blender's (x right, y up, looking down -z).
CV_TO_BLENDER = np.diag([1.0, -1.0, -1.0, 1.0])


def _material(name: str, spec: dict) -> bpy.types.Material:
    """A Cycles material from a simgap material description."""
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    out = nodes["Material Output"]
    for node in [n for n in nodes if n.type != "OUTPUT_MATERIAL"]:
        nodes.remove(node)
    kind = spec["kind"]
    if kind in ("diffuse", "print"):  # Lambertian, as Mitsuba's diffuse
        bsdf = nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*[spec.get("reflectance", 1.0)] * 3, 1.0)
        colour = "Color"
    else:
        bsdf = nodes.new("ShaderNodeBsdfPrincipled")
        alpha = spec.get("alpha")
        bsdf.inputs["Roughness"].default_value = 0.0 if alpha is None else math.sqrt(alpha)
        colour = "Base Color"
        if kind == "conductor":
            bsdf.inputs["Metallic"].default_value = 1.0
            bsdf.inputs[colour].default_value = (0.91, 0.92, 0.92, 1.0)  # aluminium
        else:  # a plastic: diffuse base under a dielectric coating
            bsdf.inputs["IOR"].default_value = spec["int_ior"]
            bsdf.inputs[colour].default_value = (*[spec["reflectance"]] * 3, 1.0)
    texture = spec.get("texture")
    if texture is not None:
        image = _albedo_image(name, np.asarray(texture["albedo"], np.float32))
        tex = nodes.new("ShaderNodeTexImage")
        tex.image = image
        tex.interpolation = "Closest" if texture["filter"] == "nearest" else "Linear"
        links.new(tex.outputs["Color"], bsdf.inputs[colour])
    shader = "BSDF" if "BSDF" in bsdf.outputs else 0
    links.new(bsdf.outputs[shader], out.inputs["Surface"])
    return mat


def _albedo_image(name: str, albedo: np.ndarray) -> bpy.types.Image:
    """A linear float image of ``albedo`` (rows top first, as a bitmap) for a texture node."""
    h, w = albedo.shape
    image = bpy.data.images.new(name, w, h, float_buffer=True, alpha=False)
    image.colorspace_settings.name = "Non-Color"
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = albedo[::-1, :, None]  # Blender's row 0 is the bottom
    image.pixels.foreach_set(rgba.ravel())
    return image


def _look_at(position, target) -> np.ndarray:
    """Light transform whose -z points from ``position`` to ``target`` (up: +z of the rail)."""
    origin, aim = np.asarray(position, float), np.asarray(target, float)
    forward = (aim - origin) / np.linalg.norm(aim - origin)
    left = np.cross([0.0, 0.0, 1.0], forward)
    left /= np.linalg.norm(left)
    up = np.cross(forward, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, -up, -forward, origin
    return m


def _light(index: int, spec: dict, world_node) -> bpy.types.Object | None:
    """A Cycles light (an object), or the world colour for the constant environment."""
    rgb = np.asarray(spec["rgb"], float)
    if spec["type"] == "constant":
        world_node.inputs["Color"].default_value = (*(rgb * spec["radiance"]), 1.0)
        world_node.inputs["Strength"].default_value = 1.0
        return None
    kind = {"area": "AREA", "point": "POINT", "spot": "SPOT"}[spec["type"]]
    light = bpy.data.lights.new(f"light{index}", kind)
    light.color = tuple(rgb)
    if kind == "AREA":
        light.shape = "RECTANGLE"
        light.size, light.size_y = spec["size"]
        light.energy = math.pi * spec["radiance"] * spec["size"][0] * spec["size"][1]
    else:
        light.energy = 4.0 * math.pi * spec["intensity"]
        light.shadow_soft_size = 0.0
        if hasattr(light, "use_soft_falloff"):
            light.use_soft_falloff = False
        if kind == "SPOT":
            light.spot_size = 2.0 * math.radians(spec["cutoff_deg"])
            light.spot_blend = 0.0
    obj = bpy.data.objects.new(f"light{index}", light)
    obj.matrix_world = Matrix(_look_at(spec["position"], spec["target"]).tolist())
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _tag_mesh(name: str) -> bpy.types.Mesh:
    """The 2 x 2 sticker rectangle (z its normal), uv (x + 1) / 2, (y + 1) / 2 as Mitsuba's."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    uv = mesh.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(mesh.loops, ((0, 0), (1, 0), (1, 1), (0, 1)), strict=True):
        uv.data[loop.index].uv = (u, v)
    return mesh


def build(desc: dict) -> dict[str, bpy.types.Object]:
    """The scene of ``desc``: meshes, tags, lights, camera and Cycles settings; objects by name."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = max(desc["max_depth"] - 2, 0)
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    cam = desc["camera"]
    scene.render.resolution_x, scene.render.resolution_y = cam["width"], cam["height"]
    scene.render.resolution_percentage = 100
    scene.render.use_border = True
    scene.render.use_crop_to_border = True
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    world = bpy.data.worlds.new("world")
    world.use_nodes = True
    scene.world = world
    objects: dict[str, bpy.types.Object] = {}
    materials = {name: _material(name, m) for name, m in desc["materials"].items()}
    for name, obj in desc["objects"].items():
        bpy.ops.wm.ply_import(filepath=obj["mesh"])
        imported = bpy.context.selected_objects[0]
        imported.name = name
        imported.data.materials.clear()
        imported.data.materials.append(materials[obj["material"]])
        for poly in imported.data.polygons:  # Mitsuba's face_normals
            poly.use_smooth = False
        objects[name] = imported
    for tag_id, albedo in desc["tags"]["albedo"].items():
        texture = {**desc["tags"]["texture"], "albedo": albedo}
        spec = {**desc["tags"]["material"], "texture": texture}
        mesh = _tag_mesh(f"tag_{tag_id}")
        mesh.materials.append(_material(f"tag_{tag_id}", spec))
        obj = bpy.data.objects.new(f"tag_{tag_id}", mesh)
        scene.collection.objects.link(obj)
        objects[f"tag_{tag_id}"] = obj
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    for i, light in enumerate(desc["lights"]):
        _light(i, light, background)
    data = bpy.data.cameras.new("camera")
    data.sensor_fit = "HORIZONTAL"
    data.sensor_width = 36.0
    data.lens = cam["fx"] * data.sensor_width / cam["width"]
    side = max(cam["width"], cam["height"])
    # OpenCV pixel centres are integers: the principal point in continuous coordinates is c + 0.5
    data.shift_x = -((cam["cx"] + 0.5) - cam["width"] / 2) / side
    data.shift_y = ((cam["cy"] + 0.5) - cam["height"] / 2) / side
    data.clip_start = 0.01
    camera = bpy.data.objects.new("camera", data)
    scene.collection.objects.link(camera)
    scene.camera = camera
    objects["camera"] = camera
    return objects


def pose(objects: dict, desc: dict, config: dict) -> None:
    """Move objects, tags and camera to one configuration; set the render border to its crop."""
    world = {k: np.asarray(v, float) for k, v in config["transforms"].items()}
    for name, obj in desc["objects"].items():
        objects[name].matrix_world = Matrix(world[obj["frame"]].tolist())
    for tag_id in desc["tags"]["albedo"]:
        objects[f"tag_{tag_id}"].matrix_world = Matrix(world[f"tag_{tag_id}"].tolist())
    objects["camera"].matrix_world = Matrix((world["camera"] @ CV_TO_BLENDER).tolist())
    render, cam = bpy.context.scene.render, desc["camera"]
    (x0, y0), (w, h) = config["offset"], config["size"]
    render.border_min_x, render.border_max_x = x0 / cam["width"], (x0 + w) / cam["width"]
    render.border_min_y = 1.0 - (y0 + h) / cam["height"]
    render.border_max_y = 1.0 - y0 / cam["height"]


def render(path: Path, spp: int, seed: int) -> tuple[float, np.ndarray]:
    """Render the border region at ``spp``; seconds and linear RGB (H x W x 3, top row first)."""
    scene = bpy.context.scene
    scene.cycles.samples, scene.cycles.seed = spp, seed
    scene.render.filepath = str(path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    seconds = time.perf_counter() - t0
    image = bpy.data.images.load(str(path))
    w, h = image.size
    pixels = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return seconds, pixels.reshape(h, w, 4)[::-1, :, :3].copy()


def main() -> None:
    desc = json.loads(Path(sys.argv[1]).read_text())
    out = Path(sys.argv[2])
    t0 = time.perf_counter()
    objects = build(desc)
    timings = {"scene_build_s": time.perf_counter() - t0, "renders": []}
    first = desc["configurations"][0]
    pose(objects, desc, first)
    timings["first_render_s"] = render(out / "warmup.exr", 1, 0)[0]  # kernels, BVH
    for k, config in enumerate(desc["configurations"]):
        t0 = time.perf_counter()
        pose(objects, desc, config)
        pose_s = time.perf_counter() - t0
        for spp in desc["spp"]:
            seconds, rgb = render(out / f"c{k}_s{spp}.exr", spp, k)
            np.save(out / f"c{k}_s{spp}.npy", rgb)
            timings["renders"].append(
                {"config": k, "spp": spp, "seconds": seconds + pose_s, "pose_s": pose_s}
            )
    (out / "timings.json").write_text(json.dumps(timings))


if __name__ == "__main__":
    main()
