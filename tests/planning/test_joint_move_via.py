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


def test_move_screens_run_when_first_asked(monkeypatch):
    """`_Moves.prefetch` screens a move when it is first asked for, with the moves handed
    after it (`SCREEN_BATCH` at a time): a move the screen calls colliding scores -1
    without its own check, and moves never asked for are never screened."""
    from types import SimpleNamespace

    from assistant.planning import joint_moves as jm

    screened: list[list[float]] = []

    def screen(verifier, Q0, Q1, exempt, max_step=None):
        screened.append([float(b[0]) for b in Q1])
        return np.array([b[0] % 2 == 0 for b in Q1])  # odd targets collide

    monkeypatch.setattr(jm, "motions_free", screen)
    checks = []

    class Verifier:
        def check_motion(self, a, b, exempt):
            checks.append(float(b[0]))
            return SimpleNamespace(valid=True)

        def min_clearance_along(self, qs, max_step):
            return 0.02

    moves = jm._Moves(Verifier(), frozenset(), 0.02, budget=100)
    a = np.zeros(2)
    q = [np.array([float(i), 0.0]) for i in range(20)]
    moves.prefetch([(a, v) for v in q])
    assert not screened  # nothing asked yet
    assert moves.clearance(a, q[2]) == pytest.approx(0.02)
    assert screened == [[float(i) for i in range(2, 2 + jm.SCREEN_BATCH)]]
    assert moves.clearance(a, q[3]) == -1.0 and checks == [2.0]  # screened out: no check
    assert moves.clearance(a, q[0]) == pytest.approx(0.02)  # before the batch: its own
    assert screened[-1] == [0.0, 1.0] + [float(i) for i in
                                         range(2 + jm.SCREEN_BATCH, 8 + jm.SCREEN_BATCH)]
    assert len(screened) == 2 and sum(map(len, screened)) == 2 * jm.SCREEN_BATCH


def _every_via_move(robot, world, q_s, q_g, *, verifier, screen, exempt, clearance,
                    assembly, label, params, vias=96, exact_vias=3):
    """`via_move` as it was before its batches: every via's moves screened at once, the
    durations by numpy's row-wise max, the fine check before the clearance."""
    from assistant.planning.joint_moves import SCREEN_STEP, motions_free, step_verify
    from assistant.planning.transfer_forms import _certified, clearance_kept

    _, offsets, Q = world.cell_positions_shared()
    vmax = np.maximum(robot.limits.velocity, 1e-6)
    dur = (np.abs(Q - q_s) / vmax).max(axis=1) + (np.abs(q_g - Q) / vmax).max(axis=1)
    starts = offsets[:-1][np.diff(offsets) > 0]
    ends = np.r_[starts[1:], len(dur)]
    best = np.minimum.reduceat(dur, starts)
    n = min(len(best), vias)
    top = np.argpartition(best, n - 1)[:n] if n < len(best) else np.arange(len(best))
    top = top[np.argsort(best[top], kind="stable")]
    V = Q[[starts[i] + int(np.argmin(dur[starts[i]:ends[i]])) for i in top.tolist()]]
    A, B = np.repeat(q_s[None], len(V), 0), np.repeat(q_g[None], len(V), 0)
    free = motions_free(screen, np.concatenate([A, V]), np.concatenate([V, B]), exempt,
                        max_step=SCREEN_STEP)
    step, near = step_verify(params), []
    for v in V[free[:len(V)] & free[len(V):]]:
        if not motions_free(screen, np.stack([q_s, v]), np.stack([v, q_g]), exempt).all():
            continue
        if screen.min_clearance_along([q_s, v, q_g], max_step=step) < clearance:
            near.append(v)
            continue
        got = _certified(robot, [q_s, v, q_g], verifier, assembly, label)
        if got is not None:
            return got
    for v in near[:exact_vias]:
        if clearance_kept(screen, [q_s, v, q_g], clearance, step)[0]:
            got = _certified(robot, [q_s, v, q_g], verifier, assembly, label)
            if got is not None:
                return got
    return None


def test_batched_via_search_chooses_the_via_of_screening_every_via(scenario, robot):
    """`transfer_forms.via_move` screens its vias in doubling batches and stops at the first
    that keeps the clearance: on the thesis cell it returns the same two moves as the
    search that screened all of them first, for transfers whose straight move is blocked."""
    from planning_fixtures import make_planner

    from assistant.planning.transfer_forms import via_move

    mp = make_planner(robot, scenario.known_obstacles())
    rng = np.random.default_rng(57)
    lim = robot.limits
    found = tried = 0
    for _ in range(400):
        if tried == 8:
            break
        q_s, q_g = rng.uniform(lim.lower, lim.upper, (2, robot.dof))
        if not (mp.checker.is_valid(q_s) and mp.checker.is_valid(q_g)
                and mp._terminals_ok(q_s, q_g)) or \
                mp.checker.first_invalid_fraction(q_s, q_g) is None:
            continue
        tried += 1
        args = mp._form_args(q_s, "T")
        got = via_move(robot, mp.world, q_s, q_g, **args)
        want = _every_via_move(robot, mp.world, q_s, q_g, **args)
        assert (got is None) == (want is None)
        if got is None:
            continue
        found += 1
        # same process, same code on the same via: the same numbers
        assert np.array_equal(got.trajectory.motions[0].target.q,
                              want.trajectory.motions[0].target.q)
    assert tried == 8 and found >= 2  # blocked transfers, some of them with a via
