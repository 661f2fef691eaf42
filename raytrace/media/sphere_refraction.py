"""Single scattering inside a refractive exact sphere (geometry/sphere.py) lit through the sphere:
the exact refracted light at each inside point, for point, spot and directional lights; and the light
of a point or spot light inside the sphere on surfaces outside (`surface_out_of_sphere`), and of a point
or spot light well inside it in a scattering medium outside (`out_of_sphere`), on its paths out.

The plane of the light's paths: a ray from a point light L (or along a directional light) refracted
at P on the sphere (centre c, radius R) stays in the plane through L, c and P (the normal at P lies in
it), so the paths that reach an inside point X lie in the plane through the light's axis (the line
through c toward L, or along the sun) and X. In that plane, with z along the axis toward the light
and y toward X (X = (z_X, y_X), y_X >= 0), P(theta) = R (cos theta, sin theta) for theta in
(-theta_a, theta_a), the lit arc: the incidence cosine cos_i falls with |theta| and theta_a is where
it reaches 0 (or sqrt(1 - eta^2) for eta < 1, total reflection beyond). The ray refracted at
P(theta) (Snell, media/slab.py `refract`) runs along t(theta); X lies on it where
    h(theta) = t(theta) x (X - P(theta)) = 0
(a 2-D cross product; X is then ahead of P, the chord being inside). Every root is a path (Fermat's
stationary path); near the back of the ball refracted rays cross (a caustic) and X takes up to three.

The paths, proven. `paths` starts from SCAN uniform cells of the arc and halves a cell until a bound
K on |h''| over it decides it: no root where h keeps its sign and the least |h| at its ends exceeds
K w^2 / 8 (h is within K (theta - a)(b - theta) / 2 of its chord) or where the secant's slope exceeds
K w (h' then keeps its sign over the cell: monotone), one where h changes sign and is monotone,
bisected to the resolution of doubles; each test less the values' rounding (the monotone test
decides the cells beside a double root, where h is too small for the first). The cell loop is one
(`_halving`) for this scan and the two below, on a record of the scanned function (`PathScan`,
`CausticScan`, `EdgeCone`) whose class picks its value and its cells' tests at compile time. With
phi(theta) the angle of the unit direction t, P' and P'' of length R and |X - P| <= |X| + R:
    h'' = t'' x (X - P) - 2 t' x P' - t x P'',  |h''| <= (|phi''| + phi'^2)(|X| + R) + 2 |phi'| R + R.
phi = theta + pi + theta_t, sin theta_t = sin theta_i / eta, theta_i = alpha - theta - pi (alpha the
arriving direction's angle: constant for the sun; for a lamp at distance d, alpha' =
R (R - d cos theta) / o^2 and alpha'' = R d sin theta / o^2 - 2 R^2 d sin theta (R - d cos theta) / o^4),
so with g' = cos_i / (eta cos_t) <= 1 / (eta cos_t) and |g''| <= (1 + 1 / (eta^2 cos_t)) / (eta cos_t^2)
(the derivatives of theta_t in theta_i), |phi'| <= 1 + g' |theta_i'| and |phi''| <= |g''| theta_i'^2 +
g' |alpha''|, each bounded over the cell by its extreme ends: cos_t least at the larger |theta| (the
incidence grows with |theta|), o least and |R - d cos theta| largest at the smaller, |sin theta| largest
at the larger (`angular_bounds`, per SCAN cell, valid for its halves; checked against mpmath's
derivatives by tests/test_sphere_paths.py). The values' rounding: t's components are off by
(e_d + 8u)(1 + 2 / eta + 2 / (eta^2 cos_t)) + 16u (e_d = 8u (R + d) / o + 4u the arriving direction's),
h by twice 2 that (|X| + R) + 16u (|X| + 2R), doubled. A cell not decided after MAX_HALVINGS halvings,
or after MAX_EVALS in one scan (a point within rounding of the caustic, where a root is double, or
near its cusp on the axis, where it is triple; the end of the arc for eta < 1, where cos_t reaches 0
and K is infinite) leaves the scan unproven, counted by the record.

Each path contributes ks Phi(mu) E F exp(-kt (x + s) - kt_out o): mu the scattering cosine (the
light travels along t, mu = -t.w), s the path inside from P to X, o the path outside (0 for a
directional light, which the outside medium does not attenuate), F a spot's falloff toward the
direction the light leaves in (P - L) / o, and E the irradiance of the ray tube at X: just inside P it
is T cos_i / (o^2 cos_t) per unit intensity (T cos_i / cos_t per unit irradiance for a directional
light; T = 1 - media/slab.py `fresnel`), and the refracted wavefront there has the principal
curvatures of Coddington's equations (the tangential, in the plane, and the sagittal, across it),
    kappa_t = ((eta cos_t - cos_i) / R - cos_i^2 / o) / (eta cos_t^2),
    kappa_s = ((eta cos_t - cos_i) / R - 1 / o) / eta,
so that each width of the tube scales by (1 - s kappa) along the ray:
    E(s) = E(0) / |(1 - s kappa_t)(1 - s kappa_s)|.
(For R -> inf this is media/slab.py `refracted_at`'s planar tube.) The tangential factor vanishes on
the caustic, where E has an integrable 1/sqrt singularity along a camera ray and the number of paths
changes by two; the sagittal one on the axis (the axial caustic, integrable across it).

Along an inside segment o + x w the integrand breaks where the segment crosses the tangential
caustic surface (the caustic points C(theta) = P + t / kappa_t turned about the axis), falls to 0
with a square-root kink where a path leaves through the lit arc's end (the segment crosses the cone
of the marginal rays, refracted at grazing incidence, about the axis with its apex where they meet
it), and peaks where it passes closest to the axis; `breaks` cuts it there: the closest approach and
the cone's crossings (a quadratic, geometry/sphere.py `quadratic_roots`) in closed form, the caustic
crossings by a proven scan in theta (below, "The caustic's crossings, proven"). A spot's falloff has
kinks, its band edges, which fool the rule's error estimate inside a piece (`spot_edges`): aimed at
the centre (its axis along the light's axis) they lie at fixed angles +-theta_e, the pieces in x cut
where those rays reach the segment and the fold pair's window in theta at +-theta_e; aimed elsewhere
the edge's refraction point moves with the plane of the point: the pieces cut where the segment
meets the refracted edge rays, found by a proven scan over them (below, "The band edges, proven"),
and the window at their angles (located to the resolution of doubles, a kink of a continuous
falloff misplaced by dx changes the integral by its jump in slope x dx^2, far below the rounding; a
hard edge's jump x dx is not in the bound). QUAD integrates the
pieces with the project's adaptive Gauss-Legendre rule, a piece beside a cone or caustic crossing x_b
in u with x = x_b + (x - x_b) u^2 (`NearCaustic`), the two pieces beside a caustic crossing as below;
MARCH and SAMPLE take media/slab.py's midpoint march and free-path samples of the same integrand
(their bound is infinite).

The caustic (`_fold`). Where the segment crosses the caustic two paths (the fold pair) meet and
vanish; along the segment each carries E's 1/sqrt singularity there, whose rounding (the pair's roots
are nearly double: their spread and the tube factor's relative error grow without bound) defeats a
bound in x. Over the pieces [a, b] on both sides of the crossing, with W = [theta_1, theta_2] the
angles of the pair at the end with two paths more (both ends' scans proven; at a cone's crossing with
one more, the outermost path and the lit arc's end, the pair's other path leaving there), the
integral splits exactly, for any W, into the paths refracted outside W, in x (`refracted_value` with
the record's window: a count of them that changes between evaluations is the guard's), and those
inside W, in theta: by the area formula each point x of [a, b] that the ray refracted at theta
reaches (h(theta; X(x)) = 0, a quadratic in x once squared) weighs in at |dx/dtheta| = |h_theta| /
|h_x|, and |h_theta| = R cos_t |1 - s kappa_t| (the tube's width in the plane) cancels the tangential
factor of E, so the integrand in theta (`fold_value`, `FoldPair`) is smooth through the caustic. Where a cone's crossing
is the break beside the caustic's, the pieces reach across it to the middle of the piece beyond (the
end with one path more then lies on that side: W is the outermost path there and the lit arc's end,
the pair's other path entering at the cone's crossing), so that no piece in x ends near the
caustic, where its pair's rounding and the rule's nodes would meet the 1/sqrt; the paths outside W
are integrated in x on both sides of the cone's crossing.

The bound (QUAD, `_one`; docs/error_bounds.md, "Refractive exact spheres"): the rule's
(media/adaptive.py `bounded_piecewise`, per piece), plus 3 x the least of the largest relative
rounding of an evaluation x (the value + the rule's bound) and the sum over the pieces of their
evaluations' largest absolute rounding x their length (the rule's weights are positive; a piece beside a
crossing split where that exceeds its rule's bound, `_near`), plus each cone crossing's location error
(a quadratic's: its rounding over its slope there, or the square root where the segment grazes the
cone) x 8 x the integrand's largest of
three evaluations around it; beside a caustic crossing the rule's bounds of both integrals, the
rounding of `fold_value` (its absolute largest x W's width) and each end of W off by its root's spread
x 8 x `fold_value` there. An evaluation's rounding is the sum over its paths of the value times,
first order and doubled: the root off by dth = 2 (dh + dX) / s_min (`paths`' spread; dX the rounding
of X's coordinates, s_min the least |h'| about the root: over its cell, or where that is below half
the cell's secant over narrower intervals about it, `_steepest`) plus t's own rounding, carried through
|ds/dtheta| <= |phi'| (|X| + R) + R (the path inside; R for the path outside and 2 R / o for 1 / o^2),
the cosines (|cos_i'|, |cos_t'| <= |theta_i'| (/ eta^2 cos_t); Fresnel's T at most twice cos_i's
relative error, eta > 1), the scattering cosine (|phi'| and e_y's rounding 2 dX / y_X, times the
phase's condition) and the tube factors 1 - s kappa (kappa's derivative through the cosines and o,
over the factor; their own rounding over the factor too); a spot's falloff at its slope. In
`fold_value` theta is exact (t's rounding only), the point's x is off by 2 (|h| + its rounding) / |h_x|
at the computed root (through the path, the attenuation and X's coordinates) and h_x by its own
rounding and its slope (|h_xx| <= |t_z| |v|^2 / y_X) times that. Infinite, counted in stats[UNBOUNDED]:
a caustic crossing that `_fold` cannot take (no such pair at the ends, an end's scan unproven, two
crossings in a row), an evaluation whose scan was unproven, a piece whose path count (or the count
on each side of a spot's band edges) changed between its evaluations (the guard against a crossing
the breaks missed), a caustic or band edge scan unproven, eta <= 1.

The caustic's crossings, proven (`caustic_crossings`). The caustic point is C = P + t R cos_t / phi'
(1 / kappa_t = R cos_t / phi'; inside the sphere iff phi' >= 1/2, the chord being 2 R cos_t; none ahead
of P where phi' <= 0, as everywhere for eta <= 1: g' >= 1 / eta >= 1 there and theta_i' = alpha' - 1 <=
-1 on the lit arc). Its derivative is C' = lambda t, lambda = -R sin(theta_t) (2 phi' - 1) / phi'
- R cos_t phi'' / phi'^2 (theta_t' = phi' - 1), with phi'' = g'' theta_i'^2 + g' alpha'' in closed form
(s, c the sine and cosine of theta_i: g'' = s (1 - eta^2) / (eta^3 cos_t^3), alpha'' = R d sin(theta)
(d^2 - R^2) / o^4), and C'' = lambda' t + lambda phi' n holds phi''' = g''' theta_i'^3 + 3 g'' theta_i'
alpha'' + g' alpha''' (g''' = (1 - eta^2) c (eta^2 cos_t^2 + 3 s^2) / (eta^5 cos_t^5), alpha''' = R d
(d^2 - R^2) (cos(theta) - 4 R d sin(theta)^2 / o^2) / o^4). The segment f + x v across the axis, fz +
x wz along it, meets C turned about the axis where H(theta) = |A|^2 - wz^2 y_C^2 = 0, A = F + z_C v,
F = wz f - fz v (wz^2 (|f + x v|^2 - y_C^2) at x = (z_C - fz) / wz; H is even in theta: [0, theta_a]
is scanned), with H' = 2 z_C' v.A - 2 wz^2 y_C y_C' and H'' = 2 z_C'' v.A + 2 z_C'^2 |v|^2 - 2 wz^2
(y_C'^2 + y_C y_C''). Over a cell [a, b] (`third_bound`: |phi''| <= q2 = G2 (1 + a1)^2 + G1 a2 and
|phi'''| <= p3 = G3 (1 + a1)^3 + 3 G2 (1 + a1) a2 + G1 a3, G1 = 1 / (eta cos_t), G2 = |eta^2 - 1| /
(eta^3 cos_t^3), G3 = |eta^2 - 1| (eta^2 + 2) / (eta^5 cos_t^5) at the least cos_t, a1 as in
`angular_bounds`, a2 = R d (d^2 - R^2) sin / o^4 and a3 = R d (d^2 - R^2) / o^4 (1 + 4 R d sin^2 / o^2)
at the least o and the largest sin; tests/test_sphere_paths.py checks these against mpmath's derivatives) phi' lies within
(phi'(a) + phi'(b) -+ q2 w) / 2: the cell is dropped where that is below 1/2 throughout, else with m > 0
the least, d1 = p1 - 1 >= |phi' - 1|: |C'| <= c1 = R (1 + d1 / m + q2 / m^2), |lambda'| <= R (d1 +
d1^2 / m + (q2 (1 + d1) + p3) / m^2 + 2 q2^2 / m^3), |C''| <= c2 = that + c1 p1; c1 at most the larger
|C'| at the ends + c2 w / 2 too, |A| and |y_C| at most their larger end values + c1 |v| w / 2 and
c1 w / 2, and K = 2 c2 (|v| |A| + wz^2 |y_C|) + 2 c1^2 (|v|^2 + wz^2) bounds |H''|. The cell is then
decided as `paths` decides h's: no root where H keeps its sign and the least |H| at the ends exceeds
K w^2 / 8, or where it is monotone: the secant's slope above K w, or H' of one sign at both ends with
|H'(a)| + |H'(b)| above K w (H' exceeds (|H'(a)| + |H'(b)| - K w) / 2 in size over the cell: this
decides the cells about a nearly double root, where H is too small for the secant); one where H
changes sign and is monotone, bisected; each test less the values' rounding (C off by 4u R + R / m
(t's rounding + 2 x phi''s 64u p1 (1 + 1 / (eta^2 cos_t^2)) / m + 16u / cos_t^2), C' by that carried
through lambda, H and H' by those at the ends' |A|, |y_C| and |C'|, doubled). Not proven (the
segment's bound inf): a cell undecided after MAX_HALVINGS halvings or MAX_EVALS in one scan (a segment
within rounding of tangent to the caustic surface: tests/test_caustic_crossings.py, against the
envelope of the refracted rays from mpmath, finds every crossing and the scan proven on lines 1e-3 to
1e-6 from tangent and beside the cusp, not always at 1e-9), or wz = 0.

The fog's bound (`fog_rounding`, `out_of_sphere`). An evaluation of `fog_value` at o + x w rounds q = o + x w
(3u (|o| + x)), q - c and d = |q - c| (dd = 3u (|o| + x) + 6u d), the axis e_z (dez = dd / d + 8u, absolute), the
light's coordinates X = (z_X, y_X) about it (dxy = |L - c| (3 dez + 16u)) and e_y (2 |L - c| (2 dez + 10u) / y_X).
At fixed theta d turns the arriving direction at P by dal = |p_y| dd / o^2 (d alpha / dd = p_y / o^2), plus its
own rounding (`angular_bounds`' e_t, which bounds it). The root: h = t x (X - P) has h_theta = R cos_t (1 - s
kappa_t) (t' = phi' n, t' x (X - P) = -phi' s, t x P' = -R cos_t: the tube's width in the plane) and h_d =
-s phi_d, |phi_d| <= g' dal / dd (g' = cos_i / (eta cos_t)), so the computed root is off by at most the least of
2 (dh + dxy + s g' dal) / |h_theta| + 4u theta_a (first order, doubled: dh `paths`' rounding of h) and `paths`'
proven spread plus what of dxy exceeds its dx and s g' dal, over |h_theta|. Then theta_i is off by a1 dth + dal,
t's angle by p1 dth + g' dal + e_t (a1, p1 of the root's SCAN cell), o by R dth + dd, s by that angle x (|X| + R)
+ R dth + dxy; and the term's relative error, first order, doubled: the legs' attenuation (their errors times
kt and kt_in, 16u of the exponent), 1 / o^2 (2 do / o), T cos_i / cos_t (Fresnel's T at most twice cos_i's
relative error for eta > 1, |d cos_t| <= |d cos_i| / (eta^2 cos_t), 16u / T its own rounding), the tube factors
1 - s kappa (kappa's error through the cosines and 1 / o, s's, and their rounding, each over the factor), the
phase at its condition times toward's error ((R dth + dd) / o + dez + |p_y| / o x e_y's) and a spot's falloff at
its slope times the cosine's error (t's angle, e_z's and e_y's). It grows like 8u (R + d) / o toward the glass (the
arriving direction's rounding): measured at most 1e-8 of the value there, 1.4e-11 at a distance. The integral's:
media/adaptive.py's rule bound b plus 3 min(rho (|value| + b), sum_i e_i l_i) (rho the largest relative rounding
of the evaluations, e_i the largest absolute of those on piece i between a spot's cuts, of length l_i: the rule's
weights are positive and sum to each piece's length, and a piece the spot does not reach adds 0, where one e x
length over the segment was ~7x the integral of the rounding under the spot). tests/test_globe_bounds.py checks it
against the twin.

The spot's band edges outside (`out_edge_cuts`). A spot inside the sphere (d = |L - c| < R / eta) lights the
fog outside through its falloff, whose band edges (cosines ce = cos_end, cos_start to its axis a) are kinks of the
integrand along a segment: where the segment crosses the edge rays refracted out. The edge's directions are u(phi)
= ce a - se (cos phi b1 + sin phi b2) (b1 the unit normal to a toward q = L - c, b2 = a x b1); each leaves at P =
L + r u, r = S - b (b = q.u, S = sqrt(b^2 + R^2 - d^2) = R cos_1 >= S0 = sqrt(R^2 - d^2)), along t = eta u +
(cos_2 - eta cos_1) n (n = (P - c) / R, cos_2 = sqrt(1 - eta^2 + eta^2 cos_1^2) >= sqrt(1 - eta^2 d^2 / R^2) > 0:
no ray is totally reflected, so every phi in [-pi, pi] gives one smooth ray). A point of the segment whose one path
leaves at the edge's cosine lies on such a ray, so the segment's crossings are among the roots of G(phi) =
det(w, t, o - P) (the lines coplanar), each kept where the two lines meet at 0 < x < end ahead of P. Over all phi
(|b|, |b'|, |b''| <= d, d se, d se; |S'| <= d^2 se / S0, |S''| <= (d^2 se^2 + d^2 se + S'^2) / S0; r <= R + d;
P' = r' u + r u', P'' = r'' u + 2 r' u' + r u'' with |u'| = |u''| = se; cos_1 = S / R; |cos_2'| <= eta^2 |cos_1'| /
cos_2, |cos_2''| <= (eta^2 (cos_1'^2 + |cos_1''|) + cos_2'^2) / cos_2; t' = eta u' + f' n + f n', t'' = eta u'' + f''
n + 2 f' n' + f n'' with f = cos_2 - eta cos_1, |f| <= 1 + eta) K = |t''| (|o - c| + R) + 2 |t'| |P'| + |P''|
bounds |G''|; G is scanned as `paths` scans h (`_halving`, its rounding 2 ((|o - c| + R)(e_t + 16u) + e_p + 4u (|o|
+ |c|)), e_p = 64u (|L| + |c| + R + d)(1 + d / S0) P's and e_t t's). QUAD integrates between the crossings (the
falloff smooth between; a crossing misplaced by dx changes the integral by its jump in slope x dx^2 for a continuous
falloff, far below the rounding; a hard edge's jump x dx is not in the bound); a scan not proven leaves the bound
inf (counted). tests/test_globe_bounds.py checks the crossings against the twin's bisection of the leaving cosine.

The band edges, proven (`edge_crossings`). The edge's directions out of the light L, at cosine ce
to the spot's unit axis a, are u(phi) = ce a - se (cos phi b1 + sin phi b2) (se = sqrt(1 - ce^2), b1
the unit normal to a toward q = L - c, b2 = a x b1), b = q.u = A0 - A1 cos phi (A0 = ce q.a, A1 = se
|q - (q.a) a|); u's ray enters the sphere where b <= -beta, beta = sqrt(d^2 - R^2) (sqrt(d^2 - R^2
eta^2) for eta < 1, the critical angle), there with S = sqrt(b^2 - beta^2) = R cos_i (R eta cos_t
for eta < 1), meeting it at P = L + r u, r = -b - R cos_i, and refracted along t = u / eta + (cos_i /
eta - cos_t) n (n = (P - c) / R). The segment meets the edge ray's line where G = det(w, t, o - P)
= 0 (x and the distance s along t from the two lines, kept for 0 < x < end and s >= 0). Where every
ray enters (A0 + A1 < -beta: mode 2) phi runs over [-pi, pi], S' = b b' / S and S'' = (b'^2 + b b'' -
S'^2) / S bounded with S above sqrt((A0 - A1 cos phi_max)^2 - beta^2); where some do (mode 1: the
arc |phi| < Phi, cos Phi = c* = (A0 + beta) / A1), sin(phi / 2) = s sin(tau), s = sin(Phi / 2), tau
in [-pi/2, pi/2] makes S = 2 s sqrt(A1) cos(tau) sqrt(beta + kappa cos^2 tau) and b = -beta - 2
kappa cos^2 tau (kappa = A1 s^2) smooth through the ends (grazing, or the critical angle: in phi S
has a square root there), with |phi'| <= 2 s min(1, cos / sqrt(1 - s^2 sin^2)), |phi''| <= 2 s (1 -
s^2) |sin| / (1 - s^2 sin^2)^(3/2), |S'| <= 2 s sqrt(A1) |sin| H(cos^2), H(y) = (beta + 2 kappa y) /
sqrt(beta + kappa y) (rising), |S''| <= 2 s sqrt(A1) cos (H + 3 kappa sin^2 / sqrt(beta)) (H' falls
from 3 kappa / (2 sqrt(beta))), each at the cell's extreme cos and sin. P, t are smooth in (phi, S):
|P_phi| <= sqrt(A1^2 + r_max^2 se^2) (r_max = sqrt(d^2 - R^2)), |P_phiphi| <= A1 (1 + 2 se) + r_max
se, |P_S| <= 1, |P_phiS| <= se, |P_SS| <= 1 / (R c_min) for eta < 1 (c_min = sqrt(1 - eta^2), else
0); with f = cos_i / eta - cos_t, |f| <= max(1, 1 / eta), |f_S| <= 1 / (R eta), |f_SS| <= (eta^2 -
1) / (R^2 eta^4 cos_t^3) (1 / (eta R^2 c_min) for eta < 1), t_phi = u_phi / eta + f P_phi / R, t_S =
f_S n + f P_S / R, t_phiphi = u_phiphi / eta + f P_phiphi / R, t_phiS = (f_S P_phi + f P_phiS) / R,
t_SS = f_SS n + (2 f_S P_S + f P_SS) / R; the chain rule through (phi', S') gives |P'|, |t'|, |P''|,
|t''| and K = |t''| (|o - c| + R) + 2 |t'| |P'| + |P''| bounds |G''| over the cell (`edge_bound`;
tests/test_sphere_band_edges.py checks it against mpmath's derivatives). The cells are decided as
`paths` decides h's, less G's rounding: 2 ((|o - c| + R)(e_t + 16u) + e_p), e_p = 64u (|L| + |c| +
|o| + d + R + d cond) an edge point's distance from the exact edge rays (cond the parameter's
conditioning: (|A0| + beta + A1) / (A1 s sqrt(1 - s^2)) in mode 1, d / S_min in mode 2), e_t its
direction's; and, as the caustic's, monotone too where G' keeps its sign at both ends and |G'(a)| +
|G'(b)| less their rounding exceeds K w (G' >= G'(a) - K (x - a) and >= G'(b) - K (b - x), so over
the cell |G'| exceeds half that excess: G has at most one root there, decided by its ends' signs).
This decides the cells beside a nearly double root (a segment nearly tangent to the edge's surface),
where |G| is within its rounding and the secant's slope is lost in it. G' = det(w, t', o - P) -
det(w, t, P') (`edge_slope`) in closed form: mode 1 phi' = 2 s cos / sqrt(1 - s^2 sin^2), b' = 4 kappa
cos sin, S' = -2 s sqrt(A1) sin (beta + 2 kappa cos^2) / sqrt(beta + kappa cos^2); mode 2 phi' = 1,
b' = A1 sin phi, S' = b b' / S; u' = phi' se (sin phi b1 - cos phi b2), cos_i' and cos_t' from S' (S =
R cos_i, cos_t' = cos_i cos_i' / (eta^2 cos_t); for eta < 1 S = R eta cos_t, cos_i' = S S' / (R^2
cos_i)), r' = -b' - R cos_i', P' = r' u + r u', f' = cos_i' / eta - cos_t', t' = u' / eta + (f' P +
f P') / R; its rounding is each intermediate's absolute rounding carried alongside to first order
(sums and products at their magnitudes, sqrt, asin and quotients at their conditioning), doubled
(tests/test_sphere_band_edges.py: within 1% of it against mpmath's derivative of the closed form, at
random parameters and at the ends of the range). Not proven (the segment's bound inf): a cell
undecided after MAX_HALVINGS halvings or MAX_EVALS in one scan (a segment within rounding of tangent
to the edge's surface: the test, against a reference that solves Snell's law in mpmath along the
segment, finds every crossing and the scan proven on random lines and lines 1e-3, 1e-6 and 1e-9 from
tangent).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..geometry.sphere import quadratic_roots
from ..jit import njit
from ..lights import falloff
from ..lights.spot import band_slope
from ..geometry.sorting import sort_few
from .adaptive import bounded_piecewise
from .integrand import integrand_of, record_dispatch
from .phase import phase_value
from .gauss import N10, N20, W10, W20
from .inside_rule import QUAD, cut_length, march_or_sample
from .slab import fresnel, phase_condition

SCAN = 48  # uniform cells on which a halving scan starts (`_halving`: the lit arc, its half, the edge rays)
MAX_HALVINGS = 40  # of a cell of a halving scan before it is left unresolved
MAX_EVALS = 1000  # halvings of one halving scan before its undecided cells are left unresolved
CELL_STACK = SCAN + 2 * MAX_HALVINGS + 2
U = 2.0 ** -53
# a record's `track` slots, written by its integrand: the evaluations whose scan was not proven, the
# largest relative rounding bound and the largest absolute one (of the piece's evaluations), the path
# count of the piece's first evaluation (-1: none yet), the evaluations whose count differed from it,
# the largest absolute rounding of a fold pair's integrand (per unit angle) and the sum over the pieces
# of their largest absolute rounding times their length
UNRESOLVED, ROUNDING, ROUNDING_ABS, COUNT, COUNT_CHANGED, FOLD_ABS, PIECES_ABS = range(7)
TRACK = 7
MAX_PATHS = 8  # room for an inside point's paths (at most three are found in practice)
UNBOUNDED = 8  # the stats slot (interiors/support.py's) of the QUAD segments whose bound is inf
GAP = 6  # `_gap`'s values
SPLIT, SPLITS = 0.1, 3  # `_near`: where a piece beside a crossing is split (in u), and how many times at most
EDGES = 8  # room for the x where a path crosses a spot's band edge (two angles, two rays each, two points)


class SphereRefracted(NamedTuple):
    """One inside segment of a refractive exact sphere and one unit light (module docstring): the
    segment's start o and direction w, the sphere's centre c and radius, the light's position (a
    directional light: the unit direction toward it), its axis ez (the unit direction from c toward
    the light), d = |L - c| (inf for a directional light), theta_a the lit arc's half-width, the
    spot's axis and (cos_end, cos_start, curve), `cell_table`, the integrand's track, the window of
    angles whose paths `refracted_value` leaves out (empty: (inf, -inf)) and the spot's band edges
    (`spot_edges`: their count, then the x where a path crosses one, ascending; then the angles)."""
    o: np.ndarray
    w: np.ndarray
    c: np.ndarray
    radius: float
    light: np.ndarray
    distant: bool
    ez: np.ndarray
    d: float
    theta_a: float
    eta: float
    kt: float
    ks: float
    code: int
    g: float
    kt_out: float
    axis: np.ndarray
    spot: tuple
    cells: np.ndarray
    track: np.ndarray
    window: np.ndarray
    edges: np.ndarray


@njit
def _arriving(theta, radius, d):
    """(cos theta, sin theta, pz, py, dz, dy, o): the point P = radius (cos theta, sin theta), the unit
    direction (dz, dy) of the light arriving there from the light at distance d on the axis (inf: a
    directional light along -z) and the path outside o (inf for a directional light)."""
    cth, sth = math.cos(theta), math.sin(theta)
    pz, py = radius * cth, radius * sth
    if d == math.inf:
        return cth, sth, pz, py, -1.0, 0.0, math.inf
    dz, dy = pz - d, py
    o = math.sqrt(dz * dz + dy * dy)
    return cth, sth, pz, py, dz / o, dy / o, o


@njit
def incidence(theta, radius, d, eta):
    """(pz, py, tz, ty, cos_i, cos_t, o) of the ray from the light (at distance d from the centre on
    the axis, inf: a directional light along -z) refracted at P = radius (cos theta, sin theta): its
    unit direction inside (tz, ty), the incidence and refraction cosines and the path outside o (inf
    for a directional light); cos_t = 0 where it does not enter (cos_i <= 0, total reflection)."""
    cth, sth, pz, py, dz, dy, o = _arriving(theta, radius, d)
    cos_i = -(dz * cth + dy * sth)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)
    if cos_i <= 0.0 or sin2_t >= 1.0:
        return pz, py, dz, dy, cos_i, 0.0, o
    cos_t = math.sqrt(1.0 - sin2_t)
    f = cos_i / eta - cos_t
    return pz, py, dz / eta + f * cth, dy / eta + f * sth, cos_i, cos_t, o


@njit
def path_to(theta, zx, yx, radius, d, eta):
    """(pz, py, tz, ty, cos_i, cos_t, o, s, tube) of the path refracted at theta (`incidence`) on to the
    point (zx, yx) of its plane: s the leg inside, tube |(1 - s kappa_t)(1 - s kappa_s)| the ray tube's
    factor (module docstring, Coddington's curvatures); tube nan where the path does not reach the point
    (cos_t = 0, or the point behind the refraction point)."""
    pz, py, tz, ty, cos_i, cos_t, o = incidence(theta, radius, d, eta)
    s = tz * (zx - pz) + ty * (yx - py)
    if cos_t == 0.0 or not s >= 0.0:
        return pz, py, tz, ty, cos_i, cos_t, o, s, math.nan
    tube = abs((1.0 - s * tangential_curvature(cos_i, cos_t, 1.0 / o, radius, eta))
               * (1.0 - s * ((eta * cos_t - cos_i) / radius - 1.0 / o) / eta))
    return pz, py, tz, ty, cos_i, cos_t, o, s, tube


@njit
def lit_arc(radius, d, eta):
    """theta_a: the lit arc's half-width, where the incidence cosine (falling with |theta|) reaches 0,
    or sqrt(1 - eta^2) for eta < 1 (bisected to the resolution of doubles)."""
    c_min = math.sqrt(1.0 - eta * eta) if eta < 1.0 else 0.0
    hi = 0.5 * math.pi if d == math.inf else math.acos(min(radius / d, 1.0))
    if c_min == 0.0:
        return hi
    lo = 0.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if incidence(mid, radius, d, eta)[4] > c_min:
            lo = mid
        else:
            hi = mid
    return lo


@njit
def tangential_curvature(cos_i, cos_t, inv_o, radius, eta):
    """kappa_t, the refracted wavefront's curvature in the plane of the path (Coddington's tangential
    equation, module docstring); inv_o = 1 / the path outside (0 for a directional light)."""
    return ((eta * cos_t - cos_i) / radius - cos_i * cos_i * inv_o) / (eta * cos_t * cos_t)


@njit
def _clamped(theta, radius, d, eta):
    """(pz, py, tz, ty, cos_t, cos_i, o) of `incidence` with the incidence cosine clamped at 0 and the refraction
    cosine's square at 0: continuous in theta, at the lit arc's ends (theta_a) the ray refracted at
    grazing incidence (or at the critical angle for eta < 1), its limit from inside the arc; the
    same numbers as `incidence` inside it."""
    cth, sth, pz, py, dz, dy, o = _arriving(theta, radius, d)
    cos_i = max(-(dz * cth + dy * sth), 0.0)
    cos_t = math.sqrt(max(1.0 - (1.0 - cos_i * cos_i) / (eta * eta), 0.0))
    f = cos_i / eta - cos_t
    return pz, py, dz / eta + f * cth, dy / eta + f * sth, cos_t, cos_i, o


@njit
def angular_bounds(lo, hi, radius, d, eta):
    """(p1, p2, et, a1) over theta in [lo, hi] (within the lit arc): bounds on |phi'| and |phi''|, phi(theta)
    the angle of the refracted direction t, on the rounding of t's computed components and on |theta_i'|,
    theta_i the signed incidence angle (module
    docstring, "The paths, proven"); inf where the refraction cosine reaches 0 (eta < 1 at the arc's end)."""
    m_lo = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
    m_hi = max(abs(lo), abs(hi))
    ct = _clamped(m_hi, radius, d, eta)[4] * (1.0 - 1e-9) - 4.0 * U  # the least refraction cosine
    if not ct > 0.0:
        return math.inf, math.inf, math.inf, math.inf
    a1 = a2 = ed = 0.0
    if d != math.inf:  # alpha, the arriving direction's angle: its derivatives
        half = math.sin(0.5 * m_lo)
        o2 = ((d - radius) * (d - radius) + 4.0 * radius * d * half * half) * (1.0 - 1e-12)  # the least o^2
        q = max(d * math.cos(m_lo) - radius, 0.0) + 4.0 * U * d  # the largest d cos(theta) - R
        a1 = radius * q / o2
        a2 = radius * d * math.sin(m_hi) / o2 * (1.0 + 2.0 * radius * q / o2)
        ed = 8.0 * U * (radius + d) / math.sqrt(o2) + 4.0 * U
    g1 = 1.0 / (eta * ct)
    g2 = (1.0 + 1.0 / (eta * eta * ct)) / (eta * ct * ct)
    p1 = 1.0 + g1 * (1.0 + a1)
    p2 = g2 * (1.0 + a1) * (1.0 + a1) + g1 * a2
    et = (ed + 8.0 * U) * (1.0 + 2.0 / eta + 2.0 / (eta * eta * ct)) + 16.0 * U
    return p1 * (1.0 + 1e-9), p2 * (1.0 + 1e-9), et * 2.0, (1.0 + a1) * (1.0 + 1e-9)


@njit
def third_bound(lo, hi, radius, d, eta):
    """(q2, p3, ct) over theta in [lo, hi] (within the lit arc): bounds on |phi''| and |phi'''| and the
    least refraction cosine (module docstring, "The caustic's crossings, proven"): G2 (1 + a1)^2 + G1 a2
    and G3 (1 + a1)^3 + 3 G2 (1 + a1) a2 + G1 a3, taken at the cell's extreme ends as `angular_bounds`
    takes its bounds (q2 tighter than its p2: g'' in closed form); inf where the refraction cosine
    reaches 0."""
    m_lo = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
    m_hi = max(abs(lo), abs(hi))
    ct = _clamped(m_hi, radius, d, eta)[4] * (1.0 - 1e-9) - 4.0 * U
    if not ct > 0.0:
        return math.inf, math.inf, 0.0
    a1 = a2 = a3 = 0.0
    if d != math.inf:
        half = math.sin(0.5 * m_lo)
        o2 = ((d - radius) * (d - radius) + 4.0 * radius * d * half * half) * (1.0 - 1e-12)  # the least o^2
        q = max(d * math.cos(m_lo) - radius, 0.0) + 4.0 * U * d  # the largest d cos(theta) - R
        sn = math.sin(m_hi)
        k = radius * d * (d * d - radius * radius) / (o2 * o2)
        a1, a2, a3 = radius * q / o2, k * sn, k * (1.0 + 4.0 * radius * d * sn * sn / o2)
    e2 = abs(eta * eta - 1.0)
    g1 = 1.0 / (eta * ct)
    g2 = e2 * g1 * g1 * g1
    g3 = e2 * (eta * eta + 2.0) * g1 ** 5
    p = 1.0 + a1
    return (g2 * p * p + g1 * a2) * (1.0 + 1e-9), (g3 * p * p * p + 3.0 * g2 * p * a2 + g1 * a3) * (1.0 + 1e-9), ct


@njit
def cell_table(theta_a, radius, d, eta):
    """(SCAN, 7) of the SCAN uniform cells of the lit arc (-theta_a, theta_a): `angular_bounds`, then
    `third_bound`."""
    out = np.empty((SCAN, 7))
    step = 2.0 * theta_a / SCAN
    for j in range(SCAN):
        lo, hi = -theta_a + j * step, -theta_a + (j + 1) * step
        out[j, 0], out[j, 1], out[j, 2], out[j, 3] = angular_bounds(lo, hi, radius, d, eta)
        out[j, 4], out[j, 5], out[j, 6] = third_bound(lo, hi, radius, d, eta)
    return out


@njit
def _caustic(theta, radius, d, eta):
    """(phi', cz, cy, dcz, dcy) at theta (`_clamped`'s ray, continuous to the arc's ends): phi' = 1 + g'
    theta_i' = 1 - cos_i (1 - alpha') / (eta cos_t), the caustic point C = P + t R cos_t / phi' and
    its derivative C' = lambda t (module docstring, "The caustic's crossings, proven"; phi'' = g''
    theta_i'^2 + g' alpha'' with sin(theta_i) = eta sin(theta_t)); C nan where the refraction cosine is
    0 or phi' <= 0 (no caustic point ahead of P)."""
    pz, py, tz, ty, cos_t, cos_i, o = _clamped(theta, radius, d, eta)
    if not cos_t > 0.0:
        return math.nan, math.nan, math.nan, math.nan, math.nan
    a1 = a2 = 0.0
    if d != math.inf:
        o2 = o * o
        a1 = radius * (radius - d * math.cos(theta)) / o2
        a2 = radius * d * math.sin(theta) * (d * d - radius * radius) / (o2 * o2)
    g1 = cos_i / (eta * cos_t)
    phi1 = 1.0 - g1 * (1.0 - a1)
    if not phi1 > 0.0:
        return phi1, math.nan, math.nan, math.nan, math.nan
    sin_t = (tz * py - ty * pz) / radius
    phi2 = sin_t * (1.0 - eta * eta) / (eta * eta * cos_t ** 3) * (1.0 - a1) * (1.0 - a1) + g1 * a2
    rho = radius * cos_t / phi1
    lam = -radius * sin_t * (2.0 * phi1 - 1.0) / phi1 - rho * phi2 / phi1
    return phi1, pz + tz * rho, py + ty * rho, lam * tz, lam * ty


@njit
def _gap(theta, s):
    """(H, phi', H', |A|, |y_C|, |C'|) at theta of the `CausticScan` s: H = |A|^2 - wz^2 y_C^2, A = F + z_C v,
    of the caustic point C(theta) (`_caustic`; F = (f0, f1, f2) = wz f - z0 v, v = (v0, v1, v2) of the
    segment f + x v across the axis, z0 + x wz along it: 0 where C turned about the axis meets the
    segment's line) and its derivative."""
    phi1, cz, cy, dcz, dcy = _caustic(theta, s.radius, s.d, s.eta)
    f0, f1, f2, v0, v1, v2, wz = s.f0, s.f1, s.f2, s.v0, s.v1, s.v2, s.wz
    a0, a1, a2 = f0 + cz * v0, f1 + cz * v1, f2 + cz * v2
    aa = a0 * a0 + a1 * a1 + a2 * a2
    return aa - wz * wz * cy * cy, phi1, 2.0 * dcz * (v0 * a0 + v1 * a1 + v2 * a2) - 2.0 * wz * wz * cy * dcy, \
        math.sqrt(aa), abs(cy), math.sqrt(dcz * dcz + dcy * dcy)


# The halving scan (`_halving`) of `paths`, `caustic_crossings` and `edge_crossings`, on a scan record
# (`PathScan`, `CausticScan`, `EdgeCone`) that names the function and its cells' tests:

def scan_at(s, x):
    """A tuple at x: the scanned function's value, then what `scan_cell` needs of that point."""


def scan_value(s, x):
    """The scanned function at x (`scan_at`'s first)."""


def scan_cell(s, a, b, j, e):
    """The verdict on the cell [a, b] (within the scan's uniform cell j; e: `scan_at` at a, then at b):
    -1 no root, 1 monotone (one root where the ends' signs differ), 0 undecided (halved)."""


def scan_spread(s, root, a, b, fa, fb, j):
    """How far the root found in the monotone cell [a, b] (fa, fb the function there) may lie from the
    exact function's (inf where not bounded)."""


_at_of = record_dispatch(scan_at, 0, inline=True)
_value_of = record_dispatch(scan_value, 0, inline=True)
_cell_of = record_dispatch(scan_cell, 0, inline=True)
_spread_of = record_dispatch(scan_spread, 0, inline=True)


class PathScan(NamedTuple):
    """`paths`' h of the point X = (zx, yx), X's rounding dx and reach = |X| + R (at least |X - P|), for
    the light and sphere of a `SphereRefracted` (its radius, d, eta, theta_a and cells)."""
    zx: float
    yx: float
    dx: float
    reach: float
    radius: float
    d: float
    eta: float
    theta_a: float
    cells: np.ndarray


class CausticScan(NamedTuple):
    """`caustic_crossings`' H for r's light and the segment's line: F = (f0, f1, f2), v = (v0, v1, v2), wz
    (`_gap`), |v|, |v|^2, wz^2 and F's rounding e_f, for the light and sphere of a `SphereRefracted`
    (its radius, d, eta and cells)."""
    f0: float
    f1: float
    f2: float
    v0: float
    v1: float
    v2: float
    wz: float
    vn: float
    vv: float
    ww: float
    e_f: float
    radius: float
    d: float
    eta: float
    cells: np.ndarray


@njit
def _bisect(s, lo, hi, h_lo):
    """The root of the scan record s's function in [lo, hi] (h_lo its sign at lo, the other sign at hi) to
    the resolution of doubles."""
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if not lo < mid < hi:
            break
        if scan_value(s, mid) * h_lo > 0.0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@njit
def _halving(s, lo, step, first, start, right_node, out, spread):
    """The roots of the scan record s's function over the uniform cells first to SCAN - 1 of width step
    from lo (the first cell starting at start) into out, ascending, each with its `scan_spread` (inf at a
    node or in an unresolved cell) into spread; returns (count, proven): each cell halved until
    `scan_cell` decides it, a root of a monotone cell bisected to the resolution of doubles, roots at the
    nodes taken as they are (the right end's where right_node); not proven where a cell reached
    MAX_HALVINGS halvings, the scan MAX_EVALS or out filled up (sign changes are still bisected)."""
    node = scan_at(s, lo + SCAN * step)
    width = len(node)
    ca, cb = np.empty(CELL_STACK), np.empty(CELL_STACK)
    vals = np.empty((CELL_STACK, 2 * width))  # `scan_at` at both ends
    ends = np.empty(2 * width)  # a cell's, for `scan_cell`
    which, depth = np.empty(CELL_STACK, dtype=np.int64), np.empty(CELL_STACK, dtype=np.int64)
    m, top, proven, evals = 0, 0, True, 0
    cap = out.shape[0]
    if node[0] == 0.0 and right_node:
        out[m] = lo + SCAN * step
        spread[m] = math.inf
        m += 1
    for j in range(SCAN - 1, first - 1, -1):  # pushed last to first: popped from the left
        left = lo + j * step if j > first else start
        for i in range(width):
            vals[top, width + i] = node[i]
        node = scan_at(s, left)
        if node[0] == 0.0 and m < cap:
            out[m] = left
            spread[m] = math.inf
            m += 1
        ca[top], cb[top], which[top], depth[top] = left, lo + (j + 1) * step, j, 0
        for i in range(width):
            vals[top, i] = node[i]
        top += 1
    while top > 0:
        top -= 1
        a, b, j = ca[top], cb[top], which[top]
        fa, fb = vals[top, 0], vals[top, width]
        for i in range(2 * width):
            ends[i] = vals[top, i]
        verdict = scan_cell(s, a, b, j, ends)
        if verdict < 0:
            continue
        if verdict > 0:
            if fa * fb < 0.0:
                if m < cap:
                    out[m] = _bisect(s, a, b, fa)
                    spread[m] = scan_spread(s, out[m], a, b, fa, fb, j)
                    m += 1
                else:
                    proven = False
            continue
        mid = 0.5 * (a + b)
        if depth[top] >= MAX_HALVINGS or top + 2 > CELL_STACK or evals >= MAX_EVALS or not a < mid < b:
            proven = False
            if fa * fb < 0.0 and m < cap:
                out[m] = _bisect(s, a, b, fa)
                spread[m] = math.inf
                m += 1
            continue
        node = scan_at(s, mid)
        evals += 1
        if node[0] == 0.0:
            if m < cap:
                out[m] = mid
                spread[m] = math.inf
                m += 1
            else:
                proven = False
        level = depth[top] + 1
        ca[top + 1], cb[top + 1], which[top + 1], depth[top + 1] = a, mid, j, level
        for i in range(width):
            vals[top + 1, i], vals[top + 1, width + i], vals[top, i] = vals[top, i], node[i], node[i]
        ca[top], depth[top] = mid, level
        top += 2
    for p in range(1, m):  # insertion sort, the spreads alongside
        x, s0, q = out[p], spread[p], p
        while q > 0 and out[q - 1] > x:
            out[q], spread[q] = out[q - 1], spread[q - 1]
            q -= 1
        out[q], spread[q] = x, s0
    return m, proven


@njit
def _h(theta, zx, yx, radius, d, eta):
    """h(theta) = t x (X - P) of the point X = (zx, yx) (`_clamped`'s t, continuous to the arc's ends)."""
    pz, py, tz, ty, _, _, _ = _clamped(theta, radius, d, eta)
    return tz * (yx - py) - ty * (zx - pz)


@njit
def _paths_bound(s, j):
    """(K, dh) of the `PathScan` s over SCAN cell j: the bound on |h''| and h's rounding (module docstring,
    "The paths, proven")."""
    radius, reach = s.radius, s.reach
    p1, p2, et = s.cells[j, 0], s.cells[j, 1], s.cells[j, 2]
    k = (p2 + p1 * p1) * reach + 2.0 * p1 * radius + radius
    return k, 2.0 * (2.0 * et * reach + 16.0 * U * (radius + reach))


@_at_of(PathScan, inline=True)
@njit
def _paths_at(s, x):
    return (_h(x, s.zx, s.yx, s.radius, s.d, s.eta),)


@_value_of(PathScan, inline=True)
@njit
def _paths_value(s, x):
    return _h(x, s.zx, s.yx, s.radius, s.d, s.eta)


@_cell_of(PathScan, inline=True)
@njit
def _paths_cell(s, a, b, j, e):
    """No root where h keeps its sign and either its least |h| at the ends exceeds K w^2 / 8 or the
    secant's slope exceeds K w; monotone where the secant's slope exceeds K w (each less the rounding)."""
    k, dh = _paths_bound(s, j)
    fa, fb, w = e[0], e[1], b - a
    if fa * fb > 0.0:
        return -1 if min(abs(fa), abs(fb)) - dh > 0.125 * k * w * w or abs(fb - fa) - 2.0 * dh > k * w * w else 0
    return 1 if abs(fb - fa) - 2.0 * dh > k * w * w else 0


@_spread_of(PathScan)
@njit
def _paths_spread(s, root, a, b, fa, fb, j):
    """2 (the values' rounding + dx) / the least |h'| about the root (`_steepest`)."""
    k, dh = _paths_bound(s, j)
    slope = _steepest(root, a, b, fa, fb, k, dh + s.dx, s)
    return 2.0 * (dh + s.dx) / slope + 4.0 * U * s.theta_a if slope > 0.0 else math.inf


@njit
def _steepest(root, a, b, fa, fb, k, e, s):
    """A lower bound on |h'| about the root of h (of the `PathScan` s) in the monotone cell [a, b] (h(a) =
    fa, h(b) = fb, K = k over it) within which the root of h off by e at most lies: the cell's secant's
    slope less K w, and where that is below half the secant's, narrower intervals about the root, each
    quartered: their secant less K w where h there differs from 0 by more than e at both ends (the root of
    h off by e is then inside: |h| grows away from the root, h being monotone in the cell)."""
    w = b - a
    secant = abs(fb - fa) / w
    best = secant - k * w - 2.0 * e / w  # the cell's: its ends' values off by e each
    half = 0.25 * w
    for _ in range(24):
        if best >= 0.5 * secant:
            break
        lo, hi = max(a, root - half), min(b, root + half)
        f1 = _h(lo, s.zx, s.yx, s.radius, s.d, s.eta)
        f2 = _h(hi, s.zx, s.yx, s.radius, s.d, s.eta)
        wn = hi - lo
        if not wn > 0.0 or not f1 * f2 < 0.0 or min(abs(f1), abs(f2)) <= 2.0 * e:
            break
        secant = abs(f2 - f1) / wn
        best = max(best, secant - k * wn - 2.0 * e / wn)
        half *= 0.25
    return best


@njit
def paths(r, zx, yx, dx, out, spread):
    """The roots of h of the point X = (zx, yx) on the lit arc into out, ascending, and into spread[k]
    how far each may be from the exact root of X, whose computed coordinates are off by dx at most: 2
    (the values' rounding + dx) / the least |h'| about the root (`_steepest`; inf for a root at a node
    or in an unresolved cell); returns (count, proven): `_halving` over SCAN uniform cells, each halved
    until the bound K on |h''| over it (`angular_bounds` of its SCAN cell) shows that it holds no root
    (no sign change and either the least |h| at its ends above K w^2 / 8 or h monotone: the secant's
    slope above K w, each less the values' rounding) or one (a sign change and h monotone), that root
    bisected to the resolution of doubles (module docstring, "The paths, proven")."""
    s = PathScan(zx, yx, dx, math.sqrt(zx * zx + yx * yx) + r.radius, r.radius, r.d, r.eta, r.theta_a, r.cells)
    step = 2.0 * r.theta_a / SCAN
    return _halving(s, -r.theta_a, step, 0, -r.theta_a, True, out, spread)


@njit
def caustic_crossings(r, f, v, fz, wz, out):
    """The angles theta in [0, theta_a] where the caustic point C(theta) turned about the axis meets the
    line of the segment f + x v across the axis, fz + x wz along it: the roots of `_gap`'s H (F = wz f
    - fz v) into out, ascending; returns (count, proven) (module docstring, "The caustic's crossings,
    proven"): `_halving` over the SCAN / 2 cells of `cell_table` on [0, theta_a], each halved until it
    is decided: left out where phi' < 1/2 over it (C beyond the sphere or behind P), else, where phi'
    >= m > 0 over it, as `paths` decides a cell of h by the bound K on |H''| and H's rounding, and
    monotone too where H' keeps its sign at both ends and |H'(a)| + |H'(b)| exceeds K w (each less its
    rounding); each root bisected to the resolution of doubles. Not proven where a cell reached
    MAX_HALVINGS halvings, the scan MAX_EVALS or out filled up (a segment within rounding of tangent to
    the caustic surface, where a root is double), or where wz = 0 (the caustic point's height alone does
    not place it on the segment); none for eta <= 1 (phi' < 0: no caustic point ahead of P)."""
    if not r.eta > 1.0:
        return 0, True
    if wz == 0.0:
        return 0, False
    v0, v1, v2 = v[0], v[1], v[2]
    vv = v0 * v0 + v1 * v1 + v2 * v2
    vn = math.sqrt(vv)
    e_f = 16.0 * U * (abs(wz) * math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) + abs(fz) * vn)  # F's rounding
    s = CausticScan(wz * f[0] - fz * v[0], wz * f[1] - fz * v[1], wz * f[2] - fz * v[2], v0, v1, v2, wz, vn, vv,
                    wz * wz, e_f, r.radius, r.d, r.eta, r.cells)
    step = 2.0 * r.theta_a / SCAN
    return _halving(s, -r.theta_a, step, SCAN // 2, 0.0, True, out, np.empty(out.shape[0]))


@_at_of(CausticScan, inline=True)
@njit
def _caustic_at(s, x):
    return _gap(x, s)


@_value_of(CausticScan, inline=True)
@njit
def _caustic_value(s, x):
    return _gap(x, s)[0]


@_cell_of(CausticScan, inline=True)
@njit
def _caustic_cell(s, a, b, j, e):
    """No root where phi' < 1/2 over the cell; else, where phi' >= m > 0 over it, as `_paths_cell` by the
    bound K on |H''| (module docstring, "The caustic's crossings, proven") and monotone too where H' keeps
    its sign at both ends and |H'(a)| + |H'(b)| exceeds K w, each less its rounding; no root needs both
    ends' |H| above their rounding."""
    radius, eta, cells = s.radius, s.eta, s.cells
    vn, vv, ww = s.vn, s.vv, s.ww
    fa, qa, sa, fb, qb, sb = e[0], e[1], e[2], e[GAP], e[GAP + 1], e[GAP + 2]
    w = b - a
    p1, et, p2, p3, ct = cells[j, 0], cells[j, 2], cells[j, 4], cells[j, 5], cells[j, 6]
    g = 1.0 + 1.0 / (eta * eta * ct * ct)
    slack = 64.0 * U * p1 * g  # phi''s rounding
    if 0.5 * (qa + qb + p2 * w) + slack < 0.5:
        return -1  # phi' < 1/2 over the cell: C beyond the sphere or behind P
    low = 0.5 * (qa + qb - p2 * w) - slack  # the least phi' over the cell
    if not (low > 0.0 and fa == fa and fb == fb):
        return 0
    d1 = p1 - 1.0  # |phi' - 1| at most
    c2 = radius * (d1 + d1 * d1 / low + (p2 * (1.0 + d1) + p3) / (low * low) + 2.0 * p2 * p2 / low ** 3)
    c1 = radius * (1.0 + d1 / low + p2 / (low * low))  # |C'|
    c2 += c1 * p1  # |C''|
    c1 = min(c1, max(e[5], e[GAP + 5]) + 0.5 * c2 * w)
    amax = max(e[3], e[GAP + 3]) + 0.5 * c1 * vn * w  # |F + z_C v|
    ymax = max(e[4], e[GAP + 4]) + 0.5 * c1 * w  # |y_C|
    k = 2.0 * c2 * (vn * amax + ww * ymax) + 2.0 * c1 * c1 * (vv + ww)
    e_r = et + 2.0 * slack / low  # t's rounding and 1 / phi''s relative
    e_c = 4.0 * U * radius + radius / low * (e_r + 16.0 * U / (ct * ct))  # C's
    e_c1 = (c1 * (2.0 + eta) + radius * (2.0 + 1.0 / low)) * e_r + radius * p2 / (low * low) * 64.0 * U * g  # C''s
    e_a = vn * e_c + s.e_f + 16.0 * U * (radius + radius / low) * vn  # A's
    dha = 2.0 * (2.0 * (e[3] * e_a + ww * e[4] * e_c) + 8.0 * U * (e[3] * e[3] + ww * e[4] * e[4]))
    dhb = 2.0 * (2.0 * (e[GAP + 3] * e_a + ww * e[GAP + 4] * e_c) + 8.0 * U * (e[GAP + 3] ** 2 + ww * e[GAP + 4] ** 2))
    dsa = 4.0 * ((vn * e[3] + ww * e[4]) * (e_c1 + 8.0 * U * e[5]) + e[5] * (vn * e_a + ww * e_c))
    dsb = 4.0 * ((vn * e[GAP + 3] + ww * e[GAP + 4]) * (e_c1 + 8.0 * U * e[GAP + 5]) +
                 e[GAP + 5] * (vn * e_a + ww * e_c))
    mono = sa * sb > 0.0 and abs(sa) + abs(sb) - 2.0 * (dsa + dsb) > k * w or \
        abs(fb - fa) - 2.0 * (dha + dhb) > k * w * w
    if fa * fb > 0.0:
        return -1 if abs(fa) > dha and abs(fb) > dhb and (min(abs(fa) - dha, abs(fb) - dhb) > 0.125 * k * w * w
                                                           or mono) else 0
    return 1 if mono else 0


@_spread_of(CausticScan, inline=True)
@njit
def _caustic_spread(s, root, a, b, fa, fb, j):
    return math.inf


class EdgeCone(NamedTuple):
    """A spot's band edge, not aimed at the centre, and one segment (module docstring, "The band
    edges, proven"): mode 0 (no edge ray enters), 1 (some: tau in [-pi/2, pi/2]) or 2 (all: phi in
    [-pi, pi]); A0, A1 of b = q.u = A0 - A1 cos phi, beta (b <= -beta where the ray enters), s and kappa
    = A1 s^2 of mode 1, the edge's cosine ce and sine se, the unit axis a and b1, b2 across it (b1
    toward q), q = L - c, the segment's start oc relative to the centre and its direction w (3-tuples:
    scalars, no arrays to count references to in the scan), the radius, eta, d = |q|, reach (|oc| + R, at
    least |oc - P|) and dg (G's rounding)."""
    mode: int
    a0: float
    a1: float
    beta: float
    s: float
    kappa: float
    ce: float
    se: float
    a: tuple
    b1: tuple
    b2: tuple
    q: tuple
    oc: tuple
    w: tuple
    radius: float
    eta: float
    d: float
    reach: float
    dg: float


@njit
def _norm(v):
    """|v| of a 3-vector."""
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


@njit
def edge_cone(r, ce):
    """The `EdgeCone` of r's spot edge at cosine ce (module docstring, "The band edges, proven"): the
    entering rays' parameter, and G's rounding dg = 2 (reach (e_t + 16u) + e_p), e_p = 64u (|L| + |c| +
    |o| + d + R + d cond) the position error of an edge point (cond: the parameter's conditioning) and
    e_t = e_p (1 / (eta (d - R)) + 3 max(1, 1 / eta) / R) + 32u (1 + 2 max(1, 1 / eta)) its direction's."""
    radius, eta, d = r.radius, r.eta, r.d
    a = r.axis / _norm(r.axis)
    q = r.light - r.c
    qa = q[0] * a[0] + q[1] * a[1] + q[2] * a[2]
    b1 = q - qa * a
    big = _norm(b1)
    if not big > 1e-12 * d:  # q along the axis: any normal to it
        k = 0 if abs(a[0]) < 0.9 else 1
        b1[:] = -a[k] * a
        b1[k] += 1.0
        big = 0.0
    b1 /= _norm(b1)
    b2 = np.array([a[1] * b1[2] - a[2] * b1[1], a[2] * b1[0] - a[0] * b1[2], a[0] * b1[1] - a[1] * b1[0]])
    se = math.sqrt((1.0 - ce) * (1.0 + ce))
    a0, a1 = ce * qa, se * big
    beta = math.sqrt(max((d - radius) * (d + radius), 0.0)) if eta >= 1.0 else \
        math.sqrt(max((d - radius * eta) * (d + radius * eta), 0.0))
    oc = r.o - r.c
    mode, s, kappa, cond = 0, 0.0, 0.0, math.inf
    if not d > radius or a0 - a1 >= -beta:
        mode = 0
    elif a0 + a1 < -beta:
        mode = 2
        cond = d / math.sqrt((-a0 - a1 - beta) * (beta - a0 - a1))
    else:
        mode = 1
        s = math.sqrt(0.5 * (1.0 - (a0 + beta) / a1))
        kappa = a1 * s * s
        if s < 1.0:
            cond = (abs(a0) + beta + a1) / (a1 * s * math.sqrt((1.0 - s) * (1.0 + s)))
    fm = max(1.0, 1.0 / eta)
    ep = 64.0 * U * (_norm(r.light) + _norm(r.c) + _norm(r.o) + d + radius + d * cond)
    et = ep * (1.0 / (eta * (d - radius)) + 3.0 * fm / radius) + 32.0 * U * (1.0 + 2.0 * fm)
    reach = _norm(oc) + radius
    return EdgeCone(mode, a0, a1, beta, s, kappa, ce, se, _tuple(a), _tuple(b1), _tuple(b2), _tuple(q), _tuple(oc),
                    _tuple(r.w), radius, eta, d, reach, 2.0 * (reach * (et + 16.0 * U) + ep))


@njit
def _tuple(v):
    """A 3-vector's components as a tuple."""
    return v[0], v[1], v[2]


@njit
def _edge_direction(cp, sp, k):
    """u = ce a - se (cos(phi) b1 + sin(phi) b2) of the `EdgeCone` k (cp, sp: cos and sin phi)."""
    a, b1, b2, ce, se = k.a, k.b1, k.b2, k.ce, k.se
    return (ce * a[0] - se * (cp * b1[0] + sp * b2[0]), ce * a[1] - se * (cp * b1[1] + sp * b2[1]),
            ce * a[2] - se * (cp * b1[2] + sp * b2[2]))


@njit
def _axpy(x, f, y):
    """x + f y of 3-tuples x, y and a scalar f."""
    return x[0] + f * y[0], x[1] + f * y[1], x[2] + f * y[2]


@njit
def _edge_cosines(sq, radius, eta):
    """(cos_i, cos_t) of an edge ray from S (`edge_ray`): S = R cos_i for eta >= 1, R eta cos_t below."""
    if eta >= 1.0:
        ci = sq / radius
        return ci, math.sqrt((eta - 1.0) * (eta + 1.0) + ci * ci) / eta
    return math.sqrt((1.0 - eta) * (1.0 + eta) + (sq / radius) ** 2), sq / (radius * eta)


@njit
def edge_ray(tau, k):
    """(P - c, t) of the edge ray at parameter tau of the `EdgeCone` k (module docstring): its
    refraction point relative to the centre and its refracted unit direction."""
    if k.mode == 1:
        cs = max(math.cos(tau), 0.0)
        phi = 2.0 * math.asin(k.s * math.sin(tau))
        b = -k.beta - 2.0 * k.kappa * cs * cs
        sq = 2.0 * k.s * math.sqrt(k.a1) * cs * math.sqrt(k.beta + k.kappa * cs * cs)
    else:
        phi = tau
        b = k.a0 - k.a1 * math.cos(phi)
        sq = math.sqrt(max((-b - k.beta) * (k.beta - b), 0.0))
    u = _edge_direction(math.cos(phi), math.sin(phi), k)
    ci, ct = _edge_cosines(sq, k.radius, k.eta)
    pc = _axpy(k.q, -b - k.radius * ci, u)
    f, eta = (ci / k.eta - ct) / k.radius, k.eta
    return pc, (u[0] / eta + f * pc[0], u[1] / eta + f * pc[1], u[2] / eta + f * pc[2])


@njit
def edge_gap(tau, k):
    """G(tau) = det(w, t, o - P) of the edge ray at tau (`edge_ray`): 0 where its line meets the segment's."""
    pc, t = edge_ray(tau, k)
    w = k.w
    m0, m1, m2 = k.oc[0] - pc[0], k.oc[1] - pc[1], k.oc[2] - pc[2]
    return w[0] * (t[1] * m2 - t[2] * m1) + w[1] * (t[2] * m0 - t[0] * m2) + w[2] * (t[0] * m1 - t[1] * m0)


@njit
def _det(w, x, y):
    """det(w, x, y) of 3-vectors."""
    return w[0] * (x[1] * y[2] - x[2] * y[1]) + w[1] * (x[2] * y[0] - x[0] * y[2]) + w[2] * (x[0] * y[1] - x[1] * y[0])


@njit
def edge_slope(tau, k):
    """(G', its rounding) at tau of the `EdgeCone` k (module docstring, "The band edges, proven"): G' =
    det(w, t', o - P) - det(w, t, P') through phi', S' and b' = q.u' in closed form, each intermediate's
    absolute rounding carried to first order alongside (u the unit roundoff; sqrt, asin and the quotients
    at their conditioning), doubled."""
    radius, eta, beta, u = k.radius, k.eta, k.beta, U
    if k.mode == 1:
        cs, sn = max(math.cos(tau), 0.0), math.sin(tau)
        den = (1.0 - k.s * sn) * (1.0 + k.s * sn)
        root = math.sqrt(den)
        phi = 2.0 * math.asin(k.s * sn)
        e_phi = 16.0 * u / root + 4.0 * u * abs(phi)
        d_phi = 2.0 * k.s * cs / root
        e_dphi = abs(d_phi) * (8.0 * u + 4.0 * u / den)
        y = beta + k.kappa * cs * cs
        b, db = -beta - 2.0 * k.kappa * cs * cs, 4.0 * k.kappa * cs * sn
        e_b, e_db = 8.0 * u * abs(b), 8.0 * u * abs(db)
        g = 2.0 * k.s * math.sqrt(k.a1)
        sq, dsq = g * cs * math.sqrt(y), -g * sn * (beta + 2.0 * k.kappa * cs * cs) / math.sqrt(y)
        e_sq, e_dsq = 16.0 * u * sq, 16.0 * u * abs(dsq)
    else:
        phi, d_phi, e_phi, e_dphi = tau, 1.0, 0.0, 0.0
        b, db = k.a0 - k.a1 * math.cos(phi), k.a1 * math.sin(phi)
        e_b, e_db = 4.0 * u * (abs(k.a0) + k.a1), 4.0 * u * k.a1
        sq = math.sqrt(max((-b - beta) * (beta - b), 0.0))
        dsq = b * db / sq
        e_sq = (abs(b) * e_b + 4.0 * u * b * b) / sq + 4.0 * u * sq
        e_dsq = (e_b * abs(db) + abs(b) * e_db) / sq + abs(dsq) * (e_sq / sq + 4.0 * u)
    cp, sp = math.cos(phi), math.sin(phi)
    uu = _edge_direction(cp, sp, k)
    g_u, b1, b2 = d_phi * k.se, k.b1, k.b2
    du = (g_u * (sp * b1[0] - cp * b2[0]), g_u * (sp * b1[1] - cp * b2[1]), g_u * (sp * b1[2] - cp * b2[2]))
    e_u = k.se * e_phi + 12.0 * u
    e_du = k.se * (abs(d_phi) * (e_phi + 8.0 * u) + e_dphi)
    if eta >= 1.0:
        ci, dci = sq / radius, dsq / radius
        e_ci, e_dci = e_sq / radius + u * ci, e_dsq / radius + u * abs(dci)
        ct = math.sqrt((eta - 1.0) * (eta + 1.0) + ci * ci) / eta
        dct = ci * dci / (eta * eta * ct)
        e_ct = ci * e_ci / (eta * eta * ct) + 4.0 * u * ct
        e_dct = (abs(dci) * e_ci + ci * e_dci) / (eta * eta * ct) + abs(dct) * (e_ct / ct + 4.0 * u)
    else:
        ci = math.sqrt((1.0 - eta) * (1.0 + eta) + (sq / radius) ** 2)
        ct, dct = sq / (radius * eta), dsq / (radius * eta)
        dci = sq * dsq / (radius * radius * ci)
        e_ci = sq * e_sq / (radius * radius * ci) + 4.0 * u * ci
        e_ct, e_dct = e_sq / (radius * eta) + 2.0 * u * ct, e_dsq / (radius * eta) + 2.0 * u * abs(dct)
        e_dci = (e_sq * abs(dsq) + sq * e_dsq) / (radius * radius * ci) + abs(dci) * (e_ci / ci + 4.0 * u)
    r, dr = -b - radius * ci, -db - radius * dci
    e_r = e_b + radius * e_ci + 2.0 * u * (abs(b) + radius * ci)
    e_dr = e_db + radius * e_dci + 2.0 * u * (abs(db) + radius * abs(dci))
    pc = _axpy(k.q, r, uu)
    dp = (dr * uu[0] + r * du[0], dr * uu[1] + r * du[1], dr * uu[2] + r * du[2])
    n_u, n_du, n_p, n_dp = _norm(uu), _norm(du), _norm(pc), _norm(dp)
    e_p = 2.0 * u * _norm(k.q) + e_r + abs(r) * e_u + 2.0 * u * abs(r)
    e_dp = e_dr + abs(dr) * e_u + e_r * n_du + abs(r) * e_du + 4.0 * u * (abs(dr) + abs(r) * n_du)
    f, df = ci / eta - ct, dci / eta - dct
    e_f = e_ci / eta + e_ct + 2.0 * u * (ci / eta + ct)
    e_df = e_dci / eta + e_dct + 2.0 * u * (abs(dci) / eta + abs(dct))
    fr, dfr = f / radius, df / radius
    t = (uu[0] / eta + fr * pc[0], uu[1] / eta + fr * pc[1], uu[2] / eta + fr * pc[2])
    dt = (du[0] / eta + dfr * pc[0] + fr * dp[0], du[1] / eta + dfr * pc[1] + fr * dp[1],
          du[2] / eta + dfr * pc[2] + fr * dp[2])
    e_t = e_u / eta + (e_f * n_p + abs(f) * e_p) / radius + 4.0 * u * (n_u / eta + abs(f) * n_p / radius)
    e_dt = e_du / eta + (e_df * n_p + abs(df) * e_p + e_f * n_dp + abs(f) * e_dp) / radius + \
        6.0 * u * (n_du / eta + (abs(df) * n_p + abs(f) * n_dp) / radius)
    m = (k.oc[0] - pc[0], k.oc[1] - pc[1], k.oc[2] - pc[2])
    n_m = _norm(m)
    e_m = e_p + u * (_norm(k.oc) + n_p)
    n_t, n_dt = _norm(t), _norm(dt)
    slope = _det(k.w, dt, m) - _det(k.w, t, dp)
    e_g = e_dt * n_m + n_dt * e_m + e_t * n_dp + n_t * e_dp + 16.0 * u * (n_dt * n_m + n_t * n_dp)
    return slope, 2.0 * e_g


@njit
def edge_bound(lo, hi, k):
    """K >= |G''| over [lo, hi] of the `EdgeCone` k (module docstring, "The band edges, proven"): the
    parameter's (phi', phi'', S', S'', the least S) then |P''|, |t''|, |P'|, |t'| through the partial
    derivatives in phi and S; inf where S may reach 0 in mode 2 or s = 1 at the end of mode 1."""
    radius, eta, a1, beta, kappa, s, se = k.radius, k.eta, k.a1, k.beta, k.kappa, k.s, k.se
    far = max(abs(lo), abs(hi))
    near = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
    if k.mode == 1:
        cmax, cmin = min(math.cos(near) + 4.0 * U, 1.0), max(math.cos(far) - 4.0 * U, 0.0)
        smax = min(math.sin(far) + 4.0 * U, 1.0)
        den = (1.0 - s * smax) * (1.0 + s * smax)
        if not den > 0.0:
            return math.inf
        p1 = 2.0 * s * min(1.0, cmax / math.sqrt(den))
        p2 = 2.0 * s * (1.0 - s) * (1.0 + s) * smax / den ** 1.5
        root = 2.0 * s * math.sqrt(a1)
        hmax = (beta + 2.0 * kappa * cmax * cmax) / math.sqrt(beta + kappa * cmax * cmax)
        s1 = root * smax * hmax
        s2 = root * cmax * (hmax + 3.0 * kappa * smax * smax / math.sqrt(beta))
        smin = root * cmin * math.sqrt(beta + kappa * cmin * cmin) * (1.0 - 1e-9)
    else:
        p1, p2 = 1.0, 0.0
        bmax = a1 - k.a0  # the largest |b|
        bb = a1 * math.cos(min(far, math.pi)) - k.a0  # the least |b| over the cell
        smin = math.sqrt(max((bb - beta) * (bb + beta), 0.0)) * (1.0 - 1e-9)
        if not smin > 0.0:
            return math.inf
        s1 = bmax * a1 / smin
        s2 = (a1 * a1 + bmax * a1 + s1 * s1) / smin
    fss = pss = 0.0
    if eta >= 1.0:
        ct = math.sqrt((eta - 1.0) * (eta + 1.0) + (smin / radius) ** 2) / eta * (1.0 - 1e-9)
        if eta > 1.0:
            fss = (eta - 1.0) * (eta + 1.0) / (radius * radius * eta ** 4 * ct ** 3)
    else:
        c_min = math.sqrt((1.0 - eta) * (1.0 + eta))
        fss, pss = 1.0 / (eta * radius * radius * c_min), 1.0 / (radius * c_min)
    rmax = math.sqrt((k.d - radius) * (k.d + radius))  # the distance from the light to a near refraction point
    fm, fs = max(1.0, 1.0 / eta), 1.0 / (radius * eta)
    pp = math.sqrt(a1 * a1 + rmax * rmax * se * se)  # |P_phi|
    ppp = a1 * (1.0 + 2.0 * se) + rmax * se  # |P_phiphi|
    tp, ts = se / eta + fm * pp / radius, fs + fm / radius
    tpp, tps = se / eta + fm * ppp / radius, (fs * pp + fm * se) / radius
    tss = fss + 2.0 * fs / radius + fm * pss / radius
    p_1 = p1 * pp + s1
    t_1 = p1 * tp + s1 * ts
    p_2 = p1 * p1 * ppp + 2.0 * p1 * s1 * se + s1 * s1 * pss + p2 * pp + s2
    t_2 = p1 * p1 * tpp + 2.0 * p1 * s1 * tps + s1 * s1 * tss + p2 * tp + s2 * ts
    return (t_2 * k.reach + 2.0 * t_1 * p_1 + p_2) * (1.0 + 1e-9)


@njit
def edge_crossings(k, out):
    """The roots of `edge_gap` over the `EdgeCone` k's parameter range into out, ascending; returns
    (count, proven) (module docstring, "The band edges, proven"): `_halving` over SCAN uniform cells,
    each halved until `edge_bound`'s K decides it as `paths` decides a cell of h (no root: G keeps its
    sign and its least |G| at the ends exceeds K w^2 / 8, or it is monotone, the secant's slope above K
    w or G' (`edge_slope`) of one sign at both ends with |G'(a)| + |G'(b)| above K w; one root: a sign
    change and monotone; each less its rounding), each root bisected to the resolution of doubles. Not
    proven where a cell reached MAX_HALVINGS halvings, the scan MAX_EVALS or out filled up (a segment
    within rounding of tangent to the band edge's surface), or G's rounding is not bounded."""
    if k.mode == 0:
        return 0, True
    lo = -0.5 * math.pi if k.mode == 1 else -math.pi
    # (mode 2's ends are one ray: a root there counted at its start)
    m, proven = _halving(k, lo, -2.0 * lo / SCAN, 0, lo, k.mode == 1, out, np.empty(out.shape[0]))
    return m, proven and k.dg < math.inf


@_at_of(EdgeCone)
@njit
def _edge_at(k, x):
    return (edge_gap(x, k),) + edge_slope(x, k)


@_value_of(EdgeCone)
@njit
def _edge_value(k, x):
    return edge_gap(x, k)


@_cell_of(EdgeCone)
@njit
def _edge_cell(k, a, b, j, e):
    """As `_paths_cell`, by `edge_bound`'s K and G's rounding dg, and monotone too where G' (`edge_slope`)
    keeps its sign at both ends and |G'(a)| + |G'(b)| less their rounding exceeds K w (G' then exceeds half
    the excess in size over the cell, as G'(a) - K (x - a) and G'(b) - K (b - x) bound it)."""
    kk, dg = edge_bound(a, b, k), k.dg
    fa, sa, dsa, fb, sb, dsb, w = e[0], e[1], e[2], e[3], e[4], e[5], b - a
    mono = abs(fb - fa) - 2.0 * dg > kk * w * w or sa * sb > 0.0 and abs(sa) + abs(sb) - dsa - dsb > kk * w
    if fa * fb > 0.0:
        return -1 if min(abs(fa), abs(fb)) - dg > 0.125 * kk * w * w or mono else 0
    return 1 if mono else 0


@_spread_of(EdgeCone)
@njit
def _edge_spread(k, root, a, b, fa, fb, j):
    return math.inf


@njit
def _plane(r, x):
    """(z_X, y_X, e_y) of the point o + x w: its coordinates along the axis and across it from the
    centre, and the unit direction across (any normal to the axis on the axis)."""
    q = np.empty(3)
    for k in range(3):
        q[k] = r.o[k] + x * r.w[k] - r.c[k]
    return about_axis(q, r.ez)


@njit
def about_axis(v, ez):
    """(z, y, e_y) of the vector v about the unit axis ez: its component along the axis, its length across it and
    the unit direction across (any normal to the axis on the axis)."""
    zx = v[0] * ez[0] + v[1] * ez[1] + v[2] * ez[2]
    ey = v - zx * ez
    yx = math.sqrt(ey[0] * ey[0] + ey[1] * ey[1] + ey[2] * ey[2])
    if yx > 0.0:
        ey /= yx
    else:  # on the axis: any normal to it
        k = 0 if abs(ez[0]) < 0.9 else 1
        ey[:] = -ez[k] * ez
        ey[k] += 1.0
        ey /= math.sqrt(ey[0] * ey[0] + ey[1] * ey[1] + ey[2] * ey[2])
    return zx, yx, ey


@njit
def _rounding_of_x(r, x, qn):
    """The rounding of the plane coordinates of o + x w (their distance qn from the centre): the
    point's and the axis's."""
    return 16.0 * U * (math.sqrt((r.o[0] - r.c[0]) ** 2 + (r.o[1] - r.c[1]) ** 2 + (r.o[2] - r.c[2]) ** 2) + x +
                       r.radius) + 8.0 * U * qn


@njit
def _contribution(r, x, zx, yx, ey, theta, dth, dx, fold):
    """(value, err, c) of the path refracted at theta to the point o + x w, (zx, yx) in its plane (ey the
    unit direction across the axis): ks Phi(mu) E F exp(-kt (x + s) - kt_out o) and its rounding bound
    (module docstring, "The bound") for theta off by dth and X's coordinates by dx, and the cosine to
    the spot's axis of the direction the light leaves in (nan for a directional light or where it is
    not reached); fold: the value times |1 - s kappa_t|, the tangential tube factor left out of both
    (`fold_value`); value and err 0 where the path does not reach the point."""
    c_spot = math.nan
    eta, radius, ez = r.eta, r.radius, r.ez
    pz, py, tz, ty, cos_i, cos_t, o = incidence(theta, radius, r.d, eta)
    if cos_t == 0.0:
        return 0.0, 0.0, c_spot
    s = tz * (zx - pz) + ty * (yx - py)
    if not s >= 0.0:
        return 0.0, 0.0, c_spot
    inv_o = 0.0 if r.distant else 1.0 / o
    kappa_t = tangential_curvature(cos_i, cos_t, inv_o, radius, eta)
    kappa_s = ((eta * cos_t - cos_i) / radius - inv_o) / eta
    e = (1.0 - fresnel(cos_i, eta)) * cos_i * inv_o * inv_o / cos_t if not r.distant else \
        (1.0 - fresnel(cos_i, eta)) * cos_i / cos_t
    tang, sag = 1.0 - s * kappa_t, 1.0 - s * kappa_s
    spread_ = abs(sag) if fold else abs(tang * sag)
    if not spread_ > 0.0:
        return 0.0, 0.0, c_spot
    mu = 0.0
    for j in range(3):
        t = tz * ez[j] + ty * ey[j]
        mu -= t * r.w[j]
    f = 1.0
    if not r.distant:
        c_spot = 0.0
        for j in range(3):
            c_spot += (r.c[j] + pz * ez[j] + py * ey[j] - r.light[j]) * r.axis[j]
        c_spot /= o
        f = falloff(c_spot, r.spot[0], r.spot[1], r.spot[2])
    if f == 0.0:
        return 0.0, 0.0, c_spot
    path = r.kt * (x + s) + (r.kt_out * o if not r.distant and r.kt_out > 0.0 else 0.0)
    value = r.ks * phase_value(r.code, r.g, mu) * f * e / spread_ * math.exp(-path)
    if value == 0.0:
        return 0.0, 0.0, c_spot
    # the path's relative rounding: theta off by dth, the rest first order in u (module docstring)
    step = 2.0 * r.theta_a / SCAN
    cell = r.cells[min(max(int((theta + r.theta_a) / step), 0), SCAN - 1)]
    p1, a1 = cell[0], cell[3]
    reach = math.sqrt(zx * zx + yx * yx) + radius
    dmu = 8.0 * U + 2.0 * dx / yx if yx > 0.0 else math.inf  # e_y's direction
    ds = (p1 * reach + radius) * dth + dx
    eps = r.kt * (ds + 4.0 * U * (x + s)) + 64.0 * U
    if not r.distant:
        eps += r.kt_out * (radius * dth + 4.0 * U * o) + 2.0 * radius * dth * inv_o
    eps += 3.0 * a1 * dth / cos_i + a1 * dth / (eta * eta * cos_t * cos_t)  # T cos_i, cos_t
    eps += phase_condition(r.code, r.g) * (p1 * dth + dmu)  # the phase
    dci, dct = a1, a1 / (eta * eta * cos_t)  # |cos_i'|, |cos_t'|
    dsd = p1 * reach + radius  # |ds / dtheta|
    if not fold:
        nt = (eta * cos_t - cos_i) / radius - cos_i * cos_i * inv_o
        dnt = (eta * dct + dci) / radius + 2.0 * cos_i * dci * inv_o + radius * inv_o * inv_o
        dkt = dnt / (eta * cos_t * cos_t) + 2.0 * abs(nt) * dct / (eta * cos_t ** 3)
        eps += ((dsd * abs(kappa_t) + s * dkt) * dth + 32.0 * U * (1.0 + s * (abs(kappa_t) + 1.0 / radius + inv_o)
                                                                    / (cos_t * cos_t))) / abs(tang)
    dks = ((eta * dct + dci) / radius + radius * inv_o * inv_o) / eta
    eps += ((dsd * abs(kappa_s) + s * dks) * dth + 16.0 * U * (1.0 + s * (abs(kappa_s) + 1.0 / radius + inv_o))) \
        / abs(sag)
    err = 2.0 * eps * value
    if not r.distant and f < 1.0:  # the falloff, absolute, at the cosine's error
        dc = 2.0 * radius * dth * inv_o + 32.0 * U * (1.0 + (reach + r.d) * inv_o)
        err += 2.0 * value / f * band_slope(r.spot[0], r.spot[1], r.spot[2]) / (r.spot[1] - r.spot[0]) * dc
    return value, err, c_spot


@njit
def _track_rounding(track, total, err, slot):
    """The largest relative rounding (err / total) into track[ROUNDING], the largest absolute into track[slot]."""
    if err > 0.0:
        rel = err / total if total > 0.0 else math.inf
        track[ROUNDING], track[slot] = max(track[ROUNDING], rel), max(track[slot], err)


@njit
def refracted_value(x, r):
    """The single-scattering integrand at o + x w for a unit light: the sum over the refracted paths
    that reach the point (`paths`) of ks Phi(mu) E F exp(-kt (x + s) - kt_out o) (module docstring),
    but those refracted in the record's window (a fold pair's angles, `fold_value`'s); its rounding
    bound (module docstring, "The bound") into the record's track (the largest relative and absolute
    over the evaluations), with the evaluations whose scan was unproven and whose count of paths
    outside the window (and of those on each side of a spot's band edges) differs from the piece's
    first."""
    zx, yx, ey = _plane(r, x)
    dx = _rounding_of_x(r, x, math.sqrt(zx * zx + yx * yx))
    found = np.empty(MAX_PATHS)
    spread = np.empty(MAX_PATHS)
    m, proven = paths(r, zx, yx, dx, found, spread)
    track = r.track
    if not proven:
        track[UNRESOLVED] += 1.0
    step = 2.0 * r.theta_a / SCAN
    total = err = 0.0
    n = 0
    for k in range(m):
        if r.window[0] <= found[k] <= r.window[1]:
            continue
        n += 1
        cell = r.cells[min(max(int((found[k] + r.theta_a) / step), 0), SCAN - 1)]
        value, e, c = _contribution(r, x, zx, yx, ey, found[k], spread[k] + cell[2], dx, False)  # t's rounding too
        # the path's side of the spot's band edges: a change inside a piece is a missed kink
        n += (MAX_PATHS + 1) * ((c > r.spot[0]) + (MAX_PATHS + 1) * (c >= r.spot[1]))
        total += value
        err += e
    if track[COUNT] < 0.0:
        track[COUNT] = n
    elif track[COUNT] != n:
        track[COUNT_CHANGED] += 1.0
    if r.eta <= 1.0:
        err = math.inf if m else 0.0  # Fresnel's slope is not bounded at the critical angle
    _track_rounding(track, total, err, ROUNDING_ABS)
    return total


@njit
def _segment(r):
    """(f, v, fz, wz): the segment's start relative to the centre and its direction, across the light's
    axis (3-vectors) and along it."""
    ez = r.ez
    f, v = np.empty(3), np.empty(3)
    fz = wz = 0.0
    for k in range(3):
        fz += (r.o[k] - r.c[k]) * ez[k]
        wz += r.w[k] * ez[k]
    for k in range(3):
        f[k] = r.o[k] - r.c[k] - fz * ez[k]
        v[k] = r.w[k] - wz * ez[k]
    return f, v, fz, wz


@njit
def _ray_crossings(r, pz, py, tz, ty, a, b, xs):
    """The x in [a, b] where the line of the ray from P = (pz, py) along t = (tz, ty), turned about the
    axis, meets the segment's line, into xs (returns their count, at most 2): the roots of
    h(theta; X(x)) = 0 (the ray's line tz y - ty z = c0, squared: a quadratic in x), less the squared
    equation's other branch (the ray's mirror image across the axis)."""
    f, v, fz, wz = _segment(r)
    ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
    fv = f[0] * v[0] + f[1] * v[1] + f[2] * v[2]
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    c0 = tz * py - ty * pz
    e0 = c0 + ty * fz
    found = np.empty(2)
    n = quadratic_roots(tz * tz * vv - ty * ty * wz * wz, tz * tz * fv - ty * wz * e0, tz * tz * ff - e0 * e0, found,
                        0)
    m = 0
    for k in range(n):
        x = found[k]
        if not a <= x <= b:
            continue
        zx = fz + x * wz
        yx = math.sqrt(max(ff + x * (2.0 * fv + x * vv), 0.0))
        if yx > 0.0 and abs(tz * yx - ty * zx - c0) <= abs(tz * yx + ty * zx + c0):
            xs[m] = x
            m += 1
    return m


@njit
def _edge_meets(k, pc, t):
    """(x, s): where the edge ray P + s t (P = c + pc) meets the segment's line o + x w (their lines
    coplanar), x = ((P - o) x t).(w x t) / |w x t|^2 and s = ((P - o) x w).(w x t) / |w x t|^2 (nan
    where they are parallel)."""
    w = k.w
    m = (pc[0] - k.oc[0], pc[1] - k.oc[1], pc[2] - k.oc[2])
    c = (w[1] * t[2] - w[2] * t[1], w[2] * t[0] - w[0] * t[2], w[0] * t[1] - w[1] * t[0])
    cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2]
    if not cc > 0.0:
        return math.nan, math.nan
    mt = (m[1] * t[2] - m[2] * t[1], m[2] * t[0] - m[0] * t[2], m[0] * t[1] - m[1] * t[0])
    mw = (m[1] * w[2] - m[2] * w[1], m[2] * w[0] - m[0] * w[2], m[0] * w[1] - m[1] * w[0])
    return (mt[0] * c[0] + mt[1] * c[1] + mt[2] * c[2]) / cc, (mw[0] * c[0] + mw[1] * c[1] + mw[2] * c[2]) / cc


