"""Blender's own closed meshes for the interior scaling checks: unit icospheres written as binary PLY.

    blender -b --factory-startup --python make_icospheres.py -- OUT_FOLDER 4 7

writes OUT_FOLDER/icosphere_4.ply (1,280 triangles) and icosphere_7.ply (81,920), one per
subdivision level given (Blender's level n has 20 * 4^(n - 1) triangles).
"""
import sys
from pathlib import Path

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
out = Path(args[0])
for level in map(int, args[1:]):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=level, radius=1.0)
    bpy.ops.export_mesh.ply(filepath=str(out / f"icosphere_{level}.ply"), use_ascii=False, use_normals=False,
                            use_uv_coords=False, use_colors=False)
