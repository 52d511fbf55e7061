"""Forward kinematics of a serial chain of revolute/prismatic joints for batches of postures.

Two forms: float64 link frames and tip poses of up to `SMALL_BATCH` postures come from one
compiled loop (`chain_kernel`); big tip-pose batches and float32 use the numpy form below.

Why its own module: the reachability table and batch collision checks need the poses of
millions of configurations, and a Python loop over pinocchio calls manages ~0.6-0.9 M/s. Here every
matrix entry is a numpy vector over configurations ("component-major"), so one numpy call does
one scalar operation for a whole chunk of configurations. Three things make it fast:

* Constant folding. Entries that are exact 0 or +-1 (URDF origins are mostly multiples of 90
  deg, axes mostly +-x/y/z) are kept as Python floats, so products with them cost nothing;
  the base frame and the first joint are pure constants times cos/sin.
* Axis-aligned joints rotate two columns only (4 multiplies per row), no 3x3 product.
* `sincos`: numpy's float64 sin/cos are scalar code here (~10 ns per element each) and would
  be half of the time; a vectorised polynomial gives both for ~8 ns.

Chunks of 8-16 k configurations keep the working set in cache (`CHUNK_BYTES`). float64 results
agree with a plain 4x4 product to ~1e-11 (see `_SNAP`); ``dtype=np.float32`` (~1e-6) is about
4x faster, enough for binning a reachability table. The compiled loop multiplies the URDF's
own transforms (no snapping): the two forms agree to ~1e-10 m.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from functools import cached_property

import numpy as np

from assistant.robots.chain_kernel import PackedChain, chain_link_frames
from assistant.robots.model import BatchPoses

Array = np.ndarray
#: A matrix entry: a Python float (a constant, possibly exact 0/1) or a vector over configs.
Val = float | np.ndarray

#: Bytes per vector in a chunk (8192 float64 or 16384 float32 configurations). Vectors stay
#: below glibc's 128 KiB mmap threshold, so numpy's temporaries come from the heap instead of
#: fresh page-faulting mappings - above it every operation is ~4x slower - and a
#: chain's ~40 live vectors stay in cache.
CHUNK_BYTES = 65536
#: Tip poses of up to this many float64 postures come from the compiled loop (`chain_kernel`):
#: the planners' calls of one to a few hundred postures, where this module's ~500 numpy
#: operations per call cost ~0.5 ms of call overhead whatever the batch (the loop: ~2 us for one
#: posture, 0.25-0.35 us each for hundreds). Above it this module's tip-only form is faster
#: (0.36 us against 0.48 us a posture at 200 000: the loop writes every link's frame). Every
#: float64 `link_poses` uses the loop (3x faster than the numpy form at any size measured).
SMALL_BATCH = 8192


class JointKind(str, Enum):
    REVOLUTE = "revolute"
    PRISMATIC = "prismatic"


@dataclass(frozen=True)
class ChainJoint:
    """One actuated joint: its frame at q = 0 in the previous link frame, and its unit axis.

    The link moved by the joint has the joint frame as its frame, so that frame's origin lies
    on the axis (what `Robot.arm_radii` relies on).
    """

    name: str
    kind: JointKind
    T_prev_joint: Array
    axis: Array

    def motion(self, q: float) -> Array:
        """The joint's own motion as a 4x4 (rotation about / translation along its axis)."""
        T = np.eye(4)
        if self.kind == JointKind.PRISMATIC:
            T[:3, 3] = self.axis * q
        else:
            a = self.axis
            K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
            T[:3, :3] = np.eye(3) + np.sin(q) * K + (1.0 - np.cos(q)) * (K @ K)
        return T


