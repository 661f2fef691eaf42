"""An emissive square and a point lamp in Blender, exported by Blender's own glTF exporter, and
rendered each alone in Cycles: the reference for the glTF importer's emission convention.

    blender -b --factory-startup --python tests/data/gltf/make_emitter.py [-- OUT_DIR [--render]]

(Debian's `blender` 3.4 with `python3-numpy`.) Writes emitter.gltf (embedded buffers) beside this script,
or into OUT_DIR; with --render also emitter.exr and lamp.exr there (Cycles, direct light only) and prints
the ratio of the two at the floor point below both lights.

The scene in Blender's coordinates (z up; glTF's (x, z, -y)):
- a white floor, the plane z = 0 (Principled BSDF, specular 0, roughness 1);
- an emitting square of side 0.2 (area A = 0.04) at height 1 facing down: Principled BSDF black, Emission
  (1, 0.8, 0.6), Emission Strength S = 50, as users make a mesh light;
- a point lamp of power P = 4 S A = 8 W, colour (1, 0.8, 0.6), radius 0, at the same place;
- a camera at (0, -2.5, 0.6) aimed at the origin (the point below the lights is the image centre).
"""
import math
import sys
from pathlib import Path

import bpy

args = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
out = Path(args[0]) if args else Path(__file__).resolve().parent
S, SIDE = 50.0, 0.2
COLOUR = (1.0, 0.8, 0.6)
bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene


def plane(name, size, location, rotation, **inputs):
    """A plane with a Principled BSDF of these inputs (specular 0)."""
    bpy.ops.mesh.primitive_plane_add(size=size, location=location, rotation=rotation)
    ob = bpy.context.object
    ob.name = name
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    for key, value in {"Specular": 0.0, **inputs}.items():
        bsdf.inputs[key].default_value = value
    ob.data.materials.append(mat)
    return ob


plane("floor", 20, (0, 0, 0), (0, 0, 0), **{"Base Color": (1, 1, 1, 1), "Roughness": 1.0})
square = plane("emitter", SIDE, (0, 0, 1), (math.pi, 0, 0),
               **{"Base Color": (0, 0, 0, 1), "Emission": (*COLOUR, 1), "Emission Strength": S})

light = bpy.data.lights.new("lamp", type="POINT")
light.energy, light.shadow_soft_size, light.color = 4.0 * S * SIDE * SIDE, 0.0, COLOUR
lamp = bpy.data.objects.new("lamp", light)
lamp.location = (0, 0, 1.0)
scene.collection.objects.link(lamp)

cam = bpy.data.objects.new("camera", bpy.data.cameras.new("camera"))
scene.collection.objects.link(cam)
cam.location = (0, -2.5, 0.6)
cam.rotation_euler = (-cam.location).normalized().to_track_quat("-Z", "Y").to_euler()
scene.camera = cam

bpy.ops.export_scene.gltf(filepath=str(out / "emitter.gltf"), export_format="GLTF_EMBEDDED", export_lights=True,
                          export_cameras=True)

if "--render" in args:
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples, scene.cycles.max_bounces = "CPU", 1024, 0
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = 48
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.world = bpy.data.worlds.new("black")
    scene.world.use_nodes = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    centre = {}
    for name in ("emitter", "lamp"):
        square.hide_render, lamp.hide_render = name != "emitter", name != "lamp"
        scene.render.filepath = str(out / f"{name}.exr")
        bpy.ops.render.render(write_still=True)
        image = bpy.data.images.load(str(out / f"{name}.exr"))
        px = list(image.pixels)  # bottom row first, RGBA
        centre[name] = sum(px[4 * (48 * r + c)] for r in (23, 24) for c in (23, 24)) / 4.0
    print(f"RATIO emitter / lamp at the point below: {centre['emitter'] / centre['lamp']:.5f}")
