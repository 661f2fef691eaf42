"""`slab_approx`: the separable approximation of the analytic note on single scattering in
homogeneous slabs (its sec. 4.2), inside bounded media.

Inside a shape's medium (interiors/crossing.py) a point light's single scattering, eq. 7, is replaced by the
distant-light average of its exponential part (eq. 5 divided by the segment's length, c taken at
the entry point) times the closed-form integral of 1/d^2 (media/slab.py `point_approx`); a
directional light gets eq. 5, which is exact for the planar boundary. The approximation is the
note's real-time model: good for thin media and far lights, too dark near the light and in thick
media (measured by `render.py seed002`: down to -99 % at kt s = 100). Outside bounded media the
air-light is the analytic method's, with its parameters, so on scenes without interiors this
method is `analytic` and declares analytic's error law.
"""
from dataclasses import replace

from .analytic import METHOD as ANALYTIC

# analytic's parameters, kernels and error law (outside bounded media it is analytic: tests/test_methods.py)
METHOD = replace(
    ANALYTIC,
    name="slab_approx",
    summary="inside bounded media, the separable point-light approximation of the analytic note on single "
            "scattering in homogeneous slabs (its eq. 5 for directional lights); the analytic air-light outside",
    supports=replace(ANALYTIC.supports, interiors=replace(
        ANALYTIC.supports.interiors, closed_forms=False, entry_plane=True, lights=("point", "directional"),
        camera_inside=False,
        limits="the slab note's separable approximation is for index-matched boundaries with point lights, not "
               "spot lights")),
)
