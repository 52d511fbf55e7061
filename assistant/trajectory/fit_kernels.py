"""The primitive fitter's geometry, compiled (numba): line and arc fits and distances.

`primitives._Fitter` asks on the order of a hundred "does a line (an arc) from O cover
nodes s+1..e within the tolerance?" questions per transfer. Each answer is a few dozen small
vector operations (a principal direction or plane of the nodes, up to six circle guesses, an
unwrapped angle sweep),
and as numpy calls they cost ~100 us, a quarter of a planning query; compiled they cost a
few microseconds. The control flow (growth, look-ahead, junction refinement) stays in Python.

Each kernel follows a numpy formulation step by step (the tests compare them case for
case to 1e-9 m); the summation order inside dot products may differ in the last bit, and
the free circle's least squares goes through its 2x2 normal equations instead of numpy's
`lstsq` (which alone costs ~3 s to compile). On the 134 recorded transfer fits of the planning
benchmark both give the same primitives. A NaN deviation counts as a miss here (numpy's max
lets it through as "within tolerance"). The nodes' directions come from their 3x3 Gram matrix
(`sym3_eigvec`, `sym2_major`) rather than LAPACK's SVD: the same directions to ~1e-13, and
the same primitives and lengths (to 6e-15 m) on 480 generated transfers, at half the time.

Serves (the user-felt figure): the line/arc fit of every transfer: 0.6 s in Python in the
thesis run.
"""

from __future__ import annotations

import math

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray

_JIT = {"cache": True, "error_model": "numpy"}
_INLINE = {**_JIT, "inline": "always"}


@kernel(**_JIT)
def _dot(a: Array, b: Array) -> float:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@kernel(**_JIT)
def _cross(a: Array, b: Array) -> Array:
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@kernel(**_JIT)
def _unit(v: Array) -> Array:
    n = math.sqrt(_dot(v, v))
    return v / n if n > 1e-15 else v * 0.0


@kernel(**_JIT)
def _unit3(v0: float, v1: float, v2: float) -> tuple[float, float, float]:
    """`_unit` of (v0, v1, v2), as scalars."""
    n = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if n > 1e-15:
        return v0 / n, v1 / n, v2 / n
    return v0 * 0.0, v1 * 0.0, v2 * 0.0


@kernel(**_JIT)
def _put_guess(O: Array, t0: Array, w0: float, w1: float, w2: float, c: Array,
               n: Array) -> None:
    """A tangent circle guess: centre O + w into c, normal _unit(t0 x w) into n."""
    c[0], c[1], c[2] = O[0] + w0, O[1] + w1, O[2] + w2
    n[0], n[1], n[2] = _unit3(t0[1] * w2 - t0[2] * w1, t0[2] * w0 - t0[0] * w2,
                              t0[0] * w1 - t0[1] * w0)


@kernel(**_JIT)
def _rotate_radius(r0: Array, normal: Array, angle: float) -> Array:
    """r0 turned by `angle` about `normal` (r0 perpendicular to it). The vector form:
    the fitter uses `put_on_arc`; the tests compare the two to the bit."""
    return math.cos(angle) * r0 + math.sin(angle) * _cross(normal, r0)


@kernel(**_JIT)
def put_on_arc(centre: Array, r0: Array, normal: Array, angle: float, out: Array,
               at: int) -> None:
    """centre + `_rotate_radius`(r0, normal, angle) into out[at:at + 3], as scalars (the
    same operations; no array per intermediate)."""
    c, s = math.cos(angle), math.sin(angle)
    x0 = normal[1] * r0[2] - normal[2] * r0[1]
    x1 = normal[2] * r0[0] - normal[0] * r0[2]
    x2 = normal[0] * r0[1] - normal[1] * r0[0]
    out[at] = centre[0] + (c * r0[0] + s * x0)
    out[at + 1] = centre[1] + (c * r0[1] + s * x1)
    out[at + 2] = centre[2] + (c * r0[2] + s * x2)


@kernel(**_JIT)
def _gram(X: Array) -> Array:
    """X^T X of the rows (m, 3): its eigenvectors are X's right singular vectors."""
    M = np.zeros((3, 3))
    for i in range(X.shape[0]):
        x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
        M[0, 0] += x0 * x0
        M[0, 1] += x0 * x1
        M[0, 2] += x0 * x2
        M[1, 1] += x1 * x1
        M[1, 2] += x1 * x2
        M[2, 2] += x2 * x2
    M[1, 0], M[2, 0], M[2, 1] = M[0, 1], M[0, 2], M[1, 2]
    return M