@dataclass(frozen=True)
class BatchChain:
    """base -> joint 1 -> ... -> joint n -> tip, with constant transforms in between."""

    joints: tuple[ChainJoint, ...]
    T_last_tip: Array = field(default_factory=lambda: np.eye(4))

    @property
    def dof(self) -> int:
        return len(self.joints)

    # ------------------------------------------------------------------ reference (one q)
    def link_frames(self, q: Array) -> Array:
        """T_base_link of base + every moving link for one configuration, (n+1, 4, 4)."""
        out = np.empty((self.dof + 1, 4, 4))
        T = np.eye(4)
        out[0] = T
        for i, j in enumerate(self.joints):
            T = T @ j.T_prev_joint @ j.motion(float(q[i]))
            out[i + 1] = T
        return out

    def tip_frame(self, q: Array) -> Array:
        return self.link_frames(q)[-1] @ self.T_last_tip

    @cached_property
    def packed(self) -> PackedChain:
        """The chain as the compiled loop reads it (`chain_kernel`)."""
        return PackedChain(np.array([j.T_prev_joint for j in self.joints], dtype=float),
                           np.array([j.axis for j in self.joints], dtype=float),
                           np.array([j.kind == JointKind.PRISMATIC for j in self.joints]))

    def _compiled_frames(self, Q: Array) -> Array:
        """Link frames of a float64 batch by the compiled loop, (N, n+1, 4, 4)."""
        Q = np.ascontiguousarray(Q, dtype=np.float64)
        out = np.empty((len(Q), self.dof + 1, 4, 4))
        pk = self.packed
        chain_link_frames(Q, pk.M, pk.axes, pk.prismatic, out)
        return out

    def _compiled(self, Q: Array, dtype: type, most: float = np.inf) -> bool:
        Q = np.asarray(Q)
        return (dtype == np.float64 and Q.ndim == 2 and Q.shape[1] == self.dof
                and len(Q) <= most)

    # ------------------------------------------------------------------ batches
    def tip_poses(self, Q: Array, *, dtype: type = np.float64,
                  chunk: int | None = None) -> BatchPoses:
        """Tip poses of Q (N, n): positions (N, 3), rotations (N, 3, 3) (strided views)."""
        if self._compiled(Q, dtype, SMALL_BATCH):
            T = self._compiled_frames(Q)[:, -1] @ self.T_last_tip
            return BatchPoses(T[:, :3, 3], T[:, :3, :3])
        QT = self._check(Q, dtype)
        n = QT.shape[1]
        chunk = chunk or CHUNK_BYTES // QT.itemsize
        out = np.empty((4, 3, n), dtype=dtype)  # rows 0-2: rotation rows; row 3: position
        tip_R = _const_R(self.T_last_tip)
        tip_p = [float(v) for v in self.T_last_tip[:3, 3]]
        for a in range(0, n, chunk):
            b = min(n, a + chunk)
            frames = self._frames(QT[:, a:b], keep_all=False)
            R, p = frames[-1]
            Rt, pt = _compose(R, p, tip_R, tip_p)
            for i in range(3):
                for k in range(3):
                    out[i, k, a:b] = Rt[i][k]
                out[3, i, a:b] = pt[i]
        return BatchPoses(out[3].T, out[:3].transpose(2, 0, 1))

    def link_poses(self, Q: Array, *, dtype: type = np.float64,
                   chunk: int | None = None) -> Array:
        """T_base_link for base + every moving link of Q (N, n): shape (N, n+1, 4, 4)."""
        if self._compiled(Q, dtype):
            return self._compiled_frames(Q)
        QT = self._check(Q, dtype)
        n = QT.shape[1]
        chunk = chunk or CHUNK_BYTES // QT.itemsize
        out = np.empty((n, self.dof + 1, 4, 4), dtype=dtype)
        # Fill a component-major chunk buffer, then one transposing copy per chunk.
        buf = np.zeros((self.dof + 1, 4, 4, min(n, chunk)), dtype=dtype)
        buf[:, 3, 3] = 1.0
        for a in range(0, n, chunk):
            b = min(n, a + chunk)
            for li, (R, p) in enumerate(self._frames(QT[:, a:b], keep_all=True)):
                for i in range(3):
                    for k in range(3):
                        buf[li, i, k, : b - a] = R[i][k]
                    buf[li, i, 3, : b - a] = p[i]
            out[a:b] = buf[..., : b - a].transpose(3, 0, 1, 2)
        return out

    def _check(self, Q: Array, dtype: type) -> Array:
        Q = np.asarray(Q)
        if Q.ndim != 2 or Q.shape[1] != self.dof:
            raise ValueError(f"expected configurations of shape (N, {self.dof}), got {Q.shape}")
        return np.ascontiguousarray(Q.T, dtype=dtype)

    def _frames(self, QT: Array, *, keep_all: bool) -> list[tuple[list[list[Val]], list[Val]]]:
        """(R, p) of base and each link (or only the last link) for a chunk of configs."""
        R: list[list[Val]] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        p: list[Val] = [0.0, 0.0, 0.0]
        frames = [(R, p)] if keep_all else []
        for i, j in enumerate(self.joints):
            # Joint frame at q = 0: constant transform of the previous link frame.
            M, p = _compose(R, p, _const_R(j.T_prev_joint),
                            [float(v) for v in j.T_prev_joint[:3, 3]])
            ax = _aligned_axis(j.axis)
            if j.kind == JointKind.PRISMATIC:
                d = QT[i]
                u = _matvec(M, [float(v) for v in j.axis])
                p = [_add(p[r], _mul(u[r], d)) for r in range(3)]
                R = M
            elif ax is not None:
                a, sign = ax
                s, c = sincos(QT[i])  # per row: temporaries stay small (see DEFAULT_CHUNK)
                if sign < 0:
                    s = np.negative(s, out=s)
                b, e = (a + 1) % 3, (a + 2) % 3  # (M Rot_a)[:, b] = c M_b + s M_e, etc.
                R = [[None, None, None] for _ in range(3)]  # type: ignore[list-item]
                for r in range(3):
                    R[r][a] = M[r][a]
                    R[r][b] = _add(_mul(c, M[r][b]), _mul(s, M[r][e]))
                    R[r][e] = _sub(_mul(c, M[r][e]), _mul(s, M[r][b]))
            else:
                # General axis: Rot_axis(q) = A Rz(q) A^T with A's z column = axis.
                A = _frame_with_z(j.axis)
                MA = _matmul(M, _const_R(A))
                Rz = [[None, None, None] for _ in range(3)]  # type: ignore[list-item]
                s, c = sincos(QT[i])
                for r in range(3):
                    Rz[r][2] = MA[r][2]
                    Rz[r][0] = _add(_mul(c, MA[r][0]), _mul(s, MA[r][1]))
                    Rz[r][1] = _sub(_mul(c, MA[r][1]), _mul(s, MA[r][0]))
                R = _matmul(Rz, _const_R(A.T))
            if keep_all or i == self.dof - 1:
                frames.append((R, p))
        return frames


