"""The one-via joint move's choice (`joint_moves.choose_via`): the quickest via that keeps
the clearance target, else the clearest - the rule of scoring every via - with vias scored
quickest first and the scoring stopped at the first that keeps the target."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.planning.joint_moves import choose_via


def _every_via(cost, scores, target):
    ok = [i for i, c in enumerate(scores) if c >= target]
    k = min(ok, key=lambda i: cost[i]) if ok else int(np.argmax(scores))
    return k, scores[k]


@pytest.mark.parametrize("seed", range(40))
def test_the_choice_is_that_of_scoring_every_via(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    cost = rng.integers(0, 6, n).astype(float).tolist()  # ties in time
    scores = rng.choice([-1.0, 0.004, 0.008, 0.012, 0.02], n).tolist()  # ties in clearance
    for target in (0.01, 0.05):  # 0.05: no via keeps it, the clearest is chosen
        asked: list[int] = []

        def score(i, asked=asked):
            asked.append(i)
            return scores[i]

        assert choose_via(cost, score, target) == _every_via(cost, scores, target)
        assert len(asked) == len(set(asked))  # each via scored once at most
        if any(s >= target for s in scores):  # stopped at the first keeping the target
            assert scores[asked[-1]] >= target
            assert all(scores[i] < target for i in asked[:-1])


@pytest.mark.parametrize(("own_mm", "moves_mm", "joint_s", "want"), [
    (5.0, 12.0, 3.0, "joint"),    # only the joint moves keep 10 mm: chosen though slower
    (5.0, 8.0, 3.0, "smooth"),    # neither keeps 10 mm: the quicker one
    (15.0, 20.0, 3.0, "smooth"),  # both keep it: the quicker one
    (15.0, 20.0, 1.0, "joint"),
])
def test_the_required_clearance_comes_before_the_cycle_time(monkeypatch, own_mm, moves_mm,
                                                            joint_s, want):
    """`prefer_joint_moves`: the smoothed path (2 s) or its joint moves (`joint_s`) by the
    predicted cycle time - unless only the joint moves keep the required 10 mm."""
    from types import SimpleNamespace

    from assistant.planning import joint_moves as jm

    def asm(motions, clearance_mm):
        return SimpleNamespace(trajectory=SimpleNamespace(motions=motions),
                               report=SimpleNamespace(min_clearance=clearance_mm / 1000))

    smooth, moves = asm(["l1", "a1", "l2"], own_mm), asm(["j1", "j2"], moves_mm)
    monkeypatch.setattr(jm, "fewest_joint_moves", lambda *a, **k: jm.JointMoveResult(
        moves, 1, clearance=moves_mm / 1000))
    monkeypatch.setattr(jm, "_cycle_seconds",
                        lambda robot, traj: joint_s if traj is moves.trajectory else 2.0)
    got, _ = jm.prefer_joint_moves(None, smooth, [], None, exempt=frozenset(),
                                   clearance=0.01, step=0.01, label="T")
    assert got is (moves if want == "joint" else smooth)


def test_move_checks_are_cached_and_bounded():
    """Each distinct move is checked once; past the budget a new move scores -1 (never
    chosen) while those checked keep their scores, so the search ends with its best."""
    from types import SimpleNamespace

    from assistant.planning.joint_moves import _Moves

    calls = []

    class Verifier:
        def check_motion(self, a, b, exempt):
            calls.append((a[0], b[0]))
            return SimpleNamespace(valid=b[0] != 9.0)

        def min_clearance_along(self, qs, max_step):
            return 0.001 * qs[1][0]

    moves = _Moves(Verifier(), frozenset(), 0.02, budget=3)
    q = [np.array([float(i), 0.0]) for i in range(12)]
    assert moves.clearance(q[0], q[5]) == pytest.approx(0.005)
    assert moves.clearance(q[0], q[5]) == pytest.approx(0.005) and len(calls) == 1
    assert moves.clearance(q[0], q[9]) == -1.0  # invalid
    assert moves.clearance(q[1], q[7]) == pytest.approx(0.007)
    assert moves.checks == 3 and len(calls) == 3
    assert moves.clearance(q[2], q[8]) == -1.0 and len(calls) == 3  # over budget: unchecked
    assert moves.chain([q[0], q[5]]) == pytest.approx(0.005)  # checked ones keep scores