@njit
def spot_edges(r, end):
    """Into r.edges: the x in (0, end) where a path to the point o + x w crosses one of the spot's band
    edges (its falloff's kinks along the segment; edges[0] their count, edges[1:EDGES + 1]
    ascending) and the angles at which the fold pair's integrand crosses them. Where the spot aims
    along the axis (at the centre) its cosine toward a path's direction out of the light depends on
    theta alone, (d - R cos theta) / o, falling from 1 at theta = 0: the angles theta_e in
    (0, theta_a) where it reaches cos_end and cos_start (bisected to the resolution of doubles;
    edges[EDGES + 1:EDGES + 3], nan for none) and the x where the rays refracted at +-theta_e reach
    the segment ahead of P. Another spot's edge rays are found by `edge_crossings` (proven, else counted
    unresolved in the track: the bound inf), the x where they meet the segment ahead of P kept, the
    angles of their refraction points in the plane of that point in edges[EDGES + 3:] (nan for none).
    A crossing beyond the room of EDGES is counted unresolved too. None for other lights."""
    edges = r.edges
    edges[0] = 0.0
    edges[EDGES + 1:] = math.nan
    if r.distant:
        return
    ez, axis = r.ez, r.axis
    cross = (ez[1] * axis[2] - ez[2] * axis[1]) ** 2 + (ez[2] * axis[0] - ez[0] * axis[2]) ** 2 + \
        (ez[0] * axis[1] - ez[1] * axis[0]) ** 2
    az = ez[0] * axis[0] + ez[1] * axis[1] + ez[2] * axis[2]
    xs = np.empty(EDGES)
    m = 0
    f, v, fz, wz = _segment(r)
    if not cross <= 1e-18 or not az < 0.0:  # not aimed at the centre
        found = np.empty(2 * EDGES)
        for e in range(2):
            ce = r.spot[0] if e == 0 else r.spot[1]
            if e == 1 and r.spot[1] == r.spot[0] or not -1.0 < ce < 1.0:  # no edge (a point light: none)
                continue
            k = edge_cone(r, ce)
            n, proven = edge_crossings(k, found)
            if not proven:
                r.track[UNRESOLVED] += 1.0
            for j in range(n):
                pc, t = edge_ray(found[j], k)
                x, ahead = _edge_meets(k, pc, t)
                if not (0.0 < x < end and ahead >= 0.0):
                    continue
                if m == EDGES:
                    r.track[UNRESOLVED] += 1.0
                    continue
                _, _, ey = _plane(r, x)
                edges[EDGES + 3 + m] = math.atan2(pc[0] * ey[0] + pc[1] * ey[1] + pc[2] * ey[2],
                                                  pc[0] * ez[0] + pc[1] * ez[1] + pc[2] * ez[2])
                m += 1
                edges[m] = x
        sort_few(edges, 1, m + 1)
        edges[0] = m
        return
    for e in range(2):
        ce = r.spot[0] if e == 0 else r.spot[1]
        lo, hi = 0.0, r.theta_a
        if e == 1 and r.spot[1] == r.spot[0]:
            continue
        c_hi = (r.d - r.radius * math.cos(hi)) / _arriving(hi, r.radius, r.d)[6]
        if not c_hi < ce < 1.0:
            continue
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if not lo < mid < hi:
                break
            if (r.d - r.radius * math.cos(mid)) / _arriving(mid, r.radius, r.d)[6] > ce:
                lo = mid
            else:
                hi = mid
        edges[EDGES + 1 + e] = lo
        for theta in (lo, -lo):
            pz, py, tz, ty, _, cos_t, _ = incidence(theta, r.radius, r.d, r.eta)
            if cos_t == 0.0:
                continue
            for k in range(_ray_crossings(r, pz, py, tz, ty, 0.0, end, xs)):
                x = xs[k]
                zx = fz + x * wz
                yx = math.sqrt(max((f[0] + x * v[0]) ** 2 + (f[1] + x * v[1]) ** 2 + (f[2] + x * v[2]) ** 2, 0.0))
                if 0.0 < x < end and tz * (zx - pz) + ty * (yx - py) >= 0.0 and m < EDGES:
                    m += 1
                    edges[m] = x
    sort_few(edges, 1, m + 1)
    edges[0] = m