# ---------------------------------------------------------------------- sin/cos
# fdlibm's kernels (|r| <= pi/4, < 1 ulp) after a Cody-Waite reduction by pi/2 in three parts.
_PIO2_1 = 1.57079632673412561417e00
_PIO2_2 = 6.07710050630396597660e-11
_PIO2_3 = 2.02226624879595063154e-21
_S = (-1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04,
      2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10)
_C = (4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05,
      -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11)
_SIGN_SIN = np.array([1.0, 1.0, -1.0, -1.0])
_SIGN_COS = np.array([1.0, -1.0, -1.0, 1.0])
#: Beyond this |angle| the three-part reduction loses digits; numpy's own sin/cos take over.
_SINCOS_MAX_ARG = 1.0e5


def sincos(x: Array) -> tuple[Array, Array]:
    """(sin x, cos x) to ~1e-16 absolute, about twice as fast as np.sin + np.cos in float64.

    numpy's float64 sin/cos are not SIMD-vectorised on most builds (~10-20 ns per element),
    which made them over half of the batch FK time; this is polynomial arithmetic on whole
    arrays instead. float32 input (SIMD in numpy) and huge or non-finite angles go to numpy.
    """
    x = np.asarray(x)
    if x.dtype != np.float64 or x.size == 0 or not (np.abs(x).max() < _SINCOS_MAX_ARG):
        return np.sin(x), np.cos(x)
    k = np.rint(x * (2.0 / np.pi))
    r = k * -_PIO2_1
    r += x
    t = k * _PIO2_2
    r -= t
    t = np.multiply(k, _PIO2_3, out=t)
    r -= t
    z = r * r
    s = _S[5] * z
    for coef in _S[4::-1]:
        s += coef
        s *= z
    s *= r
    s += r
    c = _C[5] * z
    for coef in _C[4::-1]:
        c += coef
        c *= z
    c *= z
    z *= 0.5  # cos r = (1 - z/2) + z^2 P(z), summed in fdlibm's order to keep the last bit
    w = 1.0 - z
    t = np.subtract(1.0, w, out=t)
    t -= z
    c += t
    c += w
    n = k.astype(np.int64)
    n &= 3
    odd = (n & 1).astype(bool)
    sin_x = np.where(odd, c, s)
    cos_x = np.where(odd, s, c)
    sin_x *= _SIGN_SIN.take(n)
    cos_x *= _SIGN_COS.take(n)
    return sin_x, cos_x


