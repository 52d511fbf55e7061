"""Shortcutting a searched joint path into the fewest valid straight joint moves."""

from __future__ import annotations

import numpy as np

from assistant.planning.shortcut import shortcut_joint_path


def _crosses_wall(a, b) -> bool:
    """The segment a-b (2-D) crosses the wall x = 0.5, 0 <= y <= 0.8."""
    if (a[0] - 0.5) * (b[0] - 0.5) > 0 or a[0] == b[0]:
        return False
    y = a[1] + (0.5 - a[0]) / (b[0] - a[0]) * (b[1] - a[1])
    return 0.0 <= y <= 0.8


def test_a_path_around_a_wall_keeps_only_the_corner():
    # Up the left side, over the wall's end, down the right side: 9 vertices.
    path = [np.array(p) for p in [(0.2, 0.0), (0.2, 0.3), (0.2, 0.6), (0.3, 0.9), (0.5, 0.95),
                                  (0.7, 0.9), (0.8, 0.6), (0.8, 0.3), (0.8, 0.0)]]
    checks = []

    def valid(a, b):
        checks.append((tuple(a), tuple(b)))
        return not _crosses_wall(a, b)

    short = shortcut_joint_path(path, valid)
    assert np.array_equal(short[0], path[0]) and np.array_equal(short[-1], path[-1])
    assert all(valid(a, b) for a, b in zip(short[:-1], short[1:], strict=True))
    assert len(short) == 3  # start -> over the wall's end -> goal
    assert np.array_equal(short[1], path[4])
    assert len(checks) < 9 * 8 / 2


def test_nothing_valid_but_the_searched_edges_keeps_the_path():
    path = [np.array([float(i), 0.0]) for i in range(6)]
    short = shortcut_joint_path(path, lambda a, b: False)
    assert [p.tolist() for p in short] == [p.tolist() for p in path]
    assert len(shortcut_joint_path(path[:2], lambda a, b: True)) == 2
    assert len(shortcut_joint_path(path, lambda a, b: True)) == 2