@njit
def fold_value(theta, r, a, b):
    """The fold pair's integrand in theta (module docstring, "The caustic"): over the points o + x w,
    x in [a, b], that the ray refracted at theta reaches (the roots of h(theta; X(x)) = 0 in x: a
    quadratic once squared), the path's value times |dx/dtheta| = |h_theta| / |h_x| = R cos_t
    |1 - s kappa_t| / |h_x|, the tangential tube factor cancelled; its rounding into the track (relative
    into ROUNDING, absolute per unit theta into FOLD_ABS): theta exact, t's rounding as an angle, x off
    by 2 (|h| + its rounding) / |h_x| at the computed root, and h_x's own rounding."""
    radius, eta = r.radius, r.eta
    pz, py, tz, ty, cos_i, cos_t, o = incidence(theta, radius, r.d, eta)
    if cos_t == 0.0:
        return 0.0
    xs = np.empty(2)
    n = _ray_crossings(r, pz, py, tz, ty, a, b, xs)
    f, v, fz, wz = _segment(r)
    ff = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
    fv = f[0] * v[0] + f[1] * v[1] + f[2] * v[2]
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    c0 = tz * py - ty * pz
    step = 2.0 * r.theta_a / SCAN
    et = r.cells[min(max(int((theta + r.theta_a) / step), 0), SCAN - 1), 2]  # t's rounding as an angle
    total = err = 0.0
    for k in range(n):
        x = xs[k]
        zx = fz + x * wz
        yx = math.sqrt(max(ff + x * (2.0 * fv + x * vv), 0.0))
        dyx = (fv + x * vv) / yx
        hx = tz * dyx - ty * wz
        zp, yp, ey = _plane(r, x)
        qn = math.sqrt(zp * zp + yp * yp)
        dx = _rounding_of_x(r, x, qn)
        big = yx + abs(zx) + 2.0 * radius
        dg = et * big + 2.0 * dx + 16.0 * U * big  # h's rounding at the computed root
        dxr = 2.0 * (abs(tz * yx - ty * zx - c0) + dg) / abs(hx)  # the root's error in x
        value, e, _ = _contribution(r, x, zp, yp, ey, theta, et, dx + dxr, True)
        if value == 0.0:
            continue
        dhx = et * (abs(dyx) + abs(wz)) + abs(tz) * vv / yx * dxr + \
            abs(tz) * (8.0 * U * (abs(fv) + x * vv) + abs(dyx) * (8.0 * U * yx + dx)) / yx + 8.0 * U * abs(wz)
        jac = radius * cos_t / abs(hx)
        total += value * jac
        err += (e + 2.0 * value * (r.kt * dxr + (dhx + 8.0 * U * abs(hx)) / abs(hx) + 8.0 * U)) * jac
    _track_rounding(r.track, total, err, FOLD_ABS)
    return total


