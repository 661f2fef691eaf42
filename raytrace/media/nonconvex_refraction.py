"""Point and spot light into refractive shapes that are not convex: Fermat's path through every face.

Inside a closed mesh of relative index eta that is not convex, a point or spot light at L reaches an inside
point X through each triangle F whose plane separates X from L, on Fermat's path through that plane
(media/slab.py: `refraction_point`, Snell's law in the plane of incidence, and `refracted_at`, Fresnel's T on
the way in, the ray tube's irradiance of a point source through a plane, a spot's falloff on the direction the
light leaves in), where its refraction point R lies inside F and both legs are clear of the mesh: X to R meets
no other face (it stays inside), R to L meets none (it stays outside). The legs are tested by the caller
(interiors/paths.py `refracted_channels`, Embree); this module finds the candidate paths. Each face is taken in
either orientation (its plane's normal turned toward the light): a face whose outside looks toward X gives a
leg that leaves the shape before reaching it, which the leg tests reject.

The integrand jumps where a path appears or disappears (R crossing an edge of its triangle, a leg grazing
another face); those points are not located.
"""
from __future__ import annotations

import math

import numpy as np

from ..jit import njit
from .slab import refraction_point, refracted_at

PATH_COLUMNS = 10  # rows of `face_paths`: point, face, R (3), the per unit light value, k, o, the legs' cosines


def face_planes(tris):
    """Unit normals and offsets (T, 4) of the triangles (T, 3, 3) (zero rows for degenerate ones)."""
    tris = np.asarray(tris, dtype=np.float64)
    cross = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    area = np.linalg.norm(cross, axis=1)
    n = np.where(area[:, None] > 0.0, cross / np.where(area > 0.0, area, 1.0)[:, None], 0.0)
    return np.ascontiguousarray(np.column_stack([n, np.einsum("ij,ij->i", n, tris[:, 0])]))


@njit
def candidates(tris, planes, geo, ell, counts, out, fill):
    """The faces that may light segment s (geo rows of media/slab.py GEO_COLUMNS: start, direction, the
    light's position; over [0, ell[s]]), a bounding test: the light off the face's plane, some of the
    segment on the other side, and the box of the feet on that plane of the segment's ends and the light
    (which holds every refraction point through it: R lies between X's foot and the light's) meeting the
    triangle's box. counts[s] = their number; with `fill`, out (sum counts) receives them, segment by
    segment."""
    m = 0
    for s in range(geo.shape[0]):
        c = 0
        for f in range(tris.shape[0]):
            if _may_light(tris[f], planes[f], geo[s], ell[s]):
                if fill:
                    out[m] = f
                m += 1
                c += 1
        counts[s] = c


@njit
def _may_light(tri, plane, row, end):
    n0, n1, n2, cf = plane[0], plane[1], plane[2], plane[3]
    if n0 == 0.0 and n1 == 0.0 and n2 == 0.0:
        return False
    hl = n0 * row[6] + n1 * row[7] + n2 * row[8] - cf
    if hl == 0.0:
        return False
    e0, e1, e2 = row[0] + end * row[3], row[1] + end * row[4], row[2] + end * row[5]
    h0 = n0 * row[0] + n1 * row[1] + n2 * row[2] - cf
    h1 = n0 * e0 + n1 * e1 + n2 * e2 - cf
    if not (h0 * hl < 0.0 or h1 * hl < 0.0):
        return False
    size = abs(cf) + abs(row[6]) + abs(row[7]) + abs(row[8]) + abs(row[0]) + abs(e0) + abs(e1) + abs(e2)
    slack = 1e-9 * size
    for k in range(3):
        lo = min(row[k] - h0 * plane[k], row[k] + end * row[3 + k] - h1 * plane[k], row[6 + k] - hl * plane[k])
        hi = max(row[k] - h0 * plane[k], row[k] + end * row[3 + k] - h1 * plane[k], row[6 + k] - hl * plane[k])
        if hi < min(tri[0, k], tri[1, k], tri[2, k]) - slack or lo > max(tri[0, k], tri[1, k], tri[2, k]) + slack:
            return False
    return True


@njit
def _off_box(a0, a1, a2, b0, b1, b2, tri):
    """Whether the box of the segment a b misses the triangle's box (with a margin of 1e-9 of their size)."""
    slack = 1e-9 * (abs(a0) + abs(a1) + abs(a2) + abs(b0) + abs(b1) + abs(b2) + abs(tri[0, 0]) + abs(tri[0, 1])
                    + abs(tri[0, 2]))
    for lo, hi, k in ((min(a0, b0), max(a0, b0), 0), (min(a1, b1), max(a1, b1), 1), (min(a2, b2), max(a2, b2), 2)):
        if hi < min(tri[0, k], tri[1, k], tri[2, k]) - slack or lo > max(tri[0, k], tri[1, k], tri[2, k]) + slack:
            return True
    return False