@kernel(**_JIT)
def sym3_eigvec(M: Array, largest: bool) -> Array:
    """Unit eigenvector of the symmetric 3x3 M for its largest (else smallest) eigenvalue,
    by cyclic Jacobi rotations.

    Why not `np.linalg.svd` of the nodes: a LAPACK call costs ~2.5 us whatever the size, and
    the fitter asks one per fit (~250 a transfer), most of its time. Jacobi on the 3x3 Gram
    matrix converges in three or four sweeps to rounding; the direction's error is ~1e-16
    over the eigenvalue gap, i.e. far below a micrometre for the nodes' principal direction
    and a fitted plane's normal (a plane through nearly collinear nodes is ill-defined
    either way, and its circle far above r_max)."""
    A = M.copy()
    V = np.eye(3)
    for _ in range(12):
        off = abs(A[0, 1]) + abs(A[0, 2]) + abs(A[1, 2])
        scale = abs(A[0, 0]) + abs(A[1, 1]) + abs(A[2, 2])
        if off <= 1e-300 or off <= 1e-18 * scale:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            apq = A[p, q]
            if apq == 0.0:
                continue
            theta = (A[q, q] - A[p, p]) / (2.0 * apq)
            t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
            c = 1.0 / math.sqrt(t * t + 1.0)
            s = t * c
            for k in range(3):  # A <- A J (columns p, q)
                akp, akq = A[k, p], A[k, q]
                A[k, p], A[k, q] = c * akp - s * akq, s * akp + c * akq
            for k in range(3):  # A <- J^T A (rows p, q)
                apk, aqk = A[p, k], A[q, k]
                A[p, k], A[q, k] = c * apk - s * aqk, s * apk + c * aqk
            A[p, q] = A[q, p] = 0.0
            for k in range(3):
                vkp, vkq = V[k, p], V[k, q]
                V[k, p], V[k, q] = c * vkp - s * vkq, s * vkp + c * vkq
    j = 0
    for k in range(1, 3):
        if (A[k, k] > A[j, j]) if largest else (A[k, k] < A[j, j]):
            j = k
    v = V[:, j].copy()
    return v / math.sqrt(_dot(v, v))


@kernel(**_JIT)
def sym2_major(a: float, b: float, c: float) -> tuple[float, float]:
    """Unit eigenvector of [[a, b], [b, c]] for its larger eigenvalue (closed form: the
    major axis is at half the angle atan2(2 b, a - c))."""
    half = 0.5 * math.atan2(2.0 * b, a - c)
    return math.cos(half), math.sin(half)


@kernel(**_JIT)
def circle_through_kernel(a: Array, b: Array, c: Array) -> tuple[bool, Array, float, Array]:
    """(ok, centre, radius, unit normal a->b->c right-handed); ok False if collinear."""
    ab, ac = b - a, c - a
    n = _cross(ab, ac)
    nn = _dot(n, n)
    if nn < 1e-18 * max(1e-30, _dot(ab, ab) * _dot(ac, ac)):
        return False, np.zeros(3), 0.0, np.zeros(3)
    centre = a + (_cross(n, ab) * _dot(ac, ac) + _cross(ac, n) * _dot(ab, ab)) / (2.0 * nn)
    d = centre - a
    return True, centre, math.sqrt(_dot(d, d)), n / math.sqrt(nn)


@kernel(**_JIT)
def line_distances(start: Array, end: Array, points: Array) -> Array:
    """Distance of each point (m, 3) to the segment start-end. Scalars, not 3-vectors, per
    point: the fitter asks this ~80 times a transfer, and an array per intermediate would be
    an allocation each (the same operations in the same order, so the same bits)."""
    s0, s1, s2 = start[0], start[1], start[2]
    d0, d1, d2 = end[0] - s0, end[1] - s1, end[2] - s2
    out = np.empty(len(points))
    for i in range(len(points)):
        out[i] = _line_point(points[i, 0] - s0, points[i, 1] - s1, points[i, 2] - s2,
                             d0, d1, d2)
    return out