@integrand_of(SphereRefracted)
@njit
def _refracted_value(x, r):
    return refracted_value(x, r)


class NearCaustic(NamedTuple):
    """`SphereRefracted`'s integrand on the piece from a caustic crossing xb to xb + span, in u in
    [0, 1] with x = xb + span u^2: 2 |span| u f(x), smooth where f has its 1/sqrt(|x - xb|) singularity."""
    r: SphereRefracted
    xb: float
    span: float


@integrand_of(NearCaustic)
@njit
def _near_caustic(u, q):
    return 2.0 * abs(q.span) * u * refracted_value(q.xb + q.span * u * u, q.r)


class FoldPair(NamedTuple):
    """The paths of a caustic's fold pair (refracted at theta in [theta_1, theta_2]) to the piece [a, b]
    of r's segment, integrated in theta (`fold_value`)."""
    r: SphereRefracted
    a: float
    b: float


@integrand_of(FoldPair)
@njit
def _fold_pair(theta, q):
    return fold_value(theta, q.r, q.a, q.b)


@njit
def breaks(r, end, out, caustic, spans):
    """The x in (0, end) where the segment passes closest to the axis and where it crosses the
    tangential caustic surface (module docstring; caustic[k] = 1.0 for those), into out, ascending;
    returns their count. caustic[k]: 0 for the closest approach, 1 for the cone's crossings (their
    errors into spans[k], module docstring, "The bound"), 2 for the caustic's (the angle of the caustic
    point's ray into spans[k])."""
    f, v, fz, wz = _segment(r)
    m = 0
    pz, py, tz, ty, _, _, _ = _clamped(r.theta_a, r.radius, r.d, r.eta)
    if ty != 0.0:  # the cone of the marginal rays, about the axis with its apex where they meet it
        qz = fz - (pz - py * tz / ty)
        qw = f[0] * r.w[0] + f[1] * r.w[1] + f[2] * r.w[2] + qz * wz  # q = o - apex: f + qz ez
        qq = f[0] * f[0] + f[1] * f[1] + f[2] * f[2] + qz * qz
        cone = np.empty(2)
        qn = math.sqrt(qq)
        d_apex = 64.0 * U * (r.radius + abs(pz) + abs(py * tz / ty)) * (1.0 + 1.0 / abs(ty)) + 8.0 * U * abs(fz)
        for k in range(quadratic_roots(wz * wz - tz * tz, qz * wz - tz * tz * qw, qz * qz - tz * tz * qq, cone, 0)):
            if 0.0 < cone[k] < end:
                xb = cone[k]  # F(x) = (qz + x wz)^2 - tz^2 |q + x w|^2: its rounding and the apex's over |F'|
                big = qn + xb + d_apex
                num = 64.0 * U * big * big + 8.0 * big * (d_apex + 32.0 * U * (r.radius + qn))
                slope = 2.0 * abs((wz * wz - tz * tz) * xb + qz * wz - tz * tz * qw)
                curv = 2.0 * abs(wz * wz - tz * tz)
                spans[m] = 2.0 * num / slope if slope * slope > 4.0 * num * curv else 2.0 * math.sqrt(num / max(curv,
                                                                                                          1e-300))
                out[m] = xb
                caustic[m] = 1.0
                m += 1
    vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    if vv > 0.0:
        x = -(f[0] * v[0] + f[1] * v[1] + f[2] * v[2]) / vv
        if 0.0 < x < end:
            out[m] = x
            caustic[m] = 0.0
            m += 1
    found = np.empty(MAX_PATHS)
    n, proven = caustic_crossings(r, f, v, fz, wz, found)
    if not proven:
        r.track[UNRESOLVED] += 1.0
    for k in range(n):
        _, cz, cy, _, _ = _caustic(found[k], r.radius, r.d, r.eta)
        x = (cz - fz) / wz
        if cz * cz + cy * cy <= r.radius * r.radius and 0.0 < x < end and m < out.shape[0]:
            out[m] = x
            caustic[m] = 2.0
            spans[m] = found[k]
            m += 1
    for p in range(1, m):  # insertion sort of the few breaks, their flags and spans alongside
        x, flag, span, k = out[p], caustic[p], spans[p], p
        while k > 0 and out[k - 1] > x:
            out[k], caustic[k], spans[k] = out[k - 1], caustic[k - 1], spans[k - 1]
            k -= 1
        out[k], caustic[k], spans[k] = x, flag, span
    return m


