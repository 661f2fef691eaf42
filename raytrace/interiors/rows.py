"""The single scattering of inside rows: the `Segments` rows that the boundary crossing (interiors/crossing.py)
makes of camera rays inside shapes that hold a medium, integrated by the method's inside rule
(`Supports.interiors`: its inside rule, media/inside_rule.py, and what it declares of the light's path
inside), with volumetric shadows over each light's exact lit pieces, and the outside air-light whose
light crosses index-matched interiors (`through_airlight`).

Each inside row starts at its entry point (the boundary, or the camera inside the shape) and runs
along the refracted ray for its length; its `medium` is the shape whose interior holds it, its
`normals` the outward normal of the face it entered by (the analytic note's planar boundary), its
`reach` how light reaches it (`crossing.STRAIGHT`: the light's straight path to a convex index-matched
shape's faces; `TRACED`: straight through a non-convex one, measured with Embree; `REFRACTED`:
through the refracting boundary). A row integrates every light (`light` = -1).

In an index-matched shape the light's path inside is its exact straight path for the methods with
`exact_paths`, else the note's entry plane (`entry_plane`: slab_approx). With `closed_forms` (analytic,
directional lights) in an index-matched shape: convex, at most MAX_FACES planes, the closed form of
media/convex_directional.py with its bound; else the segments go to the method's rule (its adaptive
quadrature: `_traced`, rtol methods.INSIDE_RTOL), counted (HANDED), with its bound. Through a refractive boundary a
directional light enters a convex shape through every face it meets, one beam each
(`fresnel.refracted_beams`: the exact refracted path; the closed forms bounded as above), other shapes
through every triangle, each beam over its exact lit pieces (`_sun_faces`; closed forms and QUAD bounded, ior > 1:
the pieces' ends by media/nonconvex_directional.py `end_bounds`); a point or spot
light enters a convex one through every face it is outside of (media/slab.py `faces_point`: Fermat's
path per face), other shapes through every face whose legs are clear of the shape (`_through_faces`,
paths.refracted_integrand; the entry plane's model keeps the entry plane). Every light enters an exact
sphere on its exact refracted paths (media/sphere_refraction.py, `_refracted_sphere`; closed forms hand
them to the rule, counted; QUAD bounded but where a caustic crossing has no fold pair); the entry plane's
model keeps the entry plane everywhere.

QUAD (quadrature) bounds its integrals in index-matched shapes (docs/error_bounds.md, "Inside shapes"):
convex ones of at most MAX_FACES planes in media/slab.py's kernel (`plane_errors`: how far its
planes are from the faces), others on the facet walk's exit planes or on traced walks
(paths.segment_quadrature), and in refractive exact spheres (`_refracted_sphere`, but where a caustic
crossing has no fold pair); a directional light's refracted beams in convex refractive shapes (ior >
1): of at most MAX_FACES planes by the distance of each beam's value from its closed form plus the
closed form's bound (`_beam_terms`), of more by `_face_beams`; in refractive shapes that are not convex each
triangle's beam (`_sun_faces`: the pieces' ends' uncertain spans times the integrand, each piece's closed form or
rule bound); elsewhere, and for the other rules (but
the closed forms), the bound is infinite.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from ..error_bounds import KERNEL_FLOOR, product, rays_with, spot_rounding
from ..media.adaptive import CAPPED
from ..media.convex_directional import EPS, MAX_FACES, beam_intervals, beams_closed, segments_bounded
from ..media.inside_rule import MARCH, QUAD
from ..media.nonconvex_directional import crossing_error, end_bounds, face_errors, lit_pieces
from ..media.slab import EVERY, GEO_COLUMNS, STREAM, inside_radiance, phase_condition, plane_closed, segment_reach
from ..media.sphere_refraction import sphere_refracted
from ..methods import Segments
from ..methods.geometry import segment_light_table
from ..segments import gather, gather_weights
from ..shadows.beams import lit_pieces_of_beam
from ..shadows.fermat_legs import lit_pieces_of_point, span_errors
from ..shadows.frusta import exact_lit_intervals
from ..shadows.through_others import attenuated_radiance, refracted_attenuated
from ..shadows.shadow_rays import shadowed_airlight
from . import paths
from .crossing import MAX_DEPTH, REFRACTED, TRACED, scaled
from .fresnel import refract, refracted_beams, transmittance
from .held import held_lights
from .shapes import (blockers, convex_planes, hull_planes, matched, measured_plane_errors, plane_neighbours,
                     refracting_planes)
from .support import HANDED, LIT_PIECES, STATS_SIZE, THROUGH, THROUGH_CAPPED, UNLOCATED, UNSHADOWED


def integrate(prep, method, params, rows: Segments, seed, depth, shadows: bool):
    """Each inside row's single scattering (R, 3) at its start, its variance (R, 3) (0 but for the
    sampling integrator), a bound (R, 3) on its error (inf where none is known) and the statistics
    (STATS_SIZE), the rows of each interior integrated together (`lit_single_scattering`)."""
    n = len(rows)
    val, var, bound = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    stats = np.zeros(STATS_SIZE)
    for sid in np.unique(rows.medium).tolist():
        sel = np.nonzero(rows.medium == sid)[0]
        val[sel], var[sel], st, bound[sel] = lit_single_scattering(
            prep, method, params, sid, rows.origins[sel], rows.normals[sel], rows.dirs[sel], rows.length[sel],
            rows.keys[sel], rows.reach[sel[0]] if len(sel) else 0, seed, depth, shadows)
        stats += st
    return val, var, bound, stats


def single_scattering(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth, light=None,
                      piece=0, beam=None):
    """Inside single scattering (N, 3) at the entry points along the refracted rays w, over [0, ell],
    summed over the lights, for the interior `medium` with outward entry normals `normals`, its
    variance (N, 3) (0 but for the sampling integrator), its statistics (STATS_SIZE) and a bound
    (N, 3) on its error (inf where none is known). `reach`: how light reaches the rows (the crossing's
    crossing.STRAIGHT, TRACED or REFRACTED). The method's inside rule is its
    `Supports.interiors.rule(params)`; in an index-matched shape the light's path inside is its exact
    straight path (convex: `convex_planes`; else traced, `_traced`) for the methods with
    `exact_paths`, else the note's entry plane (`entry_plane`: `plane_closed`). With `closed_forms`
    (analytic, directional lights) in an index-matched shape: convex, at most MAX_FACES planes, the closed
    form of media/convex_directional.py with its bound; else the segments go to the rule (`_traced`, its
    adaptive quadrature at rtol RTOL), counted (HANDED), bounded as QUAD's. Through a refractive boundary a
    directional light enters a convex shape (`convex_planes`) through every face it meets, one beam each
    (`refracted_beams`: the exact refracted path; closed forms bounded as above, QUAD by each beam's distance
    from its closed form plus the closed form's bound, `_beam_terms`), other shapes through every triangle, each beam
    over its exact lit pieces (`_sun_faces`, bounded for closed forms and QUAD); a point or spot light a convex one through every face it is
    outside of (media/slab.py `faces_point`), or one inside it (held.py `held_lights`) along its straight
    paths, wholly inside (an exact sphere's by its chords, `_traced`); other shapes through every face whose
    legs are clear (`_through_faces`); every light outside an exact sphere on its exact refracted paths
    (`_refracted_sphere`).
    `light`: that light only (else all); `piece`: the segments' rank among their ray's lit pieces
    (`lit_single_scattering`), which numbers their random streams; `beam`: of a directional light's refracted
    beams, or of a point or spot light's refracted paths, only the one through that face (`_lit_beams`)."""
    medium = prep.scene.shapes[sid].interior
    planes = convex_planes(prep, sid)
    refractive = reach == REFRACTED
    traced = reach == TRACED  # non-convex, index-matched: paths measured with Embree
    geo = np.zeros((len(points), GEO_COLUMNS))
    geo[:, :3], geo[:, 3:6], geo[:, 14:17] = points, w, normals
    lights = prep.lights
    n = len(points)
    out = np.zeros((n, 3))
    var = np.zeros((n, 3))
    sup = method.supports.interiors
    closed = sup.closed_forms and not refractive  # the exact closed form, or the rule where there is none
    kernel = sup.closed_forms and 0 < len(planes) <= MAX_FACES  # exact and bounded (refractive: the beams)
    beams = refractive and len(planes) > 0 and not sup.entry_plane  # the note's model keeps its plane
    faces = refracting_planes(prep, sid) if refractive and not sup.entry_plane else np.zeros((0, 4))
    near = plane_neighbours(prep, sid) if len(faces) else EVERY
    bound = np.zeros((n, 3))
    rule = sup.rule(params)
    stats = np.zeros(STATS_SIZE)
    a = -np.einsum("ij,ij->i", w, normals)
    dplanes = measured_plane_errors(prep, sid)
    dims = STREAM + piece * MAX_DEPTH * len(lights) * rule.steps

    def integrate(li, distant, xh, h, hl, b, mu, wl, ll, scale, used, only=-1, toward=None, eta=float(medium.ior)):
        ch = np.nonzero((medium.sigma_s != 0.0) & (lights.intensity[li] != 0.0))[0]  # the channels lit and scattering
        if not len(ch):
            return
        unit, unit_var, unit_err = np.empty((n, len(ch))), np.empty((n, len(ch))), np.empty((n, len(ch)))
        kt, ks = medium.sigma_t[ch].astype(float), medium.sigma_s[ch].astype(float)
        kt_out = prep.scene.medium.sigma_t[ch].astype(float)
        if sup.closed_forms or sup.entry_plane:  # through the entry plane
            plane_closed(distant, xh, h, hl, a, b, mu, ell, kt, ks, medium.phase, medium.g, kt_out, sup.entry_plane,
                         unit, unit_var, unit_err)
        else:
            inside_radiance(distant, xh, h, hl, a, b, mu, ell, kt, ks, medium.phase, medium.g, kt_out, wl, ll,
                            eta, geo, used, near if used is faces else EVERY, dplanes, only, rule, keys,
                            np.uint64(dims + (depth * len(lights) + li) * rule.steps + (only + 1) * STREAM),
                            np.uint64(seed), unit, unit_var, unit_err, stats)
        if toward is not None and rule.kind == QUAD:  # beam `only`: against its closed form
            unit_err = against_beam(unit, li, only, toward, kt, ks)
        for j, c in enumerate(ch.tolist()):
            f = scale * lights.intensity[li, c]
            out[:, c] += unit[:, j] * f
            var[:, c] += unit_var[:, j] * f * f
            bound[:, c] += _light_bound(unit_err[:, j], unit[:, j] * f, f, lights.cone[li, 0])

    def against_beam(value, li, f, toward, kt, ks):
        """A bound on the error of `value` (N, C), beam f's per unit irradiance: its distance from the beam's
        closed form plus that form's bound (`_beam_terms`, which has the beam's direction and irradiance
        errors from the planes' own); inf where light enters through a lower index (ior < 1)."""
        if not medium.ior > 1.0:
            return np.where(ell[:, None] > 0.0, np.inf, 0.0) * np.ones(value.shape)
        _, val, _, _, err = _beam_terms(planes, near, f, np.ascontiguousarray(toward), lights.axis[li], medium, dplanes,
                                        (points, w, ell), kt, ks)
        return (np.abs(value - val) + err) * (1.0 + 2.0 * EPS)

    def closed_form(li, toward, scale, only):
        val, b = np.empty((n, 3)), np.empty((n, 3))
        segments_bounded(np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3]),
                         np.ascontiguousarray(points), np.ascontiguousarray(w), np.ascontiguousarray(ell),
                         np.ascontiguousarray(toward), medium.sigma_t, medium.sigma_s, medium.phase, medium.g, val, b,
                         only)
        if refractive:  # `toward` refracted through computed planes: bounded against the beam's closed form
            b = against_beam(val, li, only, toward, medium.sigma_t.astype(float), medium.sigma_s.astype(float))
        out[:] += val * (lights.intensity[li] * scale)
        bound[:] += b * (lights.intensity[li] * scale)

    zero = np.zeros(n)
    sphere = paths.exact_sphere(prep, sid) if refractive and not sup.entry_plane else None
    for li in range(len(lights)) if light is None else [light]:
        idx = np.full(n, li, dtype=np.int64)
        distant = np.full(n, lights.distant[li])
        if lights.distant[li]:
            geo[:, 9:12], geo[:, 12:14], geo[:, 17] = 0.0, lights.cone[li, :2], lights.cone[li, 2]
            if sphere is not None:
                geo[:, 6:9] = -lights.axis[li]
                _refracted_sphere(prep, sid, sphere, geo, True, ell, li, sup, rule, keys,
                                  dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats)
                continue
            if beams:
                for f, toward, irradiance in zip(*refracted_beams(planes, lights.axis[li], medium.ior)):
                    if beam is not None and f != beam:
                        continue
                    if kernel:
                        closed_form(li, toward, irradiance, int(f))
                        continue
                    geo[:, 6:9] = toward
                    integrate(li, distant, zero, zero, zero, zero, w @ toward, zero, zero, irradiance, planes, int(f),
                              np.ascontiguousarray(toward))
                continue
            if len(faces):  # more than KERNEL_PLANES planes: each beam over its lit interval
                _face_beams(prep, sid, faces, near, li, beam, (points, w, ell, keys), sup, rule,
                            dims + (depth * len(lights) + li) * rule.steps, seed, (out, var, bound, stats))
                continue
            if refractive and not sup.entry_plane:  # not convex: every triangle's beam over its lit pieces
                _sun_faces(prep, sid, li, (points, w, ell, keys), sup, rule,
                           dims + (depth * len(lights) + li) * rule.steps, seed, (out, var, bound, stats))
                continue
            if kernel:
                closed_form(li, -lights.axis[li], 1.0, -1)
                continue
            geo[:, 6:9] = -lights.axis[li]
            axis = np.broadcast_to(lights.axis[li], (n, 3))
            cos_l = -(normals @ lights.axis[li])
            t_l, b = refract(axis, normals, medium.ior)
            b = np.where(cos_l > 0.0, b, 0.0)
            mu = -np.einsum("ij,ij->i", t_l if refractive else axis, w)  # index-matched: not bent (refract
            # would mirror the light off an entry face it meets from behind)
            scale = np.where(cos_l > 0.0, transmittance(np.maximum(cos_l, 0.0), medium.ior) * np.maximum(cos_l, 0.0)
                             / np.maximum(b, 1e-300), 0.0) if refractive else 1.0
            if closed or (traced and sup.exact_paths):
                if closed:
                    stats[HANDED] += np.count_nonzero(ell > 0.0)
                _traced(prep, sid, medium, geo, True, ell, lights.intensity[li] * scale, rule, keys,
                        dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats)
                continue
            integrate(li, distant, zero, zero, zero, b, mu, zero, zero, scale, planes if not refractive else np.zeros((0, 4)))
            continue
        # a point or spot light (the spot's falloff toward the direction it leaves in: media/slab.py)
        xh, h, _, _ = segment_light_table(points, w, lights.position, lights.axis, lights.cone, idx, prep.accel.scale)
        geo[:, 6:9], geo[:, 9:12], geo[:, 12:14] = lights.position[li], lights.axis[li], lights.cone[li, :2]
        geo[:, 17] = lights.cone[li, 2]  # the spot's falloff curve
        rel = lights.position[li] - points
        hl = np.einsum("ij,ij->i", rel, normals)
        wl = ll = zero
        if refractive:  # horizontal parts, for the refracted path (media/slab.py refracted_point)
            lh = rel - hl[:, None] * normals
            wl = np.einsum("ij,ij->i", w + a[:, None] * normals, lh)
            ll = np.einsum("ij,ij->i", lh, lh)
        if sphere is not None and (li, sid) in held_lights(prep):  # inside: straight, wholly inside (chords)
            _traced(prep, sid, medium, geo, False, ell, lights.intensity[li], rule, keys,
                    dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats, lights.cone[li, 0])
            continue
        if sphere is not None:
            _refracted_sphere(prep, sid, sphere, geo, False, ell, li, sup, rule, keys,
                              dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats)
            continue
        if closed or (traced and sup.exact_paths):
            if closed:
                stats[HANDED] += np.count_nonzero(ell > 0.0)
            _traced(prep, sid, medium, geo, False, ell, lights.intensity[li], rule, keys,
                    dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats, lights.cone[li, 0])
            continue
        if refractive and sphere is None and not len(faces) and not sup.entry_plane:  # not convex: every face
            _through_faces(prep, sid, medium, geo, ell, lights.intensity[li], rule, keys,
                           dims + (depth * len(lights) + li) * rule.steps, seed, out, var, bound, stats,
                           lights.cone[li, 0])
            continue
        if refractive and (li, sid) in held_lights(prep):  # inside a convex refractive shape: straight, wholly inside
            integrate(li, distant, xh, h, hl, zero, zero, zero, zero, 1.0, planes, eta=1.0)
            continue
        integrate(li, distant, xh, h, hl, zero, zero, wl, ll, 1.0,
                  planes if not refractive else faces,  # refractive: faces_point's faces
                  -1 if beam is None else int(beam))
    used = np.arange(len(lights)) if light is None else [light]
    if np.any(lights.cubature[used]):  # an emitter's cubature or the environment's directions: no bound
        bound[ell > 0.0] = np.inf
    return out, var, stats, bound