@njit
def _inside_triangle(q0, q1, q2, tri, n0, n1, n2):
    """Whether the point q, on the triangle's plane (unit normal n), lies inside it (edges included)."""
    ax, ay, az = tri[0, 0], tri[0, 1], tri[0, 2]
    bx, by, bz = tri[1, 0], tri[1, 1], tri[1, 2]
    cx, cy, cz = tri[2, 0], tri[2, 1], tri[2, 2]
    s = 0.0
    for k in range(3):
        if k == 0:
            ux, uy, uz, vx, vy, vz = bx - ax, by - ay, bz - az, q0 - ax, q1 - ay, q2 - az
        elif k == 1:
            ux, uy, uz, vx, vy, vz = cx - bx, cy - by, cz - bz, q0 - bx, q1 - by, q2 - bz
        else:
            ux, uy, uz, vx, vy, vz = ax - cx, ay - cy, az - cz, q0 - cx, q1 - cy, q2 - cz
        side = n0 * (uy * vz - uz * vy) + n1 * (uz * vx - ux * vz) + n2 * (ux * vy - uy * vx)
        if side * s < 0.0:
            return False
        if side != 0.0:
            s = side
    return True


@njit
def face_paths(seg, x, geo, tris, planes, offsets, faces, eta, code, g, out):
    """The Fermat paths through single faces at the points x along segments seg (geo rows of media/slab.py
    GEO_COLUMNS: start, direction w, the light's position, a spot's axis, cone and curve), for the
    candidate faces faces[offsets[s]:offsets[s + 1]] of each segment s (`candidates`): where the face's
    plane separates X = p + x w from the light (normal n turned toward it: the light at height hl above
    the plane, X at depth z below it), R = X + z n + (r / rho) L_h (L_h the light's offset from X's foot,
    rho its length, r of `refraction_point`) inside the triangle, one row of PATH_COLUMNS in out: the
    point's index, the face, R, media/slab.py `refracted_at`'s value per unit light without the
    exponential (ks = 1, kt = kt_out = 0: Phi(mu) E F), the legs' lengths k inside and o outside, and
    their cosines to the face's normal, z / k and hl / o. Returns the rows' count (at most out's rows; the caller sizes
    out by the candidates)."""
    m = 0
    for i in range(x.shape[0]):
        row = geo[seg[i]]
        X0, X1, X2 = row[0] + x[i] * row[3], row[1] + x[i] * row[4], row[2] + x[i] * row[5]
        r0, r1, r2 = row[6] - X0, row[7] - X1, row[8] - X2
        for j in range(offsets[seg[i]], offsets[seg[i] + 1]):
            f = faces[j]
            n0, n1, n2 = planes[f, 0], planes[f, 1], planes[f, 2]
            hl = n0 * row[6] + n1 * row[7] + n2 * row[8] - planes[f, 3]
            z = planes[f, 3] - (n0 * X0 + n1 * X1 + n2 * X2)
            if hl < 0.0:  # the normal turned toward the light
                n0, n1, n2, hl, z = -n0, -n1, -n2, -hl, -z
            if not (hl > 0.0 and z > 0.0):
                continue
            up = hl + z
            l0, l1, l2 = r0 - up * n0, r1 - up * n1, r2 - up * n2
            f0, f1, f2 = X0 + z * n0, X1 + z * n1, X2 + z * n2  # X's foot; R lies between it and the light's
            if _off_box(f0, f1, f2, f0 + l0, f1 + l1, f2 + l2, tris[f]):
                continue
            rho = math.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
            r = refraction_point(rho, z, hl, eta)
            t = r / rho if rho > 0.0 else 0.0
            q0, q1, q2 = f0 + t * l0, f1 + t * l1, f2 + t * l2
            if not _inside_triangle(q0, q1, q2, tris[f], n0, n1, n2):
                continue
            a = -(n0 * row[3] + n1 * row[4] + n2 * row[5])
            wl = row[3] * l0 + row[4] * l1 + row[5] * l2
            na = n0 * row[9] + n1 * row[10] + n2 * row[11]
            la = l0 * row[9] + l1 * row[10] + l2 * row[11]
            value = refracted_at(0.0, z, rho, r, wl, a, hl, eta, 0.0, 1.0, code, g, 0.0, 0.0, la, na, row[12],
                                 row[13], row[17])
            if value == 0.0:
                continue
            k = math.sqrt(r * r + z * z)
            o = math.sqrt((rho - r) * (rho - r) + hl * hl)
            out[m, 0], out[m, 1], out[m, 2], out[m, 3], out[m, 4] = i, f, q0, q1, q2
            out[m, 5], out[m, 6], out[m, 7], out[m, 8], out[m, 9] = value, k, o, z / k if k > 0.0 else 1.0, hl / o
            m += 1
    return m
