"""Neighbourhood reductions on dense 3-D grids (26-neighbourhood), vectorised with numpy.

Shared by the brushfire (`voronoi`) and the source labelling (`sources`). Cells outside the
array count as absent: they contribute the reduction's neutral value.
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy import ndimage

Array = np.ndarray

#: The 26 neighbour offsets (dx, dy, dz), in a fixed order.
OFFSETS26: tuple[tuple[int, int, int], ...] = tuple(
    o for o in itertools.product((-1, 0, 1), repeat=3) if o != (0, 0, 0))


def _shifted(padded: Array, o: tuple[int, int, int], shape: tuple[int, ...]) -> Array:
    """View of the neighbour at offset o of every cell (padded by 1 on every side)."""
    return padded[1 + o[0]:1 + o[0] + shape[0], 1 + o[1]:1 + o[1] + shape[1],
                  1 + o[2]:1 + o[2] + shape[2]]


def neighbour_any(mask: Array) -> Array:
    """True where some 26-neighbour is True."""
    p = np.pad(mask, 1, constant_values=False)
    out = np.zeros(mask.shape, dtype=bool)
    for o in OFFSETS26:
        out |= _shifted(p, o, mask.shape)
    return out


def neighbour_min(values: Array, fill: int) -> Array:
    p = np.pad(values, 1, constant_values=fill)
    out = np.full(values.shape, fill, dtype=values.dtype)
    for o in OFFSETS26:
        np.minimum(out, _shifted(p, o, values.shape), out=out)
    return out


def neighbour_max(values: Array, fill: int) -> Array:
    p = np.pad(values, 1, constant_values=fill)
    out = np.full(values.shape, fill, dtype=values.dtype)
    for o in OFFSETS26:
        np.maximum(out, _shifted(p, o, values.shape), out=out)
    return out


def dilate(mask: Array, radius: int) -> Array:
    """Cells within Chebyshev distance `radius` of a True cell.

    Filtered on the True cells' bounding box grown by `radius` only: nothing outside it is
    that near, and the Voronoi update dilates small regions of a large grid several times
    per query (the whole 32^3 grid costs ~0.1 ms a call)."""
    if radius <= 0:
        return mask.copy()
    out = np.zeros(mask.shape, dtype=bool)
    sl = bbox(mask, margin=radius)
    if sl is not None:
        out[sl] = ndimage.maximum_filter(mask[sl].astype(np.uint8), size=2 * radius + 1,
                                         mode="constant", cval=0).astype(bool)
    return out


def components26(mask: Array) -> tuple[Array, int]:
    """Connected components (26-connectivity), labels 1..n, 0 outside the mask."""
    lab, n = ndimage.label(mask, structure=np.ones((3, 3, 3), dtype=bool))
    return lab.astype(np.int32), int(n)


def connected26(mask: Array, a: int, b: int) -> bool:
    """Whether flat cells a and b of the 3-D mask (both True) are in one component
    (26-connectivity): the labels of `components26` (~0.3 ms on the 32^3 grid, asked only
    when the roads hold no path)."""
    lab, _ = components26(mask)
    flat = lab.reshape(-1)
    return bool(flat[a] != 0 and flat[a] == flat[b])


def bbox(mask: Array, margin: int = 0) -> tuple[slice, slice, slice] | None:
    """Slices of the bounding box of the True cells, grown by `margin` (clipped)."""
    idx = np.nonzero(mask)
    if not len(idx[0]):
        return None
    out = []
    for a in range(3):
        lo = max(0, int(idx[a].min()) - margin)
        hi = min(mask.shape[a], int(idx[a].max()) + 1 + margin)
        out.append(slice(lo, hi))
    return out[0], out[1], out[2]