# ---------------------------------------------------------------------- scalar/vector algebra
def _is_const(v: Val) -> bool:
    return isinstance(v, float)


def _mul(a: Val, b: Val) -> Val:
    if _is_const(a):
        if a == 0.0:
            return 0.0
        if a == 1.0:
            return b
        if a == -1.0:
            return -b
    if _is_const(b):
        if b == 0.0:
            return 0.0
        if b == 1.0:
            return a
        if b == -1.0:
            return -a
    return a * b


def _add(a: Val, b: Val) -> Val:
    if _is_const(a) and a == 0.0:
        return b
    if _is_const(b) and b == 0.0:
        return a
    return a + b


def _sub(a: Val, b: Val) -> Val:
    if _is_const(b) and b == 0.0:
        return a
    if _is_const(a) and a == 0.0:
        return -b
    return a - b


#: Constants this close to 0 or +-1 are taken as exact, so products with them fold away. URDFs
#: write pi/2 with ~11 digits (cos = 5e-12); the deviation this causes is < 1e-10 m.
_SNAP = 1e-11


def _clean(x: float) -> float:
    """Snap rounding noise of rpy-built rotations to exact 0/+-1 (see `_SNAP`)."""
    for t in (0.0, 1.0, -1.0):
        if abs(x - t) < _SNAP:
            return t
    return float(x)


def _const_R(T: Array) -> list[list[Val]]:
    return [[_clean(T[i, k]) for k in range(3)] for i in range(3)]


def _matmul(A: list[list[Val]], B: list[list[Val]]) -> list[list[Val]]:
    out: list[list[Val]] = []
    for i in range(3):
        row: list[Val] = []
        for k in range(3):
            acc: Val = 0.0
            for m in range(3):
                acc = _add(acc, _mul(A[i][m], B[m][k]))
            row.append(acc)
        out.append(row)
    return out


def _matvec(A: list[list[Val]], v: list[Val]) -> list[Val]:
    out: list[Val] = []
    for i in range(3):
        acc: Val = 0.0
        for m in range(3):
            acc = _add(acc, _mul(A[i][m], v[m]))
        out.append(acc)
    return out


def _compose(R: list[list[Val]], p: list[Val], R2: list[list[Val]],
             p2: list[Val]) -> tuple[list[list[Val]], list[Val]]:
    """(R, p) o (R2, p2) = (R R2, p + R p2)."""
    Rp2 = _matvec(R, [_clean(v) if _is_const(v) else v for v in p2])
    return _matmul(R, R2), [_add(p[i], Rp2[i]) for i in range(3)]


def _aligned_axis(axis: Array) -> tuple[int, int] | None:
    """(index, sign) if the axis is +-x, +-y or +-z, else None."""
    for k in range(3):
        if abs(abs(axis[k]) - 1.0) < 1e-15 and abs(axis[(k + 1) % 3]) < 1e-15 \
                and abs(axis[(k + 2) % 3]) < 1e-15:
            return k, (1 if axis[k] > 0 else -1)
    return None


def _frame_with_z(axis: Array) -> Array:
    z = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(helper, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return np.column_stack([x, y, z])