def _face_beams(prep, sid, planes, near, li, beam, rows, sup, rule, dim0, seed, acc, others=None):
    """acc = (out, var, bound, stats) += directional light li's single scattering over the rows (points,
    w, ell, keys) of the convex refractive shape sid of more than KERNEL_PLANES face `planes` (neighbours
    `near`): each beam it makes (`refracted_beams`; with `beam`, that face's alone) over the interval
    of each segment where the path back leaves through its face (media/convex_directional.py
    `beam_intervals`, from the face's neighbours alone), as the method declares (`sup`): with closed
    forms the closed form (`beams_closed`, bounded as `segments_bounded` with the planes' own errors), else
    its `rule` (QUAD, MARCH or SAMPLE) over the interval from its start on the face's plane alone (the exit
    there is that face's; the kernel takes it as a straight path, eta 1, the beam's direction and irradiance
    given, so QUAD's bound is `convex_bounded`'s), carried back by exp(-sigma_t lo); the closed form's and QUAD's
    bounds add
    the beam's direction and irradiance errors (`_beam_errors`) and what the interval's ends may
    change, misplaced within their spans. `others` (`_other_interiors`): the beam attenuated by the
    other index-matched interiors on its entry point's path to the sun (shadows/through_others.py
    `attenuated_radiance` on face f's plane alone, `only` that plane; closed forms, which have none with
    the chords, by the rule, counted HANDED), the kernel's bound with the planes' normal error widened
    by twice the beam direction's error (the entry point X + k toward moves by at most 2 k du / q_f);
    the ends' spans bounded as without them (the attenuation is at most 1)."""
    points, w, ell, keys = rows
    out, var, bound, stats = acc
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    ch, kt, ks, kt_out = _scattering_channels(prep, medium, li)
    if not len(ch):
        return
    dplanes = measured_plane_errors(prep, sid)
    eta = float(medium.ior)
    for f, toward, irradiance in zip(*refracted_beams(planes, lights.axis[li], medium.ior)):
        if beam is not None and f != beam:
            continue
        toward = np.ascontiguousarray(toward)
        ints, val, edges, rel, err = _beam_terms(planes, near, int(f), toward, lights.axis[li], medium, dplanes,
                                                (points, w, ell), kt, ks)
        f_li = irradiance * lights.intensity[li, ch]
        if sup.closed_forms and others is None:
            out[:, ch] += val * f_li
            bound[:, ch] += product(err, f_li)
            continue
        sel = np.nonzero(ints[:, 1] > ints[:, 0])[0]
        lo, m = ints[sel, 0], len(sel)
        geo = np.zeros((m, GEO_COLUMNS))
        geo[:, :3], geo[:, 3:6], geo[:, 6:9] = points[sel] + lo[:, None] * w[sel], w[sel], toward
        geo[:, 12:14], geo[:, 17] = lights.cone[li, :2], lights.cone[li, 2]
        unit, unit_var, unit_err = np.empty((m, len(ch))), np.empty((m, len(ch))), np.empty((m, len(ch)))
        face, dim = np.ascontiguousarray(planes[f:f + 1]), np.uint64(dim0 + (f + 1) * STREAM)
        if others is None:
            zero = np.zeros(m)
            inside_radiance(np.ones(m, np.bool_), zero, zero, zero, zero, zero, w[sel] @ toward, ints[sel, 1] - lo, kt,
                            ks, medium.phase, medium.g, kt_out, zero, zero, 1.0, geo, face, EVERY, dplanes, -1, rule,
                            keys[sel], dim, np.uint64(seed), unit, unit_var, unit_err, stats)
        else:
            oplanes, first, stop, kt_other, dothers, balls = others
            du, _ = _beam_errors(float(-(planes[f, :3] @ lights.axis[li])), eta, dplanes[0])
            wide = np.array([dplanes[0] + 2.0 * du, dplanes[1]])
            if sup.closed_forms:
                stats[HANDED] += m
            col, col_var, col_err = np.empty(m), np.empty(m), np.empty(m)
            for j, c in enumerate(ch.tolist()):
                attenuated_radiance(True, geo, face, ints[sel, 1] - lo, kt[j], ks[j], medium.phase, medium.g, kt_out[j],
                                    oplanes, first, stop, np.ascontiguousarray(kt_other[:, c]), rule, keys[sel],
                                    dim, np.uint64(seed), wide, dothers, balls, 0,
                                    np.ascontiguousarray(-lights.axis[li]), col, col_var, col_err, stats)
                unit[:, j], unit_var[:, j], unit_err[:, j] = col, col_var, col_err
        with np.errstate(over="ignore", invalid="ignore"):
            tr = np.where(kt[None, :] == 0.0, 1.0, np.exp(-kt[None, :] * lo[:, None]))
        for j, c in enumerate(ch.tolist()):
            out[sel, c] += unit[:, j] * tr[:, j] * f_li[j]
            var[sel, c] += unit_var[:, j] * (tr[:, j] * f_li[j]) ** 2
            bound[sel, c] += _light_bound(product(unit_err[:, j], tr[:, j]) + rel[sel, j] * unit[:, j] * tr[:, j],
                                          unit[:, j] * tr[:, j] * f_li[j], f_li[j], lights.cone[li, 0])
        if rule.kind == QUAD:  # the closed form's, or QUAD's
            bound[:, ch] += product(edges, f_li)
        else:
            bound[np.ix_(ell > 0.0, ch)] = np.inf
    if eta < 1.0:  # the irradiance is not monotone in cos_i there (`_beam_errors`)
        bound[np.ix_(ell > 0.0, ch)] = np.inf


