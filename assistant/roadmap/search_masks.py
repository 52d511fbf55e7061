"""The cells a roadmap query searches, in one compiled pass (numba).

Why: a query's masks - the escape boxes around start and goal, the free cells with them,
the roads (the base labels and the terminals' own) among those - take a dozen numpy
operations on the whole 32^3 grid (~35 us a query). `RoadmapPlanner.plan` documents what
each part means; this is the same set logic cell by cell.

Serves (the user-felt figure): the searchable cells of every query: 0.3 s in Python in the
thesis run.
"""

from __future__ import annotations

import numpy as np

from assistant.kernels.lazy import kernel

Array = np.ndarray


@kernel(cache=True)
def search_masks(lab: Array, road: int, s_lab: int, g_lab: int, free: Array, offers: Array,
                 cad: Array, n: int, sc: int, gc: int, r: int) -> tuple[Array, Array]:
    """(searchable, free') over the flat (n, n, n) grid.

    escape = the cells within Chebyshev radius r of the start leaf sc that offer positions,
    and those around the goal leaf gc that also belong to a CAD part (`cad`; none if r <= 0);
    free' = free | escape, with sc and gc free; searchable = (a road, lab == road, or a
    terminal's own region, s_lab / g_lab) & free', | escape.
    """
    m = lab.shape[0]
    escape = np.zeros(m, dtype=np.bool_)
    if r > 0:
        for cell, need_cad in ((sc, False), (gc, True)):
            i, j, k = cell // (n * n), (cell // n) % n, cell % n
            for a in range(max(0, i - r), min(n, i + r + 1)):
                for b in range(max(0, j - r), min(n, j + r + 1)):
                    for c in range(max(0, k - r), min(n, k + r + 1)):
                        f = (a * n + b) * n + c
                        if offers[f] and (cad[f] or not need_cad):
                            escape[f] = True
    free_q = np.empty(m, dtype=np.bool_)
    for f in range(m):
        free_q[f] = free[f] or escape[f]
    free_q[sc] = True
    free_q[gc] = True
    searchable = np.empty(m, dtype=np.bool_)
    for f in range(m):
        on_road = lab[f] == road or lab[f] == s_lab or lab[f] == g_lab
        searchable[f] = (on_road and free_q[f]) or escape[f]
    return searchable, free_q