@njit
def frame(sphere, light, distant, eta):
    """(ez, d, theta_a, cells) of one light and the refractive exact sphere (centre, radius): the light's
    axis, its distance from the centre (inf for a directional light, light its direction toward it),
    the lit arc's half-width and its `cell_table`."""
    radius = sphere[3]
    if distant:
        d = math.inf
        ez = light / math.sqrt(light[0] * light[0] + light[1] * light[1] + light[2] * light[2])
    else:
        rel = light - sphere[:3]
        d = math.sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2])
        ez = rel / d
    theta_a = lit_arc(radius, d, eta)
    return ez, d, theta_a, cell_table(theta_a, radius, d, eta)


@njit
def record(sphere, geo_row, distant, eta, kt, ks, code, g, kt_out, light_frame):
    """The `SphereRefracted` record of one segment (geo_row: media/slab.py's GEO_COLUMNS; light_frame: `frame`)."""
    ez, d, theta_a, cells = light_frame
    return SphereRefracted(geo_row[:3].copy(), geo_row[3:6].copy(), sphere[:3].copy(), sphere[3],
                           geo_row[6:9].copy(), distant, ez, d, theta_a, eta, kt, ks, code, g, kt_out,
                           geo_row[9:12].copy(), (geo_row[12], geo_row[13], int(geo_row[17])), cells, np.zeros(TRACK),
                           np.array([math.inf, -math.inf]), np.zeros(2 * EDGES + 3))