def _scattering_channels(prep, medium, li):
    """(channels, sigma_t, sigma_s inside, sigma_t outside on them): the channels where the shape's `medium`
    scatters light li."""
    ch = np.nonzero((medium.sigma_s != 0.0) & (prep.lights.intensity[li] != 0.0))[0]
    return (ch, medium.sigma_t[ch].astype(float), medium.sigma_s[ch].astype(float),
            prep.scene.medium.sigma_t[ch].astype(float))


def _beam_terms(planes, near, f, toward, axis, medium, dplanes, rows, kt, ks):
    """(ints, val, edges, rel, err) of the beam of directional light `axis` refracted through face f
    (minus its direction inside: `toward`) of the convex refractive shape of face `planes` (neighbours
    `near`; their measured errors `dplanes`) over the rows (points, w, ell), per channel (kt, ks):
    media/convex_directional.py `beam_intervals`' ints, `beams_closed`'s value per unit irradiance val
    and edges, rel the relative error of the beam's direction and irradiance (`_beam_errors`) and of
    s_f's own error, and err a bound on val's error against the true beam's (`beams_closed`'s rounding,
    `segments_bounded`'s form with the planes' own errors, plus rel and edges), eta > 1."""
    points, w, ell = rows
    normals, offsets = np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3])
    n = len(ell)
    ints, val, edges = np.empty((n, 9)), np.empty((n, len(kt))), np.empty((n, len(kt)))
    du, de = _beam_errors(float(-(normals[f] @ axis)), float(medium.ior), dplanes[0])
    beam_intervals(normals, offsets, near, f, toward, points, w, ell, dplanes, du, ints)
    beams_closed(ints, toward, w, kt, ks, medium.phase, medium.g, val, edges)
    rel = kt[None, :] * ints[:, 8, None] + du * (phase_condition(medium.phase, medium.g) - 1.0) + de
    q = float(normals[f] @ toward)
    cond = 8.0 * EPS * (abs(offsets[f]) + np.linalg.norm(points, axis=1) + ell) / q
    err = (KERNEL_FLOOR + kt[None, :] * cond[:, None] + rel) * val + edges
    return ints, val, edges, rel, err


