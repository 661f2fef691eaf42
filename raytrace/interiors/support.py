"""What the methods take in scenes with media inside shapes, and the statistics of the inside integrals.

Each method's `Supports.interiors` (methods/__init__.py) says how it integrates the inside rows and
what it takes there (`check` refuses the rest in one line): `quadrature` (adaptive, the reference),
`analytic` (directional lights only: the exact closed form in convex index-matched shapes of at most
MAX_FACES planes, with an error bound; the adaptive quadrature in other index-matched shapes, counted;
the refracted beams in convex refractive shapes, bounded; the adaptive quadrature in a refractive exact
sphere, counted; eq. 5 through other refractive boundaries),
`slab_approx` (eq. 5 and the note's separable approximation for point lights, not spots), `raymarch`
(its `steps` midpoints per inside row) and `montecarlo` (`samples` free-path samples per inside row
and light, whatever its --sampling; variance kept); `lecocq` and `sun` are refused for scenes with
interiors, in one line. `summarize` names the statistics' slots in the render's summary.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..lights import Lights
from ..media.adaptive import CAPPED
from ..media.inside_rule import QUAD
from ..media.sphere_refraction import UNBOUNDED
from ..methods import registry
from ..shadows.frusta import point_triangle_distance
from . import paths
from .shapes import KERNEL_PLANES, convex_planes, inside_of, interiors, refracting_planes

# the inside integrals' statistics: media/adaptive.py's slots (EVALS, INTERVALS, CAPPED), the segments a method with
# closed forms (methods/ `Interiors.closed_forms`) hands to its rule (`single_scattering`); with volumetric shadows
# the inside segments rendered unshadowed (refractive or planar-model interiors: `lit_single_scattering`), the lit
# pieces of the others, and the outside air-light's pieces whose light crosses index-matched interiors
# (`through_airlight`) and those of their integrals that fell short of their tolerance; the segments of refractive
# exact spheres whose quadrature bound is infinite, inside or in the fog a lamp inside lights (held.py; media/
# sphere_refraction.py UNBOUNDED, which writes that slot itself), and the refracted point- and spot-light segments
# whose shadow breaks could not be located (their bound inf: rows.py `_lit_point`)
HANDED, UNSHADOWED, LIT_PIECES, THROUGH, THROUGH_CAPPED = range(3, 8)
SPHERE_UNBOUNDED = UNBOUNDED  # 8
UNLOCATED = 9
STATS_SIZE = 10


def summarize(prep, method, stats, shadows: bool = False) -> dict:
    """The render statistics of the inside integrals (`single_scattering`'s, and `held_airlight`'s of the fog lit
    from inside refractive shapes) in a scene with media inside shapes: the adaptive integrator's integrals that
    fell short of their tolerance (a piece accepted at a cap), as quadrature reports its own outside; for a method
    with closed forms also the segments (one per ray and light) it handed to its rule; nothing for the other inside
    rules, which have no caps, nor for the entry plane's model. With volumetric shadows also the inside segments
    rendered unshadowed, the lit pieces of the others, the outside pieces integrated through interiors, and the
    refracted segments whose shadow breaks were not located (shadows/fermat_legs.py: their bound is inf)."""
    sup = method.supports.interiors
    if prep.interior_shapes is None or not len(prep.interior_shapes) or sup is None:
        return {}
    out = {}
    if sup.kind == QUAD and not sup.entry_plane:
        out["inside: integrals not converged"] = int(stats[CAPPED])
        if stats[SPHERE_UNBOUNDED]:
            out["inside: refracted sphere segments unbounded"] = int(stats[SPHERE_UNBOUNDED])
    if sup.closed_forms:
        out["inside: segments handed to quadrature"] = int(stats[HANDED])
    if shadows:
        through = 'quadrature' if sup.through == 'quadrature' else method.name
        out.update({"inside: segments unshadowed (refractive or planar model)": int(stats[UNSHADOWED]),
                    "inside: lit pieces": int(stats[LIT_PIECES]),
                    f"shadows: pieces through interiors ({through})": int(stats[THROUGH]),
                    "shadows: through-interior integrals not converged": int(stats[THROUGH_CAPPED]),
                    "inside: segments with shadow breaks not located (bound inf)": int(stats[UNLOCATED])})
    return out


def outside_lights(prep):
    """The lights whose air-light outside the shapes a method must integrate: none when the scene has
    interior media and the outside does not scatter (then only the inside rows' kernels see them, rows.py)."""
    if len(prep.interior_shapes) and not prep.scene.medium.scatters:
        return Lights.of([])
    return prep.lights


def check(prep, method, method_params, source: str, shadows: bool):
    """Refuse, in one line, what this first cut, or the method (its `Supports.interiors`), does not
    render in a scene with interior media (`shadows`: volumetric shadows on)."""
    inner = [i for i, m in enumerate(interiors(prep.scene)) if m is not None]
    if not inner:
        return
    key = f"shape[{inner[0]}].interior"
    sup = method.supports.interiors
    if sup is None:
        raise UserError(f"{source}: --method {method.name}: it does not integrate media inside shapes ({key}); use "
                        f"--method {', '.join(_takers())}")
    kinds = prep.lights.kinds()
    fixed = [k for k in sup.fixed if method_params.get(k, method.params[k].default) != method.params[k].default]
    if fixed:
        raise UserError(f"{source}: {' / '.join('--' + k.replace('_', '-') for k in fixed)} "
                        f"({', '.join('render.' + k for k in fixed)}): not implemented inside bounded media ({key}) "
                        f"yet; remove {'it' if len(fixed) == 1 else 'them'}")
    for kind in sorted(kinds - set(sup.lights)):
        takers = _takers(lambda s: kind in s.lights)
        why = f"{kind} lights into a bounded medium ({key})" + (f": {sup.limits}" if sup.limits else "")
        raise UserError(f"{source}: --method {method.name}: {why}; " + (
            f"use --method {', '.join(takers)}" if takers else
            "no method renders them yet (remove the shape's interior, or use point, spot or directional lights)"))
    if method.samples_shadows(method_params):
        raise UserError(f"{source}: --shadow-test samples (render.shadow_test): not implemented with media inside "
                        f"shapes ({key}); use --shadow-test intervals (the default)")
    medium = prep.scene.medium
    if not medium.homogeneous:
        raise UserError(f"{source}: {key}: media inside shapes need a homogeneous (or vacuum) [medium] outside; "
                        f"{medium.type_name} is not implemented with them yet")
    for i in inner:
        m = prep.scene.shapes[i].interior
        method.check_phase(m, f"shape[{i}].interior.phase", source)
        for kind in sorted(kinds - set(sup.refracted) if m.ior != 1.0 else ()):
            takers = _takers(lambda s: kind in s.refracted)
            why = f": {sup.limits}" if kind in sup.lights and sup.limits else ""
            raise UserError(f"{source}: shape[{i}].interior.ior: --method {method.name}: {kind} lights through a "
                            f"refractive boundary{why}; use ior = 1"
                            + (f", or --method {', '.join(takers)}" if takers else ""))
    inside = prep.camera_inside
    if inside is not None and (not sup.camera_inside or (prep.scene.shapes[inside].interior.ior != 1.0 and not len(
            refracting_planes(prep, inside)) and paths.exact_sphere(prep, inside) is None)):
        raise UserError(f"{source}: camera.position: inside shape[{inside}], which holds a medium; a camera inside a "
                        "bounded medium needs an index-matched interior (ior = 1), a convex shape or an exact sphere, "
                        f"and --method {', '.join(_takers(lambda s: s.camera_inside))}; move the camera out of the "
                        "shape or change them")
    for li in np.nonzero(~prep.lights.distant)[0]:
        inside = inside_of(prep, prep.lights.position[li], inner)
        if inside is not None and prep.lights.cubature[li]:
            raise UserError(f"{source}: light[{prep.lights.owner[li]}].position: inside shape[{inside}], which holds a "
                            "medium; an emitter inside a bounded medium is not implemented; move the light out of "
                            "the shape")
        why = _not_held(prep, inside, li, shadows) if inside is not None else None
        if why:
            raise UserError(f"{source}: light[{prep.lights.owner[li]}].position: inside shape[{inside}], which holds a "
                            f"medium of ior {prep.scene.shapes[inside].interior.ior:g}; a point or spot light inside "
                            f"a refractive medium {why}; move the light out of the shape or set its ior = 1")
        if inside is not None and sup.entry_plane:
            raise UserError(f"{source}: --method {method.name}: light[{prep.lights.owner[li]}].position inside "
                            f"shape[{inside}]: its inside model sees the light through the plane of the face a camera "
                            f"ray enters by; use --method {', '.join(_takers(lambda s: s.exact_paths))}")


def _not_held(prep, sid, li, shadows) -> str | None:
    """Why light li inside the interior of shape sid is refused, None where it is taken:
    index-matched, or a convex refractive mesh of at most KERNEL_PLANES faces or an exact sphere
    (`lit_from_inside`) with no other shape inside, the camera outside and no other shape holding a medium; in a
    scattering outside medium (`held_airlight`) a point or spot light in a convex mesh or well inside an exact sphere
    (`_globe_fog`), and with volumetric shadows none reaching into a sphere."""
    if prep.scene.shapes[sid].interior.ior == 1.0:
        return None
    sphere = paths.exact_sphere(prep, sid) is not None
    if not sphere and not len(convex_planes(prep, sid)):
        return f"needs a convex shape of at most {KERNEL_PLANES} faces or an exact sphere"
    if prep.scene.medium.scatters:  # lights the fog outside (`held_airlight`)
        why = _globe_fog(prep, sid, li) if sphere else None
        if why:
            return why
        met = _meeting(prep, sid) if shadows and sphere else None
        if met is not None:
            return (f"lights the scattering [medium] outside, where shape[{met}]'s volumetric shadow is implemented "
                    f"for shapes outside the sphere only, and shape[{met}] reaches into it; move it out of the sphere "
                    "or use --no-volumetric-shadows")
    if prep.camera_inside == sid:
        return "is not implemented with the camera inside the same shape yet"
    media = [int(j) for j in prep.interior_shapes if j != sid]
    if media:  # the light refracted out into another medium
        return f"is not implemented with another shape holding a medium (shape[{media[0]}]) yet"
    inner = _meeting(prep, sid) if sphere else _reaching(prep, sid)
    if inner is not None:
        return f"is not implemented with another shape inside it or reaching into it (shape[{inner}]) yet"
    return None


def _reaching(prep, sid, rel=1e-9) -> int | None:
    """The first other shape with a triangle reaching into the convex mesh sid ({x : n_f·x <= c_f}), deeper than rel
    of the mesh's size inside every plane (touching it is not reaching in), else None: each triangle not beyond one
    plane with all its corners is clipped against every plane (Sutherland-Hodgman); it reaches in where some of it
    is left."""
    planes = convex_planes(prep, sid)
    own = prep.accel.triangles[prep.shape_ids == sid].reshape(-1, 3).astype(float)
    inset = planes[:, 3] - rel * (np.ptp(own, axis=0).max() + np.abs(own).max())
    tris = prep.accel.triangles.astype(float)
    depth = np.einsum("tkj,fj->tfk", tris, planes[:, :3]) - inset[None, :, None]  # (T, F, 3)
    near = np.nonzero((prep.shape_ids != sid) & ~(depth >= 0.0).all(axis=2).any(axis=1))[0]
    for t in near:
        poly = list(tris[t])
        for n, c in zip(planes[:, :3], inset):
            poly = _clip(poly, n, c)
        if poly:
            return int(prep.shape_ids[t])
    return None


def _clip(poly, n, c):
    """The convex polygon poly (a list of points) cut to n·x < c (Sutherland-Hodgman)."""
    out = []
    for i, p in enumerate(poly):
        q = poly[(i + 1) % len(poly)]
        dp, dq = float(p @ n) - c, float(q @ n) - c
        if dp < 0.0:
            out.append(p)
        if (dp < 0.0) != (dq < 0.0):
            out.append(p + dp / (dp - dq) * (q - p))
    return out


def _meeting(prep, sid) -> int | None:
    """The first other shape with a triangle within the exact sphere sid's ball (its shadow on the light refracted
    out would start inside the glass: media/globe_shadows.py takes occluders outside), else None."""
    sphere = paths.exact_sphere(prep, sid)
    centre, radius = np.asarray(sphere[:3], float), float(sphere[3])
    tris = prep.accel.triangles.astype(float)
    near = np.nonzero((prep.shape_ids != sid) & (tris.min(axis=1) <= centre + radius).all(axis=1)
                      & (tris.max(axis=1) >= centre - radius).all(axis=1))[0]
    for t in near:
        if point_triangle_distance(*centre, *tris[t]) <= radius:
            return int(prep.shape_ids[t])
    return None


def _globe_fog(prep, sid, li) -> str | None:
    """Why point or spot light li inside the refractive exact sphere sid is refused with a scattering outside medium
    (None where taken: ior > 1 and the light closer to the centre than radius / ior, where each point outside has
    one path, media/sphere_refraction.py `out_of_sphere`)."""
    sphere = paths.exact_sphere(prep, sid)
    centre, radius = sphere[:3], float(sphere[3])
    ior = prep.scene.shapes[sid].interior.ior
    if ior < 1.0 or np.linalg.norm(prep.lights.position[li] - centre) >= radius / ior:
        return (f"in an exact sphere lights the scattering [medium] outside only from within radius / ior "
                f"({radius / ior:g}) of its centre, with ior > 1; beyond, the breaks where its paths out change (the "
                "critical angle's cones, the caustic) are not implemented yet; move the light closer to the centre, "
                "or use a [medium] that does not scatter")
    return None


def _takers(test=lambda interiors: True) -> list[str]:
    """The methods that integrate media inside shapes and whose `Supports.interiors` passes `test`."""
    return [m.name for m in registry().values() if m.supports.interiors is not None and test(m.supports.interiors)]