@kernel(**_JIT)
def line_deviation(start: Array, end: Array, points: Array) -> float:
    """`_max_or_nan(line_distances(...))` without the array of distances."""
    s0, s1, s2 = start[0], start[1], start[2]
    d0, d1, d2 = end[0] - s0, end[1] - s1, end[2] - s2
    worst = -np.inf
    for i in range(len(points)):
        d = _line_point(points[i, 0] - s0, points[i, 1] - s1, points[i, 2] - s2, d0, d1, d2)
        if d != d:
            return np.nan
        worst = max(worst, d)
    return worst


@kernel(**_INLINE)
def _line_point(x0: float, x1: float, x2: float, d0: float, d1: float, d2: float) -> float:
    """Distance of start + x to the segment start -> start + d (scalars; `line_distances`
    and `line_deviation` share it)."""
    L2 = d0 * d0 + d1 * d1 + d2 * d2
    s = 0.0
    if L2 > 0.0:
        s = min(max((x0 * d0 + x1 * d1 + x2 * d2) / L2, 0.0), 1.0)
    r0, r1, r2 = x0 - s * d0, x1 - s * d1, x2 - s * d2
    return math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)


@kernel(**_JIT)
def arc_distances(start: Array, end: Array, centre: Array, radius: float, normal: Array,
                  sweep: float, points: Array) -> Array:
    """Distance of each point (m, 3) to the arc (not the full circle): to the circle where
    the point's angle about the normal lies within the sweep, else to the nearer end.
    Scalars per point, as `line_distances`."""
    out = np.empty(len(points))
    for i in range(len(points)):
        out[i] = _arc_point(points[i, 0], points[i, 1], points[i, 2], start, end, centre,
                            radius, normal, sweep)
    return out


@kernel(**_JIT)
def arc_deviation(start: Array, end: Array, centre: Array, radius: float, normal: Array,
                  sweep: float, points: Array) -> float:
    """`_max_or_nan(arc_distances(...))` without the array of distances."""
    worst = -np.inf
    for i in range(len(points)):
        d = _arc_point(points[i, 0], points[i, 1], points[i, 2], start, end, centre, radius,
                       normal, sweep)
        if d != d:
            return np.nan
        worst = max(worst, d)
    return worst


@kernel(**_JIT)
def _arc_point(p0: float, p1: float, p2: float, start: Array, end: Array, centre: Array,
               radius: float, normal: Array, sweep: float) -> float:
    """Distance of the point p to the arc (`arc_distances` and `arc_deviation` share it;
    the point as scalars, no row view per point)."""
    n0, n1, n2 = normal[0], normal[1], normal[2]
    r00, r01, r02 = start[0] - centre[0], start[1] - centre[1], start[2] - centre[2]
    y0, y1, y2 = n1 * r02 - n2 * r01, n2 * r00 - n0 * r02, n0 * r01 - n1 * r00  # n x r0
    x0, x1, x2 = p0 - centre[0], p1 - centre[1], p2 - centre[2]
    h = x0 * n0 + x1 * n1 + x2 * n2
    v0, v1, v2 = x0 - h * n0, x1 - h * n1, x2 - h * n2
    rho = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    phi = math.atan2(v0 * y0 + v1 * y1 + v2 * y2, v0 * r00 + v1 * r01 + v2 * r02)
    if phi < 0.0:
        phi += 2.0 * math.pi
    if phi <= sweep + 1e-12:
        return math.sqrt(h * h + (rho - radius) ** 2)
    s0, s1, s2 = p0 - start[0], p1 - start[1], p2 - start[2]
    e0, e1, e2 = p0 - end[0], p1 - end[1], p2 - end[2]
    return min(math.sqrt(s0 * s0 + s1 * s1 + s2 * s2), math.sqrt(e0 * e0 + e1 * e1 + e2 * e2))


@kernel(**_JIT)
def _max_or_nan(values: Array) -> float:
    """The largest value; NaN if any is NaN (so a `<= tol` test fails). The fitter asks
    `line_deviation`/`arc_deviation`, which keep this rule without the array; the tests
    compare them with this."""
    m = -np.inf
    for v in values:
        if v != v:
            return np.nan
        m = max(m, v)
    return m