def _beam_span(prep, sid, planes, f, toward, axis, points, w, ell):
    """(segments, lo, hi): the segments that the beam of directional light `axis` refracted through face f
    (minus its direction inside: `toward`) of the convex refractive shape sid (its face `planes`) may
    light, and the widest interval of each where it may (media/convex_directional.py `beam_intervals`:
    from the lowest to the highest place its ends may lie)."""
    dplanes = measured_plane_errors(prep, sid)
    du, _ = _beam_errors(float(-(planes[f, :3] @ axis)), float(prep.scene.shapes[sid].interior.ior), dplanes[0])
    ints = np.empty((len(ell), 9))
    beam_intervals(np.ascontiguousarray(planes[:, :3]), np.ascontiguousarray(planes[:, 3]), plane_neighbours(prep, sid),
                   int(f), np.ascontiguousarray(toward), points, w, ell, dplanes, du, ints)
    sel = np.nonzero(ints[:, 5] > ints[:, 2])[0]
    return sel, ints[sel, 2], ints[sel, 5]


def _beam_errors(cos_i, eta, dn):
    """(du, de) of a beam refracted through a face whose computed normal is dn (per component) and a few
    ulps off the true face's (first order): du bounds the error of its direction inside (Snell's vector
    form t = d / eta + (cos_i / eta - cos_t) n: 2 sqrt(3) dn for the normal's terms, and the cosines'
    errors dcos_i = sqrt(3) dn + 8u over eta and dcos_t = dcos_i cos_i / (eta^2 cos_t)), de the relative
    error of its irradiance E = T cos_i / cos_t, which for eta > 1 increases with cos_i (T does, and
    d(cos_i / cos_t) / dcos_i = (1 - eta^-2) / cos_t^3 > 0): its change over cos_i +- dcos_i, plus
    16u. eta < 1: (0, 0), and `_face_beams` leaves the bound infinite."""
    u = 2.0 ** -53
    dcos = math.sqrt(3.0) * dn + 8.0 * u
    if not eta > 1.0:
        return 0.0, 0.0
    cos = np.array([max(cos_i - dcos, 0.0), cos_i, min(cos_i + dcos, 1.0)])
    cos_t = np.sqrt(1.0 - (1.0 - cos * cos) / (eta * eta))
    e = transmittance(cos, eta) * cos / cos_t
    du = 2.0 * math.sqrt(3.0) * dn + dcos / eta + dcos * cos_i / (eta * eta * cos_t[1]) + 8.0 * u
    return du, (max(e[2] - e[1], e[1] - e[0]) / e[1] if e[1] > 0.0 else 0.0) + 16.0 * u


def _sun_faces(prep, sid, li, rows, sup, rule, dim0, seed, acc):
    """acc = (out, var, bound, stats) += directional light li's single scattering over the rows (points, w, ell,
    keys) of the refractive shape sid that is not convex: each triangle's beam (`refracted_beams` of its plane
    turned toward the light) over the pieces of each segment it lights (media/nonconvex_directional.py
    `lit_pieces`: the path back leaves through that triangle, both legs clear of the shape), integrated as
    `_face_beams` integrates a convex shape's beams: with closed forms `beams_closed` on each piece, else the
    `rule` from each piece's start on the face's plane alone, carried back by exp(-sigma_t x0), each piece of a
    segment on its own random stream. The bound (eta > 1, closed forms and QUAD; inf for the other rules, as
    `_face_beams` has them): each piece's (the closed form's rounding as `_beam_terms`', or the rule's bound with
    its face's own plane errors, plus the rounding of exp(-sigma_t x0): 2 ulps and kt x0 u, doubled), the
    relative error rel of the beam's direction (du: s_F's error times kt, the phase's condition) and irradiance
    (de) of `_beam_errors` from the face's measured normal, plus what the pieces' ends may change (`lit_pieces`'
    spans, `end_bounds`: media/nonconvex_directional.py's docstring, the triangles' planes and edges measured by
    `face_errors`)."""
    points, w, ell, keys = rows
    out, var, bound, stats = acc
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    ch, kt, ks, kt_out = _scattering_channels(prep, medium, li)
    if not len(ch):
        return
    tris, planes, errs = prep.memo(("sun faces", sid), lambda: _shape_faces(prep, sid))
    turned, faces, towards, scales, du, de = prep.memo(("sun beams", sid, li), lambda: _sun_beams(prep, sid, li, planes,
                                                                                                   errs))
    points, w, ell = (np.ascontiguousarray(a, dtype=float) for a in (points, w, ell))
    bounded = (sup.closed_forms or rule.kind == QUAD) and medium.ior > 1.0  # else inf, as `_face_beams` has it
    (beams, srcs, x0s, x1s), spans = lit_pieces(tris, planes, errs, faces, towards, du, lights.axis[li], points, w, ell,
                                                bounded)
    if bounded:
        ends = np.zeros((len(ell), len(ch)))
        end_bounds(*spans, towards, scales, w, kt, ks, medium.phase, medium.g, ends)
        bound[:, ch] += product(ends, lights.intensity[li, ch])
        per, rule_err = np.zeros((len(beams), len(ch))), np.zeros((len(beams), len(ch)))  # each piece's, carried back
    else:
        bound[np.ix_(ell > 0.0, ch)] = np.inf
    bounds = np.searchsorted(beams, np.arange(len(faces) + 1))
    for i in np.unique(beams).tolist():
        f, toward, irradiance = int(faces[i]), towards[i], scales[i]
        src, x0, x1 = (a[bounds[i]:bounds[i + 1]] for a in (srcs, x0s, x1s))
        f_li = irradiance * lights.intensity[li, ch]
        if sup.closed_forms:
            q = float(turned[f, :3] @ toward)
            ints = np.zeros((len(src), 9))
            ints[:, 0], ints[:, 2], ints[:, 3] = x0, x0, x0
            ints[:, 1], ints[:, 4], ints[:, 5] = x1, x1, x1
            ints[:, 6], ints[:, 7] = (turned[f, 3] - points[src] @ turned[f, :3]) / q, -(w[src] @ turned[f, :3]) / q
            val, spans = np.empty((len(src), len(ch))), np.empty((len(src), len(ch)))  # spans: 0 (ends given)
            beams_closed(ints, toward, w[src], kt, ks, medium.phase, medium.g, val, spans)
            np.add.at(out, (src[:, None], ch[None, :]), val * f_li)
            if bounded:
                per[bounds[i]:bounds[i + 1]] = val
            continue
        rank = np.arange(len(src)) - np.searchsorted(src, src)
        face, dplanes = np.ascontiguousarray(turned[f:f + 1]), np.array(errs[f, :2])  # a C array: the kernel's type
        for piece in np.unique(rank).tolist():
            at = np.nonzero(rank == piece)[0]
            sel, lo, m = src[at], x0[at], len(at)
            geo = np.zeros((m, GEO_COLUMNS))
            geo[:, :3], geo[:, 3:6], geo[:, 6:9] = points[sel] + lo[:, None] * w[sel], w[sel], toward
            geo[:, 12:14], geo[:, 17] = lights.cone[li, :2], lights.cone[li, 2]
            unit, unit_var, unit_err = np.empty((m, len(ch))), np.empty((m, len(ch))), np.empty((m, len(ch)))
            zero = np.zeros(m)
            inside_radiance(np.ones(m, np.bool_), zero, zero, zero, zero, zero, w[sel] @ toward, x1[at] - lo, kt, ks,
                            medium.phase, medium.g, kt_out, zero, zero, 1.0, geo, face, EVERY, dplanes, -1, rule,
                            keys[sel], np.uint64(dim0 + (1 + f + piece * len(planes)) * STREAM), np.uint64(seed), unit,
                            unit_var, unit_err, stats)
            with np.errstate(over="ignore", invalid="ignore"):
                tr = np.where(kt[None, :] == 0.0, 1.0, np.exp(-kt[None, :] * lo[:, None]))
            out[np.ix_(sel, ch)] += unit * tr * f_li
            var[np.ix_(sel, ch)] += unit_var * (tr * f_li) ** 2
            if bounded:
                per[bounds[i] + at], rule_err[bounds[i] + at] = unit * tr, product(unit_err, tr)
    if bounded:
        _sun_piece_bounds(prep, sid, li, (points, ell), (beams, srcs, x0s), (turned, faces, towards, scales, du, de),
                          (tris, errs), per, rule_err, sup, bound)


