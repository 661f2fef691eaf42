"""The built-in default scene: a hall with two rows of columns, a gabled roof and two lamps in fog.

Made of primitives only, so `python render.py` needs no files.
"""


def _columns():
    out = []
    for x in (-6.0, -3.0, 0.0, 3.0, 6.0):
        for z in (-2.6, 2.6):
            out.append(f"""
[[shape]]
primitive = "cylinder"
base = [{x}, 0.0, {z}]
top = [{x}, 5.0, {z}]
radius = 0.35
segments = 24
reflectance = [0.62, 0.58, 0.52]
""")
    return "".join(out)


DEFAULT_TOML = f"""
name = "default"

[camera]
type = "perspective"
position = [-9.2, 2.2, 0.0]
look_at = [4.0, 2.4, 0.0]
fov = 62.0
width = 480
height = 320
spp = 4

[[shape]]          # the hall: floor and walls
primitive = "box"
min = [-10.0, 0.0, -4.5]
max = [10.0, 7.0, 4.5]
reflectance = [0.55, 0.5, 0.45]

[[shape]]          # roof, two slopes meeting at the ridge
primitive = "quad"
corners = [[-10.0, 5.0, -4.5], [10.0, 5.0, -4.5], [10.0, 7.0, 0.0], [-10.0, 7.0, 0.0]]
reflectance = [0.45, 0.35, 0.3]

[[shape]]
primitive = "quad"
corners = [[-10.0, 5.0, 4.5], [10.0, 5.0, 4.5], [10.0, 7.0, 0.0], [-10.0, 7.0, 0.0]]
reflectance = [0.45, 0.35, 0.3]

[[shape]]          # an altar at the far end
primitive = "box"
min = [7.5, 0.0, -1.2]
max = [8.7, 1.1, 1.2]
reflectance = [0.7, 0.7, 0.72]

[[shape]]
primitive = "sphere"
center = [0.0, 0.6, 0.0]
radius = 0.6
segments = 32
reflectance = [0.3, 0.45, 0.7]
{_columns()}
[[light]]
position = [-1.5, 3.6, -1.2]
intensity = [30.0, 22.0, 14.0]

[[light]]
position = [4.5, 3.2, 1.4]
intensity = [14.0, 20.0, 30.0]

[medium]
sigma_a = 0.02
sigma_s = 0.06
phase = "isotropic"

[render]
method = "analytic"
"""