@kernel(**_JIT)
def _within_cone(d: Array, axis: Array, angle: float) -> Array:
    """d, or the closest direction to it within `angle` of `axis`."""
    c = min(max(_dot(d, axis), -1.0), 1.0)
    if c >= math.cos(angle):
        return d
    perp = _unit(d - c * axis)
    if not (perp[0] != 0.0 or perp[1] != 0.0 or perp[2] != 0.0):
        return axis
    return math.cos(angle) * axis + math.sin(angle) * perp


@kernel(**_JIT)
def fit_line(O: Array, t0: Array, has_t0: bool, pts: Array, tol: float, slack: float,
             ) -> tuple[bool, Array]:
    """(found, end) of a line from O covering the nodes `pts` (m, 3) within `tol`.

    Directions tried in order: with an incoming tangent t0, t0 itself and the least-squares
    direction (through O) pulled into the `slack` cone about t0; without, the least-squares
    direction and the one to the last node. The nodes' projections must advance (no step
    back by more than tol) and the segment ends at the last node's projection.
    """
    m = len(pts)
    X = pts - O
    v0 = sym3_eigvec(_gram(X), True)  # the least-squares direction through O
    total = X.sum(axis=0)
    proj_sum = _dot(v0, total)
    sign = 1.0 if proj_sum == 0.0 else np.sign(proj_sum)
    d_ls = v0 * sign
    dirs = np.empty((2, 3))
    if has_t0:
        dirs[0] = t0
        dirs[1] = _within_cone(d_ls, t0, slack)
    else:
        dirs[0] = d_ls
        dirs[1] = _unit(X[m - 1])
    proj = np.empty(m)
    for k in range(2):
        d = dirs[k]
        for i in range(m):
            proj[i] = _dot(X[i], d)
        if not proj[m - 1] > 0.0:
            continue
        back = False
        for i in range(m - 1):
            if proj[i + 1] - proj[i] < -tol:
                back = True
                break
        if back:
            continue
        end = O + proj[m - 1] * d
        if line_deviation(O, end, pts) <= tol:
            return True, end
    return False, np.zeros(3)