def _sun_piece_bounds(prep, sid, li, rows, pieces, beams, shape, per, rule_err, sup, bound):
    """bound += each of `_sun_faces`' pieces' own bound (its docstring): the beam's relative errors rel (its direction
    du: s_F's error, `crossing_error`, times kt, and the phase's condition; its irradiance's de) on the piece's value
    per unit irradiance `per` (P, C), plus with closed forms their rounding (`_beam_terms`'), else the rule's bound
    `rule_err` and exp(-kt x0)'s rounding (2 ulps and kt x0 u, doubled). rows: (points, ell); pieces: `lit_pieces`'
    (beam, src, x0); beams: `_sun_beams`'; shape: (triangles, `face_errors`)."""
    (points, ell), (beam, src, x0), (turned, faces, towards, scales, du, de), (tris, errs) = rows, pieces, beams, shape
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    ch, kt, _, _ = _scattering_channels(prep, medium, li)
    f = faces[beam]
    q = np.einsum("ij,ij->i", turned[f, :3], towards[beam])
    r = np.linalg.norm(points[src], axis=1) + ell[src]  # |o| + T
    reach = 2.0 * float(np.linalg.norm(tris, axis=2).max(initial=0.0))  # R of media/nonconvex_directional.py
    path = 2.0 * crossing_error(np.ascontiguousarray(errs[f, :2].T), turned[f, 3], r + reach, 0.0, du[beam]) / q
    rel = kt[None, :] * path[:, None] + (du[beam] * (phase_condition(medium.phase, medium.g) - 1.0) + de[beam])[:, None]
    if sup.closed_forms:
        err = (KERNEL_FLOOR + kt[None, :] * (8.0 * EPS * (np.abs(turned[f, 3]) + r) / q)[:, None] + rel) * per
    else:
        err = rule_err + (rel + EPS * (2.0 + kt[None, :] * x0[:, None])) * per
    f_li = scales[beam][:, None] * lights.intensity[li, ch][None, :]
    np.add.at(bound, (src[:, None], ch[None, :]), _light_bound(err, per * f_li, f_li, lights.cone[li, 0]))


def _sun_beams(prep, sid, li, planes, errs):
    """(turned, faces, towards, scales, du, de): the planes of shape sid turned toward directional light li, the
    beams they refract (`refracted_beams`) and each beam's errors (`_beam_errors`, from its face's measured normal
    error, `face_errors`)."""
    axis = np.asarray(prep.lights.axis[li], dtype=float)
    turned = planes * np.where(planes[:, :3] @ axis > 0.0, -1.0, 1.0)[:, None]  # normals toward the light
    eta = float(prep.scene.shapes[sid].interior.ior)
    faces, towards, scales = refracted_beams(turned, axis, eta)
    du, de = np.zeros(len(faces)), np.zeros(len(faces))
    for i, f in enumerate(faces.tolist()):
        du[i], de[i] = _beam_errors(float(-(turned[f, :3] @ axis)), eta, errs[f, 0])
    return turned, faces, np.ascontiguousarray(towards), np.ascontiguousarray(scales), du, de


def _shape_faces(prep, sid):
    """(triangles (T, 3, 3), their planes (T, 4): paths.shape_faces', their errors (`face_errors`)) of shape sid."""
    _, tris, planes = paths.shape_faces(prep, sid)
    return tris, planes, face_errors(tris, planes)


def _refracted_sphere(prep, sid, sphere, geo, distant, ell, li, sup, rule, keys, dim0, seed, out, var, bound, stats):
    """out, var, bound += light li's single scattering over the rows (geo: GEO_COLUMNS) of the refractive
    exact sphere sid (centre, radius): its exact refracted paths (media/sphere_refraction.py) by the
    method's inside `rule` (one kernel call per channel), handed to it by a method with closed forms
    (`sup.closed_forms`: counted, HANDED); QUAD's bound (inf where a caustic crossing has no fold pair,
    counted) with a spot's rounding, inf for the others."""
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    if sup.closed_forms:
        stats[HANDED] += np.count_nonzero(ell > 0.0)
    for c in range(3):
        if medium.sigma_s[c] == 0.0 or lights.intensity[li, c] == 0.0:
            continue
        val, v, err = np.empty(len(ell)), np.empty(len(ell)), np.empty(len(ell))
        sphere_refracted(np.asarray(sphere, dtype=np.float64), geo, bool(distant), ell, float(medium.sigma_t[c]),
                         float(medium.sigma_s[c]), medium.phase, medium.g, float(prep.scene.medium.sigma_t[c]),
                         float(medium.ior), rule, keys, np.uint64(dim0), np.uint64(seed), val, v, err, stats)
        out[:, c] += val * lights.intensity[li, c]
        var[:, c] += v * lights.intensity[li, c] ** 2
        bound[:, c] += _light_bound(err, val * lights.intensity[li, c], lights.intensity[li, c], lights.cone[li, 0])


def lit_single_scattering(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth, shadows: bool):
    """`single_scattering` with volumetric shadows (`shadows`): over the pieces of each inside segment
    that each light reaches past the blockers (shadows/frusta.py's exact lit intervals of `blockers`;
    the shape's own boundary attenuates, it does not block), each piece integrated from its own
    start and carried back to the entry by exp(-sigma_t t0) (closed forms too: analytic's closed form
    and its rule take the exact path from any start); in a convex refractive shape,
    `_lit_beams`. In a refractive exact sphere alone in the scene, or holding every light, nothing blocks
    (`single_scattering`).
    Where the light's path is neither straight nor a convex shape's refracted paths (a refractive
    interior that is not convex, an exact sphere beside other shapes) or not traced (`entry_plane`: the
    note's planar model), the segments are unshadowed, counted (UNSHADOWED), and
    their bound is infinite if anything but the shape itself could stand on the light's path. Inside
    a convex index-matched shape every light is attenuated by the other index-matched interiors on
    its path where all are convex (`_through_others`, its bound; closed forms hand those segments to
    the rule, counted), else not, and the bound is infinite."""
    medium = prep.scene.shapes[sid].interior
    n, n_lights = len(points), len(prep.lights)
    if not shadows or not n or not n_lights:
        return single_scattering(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth)
    sup = method.supports.interiors
    if reach == REFRACTED and paths.exact_sphere(prep, sid) is not None and not sup.entry_plane and (
            not np.any(prep.shape_ids != sid) or all((li, sid) in held_lights(prep) for li in range(n_lights))):
        # alone in the scene, or every light inside it (nothing else inside: support.check): nothing stands on
        # the light's paths
        return single_scattering(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth)
    if reach == REFRACTED and len(refracting_planes(prep, sid)) and not sup.entry_plane:
        return _lit_beams(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth)
    if reach == REFRACTED or sup.entry_plane:  # closed forms: exact paths, directional lights
        out, var, stats, bound = single_scattering(prep, method, params, sid, points, normals, w, ell, keys, reach, seed,
                                                   depth)
        stats[UNSHADOWED] += np.count_nonzero(ell > 0.0) * np.count_nonzero(prep.lights.intensity.any(axis=1))
        if np.any(prep.shape_ids != sid):
            bound = np.where(ell[:, None] > 0.0, np.inf, bound)
        return out, var, stats, bound
    on = np.flatnonzero(prep.lights.intensity.any(axis=1))  # not a pass's dark lights (renderer.Prepared.only)
    rays = np.tile(np.arange(n), len(on))
    segs = Segments(points[rays], w[rays], ell[rays], np.repeat(on, n), rays, np.zeros(len(rays)),
                    keys[rays], np.zeros(len(rays), np.int64), seed, prep.accel.scale)
    lit, _ = exact_lit_intervals(prep.accel, segs, prep.lights, n_lights, prep.frusta())
    out, var, bound = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    stats = np.zeros(STATS_SIZE)
    stats[LIT_PIECES] += len(lit)
    piece = lit.stream // n_lights
    kt = medium.sigma_t[None, :]
    others = _other_interiors(prep, sid, sup)
    for li, rank in sorted(set(zip(lit.light.tolist(), piece.tolist()))):
        at = np.nonzero((lit.light == li) & (piece == rank))[0]
        r = lit.ray[at]
        rows = (lit.origins[at], normals[r], lit.dirs[at], lit.length[at], keys[r])
        if others is not None:
            val, v, st, b = _through_others(prep, method, params, sid, others, li, rank, rows, seed, depth)
        else:
            val, v, st, b = single_scattering(prep, method, params, sid, *rows, reach, seed, depth, li, rank)
            if len(matched(prep)) > 1:  # other index-matched interiors, not applied (a shape not convex)
                b = np.full_like(b, np.inf)
        stats += st
        _carry(out, var, bound, r, kt, lit.t0[at], val, v, b)
    return out, var, stats, bound


