"""Build the glTF test room in Blender and export it with Blender's own glTF exporter.

    blender -b --factory-startup --python tests/data/gltf/make_room.py [-- OUT_DIR]

(Debian's `blender` 3.4 with `python3-numpy`.) Writes room.glb and room.gltf + room.bin beside this
script, or into OUT_DIR. The same scene written by hand is room.toml; tests/test_io_gltf.py checks that the import of
these files equals it.

The scene, in glTF's (and the scene format's) coordinates, y up, metres; Blender's are z up, so a
point (x, y, z) here is (x, -z, y) in Blender:
- a room, the box (-2, 0, -2) .. (2, 2.5, 2), grey (0.75), seen from inside;
- an absorbing block (-0.5, 0, -0.5) .. (0.5, 0.75, 0.5) resting on the floor, a unit cube scaled and
  turned a quarter about the vertical by its object transform: Principled BSDF with
  transmission 1 and IOR 1 (index-matched), a glTF Material Output node with Thickness 1, a Volume
  Absorption node with colour (0.5, 0.25, 0.75) and density 2 (attenuationDistance 0.5);
- a point light of 100 W, colour (1, 0.75, 0.5), at (1, 2, 1);
- a spot light of 200 W at (-1, 2, 0.5) aimed at (-0.5, 0, 0), spot size 60 degrees, blend 0.25;
- a perspective camera at (0, 1.25, 1.75) aimed at (0, 0.5, 0), vertical field of view 50 degrees,
  render resolution 48 x 32 (aspect ratio 1.5).
The room's size is in its mesh; the block's in its node (scale, rotation).
Values are chosen exactly representable in float32 where Blender stores them.
"""
import math
import sys
from pathlib import Path

import bpy
from mathutils import Vector

from io_scene_gltf2.blender.com.gltf2_blender_material_helpers import create_settings_group, get_gltf_node_name

OUT = Path(sys.argv[sys.argv.index("--") + 1]) if "--" in sys.argv else Path(__file__).resolve().parent


def blender(p):
    """A point of the y-up scene in Blender's z-up coordinates."""
    x, y, z = p
    return Vector((x, -z, y))


def box(name, lo, hi, material, in_mesh=True):
    """A cube from lo to hi: its size in the mesh (in_mesh) or in the object's scale, then turned a
    quarter about the vertical (the same box, reached through the node's rotation and scale)."""
    lo, hi = blender(lo), blender(hi)
    a, b = Vector(map(min, lo, hi)), Vector(map(max, lo, hi))
    bpy.ops.mesh.primitive_cube_add(size=2.0, location=(a + b) / 2, scale=(b - a) / 2 if in_mesh else (1, 1, 1))
    obj = bpy.context.object
    obj.name = name
    obj.data.materials.append(material)
    if not in_mesh:
        half = (b - a) / 2
        obj.scale = (half.y, half.x, half.z)
        obj.rotation_euler = (0.0, 0.0, math.pi / 2)
    return obj


def aim(obj, position, target):
    obj.location = blender(position)
    obj.rotation_mode = "QUATERNION"
    obj.rotation_quaternion = (blender(target) - blender(position)).to_track_quat("-Z", "Y")


def diffuse(name, rgb):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*rgb, 1.0)
    bsdf.inputs["Metallic"].default_value = 0.0
    return m


def absorbing(name, colour, density, thickness):
    m = diffuse(name, (1.0, 1.0, 1.0))
    nodes, links = m.node_tree.nodes, m.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Transmission"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.0
    settings = nodes.new("ShaderNodeGroup")  # what Add > Output > glTF Material Output makes
    settings.node_tree = bpy.data.node_groups.get(get_gltf_node_name()) or create_settings_group(get_gltf_node_name())
    settings.inputs["Thickness"].default_value = thickness
    volume = nodes.new("ShaderNodeVolumeAbsorption")
    volume.inputs["Color"].default_value = (*colour, 1.0)
    volume.inputs["Density"].default_value = density
    links.new(volume.outputs["Volume"], nodes["Material Output"].inputs["Volume"])
    return m


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 48, 32

    box("Room", (-2.0, 0.0, -2.0), (2.0, 2.5, 2.0), diffuse("Walls", (0.75, 0.75, 0.75)))
    box("Block", (-0.5, 0.0, -0.5), (0.5, 0.75, 0.5), absorbing("Absorber", (0.5, 0.25, 0.75), 2.0, 1.0),
        in_mesh=False)

    point = bpy.data.lights.new("Point", "POINT")
    point.energy, point.color = 100.0, (1.0, 0.75, 0.5)
    obj = bpy.data.objects.new("Point", point)
    scene.collection.objects.link(obj)
    obj.location = blender((1.0, 2.0, 1.0))

    spot = bpy.data.lights.new("Spot", "SPOT")
    spot.energy, spot.spot_size, spot.spot_blend = 200.0, math.radians(60.0), 0.25
    obj = bpy.data.objects.new("Spot", spot)
    scene.collection.objects.link(obj)
    aim(obj, (-1.0, 2.0, 0.5), (-0.5, 0.0, 0.0))

    cam = bpy.data.cameras.new("Camera")
    cam.sensor_fit, cam.angle = "VERTICAL", math.radians(50.0)
    obj = bpy.data.objects.new("Camera", cam)
    scene.collection.objects.link(obj)
    aim(obj, (0.0, 1.25, 1.75), (0.0, 0.5, 0.0))
    scene.camera = obj

    for fmt, name in (("GLB", "room.glb"), ("GLTF_SEPARATE", "room.gltf")):
        bpy.ops.export_scene.gltf(filepath=str(OUT / name), export_format=fmt, export_lights=True,
                                  export_cameras=True, export_yup=True)


main()