@kernel(**_JIT)
def _free_candidates(O: Array, X: Array, C: Array, N: Array, k: int) -> int:
    """Circle guesses without a tangent: the least-squares circle in the nodes' best-fit
    plane, and the circle through O, the middle and the last node. Appended to C, N at k;
    returns the new count."""
    m = len(X)
    if m > 2:
        n = sym3_eigvec(_gram(X), False)  # the nodes' best-fit plane through O
    else:
        n = _unit(_cross(X[0], X[m - 1]))
    if math.sqrt(_dot(n, n)) < 0.5:
        return k
    e1 = _unit(X[m - 1] - _dot(X[m - 1], n) * n)
    e2 = _cross(n, e1)
    # least squares 2 (x, y) . c = x^2 + y^2 through the normal equations (a 2x2 solve;
    # they are ill-conditioned only for nearly collinear nodes, whose circle is far larger
    # than r_max anyway)
    sxx = sxy = syy = bx = by = 0.0
    for i in range(m):
        x, y = _dot(X[i], e1), _dot(X[i], e2)
        q = x * x + y * y
        sxx += x * x
        sxy += x * y
        syy += y * y
        bx += x * q
        by += y * q
    det = 2.0 * (sxx * syy - sxy * sxy)
    cx = (syy * bx - sxy * by) / det
    cy = (sxx * by - sxy * bx) / det
    C[k] = O + cx * e1 + cy * e2
    N[k] = n
    k += 1
    ok, c, _, n3 = circle_through_kernel(O, O + X[m // 2], O + X[m - 1])
    if ok:
        C[k], N[k] = c, n3
        k += 1
    return k


@kernel(**_JIT)
def _tangent_candidates(O: Array, t0: Array, X: Array, C: Array, N: Array, k: int) -> int:
    """Circle guesses tangent to t0 at O: in the plane through O containing t0 whose normal
    is the least-variance direction of the nodes across t0 (and the one through the last
    node), the least-squares curvature and the exact circle through the last node."""
    m = len(X)
    # Scalars throughout (the same operations in the same order as the vector forms
    # `_unit(_cross(t0, helper))` etc.): the fitter asks this for every tangent arc guess,
    # and a small array per intermediate would be an allocation and reference counts each.
    h0, h1, h2 = (1.0, 0.0, 0.0) if abs(t0[0]) < 0.9 else (0.0, 1.0, 0.0)
    t_0, t_1, t_2 = t0[0], t0[1], t0[2]
    b10, b11, b12 = _unit3(t_1 * h2 - t_2 * h1, t_2 * h0 - t_0 * h2, t_0 * h1 - t_1 * h0)
    b20, b21, b22 = t_1 * b12 - t_2 * b11, t_2 * b10 - t_0 * b12, t_0 * b11 - t_1 * b10
    Y = np.empty((m, 2))
    r2 = np.empty(m)
    syy0 = syy1 = sy01 = 0.0
    for i in range(m):
        x0, x1, x2 = X[i, 0], X[i, 1], X[i, 2]
        Y[i, 0] = x0 * b10 + x1 * b11 + x2 * b12
        Y[i, 1] = x0 * b20 + x1 * b21 + x2 * b22
        r2[i] = x0 * x0 + x1 * x1 + x2 * x2
        syy0 += Y[i, 0] * Y[i, 0]
        sy01 += Y[i, 0] * Y[i, 1]
        syy1 += Y[i, 1] * Y[i, 1]
    major0, major1 = sym2_major(syy0, sy01, syy1)  # Y's first right singular vector
    denom = 0.0
    for i in range(m):
        denom += r2[i] * r2[i]
    ylen = math.sqrt(Y[m - 1, 0] ** 2 + Y[m - 1, 1] ** 2)
    for j in range(2):
        if j == 0:
            mc0, mc1 = major0, major1
        elif ylen > 1e-12:
            mc0, mc1 = Y[m - 1, 0] / ylen, Y[m - 1, 1] / ylen
        else:
            continue
        # in-plane normal to t0
        mv0, mv1, mv2 = mc0 * b10 + mc1 * b20, mc0 * b11 + mc1 * b21, mc0 * b12 + mc1 * b22
        s = 0.0
        for i in range(m):
            s += (X[i, 0] * mv0 + X[i, 1] * mv1 + X[i, 2] * mv2) * r2[i]
        kappa = 2.0 * s / denom if denom > 0.0 else 0.0
        if abs(kappa) < 1e-9:
            continue
        _put_guess(O, t0, mv0 / kappa, mv1 / kappa, mv2 / kappa, C[k], N[k])
        k += 1
        xl = X[m - 1, 0] * mv0 + X[m - 1, 1] * mv1 + X[m - 1, 2] * mv2
        rl = X[m - 1, 0] * X[m - 1, 0] + X[m - 1, 1] * X[m - 1, 1] + X[m - 1, 2] * X[m - 1, 2]
        if abs(xl) > 1e-12:
            k2 = 2.0 * xl / rl
            _put_guess(O, t0, mv0 / k2, mv1 / k2, mv2 / k2, C[k], N[k])
            k += 1
    return k


@kernel(**_JIT)
def _on_circle(O: Array, C: Array, N: Array, pts: Array, r_min: float, r_max: float,
               tol: float) -> Array:
    """Indices of the guesses whose circle through O passes within tol of every node with
    a radius in [r_min, r_max]; their normals in N are made perpendicular to the radius
    at O (in place)."""
    keep = np.empty(len(C), dtype=np.int64)
    nk = 0
    tol2 = tol * tol
    for k in range(len(C)):
        c = C[k]
        R0 = O - c
        r2 = _dot(R0, R0)
        n = N[k] - (_dot(N[k], R0) / r2) * R0
        n = n / math.sqrt(_dot(n, n))
        N[k] = n
        if not (r2 >= r_min * r_min and r2 <= r_max * r_max and np.isfinite(c).all()):
            continue
        r = math.sqrt(r2)
        good = True
        for i in range(len(pts)):  # scalars per node (as `line_distances`)
            x0, x1, x2 = pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2]
            h = x0 * n[0] + x1 * n[1] + x2 * n[2]
            w0, w1, w2 = x0 - h * n[0], x1 - h * n[1], x2 - h * n[2]
            dv = h * h + (math.sqrt(w0 * w0 + w1 * w1 + w2 * w2) - r) ** 2
            if not dv <= tol2:
                good = False
                break
        if good:
            keep[nk] = k
            nk += 1
    return keep[:nk]


@kernel(**_JIT)
def _arc_from(O: Array, centre: Array, normal: Array, pts: Array, t0: Array, has_t0: bool,
              tol: float, slack: float, max_sweep: float, out: Array) -> float:
    """The arc about `centre` from O over the nodes: writes normal, via, end, radius, sweep
    into `out` and returns its largest node deviation, or -1 if it does not qualify (nodes
    stepping back, sweep outside (0, max_sweep], start tangent outside the slack cone,
    a node off by more than tol)."""
    m = len(pts)
    r0 = O - centre
    radius = math.sqrt(_dot(r0, r0))
    V = np.empty((m + 1, 3))
    V[0] = r0
    n0, n1, n2 = normal[0], normal[1], normal[2]
    for i in range(m):  # scalars per node (as `line_distances`)
        x0, x1, x2 = pts[i, 0] - centre[0], pts[i, 1] - centre[1], pts[i, 2] - centre[2]
        h = x0 * n0 + x1 * n1 + x2 * n2
        V[i + 1, 0], V[i + 1, 1], V[i + 1, 2] = x0 - h * n0, x1 - h * n1, x2 - h * n2
    # unwrapped angle of each node about the normal: the sum of the signed steps
    phi = np.empty(m)
    acc = 0.0
    for i in range(m):
        a, b = V[i], V[i + 1]
        c0 = a[1] * b[2] - a[2] * b[1]  # a x b, as `_cross`
        c1 = a[2] * b[0] - a[0] * b[2]
        c2 = a[0] * b[1] - a[1] * b[0]
        acc += math.atan2(c0 * n0 + c1 * n1 + c2 * n2,
                          a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        phi[i] = acc
    if phi[m - 1] < 0.0:
        normal = -normal
        phi = -phi
    if has_t0:
        s0, s1, s2 = _unit3(normal[1] * r0[2] - normal[2] * r0[1],
                            normal[2] * r0[0] - normal[0] * r0[2],
                            normal[0] * r0[1] - normal[1] * r0[0])  # the start tangent
        if s0 * t0[0] + s1 * t0[1] + s2 * t0[2] < math.cos(slack) - 1e-12:
            return -1.0
    step_back = tol / radius
    for i in range(m - 1):
        if phi[i + 1] - phi[i] < -step_back:
            return -1.0
    sweep = phi[m - 1]
    if sweep > max_sweep or not sweep > 0.0:
        return -1.0
    put_on_arc(centre, r0, normal, sweep / 2.0, out, 3)  # via
    put_on_arc(centre, r0, normal, sweep, out, 6)  # end
    dev = arc_deviation(O, out[6:9], centre, radius, normal, sweep, pts)
    if not dev <= tol:
        return -1.0
    out[0:3] = normal
    out[9], out[10] = radius, sweep
    return dev


@kernel(**_JIT)
def fit_arc(O: Array, t0: Array, has_t0: bool, pts: Array, tol: float, slack: float,
            r_min: float, r_max: float, max_sweep: float, first_feasible: bool,
            ) -> tuple[bool, Array]:
    """(found, [centre, normal, via, end, radius, sweep, deviation]) of an arc from O over
    the nodes (m, 3).

    Guesses: with t0 the tangent ones, then (unless `first_feasible`) the free ones; without
    t0 only the free ones. With `first_feasible` the first guess that qualifies is returned
    (growth only asks whether one exists), else the one with the smallest deviation.
    """
    res = np.zeros(15)
    m = len(pts)
    X = pts - O
    if m < 2 or math.sqrt(_dot(X[m - 1], X[m - 1])) < 1e-9:
        return False, res
    C = np.empty((6, 3))
    N = np.empty((6, 3))
    k = 0
    if has_t0:
        k = _tangent_candidates(O, t0, X, C, N, k)
    if not has_t0 or not first_feasible:
        k = _free_candidates(O, X, C, N, k)
    if k == 0:
        return False, res
    Ck, Nk = C[:k], N[:k]
    out = np.empty(11)
    best = np.inf
    for j in _on_circle(O, Ck, Nk, pts, r_min, r_max, tol):
        dev = _arc_from(O, Ck[j], Nk[j], pts, t0, has_t0, tol, slack, max_sweep, out)
        if dev < 0.0 or not dev < best:
            continue
        best = dev
        res[0:3] = Ck[j]
        res[3:14] = out
        res[14] = dev
        if first_feasible:
            break
    return best < np.inf, res