def _other_interiors(prep, sid, sup, many=False):
    """(planes stacked, first, stop, sigma_t (S, 3), plane_errors (S, 2), balls (S, 4): centre and radius
    holding each) of the index-matched interiors but shape sid, for
    `_through_others`, where sid and all of them are convex (at most KERNEL_PLANES faces; `many`: sid
    a convex refractive shape of more, for its directional beams, `_face_beams`, and its point and spot
    lights' paths, `_lit_point`) and the method takes the light's exact paths (not the
    entry plane's model); else None (their attenuation is not applied)."""
    inner = [i for i in matched(prep) if i != sid]
    planes = [convex_planes(prep, i) for i in inner]
    own = refracting_planes(prep, sid) if many else convex_planes(prep, sid)
    if not inner or sup.entry_plane or not len(own) or any(not len(q) for q in planes):
        return None
    stop = np.cumsum([len(q) for q in planes])
    return (np.ascontiguousarray(np.concatenate(planes)), stop - np.array([len(q) for q in planes]), stop,
            np.array([prep.scene.shapes[i].interior.sigma_t for i in inner]),
            np.array([measured_plane_errors(prep, i) for i in inner]), np.array([_ball(prep, i) for i in inner]))


def _ball(prep, sid):
    """(centre, radius) of a ball that holds shape sid's triangles: their box's centre, and the largest
    distance from it with a few ulps of its size more."""
    pts = prep.accel.triangles[prep.shape_ids == sid].reshape(-1, 3)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    size = float(np.max(np.abs(pts)))
    return np.array([*centre, float(np.max(np.linalg.norm(pts - centre, axis=1))) + 1e-14 * size])


def _through_others(prep, method, params, sid, others, li, piece, rows, seed, depth, beam=None, face=None):
    """`single_scattering` of light li over the rows (points, normals, w, ell, keys) of convex
    index-matched shape sid, the light attenuated by the other interiors `others`
    (`_other_interiors`) on its straight path: shadows/through_others.py, by the method's inside rule
    (QUAD at its rtol, MARCH, SAMPLE on the streams `single_scattering` would use; closed forms, which
    have none with the chords, by the rule, counted HANDED). A directional light is
    attenuated by each interior's whole sigma_t (the outside medium does not attenuate it), a point
    or spot light by its excess over the outside's. `beam` = (face, toward, irradiance): in a convex
    refractive shape, the directional light's beam refracted through that face (`_lit_beams`), the
    chords taken from its entry point along the sun. `face`: in a convex refractive shape, a point or
    spot light's Fermat path through that face (`_lit_point`), the chords those of its outside leg
    (`refracted_attenuated`; in a shape of more than KERNEL_PLANES planes over the planes the face
    needs, `plane_neighbours`). QUAD bounds its integrals (with the planes' errors `plane_errors`,
    `measured_plane_errors` on refracted paths); the other rules' bound is infinite."""
    points, normals, w, ell, keys = rows
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    planes, (oplanes, first, stop, kt_other, dothers, balls) = convex_planes(prep, sid), others
    near = EVERY
    if face is not None and not len(planes):  # beyond KERNEL_PLANES: each face's path over the planes it needs
        planes, near = refracting_planes(prep, sid), plane_neighbours(prep, sid)
    n = len(points)
    distant = bool(lights.distant[li])
    geo = np.zeros((n, GEO_COLUMNS))
    geo[:, :3], geo[:, 3:6], geo[:, 14:17] = points, w, 0.0 if face is not None else normals
    geo[:, 6:9] = -lights.axis[li] if distant else lights.position[li]
    only, scale = -1 if face is None else face, 1.0
    if beam is not None:
        only, geo[:, 6:9], scale = beam
    geo[:, 9:12], geo[:, 12:14] = 0.0 if distant else lights.axis[li], lights.cone[li, :2]
    geo[:, 17] = lights.cone[li, 2]
    sup = method.supports.interiors
    rule = sup.rule(params)
    steps = rule.steps
    dim0 = STREAM + piece * MAX_DEPTH * len(lights) * steps + (depth * len(lights) + li) * steps + (only + 1) * STREAM
    out, var, bound, stats = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(STATS_SIZE)
    if sup.closed_forms:
        stats[HANDED] += np.count_nonzero(ell > 0.0)
    unit, unit_var, unit_err = np.empty(n), np.empty(n), np.empty(n)
    dplanes = measured_plane_errors(prep, sid)
    for c in range(3):
        kt, ks, kt_out = float(medium.sigma_t[c]), float(medium.sigma_s[c]), float(prep.scene.medium.sigma_t[c])
        if ks == 0.0 or lights.intensity[li, c] == 0.0:
            continue
        dk = np.ascontiguousarray(kt_other[:, c] - (0.0 if distant else kt_out))
        if face is not None:
            refracted_attenuated(geo, planes, near, ell, kt, ks, medium.phase, medium.g, kt_out, float(medium.ior),
                                 face, oplanes, first, stop, dk, rule, keys, np.uint64(dim0), np.uint64(seed), dplanes,
                                 dothers, balls, unit, unit_var, unit_err, stats)
        else:
            attenuated_radiance(distant, geo, planes, ell, kt, ks, medium.phase, medium.g, kt_out, oplanes, first,
                                stop, dk, rule, keys, np.uint64(dim0), np.uint64(seed), dplanes,
                                dothers, balls, only, -lights.axis[li], unit, unit_var, unit_err, stats)
        f = scale * lights.intensity[li, c]
        out[:, c] = unit * f
        var[:, c] = unit_var * f * f
        bound[:, c] = _light_bound(unit_err, out[:, c], f, lights.cone[li, 0])
    return out, var, stats, bound


def _carry(out, var, bound, r, kt, t0, val, v, b):
    """Add pieces' values, variances and bounds to their rays r, carried back to the entry by
    exp(-kt t0) (kt (1, 3))."""
    with np.errstate(over="ignore", invalid="ignore"):
        tr = np.where(kt == 0.0, 1.0, np.exp(-kt * t0[:, None]))
    np.add.at(out, r, tr * val)
    np.add.at(var, r, tr * tr * v)
    np.add.at(bound, r, scaled(b, tr))


