"""The leaves an arm's hand filled where a collision indication stopped it (6- and 7-axis).

Why: an indication records the stopped posture's box (`indications`: 1.5 grid steps in every
joint) and marks the leaves the arm filled as occupied, which keeps the TCP's roads away.
On a 7-axis arm that is not enough for the final, taut plan: it reaches the same place with
another posture outside every recorded box, and a wrist link that is not the TCP touches the
same unknown obstacle again (a Panda in a cell with a hidden box: a new contact on link 6 or
7 in each of four validation runs). The contacts of a transfer are nearly always on the hand
- the links near the TCP lead the motion. So on sampled stores the verifier also refuses
postures whose hand (the collision shapes' points within `reach` of the TCP) lies in a leaf
the hand filled at a recorded collision. A query whose start or goal has its hand in such
leaves is exempt from that collision's leaves (it must be able to leave and arrive); the
posture box still applies to it.

Points per shape: capsule and cylinder axes every half leaf with four points on the
surface around each, box corners and centre, sphere centre and six surface points, mesh
vertices thinned to at most `mesh_points` (evenly over the vertex list), and the TCP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from assistant.robots.model import CollisionShape, Robot, ShapeKind
from assistant.world.hand_kernel import hand_blocked
from assistant.world.octree import OctreeGrid

Array = np.ndarray


@dataclass(frozen=True)
class HandConfig:
    """Ours: the Panda's flange-to-fingertip is ~0.2 m, a UR's wrist 3 to nozzle ~0.2 m."""

    #: Points of the arm within this distance of the TCP make up the hand (m).
    reach: float = 0.25
    #: At most this many vertices of a mesh shape.
    mesh_points: int = 64


def _shape_points(s: CollisionShape, spacing: float, mesh_points: int) -> Array:
    """Points (shape's link frame) covering the shape at about `spacing`."""
    if s.kind in (ShapeKind.CAPSULE, ShapeKind.CYLINDER):
        r, h = float(s.size[0]), float(s.size[1]) / 2.0
        n = max(2, int(np.ceil(2 * h / spacing)) + 1)
        z = np.linspace(-h, h, n)
        ring = [(0.0, 0.0), (r, 0.0), (-r, 0.0), (0.0, r), (0.0, -r)]
        local = np.array([[x, y, zz] for zz in z for x, y in ring])
    elif s.kind == ShapeKind.BOX:
        e = np.asarray(s.size, dtype=float) / 2.0
        local = np.array([[0.0, 0.0, 0.0]] + [[x, y, z] for x in (-e[0], e[0])
                                              for y in (-e[1], e[1]) for z in (-e[2], e[2])])
    elif s.kind == ShapeKind.SPHERE:
        r = float(s.size[0])
        local = np.vstack([np.zeros((1, 3)), r * np.eye(3), -r * np.eye(3)])
    elif s.kind == ShapeKind.MESH and s.mesh is not None:
        V = np.asarray(s.mesh.vertices, dtype=float).reshape(-1, 3)
        if len(V) > mesh_points:
            V = V[np.linspace(0, len(V) - 1, mesh_points).astype(np.int64)]
        local = V
    else:
        local = np.zeros((1, 3))
    T = s.T_link_shape
    return local @ T[:3, :3].T + T[:3, 3]


class HandCells:
    """Leaves the hand fills at postures, for one robot and octree grid."""

    def __init__(self, robot: Robot, grid: OctreeGrid, first_link: int,
                 config: HandConfig | None = None):
        self.robot, self.grid = robot, grid
        self.config = config or HandConfig()
        pts, link = [], []
        for k in range(first_link, len(robot.links)):
            for s in robot.links[k].collision:
                P = _shape_points(s, grid.leaf / 2.0, self.config.mesh_points)
                pts.append(P)
                link.append(np.full(len(P), k))
        self._local = np.ascontiguousarray(np.concatenate(pts) if pts else np.zeros((0, 3)),
                                           dtype=float)
        self._link = np.concatenate(link).astype(np.int64) if link else np.zeros(0, np.int64)
        self._by_link = [(int(k), np.flatnonzero(self._link == k)) for k in np.unique(self._link)]

    def _points(self, Q: Array, tcp: Array | None = None) -> tuple[Array, Array, Array]:
        """For rows Q: the flat leaf of every hand point (N, M) (-1 outside the grid), which
        of them are the hand (within `reach` of the TCP) (N, M), and the TCP's leaf (N,).
        `tcp`: the rows' TCP positions if known."""
        frames = self.robot.batch_link_poses(Q)  # (N, links, 4, 4)
        P = np.empty((len(Q), len(self._local), 3))
        for k, idx in self._by_link:  # a few links: one product each, no (N, M, 4, 4) copy
            F = frames[:, k]
            P[:, idx] = np.matmul(self._local[idx], F[:, :3, :3].transpose(0, 2, 1)) + \
                F[:, None, :3, 3]
        if tcp is None:
            tcp = np.asarray(self.robot.batch_fk(Q).positions, dtype=float)  # (N, 3)
        d = P - tcp[:, None, :]
        near = np.einsum("nmi,nmi->nm", d, d) <= self.config.reach ** 2
        flat = self.grid.flat_of_points(P.reshape(-1, 3)).reshape(len(Q), -1)
        return flat, near, self.grid.flat_of_points(tcp)

    def cells(self, Q: Array) -> list[Array]:
        """Per row of Q, the flat leaves (unique, inside the grid) its hand fills."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        if not len(Q):
            return []
        flat, near, tcp_flat = self._points(Q)
        out = []
        for i in range(len(Q)):
            f = np.append(flat[i][near[i]], tcp_flat[i])
            out.append(np.unique(f[f >= 0]))
        return out

    def blocked(self, Q: Array, mask: Array) -> Array:
        """Bool per row of Q: its hand fills a leaf set in `mask` (flat bool over the grid).

        Only rows whose TCP comes within reach of a set leaf pose the hand's points: a hand
        point lies within `reach` of the TCP, and a point in a leaf within half the leaf's
        diagonal of its centre, so a TCP farther than their sum (plus 1 um for rounding)
        from every set leaf's centre fills none of them. The answer is the same; a batch far
        from the recorded hand skips the arm's link poses (about two thirds of its cost).
        Few do in a re-plan: on the Panda sample 19 of the joint RRT's 299 hand tests (it
        searches next to the hand). The rows that do are tested in one compiled pass
        (`hand_kernel`), each up to its first hand point in a set leaf."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        out = np.zeros(len(Q), dtype=bool)
        if not len(Q):
            return out
        tcp = np.asarray(self.robot.batch_fk(Q).positions, dtype=float)  # (N, 3)
        g = self.grid
        centres = g.centres_of_ijk(g.ijk_of_flat(np.flatnonzero(mask)))
        within = self.config.reach + 0.5 * np.sqrt(3.0) * g.leaf + 1e-6
        d = tcp[:, None, :] - centres[None]
        rows = (np.einsum("nki,nki->nk", d, d) <= within ** 2).any(axis=1)
        if not rows.any():
            return out
        sub = np.flatnonzero(rows)
        hits = np.zeros(len(sub), dtype=bool)
        hand_blocked(self.robot.batch_link_poses(Q[sub]), self._link, self._local,
                     np.ascontiguousarray(tcp[sub]), float(self.config.reach) ** 2,
                     np.asarray(g.origin, dtype=float), float(g.leaf), int(g.n),
                     np.ascontiguousarray(mask, dtype=bool), hits)
        out[sub] = hits
        return out
