"""CAD obstacles -> occupied octree leaves, by exact FCL tests of each leaf's box (thesis §6.3).

The thesis rasterised DXF models with Java3D collision tests on a fixed raster; here every
leaf whose box overlaps the obstacle's axis-aligned bounds is tested against the obstacle's
real geometry (box, cylinder, capsule, sphere or BVH mesh) with FCL, so a slanted or thin part
marks exactly the leaves it touches. A touched leaf gets the CAD observation 1 (the cell is
"partly occupied"; the roadmap treats partly as occupied, the conservative choice).

The joint-position side of rasterisation (which table positions make any link hit CAD) is in
`chain_levels` and `cell_positions`; `WorldModel.build` runs both and times them.
"""

from __future__ import annotations

from collections.abc import Iterable

import fcl
import numpy as np

from assistant.collision.fcl_shapes import fcl_geometry, fcl_transform, world_aabb
from assistant.collision.reports import ObstacleView
from assistant.world.octree import OctreeGrid

Array = np.ndarray


def obstacle_cells(grid: OctreeGrid, obstacle: ObstacleView) -> Array:
    """Flat ids of the leaves whose box touches the obstacle (sorted, unique)."""
    leaf = grid.leaf
    box = fcl.CollisionObject(fcl.Box(leaf, leaf, leaf))
    req = fcl.CollisionRequest()
    T_base_object = np.asarray(obstacle.T_base_object, dtype=float)
    hits: list[Array] = []
    for shape in obstacle.collision:
        lo, hi = world_aabb(shape, T_base_object)
        i0 = np.clip(grid.ijk_of_points(lo[None])[0], 0, grid.n - 1)
        i1 = np.clip(grid.ijk_of_points(hi[None])[0], 0, grid.n - 1)
        if np.any(grid.ijk_of_points(hi[None])[0] < 0) or np.any(
                grid.ijk_of_points(lo[None])[0] >= grid.n):
            continue  # entirely outside the octree
        rng = [np.arange(i0[a], i1[a] + 1) for a in range(3)]
        ijk = np.stack(np.meshgrid(*rng, indexing="ij"), axis=-1).reshape(-1, 3)
        centres = grid.centres_of_ijk(ijk)
        obj = fcl.CollisionObject(fcl_geometry(shape),
                                  fcl_transform(T_base_object @ shape.T_link_shape))
        # An obstacle's margin counts as the obstacle: the leaf box grown by it (which holds
        # every point within the margin of the leaf) meets the shape.
        side = leaf + 2.0 * float(shape.margin)
        probe = box if shape.margin <= 0.0 else fcl.CollisionObject(fcl.Box(side, side, side))
        touched = np.zeros(len(ijk), dtype=bool)
        for n, c in enumerate(centres):
            probe.setTranslation(c)
            touched[n] = fcl.collide(probe, obj, req, fcl.CollisionResult()) > 0
        hits.append(grid.flat_of_ijk(ijk[touched]))
    if not hits:
        return np.zeros(0, dtype=np.int64)
    return np.unique(np.concatenate(hits))


def rasterise_obstacles(grid: OctreeGrid, obstacles: Iterable[ObstacleView],
                        ) -> dict[str, Array]:
    """{obstacle name: flat ids of its leaves} for every obstacle."""
    out: dict[str, Array] = {}
    for ob in obstacles:
        cells = obstacle_cells(grid, ob)
        out[ob.name] = np.union1d(out[ob.name], cells) if ob.name in out else cells
    return out