def _lit_beams(prep, method, params, sid, points, normals, w, ell, keys, reach, seed, depth):
    """`lit_single_scattering` in a convex refractive shape: each directional light's refracted beams
    over the pieces they reach past the blockers (shadows/beams.py: the leg inside the shape and the
    entry point's path outside), each from its own start, carried back by exp(-sigma_t t0); point and
    spot lights likewise over the pieces their Fermat path through each face reaches (`_lit_point`).
    Where all index-matched interiors are convex (`_other_interiors`), a beam is attenuated by the others
    on its entry point's path to the sun and a point or spot light's path by those on its outside leg
    (`_through_others`); else they are not applied, and every light's bound is infinite. In a shape of
    more than KERNEL_PLANES planes (`convex_planes` empty: `_face_beams`) a beam's pieces are sought
    only where it may light a segment (`_beam_span`), the others applied by `_face_beams`, and a point
    or spot light's path by `_through_others(..., face=f)` over the planes its face needs."""
    medium, lights = prep.scene.shapes[sid].interior, prep.lights
    planes, mask = refracting_planes(prep, sid), blockers(prep)
    many = not len(convex_planes(prep, sid))
    n = len(points)
    out, var, bound = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
    stats = np.zeros(STATS_SIZE)
    kt = medium.sigma_t[None, :]
    sup = method.supports.interiors
    others = _other_interiors(prep, sid, sup)
    beam_others = _other_interiors(prep, sid, sup, many=True) if many else others
    unapplied = False  # a light's path computed without the other index-matched interiors
    for li in np.flatnonzero(lights.intensity.any(axis=1)).tolist():  # not a pass's dark lights (Prepared.only)
        if not lights.distant[li]:
            _lit_point(prep, method, params, sid, refracting_planes(prep, sid), mask, li,
                       (points, normals, w, ell, keys), reach, seed, depth, (out, var, bound, stats), beam_others)
            unapplied = unapplied or beam_others is None
            continue
        unapplied = unapplied or beam_others is None
        faces, towards, scales = refracted_beams(planes, lights.axis[li], medium.ior)
        for f, toward, irradiance in zip(faces.tolist(), towards, scales):
            if many:  # the segments the beam may reach, over the widest interval it may light
                sel, lo, hi = _beam_span(prep, sid, planes, f, toward, lights.axis[li], points, w, ell)
                src, x0, x1 = lit_pieces_of_beam(prep, sid, planes, mask, li, f, toward, points[sel] + lo[:, None] * w[sel],
                                                 w[sel], hi - lo)
                src, x0, x1 = sel[src], x0 + lo[src], x1 + lo[src]
            else:
                src, x0, x1 = lit_pieces_of_beam(prep, sid, planes, mask, li, f, toward, points, w, ell)
            stats[LIT_PIECES] += len(src)
            rank = np.arange(len(src)) - np.searchsorted(src, src)
            for piece in np.unique(rank).tolist():
                at = np.nonzero(rank == piece)[0]
                r = src[at]
                rows = (points[r] + x0[at, None] * w[r], normals[r], w[r], x1[at] - x0[at], keys[r])
                if many and beam_others is not None:
                    val, v, b, st = np.zeros((len(r), 3)), np.zeros((len(r), 3)), np.zeros((len(r), 3)), \
                        np.zeros(STATS_SIZE)
                    rule = sup.rule(params)
                    steps = rule.steps
                    dim0 = STREAM + piece * MAX_DEPTH * len(lights) * steps + (depth * len(lights) + li) * steps
                    _face_beams(prep, sid, planes, plane_neighbours(prep, sid), li, f,
                                (rows[0], rows[2], rows[3], rows[4]), sup, rule, dim0, seed,
                                (val, v, b, st), beam_others)
                elif others is not None:
                    val, v, st, b = _through_others(prep, method, params, sid, others, li, piece, rows, seed, depth,
                                                    (f, toward, irradiance))
                else:
                    val, v, st, b = single_scattering(prep, method, params, sid, *rows, reach, seed, depth, li, piece, f)
                stats += st
                _carry(out, var, bound, r, kt, x0[at], val, v, b)
    if matched(prep) and unapplied:
        bound[ell > 0.0] = np.inf
    return out, var, stats, bound


def _lit_point(prep, method, params, sid, planes, mask, li, rows, reach, seed, depth, acc, others=None):
    """acc = (out, var, bound, stats) += point or spot light li's single scattering over the rows
    (points, normals, w, ell, keys) of convex refractive shape sid: through each face it is outside of,
    over the pieces where both legs of its Fermat path clear the blockers (shadows/fermat_legs.py),
    each piece integrated along that face's path alone (`single_scattering(..., beam=f)`) from its
    start, carried back by exp(-sigma_t t0); a piece that starts inside has no entry face (zero
    normals). Rows lit whole through every face take the light's integral over all faces at once,
    as without shadows, unless `others` (`_other_interiors`) attenuate the outside legs: then every
    piece takes its face's path attenuated by them (`_through_others(..., face=f)`). A piece cut by an
    occluder's break adds its location error: over each span where the exact lit set may differ from
    the pieces (shadows/fermat_legs.py `span_errors`), times the largest attenuation of the outside
    leg by `others` (exp(sum_j max(sigma_t outside - sigma_t_j, 0) 4 S), S bounding the scene's points);
    inf on the segments whose spans are not known, counted (UNLOCATED)."""
    points, normals, w, ell, keys = rows
    out, var, bound, stats = acc
    kt = prep.scene.shapes[sid].interior.sigma_t[None, :]
    position = prep.lights.position[li]
    faces = np.nonzero(planes[:, :3] @ position - planes[:, 3] > 0.0)[0].tolist()
    dplanes = measured_plane_errors(prep, sid)
    geo = np.zeros((len(ell), GEO_COLUMNS))
    geo[:, :3], geo[:, 3:6], geo[:, 6:9] = points, w, position
    reached = np.zeros((len(ell), len(planes)), dtype=np.bool_)
    segment_reach(geo, planes, plane_neighbours(prep, sid), float(prep.scene.shapes[sid].interior.ior),
                  np.ascontiguousarray(ell, dtype=float), reached)
    faces = [f for f in faces if reached[:, f].any()]  # the others are unlit, whole, spans known (`_face_pieces`)
    found = [(f, *_face_pieces(prep, sid, planes, mask, li, f, (points, w, ell), dplanes, reached[:, f]))
             for f in faces]
    gain = np.ones(3)
    if others is not None:
        big = 4.0 * math.sqrt(3.0) * max(prep.accel.scale, float(np.abs(position).max()))
        gain = np.exp(np.maximum(prep.scene.medium.sigma_t[None, :] - others[3], 0.0).sum(axis=0) * big)
    unlocated = np.zeros(len(ell), bool)
    for f, _, _, _, _, spans in found:
        np.add.at(bound, spans[0], span_errors(prep, sid, planes, li, f, points, w, spans) * prep.lights.intensity[li]
                  * gain)
        unlocated |= ~spans[3] & (ell > 0.0)
    bound[unlocated] = np.inf
    stats[UNLOCATED] += np.count_nonzero(unlocated)
    whole = np.logical_and.reduce([f[4] for f in found], initial=True) & (ell > 0.0) & (others is None)
    clear = np.nonzero(whole)[0]
    if len(clear):
        val, v, st, b = single_scattering(prep, method, params, sid, points[clear], normals[clear], w[clear], ell[clear],
                                          keys[clear], reach, seed, depth, li)
        stats += st
        _carry(out, var, bound, clear, kt, np.zeros(len(clear)), val, v, b)
    for f, src, x0, x1, _, _ in found:
        stats[LIT_PIECES] += len(src)
        keep = ~whole[src]
        src, x0, x1 = src[keep], x0[keep], x1[keep]
        rank = np.arange(len(src)) - np.searchsorted(src, src)
        for piece in np.unique(rank).tolist():
            at = np.nonzero(rank == piece)[0]
            r = src[at]
            entry = np.where((x0[at] == 0.0)[:, None], normals[r], 0.0)
            sub = (points[r] + x0[at, None] * w[r], entry, w[r], x1[at] - x0[at], keys[r])
            if others is not None:
                val, v, st, b = _through_others(prep, method, params, sid, others, li, piece, sub, seed, depth, face=f)
            else:
                val, v, st, b = single_scattering(prep, method, params, sid, *sub, reach, seed, depth, li, piece, f)
            stats += st
            _carry(out, var, bound, r, kt, x0[at], val, v, b)


def _face_pieces(prep, sid, planes, mask, li, f, rows, dplanes, reached):
    """shadows/fermat_legs.py `lit_pieces_of_point` through face f for the segments rows = (points, w,
    ell) whose refraction points may lie on it (`reached`: media/slab.py `segment_reach`); the others,
    unlit through f, count as lit whole with their spans known and no pieces."""
    points, w, ell = rows
    sel = np.nonzero(reached)[0]
    whole, sure = np.ones(len(ell), bool), np.ones(len(ell), bool)
    if not len(sel):
        none = np.zeros(0, np.int64)
        return none, np.zeros(0), np.zeros(0), whole, (none, np.zeros(0), np.zeros(0), sure)
    src, x0, x1, whole_sel, (sseg, slo, shi, sure_sel) = lit_pieces_of_point(prep, sid, planes, mask, li, f,
                                                                             points[sel], w[sel], ell[sel], dplanes)
    whole[sel], sure[sel] = whole_sel, sure_sel
    return sel[src], x0, x1, whole, (sel[sseg], slo, shi, sure)


