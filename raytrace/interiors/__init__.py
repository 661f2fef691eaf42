"""Media inside shapes: the crossing of a boundary (crossing.py: Fresnel, refraction, exits, a camera
inside a shape) makes inside `Segments` rows, which rows.py integrates by the render's method, with
the traced walks of light paths through non-convex shapes in paths.py; surfaces.py shades the surfaces
inside shapes, held.py the light of lamps inside refractive ones; support.py says what the methods take
there and counts; shapes.py holds the shapes' planes and caches, fresnel.py Snell's and Fresnel's laws."""
