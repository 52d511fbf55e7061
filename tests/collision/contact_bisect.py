"""Postures a hair from contact, for tests that compare fast checks with brute-force FCL."""

from __future__ import annotations

import numpy as np


def bisect_to_contact(checker, free: np.ndarray, hit: np.ndarray, rounds: int = 30,
                      ) -> np.ndarray:
    """Rows of `free` and `hit` (free / colliding postures, paired) bisected `rounds` times
    by brute-force FCL (`in_collision_naive`): 30 rounds leave each pair ~1e-9 rad apart,
    far above last-bit differences. Returns the free ends, then the colliding ones."""
    for _ in range(rounds):
        mid = 0.5 * (free + hit)
        m = np.array([checker.in_collision_naive(q) for q in mid])
        hit = np.where(m[:, None], mid, hit)
        free = np.where(m[:, None], free, mid)
    return np.concatenate([free, hit])