def through_airlight(prep, method, params, segs: Segments, n_rays: int, stats):
    """The outside medium's air-light (N, 3) of the pieces `segs` whose light crosses index-matched
    interiors (shadow_frusta.split_lit's `behind`), its variance (N, 3) and its bound (N, 3): the light attenuated by
    exp(-(sigma_t inside - sigma_t outside) x length inside) of each interior on its straight path,
    integrated by the method's own rule where it has medium points (`Method.points`: raymarch's
    midpoints, Monte Carlo's samples, each point's light attenuated), else by the traced adaptive
    quadrature (paths.through_quadrature at the method's inside rtol: quadrature's own, or the
    fallback a method declares with `Supports.interiors.through`), counted (THROUGH; integrals short
    of their tolerance: THROUGH_CAPPED), carried to the camera by the outside's transmittance over t0,
    as its bound (paths.through_quadrature's; inf for the points' rules, which have none, and for an
    area light's cubature nodes)."""
    inner = matched(prep)
    for sid in inner:
        hull_planes(prep, sid)  # fills the convex shapes' planes, which through_quadrature reads
    medium = prep.scene.medium
    kt_in = np.array([prep.scene.shapes[i].interior.sigma_t for i in inner])
    dk = kt_in - medium.sigma_t[None, :]
    stats[THROUGH] += len(segs)
    if method.supports.interiors.through == "points":
        air, var = shadowed_airlight(prep.accel, method, medium, prep.lights, params,
                                     _own_streams(segs, len(prep.lights)), n_rays,
                                     functools.partial(_attenuation, prep, inner, dk))
        return air, var, np.where(rays_with(segs.ray, n_rays)[:, None], np.inf, 0.0)
    capped = np.zeros(1)
    values, bound = paths.through_quadrature(prep, segs, medium, inner, kt_in,
                                             method.supports.interiors.rule(params).rtol, capped,
                                             np.array([measured_plane_errors(prep, i) for i in inner]),
                                             np.array([_ball(prep, i) for i in inner]))
    stats[THROUGH_CAPPED] += capped[0]
    bound[prep.lights.cubature[segs.light]] = np.inf  # an area light's cubature nodes: no bound (as elsewhere)
    tr = gather_weights(segs, medium)
    return gather(segs, values, n_rays, medium, tr=tr), np.zeros((n_rays, 3)), gather(segs, bound, n_rays, medium,
                                                                                        tr=tr)


THROUGH_STREAMS = 1 << 20  # random streams of the pieces behind interiors start past any ray's clear pieces'


def _own_streams(segs: Segments, n_lights: int) -> Segments:
    """The pieces numbered per camera ray and light past the clear pieces' streams (split_lit keeps
    their segment's, which a clear piece of it also draws from)."""
    segs = segs.take(np.lexsort((segs.t0, segs.light, segs.ray)))
    group = segs.ray * n_lights + segs.light
    segs.stream = segs.light + n_lights * (THROUGH_STREAMS + np.arange(len(group)) - np.searchsorted(group, group))
    return segs


def _attenuation(prep, inner, dk, segs, pos, weight):
    """exp(-dk . lengths) (same shape as weight) of each medium point's straight path to its light
    through the index-matched interiors `inner` (dk (S, 3): their sigma_t minus the outside's), the
    lengths in float64 when every shape is convex or an exact sphere (paths.chords), else by Embree
    walks (paths.inside_lengths)."""
    out = np.zeros(weight.shape)
    lp = prep.lights.position[segs.light]
    exact = all(paths.boundary(prep, sid) is not None for sid in inner)
    for c in range(3):
        p, m = pos[..., c, :], weight[..., c] != 0.0
        rel = np.broadcast_to(lp[:, None, None, :], p.shape)[m] - p[m]
        dist = np.linalg.norm(rel, axis=1)
        dirs = rel / np.where(dist > 0.0, dist, 1.0)[:, None]
        if exact:
            lengths = paths.chords(prep, inner, p[m], dirs, dist)
        else:  # a light inside a shape: its walk starts inside
            lengths, _ = paths.inside_lengths(prep, p[m], dirs, dist, inner, margin=prep.accel.epsilon,
                                              far_inside=paths.lights_holding(prep, np.broadcast_to(
                                                  segs.light[:, None, None], p.shape[:-1])[m], inner))
        f = out[..., c]
        f[m] = np.exp(-lengths @ dk[:, c])
        out[..., c] = f
    return out


def _light_bound(err, value, f, cos_end):
    """The bound of one light's values (N,) = unit values x f (f >= 0) with the unit values' bound err
    (N,): err f (0 where f = 0: the value is exactly 0) plus a spot's rounding (error_bounds.spot_rounding
    of its `cos_end`) on the value."""
    return product(err, f) + spot_rounding(np.array([cos_end]))[0] * np.abs(value)


def _traced(prep, sid, medium, geo, distant, ell, intensity, rule, keys, dim0, seed, out, var, bound, stats,
            cos_end=-2.0):
    """out, var, bound += one light's single scattering over the segments of an index-matched shape
    (non-convex, or handed over by closed forms) by the inside `rule`, the light's straight paths measured
    with Embree (paths.py),
    its bound (`paths.segment_quadrature`'s; inf for the other rules) with a spot's rounding (`cos_end`)."""
    ch = np.nonzero((medium.sigma_s > 0.0) & (intensity != 0.0))[0]
    if not len(ch):
        return
    kts, kss, kt_outs = medium.sigma_t[ch], medium.sigma_s[ch], prep.scene.medium.sigma_t[ch]
    args = (prep, sid, geo, distant, ell, kts, kss, medium.phase, medium.g, kt_outs)
    v = np.zeros((len(ell), len(ch)))
    err = np.full((len(ell), len(ch)), np.inf)
    if rule.kind == QUAD:
        capped = np.zeros(1)
        val, err = paths.segment_quadrature(*args, rule, capped)
        stats[CAPPED] += capped[0]
    elif rule.kind == MARCH:
        val = paths.segment_march(*args, rule)
    else:
        val, v = paths.segment_samples(*args, rule, keys, dim0, seed)
    out[:, ch] += val * intensity[ch]
    var[:, ch] += v * intensity[ch] ** 2
    for j, c in enumerate(ch.tolist()):
        bound[:, c] += _light_bound(err[:, j], val[:, j] * intensity[c], intensity[c], cos_end)


def _through_faces(prep, sid, medium, geo, ell, intensity, rule, keys, dim0, seed, out, var, bound, stats, cos_end):
    """out, var, bound += one point or spot light's single scattering over the segments of the refractive shape
    sid that is not convex, on Fermat's paths through its faces (paths.refracted_integrand) by the inside `rule`;
    the bound is quadrature's (paths.refracted_quadrature: inf where a step is not proven, counted, UNLOCATED) with
    a spot's rounding (`cos_end`), infinite for the other rules."""
    ch = np.nonzero((medium.sigma_s > 0.0) & (intensity != 0.0))[0]
    if not len(ch):
        return
    kts, kss, kt_outs = medium.sigma_t[ch], medium.sigma_s[ch], prep.scene.medium.sigma_t[ch]
    args = (prep, sid, geo, ell, kts, kss, medium.phase, medium.g, kt_outs)
    v = np.zeros((len(ell), len(ch)))
    err = np.where((ell > 0.0)[:, None], np.inf, np.zeros(len(ch)))
    if rule.kind == QUAD:
        capped = np.zeros(1)
        val, err = paths.refracted_quadrature(*args, rule, capped)
        stats[CAPPED] += capped[0]
    else:
        values = paths.refracted_integrand(*args)
        channel = lambda seg, x, c: values(seg, x, [c])[:, 0]
        geo_args = (prep, sid, geo, False, ell, kts, kss, medium.phase, medium.g, kt_outs, rule)
        if rule.kind == MARCH:
            val = paths.segment_march(*geo_args, channel=channel)
        else:
            val, v = paths.segment_samples(*geo_args, keys, dim0, seed, channel=channel)
    out[:, ch] += val * intensity[ch]
    var[:, ch] += v * intensity[ch] ** 2
    for j, c in enumerate(ch.tolist()):
        bound[:, c] += _light_bound(err[:, j], val[:, j] * intensity[c], intensity[c], cos_end)
    stats[UNLOCATED] += np.count_nonzero((ell > 0.0) & ~np.all(np.isfinite(err), axis=1))
