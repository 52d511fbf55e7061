"""Shortcutting a searched joint path: the fewest straight joint moves along it that are valid.

When no smoothed (line/arc) trajectory verifies, a transfer falls back to joint moves along
the roadmap's path. That path steps from leaf to leaf, a dozen or more vertices; a program
of a dozen joint moves is slow to run and hard to read. From each kept vertex the farthest
later vertex that one straight joint move reaches validly is taken next (greedy, as the
shortcutting of sampling planners does), so the fallback is usually a few moves. The
moves are checked exactly by the caller's `valid_move`; consecutive vertices are the
search's own edges, already checked, so the result always exists.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

Array = np.ndarray


def shortcut_joint_path(path: Sequence[Array], valid_move: Callable[[Array, Array], bool],
                        ) -> list[Array]:
    """Vertices of `path` to move through in straight joint moves (first and last kept).

    From each kept vertex the farthest later vertex with `valid_move(kept, later)` is next;
    if no later vertex but the next one passes, the next one is taken anyway (it is an edge
    of the searched path). At most n (n - 1) / 2 checks on n vertices, usually a handful.
    """
    P = [np.asarray(q, dtype=float) for q in path]
    if len(P) < 3:
        return P
    out = [P[0]]
    i = 0
    while i < len(P) - 1:
        j = next((j for j in range(len(P) - 1, i + 1, -1) if valid_move(P[i], P[j])), i + 1)
        out.append(P[j])
        i = j
    return out