@njit
def _piece(rec, lo, hi, length, rtol, stats, track):
    """`bounded_piecewise` over [lo, hi] of rec, a new piece for the path count's guard; the largest
    absolute rounding of its evaluations times its length in x into track[PIECES_ABS] (summed: the
    rule's positive weights sum to the length, 2 |span| u integrating to the piece's length in x for
    `NearCaustic`)."""
    track[COUNT] = -1.0
    track[ROUNDING_ABS] = 0.0
    val, b = bounded_piecewise(rec, (lo, hi), 2, rtol, N10, W10, N20, W20, stats)
    track[PIECES_ABS] += track[ROUNDING_ABS] * length
    return val, b


@njit
def _stretch(r, lo, hi, flag_lo, flag_hi, rtol, stats, track):
    """(value, rule's bound) of `_beside` over [lo, hi] of r, split where a path crosses a spot's band
    edge (r.edges)."""
    total = rule = 0.0
    a, fa = lo, flag_lo
    for k in range(1, int(r.edges[0]) + 1):
        x = r.edges[k]
        if a < x < hi:
            val, b = _beside(r, a, x, fa, 0.0, rtol, stats, track)
            total, rule, a, fa = total + val, rule + b, x, 0.0
    val, b = _beside(r, a, hi, fa, flag_hi, rtol, stats, track)
    return total + val, rule + b


@njit
def _beside(r, lo, hi, flag_lo, flag_hi, rtol, stats, track):
    """(value, rule's bound) of `_piece` over [lo, hi] of r, in u beside an end that is a cone's or the
    caustic's crossing (flag > 0: `NearCaustic`), split at the middle where both ends are."""
    if flag_lo == 0.0 and flag_hi == 0.0:
        return _piece(r, lo, hi, hi - lo, rtol, stats, track)
    total = rule = 0.0
    mid = lo if flag_lo == 0.0 else hi if flag_hi == 0.0 else 0.5 * (lo + hi)
    if mid > lo:
        val, b = _near(NearCaustic(r, lo, mid - lo), rtol, stats, track)
        total, rule = total + val, rule + b
    if hi > mid:
        val, b = _near(NearCaustic(r, hi, mid - hi), rtol, stats, track)
        total, rule = total + val, rule + b
    return total, rule


@njit
def _near(q, rtol, stats, track):
    """(value, rule's bound) of `_piece` over the `NearCaustic` piece q, u in [0, 1]: where its rounding
    (its evaluations' largest absolute x its length) exceeds the rule's bound, that is undone and the
    piece split at u = SPLIT (x at SPLIT^2 of its span from the crossing, where the rounding of a path
    near the lit arc's end or the caustic peaks), [SPLIT, 1] integrated with its own rounding and [0,
    SPLIT] taken again the same way, at most SPLITS times."""
    total = rule = 0.0
    hi = 1.0
    span = abs(q.span)
    for _ in range(SPLITS):
        before = track[PIECES_ABS]
        val, b = _piece(q, 0.0, hi, span * hi * hi, rtol, stats, track)
        if track[PIECES_ABS] - before <= b:
            return total + val, rule + b
        track[PIECES_ABS] = before
        lo = SPLIT * hi
        val, b = _piece(q, lo, hi, span * (hi - lo) * (hi + lo), rtol, stats, track)
        total, rule, hi = total + val, rule + b, lo
    val, b = _piece(q, 0.0, hi, span * hi * hi, rtol, stats, track)
    return total + val, rule + b


