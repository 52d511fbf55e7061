"""Ball paths for synthetic scenes: functions t -> world position (metres).

Smooth minimum-jerk moves between waypoints imitate a hand bringing the pointer to a spot and
holding it there; a Lissajous figure gives continuous motion for tracking tests.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np


def _minimum_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return s**3 * (10 - 15 * s + 6 * s * s)


def waypoints(points: Sequence[np.ndarray], move_s: Sequence[float] | float,
              hold_s: Sequence[float] | float = 0.0,
              tremor: float = 0.0, seed: int = 0) -> Callable[[float], np.ndarray]:
    """Hold at points[0] for hold_s[0], minimum-jerk move to points[1] in move_s[0], hold, ...

    `tremor` (metres, standard deviation) adds a slow hand wobble (sum of a few low-frequency
    sines with random phases), as a person holding a 50 cm stick would produce.
    """
    P = [np.asarray(p, dtype=float) for p in points]
    n = len(P)
    if n == 0:
        raise ValueError("need at least one waypoint")
    moves = [float(move_s)] * (n - 1) if np.isscalar(move_s) else [float(m) for m in move_s]
    holds = [float(hold_s)] * n if np.isscalar(hold_s) else [float(h) for h in hold_s]
    if len(moves) != n - 1 or len(holds) != n:
        raise ValueError("need one move time per segment and one hold time per waypoint")
    rng = np.random.default_rng(seed)
    freqs = rng.uniform(0.5, 3.0, size=(3, 3))
    phases = rng.uniform(0, 2 * np.pi, size=(3, 3))

    def path(t: float) -> np.ndarray:
        tt = t
        p = P[-1]
        for i in range(n):
            if tt < holds[i]:
                p = P[i]
                break
            tt -= holds[i]
            if i == n - 1:
                break
            if tt < moves[i]:
                p = P[i] + (P[i + 1] - P[i]) * _minimum_jerk(tt / moves[i])
                break
            tt -= moves[i]
        if tremor > 0:
            wobble = np.sin(2 * np.pi * freqs * t + phases).sum(axis=1) / np.sqrt(1.5)
            p = p + tremor * wobble
        return p

    return path


def lissajous(center: np.ndarray, amplitude: np.ndarray,
              freq_hz: np.ndarray = (0.31, 0.23, 0.17),
              phase: np.ndarray = (0.0, 1.1, 2.3)) -> Callable[[float], np.ndarray]:
    """Continuous smooth motion around `center` (per-axis amplitude, frequency and phase)."""
    c = np.asarray(center, dtype=float)
    a = np.asarray(amplitude, dtype=float)
    f = np.asarray(freq_hz, dtype=float)
    ph = np.asarray(phase, dtype=float)
    return lambda t: c + a * np.sin(2 * np.pi * f * t + ph)


def fixed(point: np.ndarray) -> Callable[[float], np.ndarray]:
    p = np.asarray(point, dtype=float)
    return lambda t: p
