"""The rounding term of a refractive exact sphere's bound beside a marginal-cone crossing
(media/sphere_refraction.py `_near`): the rounding of the paths near the lit arc's end peaks within
about 1e-5 of the crossing, and the piece beside it, split where its largest absolute rounding x its
length exceeds its rule's bound, keeps that peak to a short piece."""
import numpy as np

from .test_refracted_sphere import CAMERA, LAMP, Twin, ball, image


def test_the_peak_beside_a_cone_crossing_stays_local():
    """The water ball under the lamp at 32 x 24, pixel (9, 14) (its segment crosses the marginal cone
    0.32 in; unsplit its bound was 174 rtol, the rounding term's): against the twin, the bound holds
    and is within 3 rtol of the value."""
    scene = ball(1.33, LAMP)
    scene["camera"] = CAMERA | {"width": 32, "height": 24}
    res = image(scene, "quadrature", {"rtol": 1e-6})
    ref = Twin(scene).pixel(9, 14)[0]
    value, bound = res.image[14, 9].astype(float), res.error_bound[14, 9].astype(float)
    assert np.all(np.abs(value - ref) <= bound), (value - ref, bound)
    assert np.all(bound < 3e-6 * value), bound / value