@njit
def _fold(r, lo, hi, flag_lo, flag_hi, theta_c, cone, cone_side, rtol, stats, track):
    """(value, rule's bound, absolute rounding, ends' bound, ok) of [lo, hi] of r across one caustic
    crossing, its caustic point's ray refracted at theta_c (module docstring, "The caustic"): the fold
    pair's window [theta_1, theta_2], the adjacent paths that bracket theta_c at the end with two paths
    more than the other (both scans proven), or at an end with one more that is a cone's crossing or
    whose side of the caustic holds one (cone in (lo, hi), cone_side 0 for lo's, 1 for hi's, -1: none)
    the outermost path and the lit arc's end beyond theta_c (the pair's other path leaves there); the
    paths refracted outside it by `_stretch` in x (split at cone), those inside by `fold_value` in
    theta, and each window end off by its root's spread at 8 x the fold integrand there. ok False
    (nothing integrated) where there is no such pair or a spread is inf."""
    found, spread = np.empty((2, MAX_PATHS)), np.empty((2, MAX_PATHS))
    counts = np.zeros(2, dtype=np.int64)
    for side in range(2):
        x = lo if side == 0 else hi
        zx, yx, _ = _plane(r, x)
        counts[side], proven = paths(r, zx, yx, _rounding_of_x(r, x, math.sqrt(zx * zx + yx * yx)), found[side],
                                     spread[side])
        if not proven:
            return 0.0, 0.0, 0.0, 0.0, False
    side = 0 if counts[0] > counts[1] else 1
    more, flag = counts[side] - counts[1 - side], flag_lo if side == 0 else flag_hi
    t1 = t2 = e1 = e2 = math.inf
    n = counts[side]
    for k in range(n - 1):
        if more == 2 and found[side, k] < theta_c < found[side, k + 1]:
            t1, t2, e1, e2 = found[side, k], found[side, k + 1], spread[side, k], spread[side, k + 1]
    if more == 1 and (flag == 1.0 or cone_side == side) and n > 0:  # the pair's other path leaves through the
        # lit arc's end there, or at the cone's crossing between that end and the caustic
        if found[side, n - 1] < theta_c:
            t1, t2, e1, e2 = found[side, n - 1], r.theta_a, spread[side, n - 1], 0.0
        elif theta_c < found[side, 0]:
            t1, t2, e1, e2 = -r.theta_a, found[side, 0], 0.0, spread[side, 0]
    if not e1 + e2 < math.inf:
        return 0.0, 0.0, 0.0, 0.0, False
    r.window[0], r.window[1] = t1, t2
    if cone_side < 0:
        total, rule = _stretch(r, lo, hi, flag_lo, flag_hi, rtol, stats, track)
    else:
        total, rule = _stretch(r, lo, cone, flag_lo, 1.0, rtol, stats, track)
        val, b = _stretch(r, cone, hi, 1.0, flag_hi, rtol, stats, track)
        total, rule = total + val, rule + b
    r.window[0], r.window[1] = math.inf, -math.inf
    track[FOLD_ABS] = 0.0
    cuts = np.empty(EDGES + 6)  # W, cut where its rays cross a spot's band edge
    cuts[0], n = t1, 1
    for e in range(EDGES + 1, EDGES + 3):
        for theta in (r.edges[e], -r.edges[e]):
            if t1 < theta < t2:
                cuts[n] = theta
                n += 1
    for e in range(EDGES + 3, 2 * EDGES + 3):
        if t1 < r.edges[e] < t2:
            cuts[n] = r.edges[e]
            n += 1
    cuts[n] = t2
    sort_few(cuts, 0, n + 1)
    val, b = bounded_piecewise(FoldPair(r, lo, hi), cuts, n + 1, rtol, N10, W10, N20, W20, stats)
    rounding = track[FOLD_ABS] * (t2 - t1)
    width = hi - lo  # the ends: the fold integrand of the branch near them, wherever on the line it meets
    ends = 8.0 * (e1 * fold_value(t1, r, lo - width, hi + width) + e2 * fold_value(t2, r, lo - width, hi + width))
    return total + val, rule + b, rounding, ends, True


@njit
def _one(r, ell, rule, key, dim0, seed, stats):
    """(value, variance, bound) of one segment: QUAD adaptive between `breaks` with its bound (module
    docstring, "The bound"; the pieces across one caustic crossing by `_fold`, across a cone's crossing
    beside it too; inf where that fails, a scan was unproven or a piece's path count changed: counted in
    stats[UNBOUNDED]), MARCH or SAMPLE
    media/inside_rule.py's (bound inf), by the inside `rule`."""
    if rule.kind == QUAD:
        rtol = rule.rtol
        end = min(ell, 745.0 / r.kt)
        spot_edges(r, end)
        br, caustic, spans = np.zeros(MAX_PATHS + 3), np.zeros(MAX_PATHS + 3), np.zeros(MAX_PATHS + 3)
        m = breaks(r, end, br[1:MAX_PATHS + 2], caustic[1:MAX_PATHS + 2], spans[1:MAX_PATHS + 2])
        br[m + 1] = end
        total = rule = folds = 0.0
        track = r.track
        i = 0
        while i <= m:
            lo, hi = br[i], br[i + 1]
            # a caustic crossing at i + 1 or i + 2 with a cone's crossing beside it (at i + 1 or i + 2):
            # the fold's pieces extend across that cone's crossing to the middle of the piece beyond it
            k = i + 2 if caustic[i + 1] == 1.0 else i + 1
            if i + 3 <= m + 1 and caustic[k] == 2.0 and caustic[2 * i + 3 - k] == 1.0 and caustic[i] != 2.0 and \
                    caustic[i + 3] != 2.0:
                a, b = (0.5 * (lo + hi), br[i + 3]) if k == i + 2 else (lo, 0.5 * (br[i + 2] + br[i + 3]))
                val, bnd, rounding, ends, ok = _fold(r, a, b, 0.0 if k == i + 2 else caustic[i],
                                                     0.0 if k == i + 1 else caustic[i + 3], spans[k],
                                                     br[2 * i + 3 - k], 0 if k == i + 2 else 1, rtol, stats, track)
                if ok:
                    total, rule, folds = total + val, rule + bnd + ends, folds + rounding
                    for c, d, fc, fd in ((lo, a, caustic[i], 0.0), (b, br[i + 3], 0.0, caustic[i + 3])):
                        if d > c:
                            val, bnd = _stretch(r, c, d, fc, fd, rtol, stats, track)
                            total, rule = total + val, rule + bnd
                    caustic[k] = 3.0  # crossed by `_fold`: bounded
                    i += 3
                    continue
            if caustic[i + 1] == 2.0 and caustic[i] != 2.0 and caustic[i + 2] != 2.0 and br[i + 2] > lo:
                val, b, rounding, ends, ok = _fold(r, lo, br[i + 2], caustic[i], caustic[i + 2], spans[i + 1], 0.0,
                                                   -1, rtol, stats, track)
                if ok:
                    total, rule, folds = total + val, rule + b + ends, folds + rounding
                    caustic[i + 1] = 3.0  # crossed by `_fold`: bounded
                    i += 2
                    continue
            if hi > lo:
                val, b = _stretch(r, lo, hi, caustic[i], caustic[i + 1], rtol, stats, track)
                total, rule = total + val, rule + b
            i += 1
        bound = rule + 3.0 * min(track[ROUNDING] * (abs(total) + rule), track[PIECES_ABS] + folds)
        for i in range(1, m + 1):
            if caustic[i] == 2.0:
                bound = math.inf
            elif caustic[i] == 1.0:  # the cone's crossing off by spans[i]: that span at twice the integrand's size
                near = 0.0
                for x in (br[i] - 2.0 * spans[i], br[i], br[i] + 2.0 * spans[i]):
                    if 0.0 <= x <= end:
                        track[COUNT] = -1.0  # not a piece's: no guard
                        near = max(near, refracted_value(x, r))
                bound += 8.0 * spans[i] * near
        if track[UNRESOLVED] > 0.0 or track[COUNT_CHANGED] > 0.0 or not bound < math.inf:
            bound = math.inf
            stats[UNBOUNDED] += 1.0
        return total, 0.0, bound
    value, var = march_or_sample(r, rule, cut_length(rule, ell, r.kt), r.kt, key, dim0, seed)
    return value, var, math.inf


@njit
def sphere_refracted(sphere, geo, distant, ell, kt, ks, code, g, kt_out, eta, rule, keys, dim0, seed, out, var, err,
                     stats):
    """out, var, err (N,) := (value, variance, bound) of the inside segments (geo: media/slab.py's GEO_COLUMNS rows;
    a directional light's direction toward it in geo[6:9]) of the refractive exact sphere (centre,
    radius) for one unit light and channel, by the inside `rule` (QUAD, MARCH or SAMPLE); stats: media/adaptive.py's
    slots (stats[UNBOUNDED]: the QUAD segments whose bound is inf). One light's `frame` serves the rows
    that share its geo[6:9]."""
    out[:], var[:], err[:] = 0.0, 0.0, 0.0
    if ks == 0.0:  # else kt >= ks > 0
        return
    light_frame = frame(sphere, geo[0, 6:9].copy(), distant, eta)
    last = geo[0, 6:9].copy()
    for s in range(ell.shape[0]):
        if not ell[s] > 0.0:
            continue
        if geo[s, 6] != last[0] or geo[s, 7] != last[1] or geo[s, 8] != last[2]:
            last = geo[s, 6:9].copy()
            light_frame = frame(sphere, last, distant, eta)
        r = record(sphere, geo[s], distant, eta, kt, ks, code, g, kt_out, light_frame)
        out[s], var[s], err[s] = _one(r, ell[s], rule, keys[s], dim0, seed, stats)


class Outward(NamedTuple):
    """`paths`' light and sphere for `surface_out_of_sphere`: the receiving point outside at distance d
    from the centre, taken as the light (the paths are reversible)."""
    radius: float
    d: float
    eta: float
    theta_a: float
    cells: np.ndarray


@njit
def surface_out_of_sphere(q, sphere, light, axis, cone, eta, value, toward, inside, outside):
    """A unit point or spot light inside the refractive exact sphere (centre, radius; relative index eta
    inside) at the points q (M, 3) outside it, through each of its refracted paths out (up to MAX_PATHS,
    the columns): `paths_out` at each point."""
    c = sphere[:3]
    rel = light - c
    value[:] = 0.0
    found, spread = np.empty(MAX_PATHS), np.empty(MAX_PATHS)
    for i in range(q.shape[0]):
        paths_out(q[i], c, sphere[3], rel, axis, cone, eta, found, spread, value[i], toward[i], inside[i], outside[i])


@njit
def paths_out(q, c, radius, rel, axis, cone, eta, found, spread, value, toward, inside, outside):
    """A unit point or spot light at c + rel inside the refractive exact sphere (centre c, radius; relative index
    eta inside) at the point q outside it, through each of its refracted paths out (up to MAX_PATHS, the entries
    of value (MAX_PATHS,), toward (MAX_PATHS, 3), inside, outside; value 0: no path; found, spread: `paths`'
    scratch): Fermat's paths from q to the light are those of a light at q reaching the inside point L (light
    paths are reversible): `paths` in the plane of q, the centre and L, proven as there. Per path (`incidence`
    from q: the cosines at the boundary, q's leg o, the direction t inside, L's leg s): value the irradiance
    across the ray at q, F T cos_i / (eta^2 o^2 cos_t |(1 - s kappa_t)(1 - s kappa_s)|) with the spot's falloff
    F toward the direction -t the light leaves in (module docstring's tube at L from a unit light at q, over
    eta^2: the etendue n^2 dA dOmega is conserved, so the solid angle per area at q from L is the one at L from
    q over eta^2; light beyond the critical angle is totally reflected and meets no path, which enters from q
    at cos_i > 0); toward the unit direction from q to the refraction point; inside s, outside o (of every path
    out, where a spot does not reach too; outside 0: no path). A point q within the sphere has none. Returns whether the scan was proven (True where q is within the sphere)."""
    value[:] = 0.0
    outside[:] = 0.0
    ez = q - c
    d = math.sqrt(ez[0] * ez[0] + ez[1] * ez[1] + ez[2] * ez[2])
    if not d > radius:
        return True
    ez /= d
    zx, yx, ey = about_axis(rel, ez)
    theta_a = lit_arc(radius, d, eta)
    scan = Outward(radius, d, eta, theta_a, cell_table(theta_a, radius, d, eta))
    dx = 16.0 * U * (d + 2.0 * radius + math.sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]))
    m, proven = paths(scan, zx, yx, dx, found, spread)
    for k in range(m):
        pz, py, tz, ty, cos_i, cos_t, o, s, tube = path_to(found[k], zx, yx, radius, d, eta)
        if math.isnan(tube):
            continue
        inside[k], outside[k] = s, o
        f = falloff(-((tz * ez[0] + ty * ey[0]) * axis[0] + (tz * ez[1] + ty * ey[1]) * axis[1]
                      + (tz * ez[2] + ty * ey[2]) * axis[2]), cone[0], cone[1], int(cone[2]))
        if f == 0.0 or not tube > 0.0:
            continue
        value[k] = f * (1.0 - fresnel(cos_i, eta)) * cos_i / (eta * eta * o * o * cos_t * tube)
        for j in range(3):
            toward[k, j] = ((pz - d) * ez[j] + py * ey[j]) / o
    return proven


class OutEdge(NamedTuple):
    """A spot's band edge at cosine ce (sine se) to its unit axis a, the spot inside the sphere at q = L - c (d = |q|
    < radius / eta), and one segment outside (start oc relative to the centre, direction w): b1, b2 across a (b1
    toward q), k2 the bound on |G''| and dg G's rounding (`out_edge`; 3-tuples: no arrays in the scan)."""
    ce: float
    se: float
    a: tuple
    b1: tuple
    b2: tuple
    q: tuple
    oc: tuple
    w: tuple
    radius: float
    eta: float
    d: float
    k2: float
    dg: float


@njit
def _out_edge_ray(phi, k):
    """(P - c, t) of the edge ray u(phi) = ce a - se (cos phi b1 + sin phi b2) of the `OutEdge` k: where it leaves
    the sphere, P = L + r u, r = S - b (b = q.u, S = sqrt(b^2 + R^2 - d^2) = R cos_1), and its direction
    out, t = eta u + (cos_2 - eta cos_1) n (n = (P - c) / R, cos_2 = sqrt(1 - eta^2 (1 - cos_1^2)))."""
    cp, sp = math.cos(phi), math.sin(phi)
    a, b1, b2, q, radius, eta = k.a, k.b1, k.b2, k.q, k.radius, k.eta
    u = (k.ce * a[0] - k.se * (cp * b1[0] + sp * b2[0]), k.ce * a[1] - k.se * (cp * b1[1] + sp * b2[1]),
         k.ce * a[2] - k.se * (cp * b1[2] + sp * b2[2]))
    b = q[0] * u[0] + q[1] * u[1] + q[2] * u[2]
    sq = math.sqrt(max(b * b + (radius - k.d) * (radius + k.d), 0.0))
    pc = _axpy(q, sq - b, u)
    c1 = sq / radius
    f = (math.sqrt(max(1.0 - eta * eta * (1.0 - c1) * (1.0 + c1), 0.0)) - eta * c1) / radius
    return pc, (eta * u[0] + f * pc[0], eta * u[1] + f * pc[1], eta * u[2] + f * pc[2])


@njit
def out_edge_gap(phi, k):
    """G(phi) = det(w, t, oc - P) of the `OutEdge` k: 0 where the segment's line meets the edge ray out's."""
    pc, t = _out_edge_ray(phi, k)
    return _det(k.w, t, (k.oc[0] - pc[0], k.oc[1] - pc[1], k.oc[2] - pc[2]))


@_at_of(OutEdge, inline=True)
@njit
def _out_edge_at(k, x):
    return (out_edge_gap(x, k),)


@_value_of(OutEdge, inline=True)
@njit
def _out_edge_value(k, x):
    return out_edge_gap(x, k)


@_cell_of(OutEdge, inline=True)
@njit
def _out_edge_cell(k, a, b, j, e):
    """As `_paths_cell`, by the `OutEdge`'s K and G's rounding."""
    fa, fb, w = e[0], e[1], b - a
    if fa * fb > 0.0:
        return -1 if min(abs(fa), abs(fb)) - k.dg > 0.125 * k.k2 * w * w or \
            abs(fb - fa) - 2.0 * k.dg > k.k2 * w * w else 0
    return 1 if abs(fb - fa) - 2.0 * k.dg > k.k2 * w * w else 0


@_spread_of(OutEdge, inline=True)
@njit
def _out_edge_spread(k, root, a, b, fa, fb, j):
    return math.inf


@njit
def out_edge(o, w, c, radius, light, axis, ce, eta):
    """The `OutEdge` of a spot at light (unit axis, edge cosine ce, |light - c| < radius / eta) and the segment o +
    x w (module docstring, "The spot's band edges outside"): K = |t''| (|oc| + R) + 2 |t'| |P'| + |P''| over all
    phi from the derivatives' bounds there, and G's rounding."""
    a = axis / _norm(axis)
    q = light - c
    d = _norm(q)
    qa = q[0] * a[0] + q[1] * a[1] + q[2] * a[2]
    b1 = q - qa * a
    if not _norm(b1) > 1e-12 * d:  # q along the axis: any normal to it
        i = 0 if abs(a[0]) < 0.9 else 1
        b1[:] = -a[i] * a
        b1[i] += 1.0
    b1 /= _norm(b1)
    b2 = np.array([a[1] * b1[2] - a[2] * b1[1], a[2] * b1[0] - a[0] * b1[2], a[0] * b1[1] - a[1] * b1[0]])
    se = math.sqrt((1.0 - ce) * (1.0 + ce))
    oc = o - c
    s0 = math.sqrt((radius - d) * (radius + d))  # the least S
    c2 = math.sqrt(max(1.0 - (eta * d / radius) ** 2, 0.0))  # the least cos_2
    db = d * se  # |b'|, |b''|
    ds1 = d * db / s0
    ds2 = (db * db + d * db + ds1 * ds1) / s0
    r0, r1, r2 = radius + d, ds1 + db, ds2 + db
    p1, p2 = r1 + r0 * se, r2 + 2.0 * r1 * se + r0 * se
    c11, c12 = ds1 / radius, ds2 / radius
    c21 = eta * eta * c11 / c2
    c22 = eta * eta * (c11 * c11 + c12) / c2 + c21 * c21 / c2
    f0, f1, f2 = 1.0 + eta, c21 + eta * c11, c22 + eta * c12
    t1 = eta * se + f1 + f0 * p1 / radius
    t2 = eta * se + f2 + 2.0 * f1 * p1 / radius + f0 * p2 / radius
    reach = _norm(oc) + radius
    k2 = (t2 * reach + 2.0 * t1 * p1 + p2) * (1.0 + 1e-9)
    ep = 64.0 * U * (_norm(light) + _norm(c) + radius + d) * (1.0 + d / s0)
    et = 8.0 * U * eta + (1.0 + eta + eta * eta / c2) * ep / radius + (1.0 + eta) * ep / radius + 16.0 * U
    dg = 2.0 * (reach * (et + 16.0 * U) + ep + 4.0 * U * (_norm(o) + _norm(c)))
    return OutEdge(ce, se, _tuple(a), _tuple(b1), _tuple(b2), _tuple(q), _tuple(oc), _tuple(w), radius, eta, d, k2, dg)


