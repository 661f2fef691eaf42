"""Media inside shapes: the crossing of a boundary (crossing.py: Fresnel, refraction, exits, a camera
inside a shape) makes inside `Segments` rows, which rows.py integrates by the render's method, with
the traced walks of light paths through non-convex shapes in paths.py."""
