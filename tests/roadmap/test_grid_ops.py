"""Dilation on the bounding box equals the whole-grid filter it replaced; the pair
connectivity search answers as the component labels."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from assistant.roadmap.grid_ops import components26, connected26, dilate


def _whole_grid(mask: np.ndarray, radius: int) -> np.ndarray:
    return ndimage.maximum_filter(mask.astype(np.uint8), size=2 * radius + 1, mode="constant",
                                  cval=0).astype(bool)


def test_dilate_matches_the_whole_grid_filter():
    rng = np.random.default_rng(3)
    for shape in [(16, 12, 9), (5, 5, 5), (1, 8, 8)]:
        for n_true in (1, 2, 5, 40):
            for radius in (1, 2, 3, 4):
                mask = np.zeros(shape, dtype=bool)
                mask[tuple(rng.integers(0, s, n_true) for s in shape)] = True
                assert np.array_equal(dilate(mask, radius), _whole_grid(mask, radius))
    # On faces and corners: the filter's outside (zeros) is the grid's outside.
    mask = np.zeros((10, 10, 10), dtype=bool)
    mask[0, 0, 0] = mask[9, 5, 9] = True
    for radius in (1, 3, 12):
        assert np.array_equal(dilate(mask, radius), _whole_grid(mask, radius))


def test_dilate_of_nothing_and_radius_zero():
    empty = np.zeros((4, 4, 4), dtype=bool)
    assert not dilate(empty, 2).any()
    mask = empty.copy()
    mask[1, 2, 3] = True
    out = dilate(mask, 0)
    assert np.array_equal(out, mask) and out is not mask


def test_connected_cells_are_joined_through_faces_edges_or_corners():
    """`connected26`: two cells joined by a chain that touches only at corners are one
    region (26-connectivity, the arm's TCP can pass diagonally); a one-cell gap parts
    them; a cell outside the mask is connected to nothing."""
    mask = np.zeros((6, 6, 6), dtype=bool)
    for k in range(5):  # a staircase through corners only
        mask[k, k, k] = True
    flat = np.ravel_multi_index
    a, b = flat((0, 0, 0), mask.shape), flat((4, 4, 4), mask.shape)
    assert connected26(mask, a, b)
    mask[2, 2, 2] = False  # a gap
    assert not connected26(mask, a, b)
    assert not connected26(mask, flat((2, 2, 2), mask.shape), a)
    lab, n = components26(mask)
    assert n == 2 and lab[0, 0, 0] != lab[4, 4, 4]