@njit
def out_edge_cuts(o, w, c, radius, light, axis, cone, eta, end, out):
    """The x in (0, end) where the segment o + x w crosses a spot's band edges' rays out of the sphere (both edges,
    cone = (cos_end, cos_start, curve)) into out, ascending; returns (count, proven): per edge `_halving` over phi
    in [-pi, pi] of G (`out_edge`), each root's ray meeting the segment's line at x (kept where 0 < x < end and
    ahead of P). Unproven where a scan was, or out filled up."""
    m, proven = 0, True
    found, spread = np.empty(EDGES), np.empty(EDGES)
    for e in range(2):
        ce = cone[e]
        if not -1.0 < ce < 1.0 or (e == 1 and ce == cone[0]):
            continue
        k = out_edge(o, w, c, radius, light, axis, ce, eta)
        n, ok = _halving(k, -math.pi, 2.0 * math.pi / SCAN, 0, -math.pi, False, found, spread)
        proven = proven and ok and n < EDGES
        for i in range(n):
            pc, t = _out_edge_ray(found[i], k)
            v = (pc[0] - k.oc[0], pc[1] - k.oc[1], pc[2] - k.oc[2])  # P - o
            wt = (w[1] * t[2] - w[2] * t[1], w[2] * t[0] - w[0] * t[2], w[0] * t[1] - w[1] * t[0])
            nn = wt[0] * wt[0] + wt[1] * wt[1] + wt[2] * wt[2]
            if not nn > 0.0:
                continue
            x = _det(v, t, wt) / nn
            sig = _det(v, w, wt) / nn
            if 0.0 < x < end and sig > 0.0:
                if m < out.shape[0]:
                    out[m] = x
                    m += 1
                else:
                    proven = False
    sort_few(out, 0, m)
    return m, proven


class GlobeFog(NamedTuple):
    """One segment o + x w of the scattering medium outside a refractive exact sphere (centre c, radius; relative
    index eta inside) and a unit point light inside it at c + rel (a spot: its axis and cone), for one channel
    (kt, ks and the phase: the outside medium's; kt_in: the inside's); `paths_out`'s rows and scratch; the pieces'
    ends (ascending, the first 0: QUAD's cuts) and each piece's flag of other shapes' shadows (media/globe_shadows.py:
> 0 lit, 0 shadowed, < 0 undecided: counted dark); and the track: the evaluations whose scan was unproven or that found
    a number of paths other than one, then (ROUNDING) the largest relative rounding of the evaluations
    (`fog_rounding`) and (ROUNDING_ABS + i) the largest absolute of those on piece i."""
    o: np.ndarray
    w: np.ndarray
    c: np.ndarray
    radius: float
    rel: np.ndarray
    axis: np.ndarray
    cone: np.ndarray
    eta: float
    kt: float
    ks: float
    code: int
    g: float
    kt_in: float
    found: np.ndarray
    spread: np.ndarray
    value: np.ndarray
    toward: np.ndarray
    inside: np.ndarray
    outside: np.ndarray
    ends: np.ndarray
    lit: np.ndarray
    track: np.ndarray


@njit
def fog_rounding(r, x, q, k):
    """The relative rounding bound of path k's term of `fog_value` at o + x w (q as computed; module docstring,
    "The fog's bound"), first order doubled, inf where a bound does not apply."""
    radius, eta = r.radius, r.eta
    rn = math.sqrt(r.rel[0] * r.rel[0] + r.rel[1] * r.rel[1] + r.rel[2] * r.rel[2])
    ez = q - r.c
    d = math.sqrt(ez[0] * ez[0] + ez[1] * ez[1] + ez[2] * ez[2])
    if not (d > radius and rn < radius):
        return math.inf
    ez /= d
    zx, yx, ey = about_axis(r.rel, ez)
    ev = 3.0 * U * (math.sqrt(r.o[0] * r.o[0] + r.o[1] * r.o[1] + r.o[2] * r.o[2]) + x) + 2.0 * U * d  # q - c's
    dd, dez = ev + 4.0 * U * d, ev / d + 8.0 * U  # d's error, ez's (absolute)
    dxy = rn * (3.0 * dez + 16.0 * U)  # X's coordinates'
    dey = 2.0 * rn * (2.0 * dez + 10.0 * U) / yx if yx > 0.0 else math.inf
    theta_a = lit_arc(radius, d, eta)
    step = 2.0 * theta_a / SCAN
    j = min(max(int((r.found[k] + theta_a) / step), 0), SCAN - 1)
    p1, _, et, a1 = angular_bounds(-theta_a + j * step, -theta_a + (j + 1) * step, radius, d, eta)
    pz, py, tz, ty, cos_i, cos_t, o = incidence(r.found[k], radius, d, eta)
    s, reach, inv_o = r.inside[k], rn + radius, 1.0 / o
    kappa_t = tangential_curvature(cos_i, cos_t, inv_o, radius, eta)
    kappa_s = ((eta * cos_t - cos_i) / radius - inv_o) / eta
    tang, sag = 1.0 - s * kappa_t, 1.0 - s * kappa_s
    g1 = cos_i / (eta * cos_t)  # |d phi / d alpha|
    dal = abs(py) * dd * inv_o * inv_o + et  # the arriving direction at fixed theta: d's error, its own rounding
    # the root: h off by its rounding dh, X's offset dxy and d's error (h_d = -s phi_d), over |h_theta| = R cos_t
    # |1 - s kappa_t|, first order doubled, or `paths_out`'s spread (h's rounding, X off by its dx) and the rest
    dx = 16.0 * U * (d + 2.0 * radius + rn)
    slope = radius * cos_t * abs(tang)
    dh = 2.0 * (2.0 * et * reach + 16.0 * U * (radius + reach))
    dth = min(2.0 * (dh + dxy + s * g1 * dal) / slope + 4.0 * U * theta_a,
              r.spread[k] + (max(dxy - dx, 0.0) + s * g1 * dal) / slope)
    dti = a1 * dth + dal  # the incidence angle's error
    dphi = p1 * dth + g1 * dal + et  # t's direction's
    do = radius * dth + dd + 4.0 * U * o
    ds = dphi * reach + radius * dth + dxy + 8.0 * U * reach
    eps = r.kt * (do + 4.0 * U * (x + o)) + r.kt_in * (ds + 4.0 * U * s) + 64.0 * U
    eps += 16.0 * U * (r.kt * (x + o) + r.kt_in * s)
    eps += 2.0 * do * inv_o  # 1 / o^2
    dci, dct = dti, dti / (eta * eta * cos_t)  # |d cos_i|, |d cos_t| (sin_t <= 1 / eta)
    eps += 3.0 * dci / cos_i + dct / cos_t + 16.0 * U / (1.0 - fresnel(cos_i, eta))  # T cos_i, cos_t
    dinv = do * inv_o * inv_o  # 1 / o's
    nt = (eta * cos_t - cos_i) / radius - cos_i * cos_i * inv_o
    dnt = (eta * dct + dci) / radius + 2.0 * cos_i * dci * inv_o + cos_i * cos_i * dinv
    dkt = dnt / (eta * cos_t * cos_t) + 2.0 * abs(nt) * dct / (eta * cos_t ** 3)
    eps += (ds * abs(kappa_t) + s * dkt + 32.0 * U * (1.0 + s * (abs(kappa_t) + 1.0 / radius + inv_o)
                                                      / (cos_t * cos_t))) / abs(tang)
    dks = ((eta * dct + dci) / radius + dinv) / eta
    eps += (ds * abs(kappa_s) + s * dks + 16.0 * U * (1.0 + s * (abs(kappa_s) + 1.0 / radius + inv_o))) / abs(sag)
    # toward = ((pz - d) e_z + py e_y) / o: P's move, q's and the frame's
    dmu = (radius * dth + dd) * inv_o + dez + (abs(py) * inv_o * dey if py != 0.0 else 0.0) + 8.0 * U
    eps += phase_condition(r.code, r.g) * dmu
    eps = 2.0 * eps
    cone = r.cone
    f = falloff(-((tz * ez[0] + ty * ey[0]) * r.axis[0] + (tz * ez[1] + ty * ey[1]) * r.axis[1]
                  + (tz * ez[2] + ty * ey[2]) * r.axis[2]), cone[0], cone[1], int(cone[2]))
    if f < 1.0:  # the falloff at the error of the cosine of -t to the axis, absolute, over F
        dc = dphi + dez + (abs(ty) * dey if ty != 0.0 else 0.0) + 8.0 * U
        eps += 2.0 * band_slope(cone[0], cone[1], int(cone[2])) / (cone[1] - cone[0]) * dc / f
    return eps


@njit
def fog_terms(x, r, q):
    """(total, err, n, proven) at q = o + x w of the `GlobeFog` r, unshadowed: over the paths out (`paths_out`),
    Phi(mu) E exp(-kt (x + o) - kt_in s), mu = toward . w (the light arrives from the refraction point); err the
    rounding of ks times it (`fog_rounding`), n the count of paths, proven `paths_out`'s."""
    proven = paths_out(q, r.c, r.radius, r.rel, r.axis, r.cone, r.eta, r.found, r.spread, r.value, r.toward,
                       r.inside, r.outside)
    total = err = 0.0
    n = 0
    for k in range(MAX_PATHS):
        n += r.outside[k] > 0.0
        if r.value[k] > 0.0:
            mu = r.toward[k, 0] * r.w[0] + r.toward[k, 1] * r.w[1] + r.toward[k, 2] * r.w[2]
            term = phase_value(r.code, r.g, mu) * r.value[k] * math.exp(-r.kt * (x + r.outside[k])
                                                                       - r.kt_in * r.inside[k])
            total += term
            err += r.ks * term * fog_rounding(r, x, q, k)
    return total, err, n, proven


@njit
def fog_value(x, r):
    """The outside medium's single scattering at o + x w of the `GlobeFog` r: ks `fog_terms` on the lit pieces, 0 on
    the others; the rounding of the sum into the track: the largest relative of the evaluations, and the largest
    absolute of those on x's piece (between r.ends)."""
    i = 1
    while i < r.ends.shape[0] - 1 and r.ends[i] <= x:
        i += 1
    if not r.lit[i - 1] > 0.0:
        return 0.0
    q = np.empty(3)
    for j in range(3):
        q[j] = r.o[j] + x * r.w[j]
    total, err, n, proven = fog_terms(x, r, q)
    if n != 1 or not proven:
        r.track[0] += 1.0
    _track_rounding(r.track, r.ks * total, err, ROUNDING_ABS + i - 1)
    return r.ks * total


@integrand_of(GlobeFog)
@njit
def _fog_value(x, r):
    return fog_value(x, r)


@njit
def _merged(cuts, m, ends, flags, ell):
    """([0, the spot's cuts and the shadows' breaks ascending, ell], each piece's shadow flag) of a segment: cuts[1:m +
    1] the spot's, ends and flags its shadow pieces (media/globe_shadows.py `shadow_pieces`, from 0 to ell)."""
    k = ends.shape[0] - 1
    br, lit = np.empty(m + k + 1), np.empty(m + k)
    br[0] = 0.0
    i, j, n = 1, 1, 1
    while i <= m or j < k:
        if j >= k or (i <= m and cuts[i] < ends[j]):
            br[n] = cuts[i]
            i += 1
        else:
            br[n] = ends[j]
            j += 1
        n += 1
    br[n] = ell
    p = 0
    for i in range(n):
        while p < k - 1 and ends[p + 1] <= 0.5 * (br[i] + br[i + 1]):
            p += 1
        lit[i] = flags[p]
    return br[:n + 1], lit[:n]


@njit
def out_of_sphere(geo, sphere, ell, kt, ks, code, g, kt_in, eta, rule, keys, dim0, seed, out, var, err, stats, start,
                  ends, flags, proven):
    """The outside medium's single scattering (N, C) over segments outside a refractive exact sphere (centre,
    radius; relative index eta = its ior > 1 inside) from a unit point or spot light inside it, closer to the centre
    than radius / eta (geo rows of media/slab.py's GEO_COLUMNS; kt, ks: the outside's, kt_in the inside's, one each per
    channel), shadowed by other shapes on the pieces media/globe_shadows.py `shadow_pieces` finds (start, ends,
    flags, proven: its output): `fog_value` along each segment. There every path leaves the sphere (the distance
    from the centre of a ray from the light, at most its own, is below radius / eta: the internal incidence below
    the critical angle) and each point outside has one path, the outward rays crossing neither each other nor the
    axis ahead (no real caustic; checked against the twin's own root-finding, tests/test_globe_fog.py), so the
    integrand is smooth along the segment but where it crosses a spot's band edges (`out_edge_cuts`) or a shadow's
    break: QUAD media/adaptive.py `bounded_piecewise` over [0, end], end = min(ell, 745 / kt), cut there (bound inf
    where either scan is not proven), its bound the rule's b plus 3 min(rho (|value| + b), sum_i e_i l_i) (rho: the
    largest relative rounding of its evaluations, `fog_rounding`; e_i: the largest absolute of those on piece i, of
    length l_i: the rule's weights are positive and sum to each piece's length; a piece the spot does not reach or
    a shadowed one adds 0) plus, per undecided piece (counted dark), its length times twice the larger of its ends'
    unshadowed values; MARCH, SAMPLE `march_or_sample` at dimensions dim0 (bound inf). The bound is inf on the
    segments with an evaluation whose scan was unproven or whose count of paths was not one (the light beyond
    radius / eta, which `check` refuses), counted in stats[UNBOUNDED] with the QUAD segments whose bound is inf for
    another reason."""
    nc = kt.shape[0]
    cone = np.empty(3)
    q = np.empty(3)
    for s in range(geo.shape[0]):
        out[s, :], var[s, :], err[s, :] = 0.0, 0.0, 0.0
        if not ell[s] > 0.0:
            continue
        cone[0], cone[1], cone[2] = geo[s, 12], geo[s, 13], geo[s, 17]
        cuts = np.zeros(2 * EDGES + 2)
        m, found = 0, True
        if rule.kind == QUAD:
            m, found = out_edge_cuts(geo[s, :3], geo[s, 3:6], sphere[:3], sphere[3], geo[s, 6:9], geo[s, 9:12],
                                     cone, eta, ell[s], cuts[1:2 * EDGES + 1])
        every, lit_of = _merged(cuts, m, ends[start[s]:start[s + 1]], flags[start[s] - s:start[s + 1] - s - 1],
                                ell[s])
        track = np.zeros(ROUNDING_ABS + every.shape[0])
        for c in range(nc):
            if ks[c] == 0.0:
                continue
            end = min(ell[s], 745.0 / kt[c])
            n = 1
            while n < every.shape[0] - 1 and every[n] < end:
                n += 1
            br = every[:n + 1].copy()  # 0, the cuts before end, end
            br[n] = end
            rec = GlobeFog(geo[s, :3].copy(), geo[s, 3:6].copy(), sphere[:3].copy(), sphere[3],
                           geo[s, 6:9] - sphere[:3], geo[s, 9:12].copy(), cone, eta, kt[c], ks[c], code, g, kt_in[c],
                           np.empty(MAX_PATHS), np.empty(MAX_PATHS), np.empty(MAX_PATHS), np.empty((MAX_PATHS, 3)),
                           np.empty(MAX_PATHS), np.empty(MAX_PATHS), br, lit_of[:n].copy(), track)
            if rule.kind == QUAD:
                track[ROUNDING:] = 0.0
                out[s, c], b = bounded_piecewise(rec, br, n + 1, rule.rtol, N10, W10, N20, W20, stats)
                if not (found and proven[s]):
                    b = math.inf
                pieces = 0.0
                for i in range(n):
                    pieces += track[ROUNDING_ABS + i] * (br[i + 1] - br[i])
                err[s, c] = b + 3.0 * min(track[ROUNDING] * (abs(out[s, c]) + b), pieces)
                for i in range(n):
                    if rec.lit[i] < 0.0:
                        most = 0.0
                        for x in (br[i], br[i + 1]):
                            for j in range(3):
                                q[j] = rec.o[j] + x * rec.w[j]
                            most = max(most, ks[c] * fog_terms(x, rec, q)[0])
                        err[s, c] += 2.0 * most * (br[i + 1] - br[i])
            else:
                out[s, c], var[s, c] = march_or_sample(rec, rule, cut_length(rule, ell[s], kt[c]), kt[c], keys[s],
                                                       dim0, seed)
                err[s, c] = math.inf
        if track[0] > 0.0:
            err[s, :] = math.inf
        if track[0] > 0.0 or (rule.kind == QUAD and not np.all(err[s] < math.inf)):
            stats[UNBOUNDED] += 1.0
