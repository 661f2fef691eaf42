"""A kink at the start of a very short piece: media/convex_chords.py `boundary_kinks` snaps an exact sphere's
tangent-cone crossings within END_SNAP of the scene's scale about the piece (its length, the start's and the
light's distances from the centre, the radius) to its ends, not within END_SNAP of its length. The Houdini scene
(tests/test_sphere_in_fog_twin.py: a sphere of medium in fog over a floor, a point light) at rtol 1e-10 has a
piece 2.4e-3 long starting on the light's tangent cone in pixel (4, 4), whose kink lay 2.4e-15 beyond the
relative snap: its panels were dropped and its bound was inf. Against that file's twin (scipy along each camera
ray, the sphere's chords in closed form), on the pixels whose fog lies in the sphere's shadow, at rtol 1e-6 and
1e-10: every bound finite, never exceeded (but for the twin's own 1e-11), and not vacuous."""
import numpy as np
import pytest

from raytrace import api

from .test_sphere_in_fog_twin import scene, twin_image

SHADOW = (2, 3, 6, 5)  # rows 3 and 4, columns 2 to 5 (crop: x0, y0, x1, y1): light crossing the sphere


@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_every_shadow_pixel_is_bounded(rtol):
    """Within 10 rtol of the twin, inside the bound plus the twin's own 1e-11, the bound finite on every pixel
    and its median at most 10 rtol of the value; no panel left short of its tolerance."""
    ref = twin_image()[3:5, 2:6]
    img = api.render(scene(), "quadrature", rtol=rtol, volumetric_shadows=True, crop=SHADOW)
    err = np.abs(img.array - ref)
    assert np.max(err / ref) < 10.0 * rtol, np.max(err / ref)
    assert np.all(err <= img.error_bound + 1e-11 * ref)
    assert np.all(np.isfinite(img.error_bound))
    assert img.stats.get("shadows: through-interior integrals not converged", 0) == 0
    assert np.median(img.error_bound / ref) <= 10.0 * rtol
