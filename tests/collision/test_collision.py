"""Exact FCL collision checks: agreement with brute force, contacts, motions, clearance."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.collision.broad_phase import ASK_FCL, CERTIFIED, FREE, OUTSIDE_LIMITS
from assistant.collision.checker import CollisionChecker
from assistant.collision.reports import Obstacle
from assistant.robots.model import CollisionShape, ShapeKind
from assistant.transforms import make_T


def box(name: str, centre, size) -> Obstacle:
    return Obstacle(name, make_T(p=centre), (CollisionShape(ShapeKind.BOX, tuple(size)),))


def _random_motions(checker, rng, lo, hi, count: int, scale: float, label_step: int = 1):
    """Samples of `count` random motions (start in the limits, a normal step of `scale`)
    as `check_motion` takes them: (rows, labels per row, the motions' row blocks)."""
    rows, groups = [], []
    for g in range(count):
        q0 = rng.uniform(lo, hi)
        q1 = q0 + rng.normal(scale=scale, size=5)
        n = checker.motion_samples(q0, q1)
        rows.append(q0 + (np.arange(n + 1) / n)[:, None] * (q1 - q0))
        groups.append(np.full(n + 1, label_step * g))
    return np.concatenate(rows), np.concatenate(groups), rows


@pytest.fixture(scope="module")
def cell_obstacles() -> list[Obstacle]:
    return [
        box("O1", [0.30, 0.10, 0.10], [0.10, 0.10, 0.20]),
        box("O2", [-0.10, 0.30, 0.25], [0.15, 0.10, 0.10]),
        box("table", [0.0, 0.0, -0.011], [1.5, 1.5, 0.02]),
    ]


@pytest.fixture(scope="module")
def checker(rv2aj, cell_obstacles) -> CollisionChecker:
    return CollisionChecker(rv2aj, cell_obstacles)


def test_batch_check_agrees_with_brute_force_fcl(checker, rv2aj):
    rng = np.random.default_rng(7)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(1500, 5))
    fast = checker.in_collision_batch(Q)
    naive = np.array([checker.in_collision_naive(q) for q in Q])
    # Booleans of random configurations: a last-bit difference in the compiled poses could
    # only flip one lying within ~1e-15 m of contact, which a random sample never does.
    assert np.array_equal(fast, naive)
    # The sample must contain both outcomes or the comparison proves nothing.
    assert 0.02 < fast.mean() < 0.9


def test_upright_arm_is_free_and_reports_clearance(checker):
    q = np.zeros(5)
    assert checker.is_valid(q)
    rep = checker.check(q)
    assert rep.valid and rep.describe() == "free"
    c = checker.clearance(q)
    # The turret capsule starts at z = 0.16 - 0.075; the table top is at z = -0.001.
    assert c.other == "table"
    assert c.distance == pytest.approx(0.085 + 0.001, abs=1e-6)


def test_contact_names_the_link_and_the_obstacle(rv2aj):
    # The arm stretched forward along +x at shoulder height sweeps through a box there.
    q = np.radians([0.0, 90.0, 0.0, 0.0, 0.0])
    p = rv2aj.link_poses(q)[3][:3, 3]  # elbow
    chk = CollisionChecker(rv2aj, [box("block", p, [0.05, 0.05, 0.05])])
    rep = chk.check(q)
    assert not rep.valid
    links = {c.link for c in rep.contacts}
    assert {"J2_upper_arm", "J3_forearm"} <= links
    assert all(c.other == "block" for c in rep.contacts)


def test_adjacent_links_overlapping_at_their_joint_are_not_a_self_collision(rv2aj):
    chk = CollisionChecker(rv2aj, [])
    assert chk.is_valid(np.zeros(5))
    linked = {(chk._rshapes[a].link, chk._rshapes[b].link) for a, b in chk._self_pairs}
    assert all(abs(a - b) > 1 for a, b in linked)


def test_folded_arm_is_a_self_collision(rv2aj):
    chk = CollisionChecker(rv2aj, [])
    rng = np.random.default_rng(3)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(3000, 5))
    hit = chk.in_collision_batch(Q)
    assert hit.any()
    q = Q[np.argmax(hit)]
    rep = chk.check(q)
    assert rep.contacts and all(c.self_collision for c in rep.contacts)
    assert chk.in_collision_naive(q)


def test_joint_limits_make_a_configuration_invalid(checker, rv2aj):
    q = np.zeros(5)
    q[0] = rv2aj.limits.upper[0] + 0.01
    assert not checker.is_valid(q)
    rep = checker.check(q)
    assert rep.collision_free and not rep.within_limits
    assert "J1" in rep.describe()


def test_continuous_check_finds_the_first_contact_within_one_step(rv2aj):
    # Swing J1 from -90 to +90 deg with the arm stretched forward: a block at +x is hit
    # when the arm passes its angular extent.
    q0 = np.radians([-90.0, 60.0, 30.0, 0.0, 0.0])
    q1 = np.radians([90.0, 60.0, 30.0, 0.0, 0.0])
    mid = q0 + 0.5 * (q1 - q0)
    wrist = rv2aj.link_poses(mid)[4][:3, 3]
    chk = CollisionChecker(rv2aj, [box("post", wrist, [0.03, 0.03, 0.03])], max_step=0.005)
    mc = chk.check_motion(q0, q1)
    assert not mc.valid
    assert mc.report is not None and not mc.report.collision_free
    f = mc.first_invalid_fraction
    assert 0.3 < f < 0.5
    # The configuration one step earlier is free: the answer is the *first* contact.
    step = 1.0 / mc.samples
    assert chk.is_valid(q0 + (f - step) * (q1 - q0))
    assert not chk.is_valid(q0 + f * (q1 - q0))


def test_motion_sampling_respects_the_step_bound(checker, rv2aj):
    rng = np.random.default_rng(11)
    for _ in range(20):
        q0 = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper)
        q1 = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper)
        n = checker.motion_samples(q0, q1, 0.005)
        pts = np.array([rv2aj.fk(q0 + f * (q1 - q0))[:3, 3] for f in np.arange(n + 1) / n])
        assert np.max(np.linalg.norm(np.diff(pts, axis=0), axis=1)) <= 0.005 + 1e-12


def test_segment_sample_counts_of_a_path_match_one_by_one(checker, rv2aj):
    """Path checks count every segment's samples in one pass; the counts (and so the samples)
    must be exactly those of `motion_samples`, also for tiny and zero-length segments."""
    rng = np.random.default_rng(13)
    path = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, (30, 5))
    path[5] = path[4]  # no motion: still one step
    path[9] = path[8] + 1e-9
    for step in (None, 0.01, 0.003):
        one_by_one = [checker.motion_samples(a, b, step)
                      for a, b in zip(path[:-1], path[1:], strict=True)]
        assert checker.motion_samples_along(path, step).tolist() == one_by_one
        assert checker.motion_samples_between(path[:-1], path[1:], step).tolist() == one_by_one
    assert one_by_one[4] == 1 and max(one_by_one) > 50


def test_clear_motion_is_valid(checker):
    q0 = np.radians([0.0, 0.0, 30.0, 0.0, 0.0])
    q1 = np.radians([0.0, 0.0, 60.0, 20.0, 0.0])
    assert checker.check_motion(q0, q1).valid
    assert checker.check_path([q0, q1, q0]) is None
    assert checker.min_clearance_along([q0, q1]) > 0.05


def test_clearance_to_a_box_is_the_analytic_distance(rv2aj):
    # Upright arm: the forearm capsule (radius 45 mm) runs along z from 550 to 710 mm; a thin
    # wall beside it at 650-670 mm is nearest to the forearm's side.
    q = np.zeros(5)
    chk = CollisionChecker(rv2aj, [box("wall", [0.30, 0.0, 0.66], [0.02, 0.4, 0.02])])
    c = chk.clearance(q)
    assert c.other == "wall" and c.link == "J3_forearm"
    assert c.distance == pytest.approx(0.30 - 0.01 - 0.045, abs=1e-5)


def _clearance_at_every_sample(checker, path, max_step=0.01) -> float:
    best = np.inf
    for a, b in zip(path[:-1], path[1:], strict=True):
        n = checker.motion_samples(a, b, max_step)
        for f in np.arange(0, n + 1) / n:
            best = min(best, checker.clearance(a + f * (b - a)).distance)
    return best


def test_path_clearance_is_the_minimum_over_every_sample(cell_obstacles, rv2aj):
    """The bounded search measures few pairs, yet returns the brute-force minimum - also
    when the path passes through an obstacle (penetration depths are not bounded)."""
    checker = CollisionChecker(rv2aj, cell_obstacles[:2])  # no table: varied minima
    rng = np.random.default_rng(11)
    found = []
    for _ in range(8):
        path = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(3, 5))
        fast = checker.min_clearance_along(list(path))
        # Round links against boxes are measured in closed form; FCL's GJK answers there
        # lie above the true distance by up to about 0.1 mm.
        ref = _clearance_at_every_sample(checker, path)
        assert ref - 1e-4 < fast <= ref + 1e-12
        found.append(fast)
    assert min(found) < 0.0 < max(found)  # through an obstacle and clear of both


def test_path_check_finds_the_same_first_contact_as_segment_by_segment(checker, rv2aj):
    rng = np.random.default_rng(12)
    outcomes = set()
    for _ in range(10):
        path = list(rng.uniform(rv2aj.limits.lower * 0.8, rv2aj.limits.upper * 0.8, (4, 5)))
        hit = checker.check_path(path)
        ref = next(((i, mc) for i in range(len(path) - 1)
                    if not (mc := checker.check_motion(path[i], path[i + 1])).valid), None)
        assert (hit is None) == (ref is None)
        outcomes.add(hit is None)
        if hit is not None:
            assert hit[0] == ref[0]
            # the same sample k of n (an integer) - its fraction k / n computed by the
            # compiled sampler or in Python: within a few ULPs of a number in [0, 1]
            assert hit[1].first_invalid_fraction == pytest.approx(
                ref[1].first_invalid_fraction, rel=0, abs=1e-15)
            assert hit[1].samples == ref[1].samples
    assert outcomes == {True, False}


def test_path_check_skips_trusted_segments_and_finds_the_same_first_contact(checker, rv2aj,
                                                                          monkeypatch):
    """Segments named `trusted` (already passed, sampled the same way) are not asked again;
    the first invalid segment found among the rest is the one the full check finds."""
    rng = np.random.default_rng(12)
    asked = []
    full_check = checker.is_valid_samples

    def counting(Q, *args, **kwargs):
        asked.append(len(Q))
        return full_check(Q, *args, **kwargs)

    hits = 0
    checked_some = False
    for _ in range(10):
        path = list(rng.uniform(rv2aj.limits.lower * 0.8, rv2aj.limits.upper * 0.8, (5, 5)))
        ref = checker.check_path(path)
        ok = [checker.check_motion(a, b).valid for a, b in zip(path[:-1], path[1:],
                                                                 strict=True)]
        trusted = np.array(ok) & (np.arange(4) % 2 == 0)  # some of the valid ones
        monkeypatch.setattr(checker, "is_valid_samples", counting)
        asked.clear()
        got = checker.check_path(path, trusted=trusted)
        n_asked = sum(asked)
        monkeypatch.undo()
        assert (got is None) == (ref is None)
        if ref is not None:
            hits += 1
            assert got[0] == ref[0]
            assert got[1].first_invalid_fraction == pytest.approx(  # k / n, see above
                ref[1].first_invalid_fraction, rel=0, abs=1e-15)
        if trusted.any() and ref is None:  # every untrusted sample asked, no trusted one
            checked_some = True
            # a segment's samples but its end (the next one's start), the path's end once
            counts = checker.motion_samples_along(np.array(path))
            assert n_asked == int(counts[~trusted].sum()) + int(not trusted[-1])
    assert hits > 0 and checked_some


def test_path_check_asks_each_vertex_once(checker, rv2aj, monkeypatch):
    """A path's samples are those of its segments' motion checks with each shared vertex
    once (the vertex itself, not its copy interpolated from the segment before)."""
    rng = np.random.default_rng(5)
    path = rng.uniform(rv2aj.limits.lower * 0.3, rv2aj.limits.upper * 0.3, (6, 5)) * 0.2
    asked = []
    full_check = checker.is_valid_samples

    def recording(Q, *args, **kwargs):
        asked.append(np.array(Q))
        return full_check(Q, *args, **kwargs)

    monkeypatch.setattr(checker, "is_valid_samples", recording)
    assert checker.check_path(list(path)) is None
    Q = np.concatenate(asked)
    counts = checker.motion_samples_along(path)
    assert len(Q) == int(counts.sum()) + 1
    assert len(np.unique(Q.round(12), axis=0)) == len(Q)
    firsts = np.r_[0, np.cumsum(counts)]  # each vertex, exactly as given
    assert np.array_equal(Q[firsts], path)  # copies of the vertices, no arithmetic


def test_free_margin_is_a_sound_certificate(checker, rv2aj):
    """Any move whose arm travel stays below a configuration's margin is free (brute-force
    FCL agrees) - including moves to just below the margin towards the obstacles."""
    rng = np.random.default_rng(11)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(600, 5))
    ok, margin = checker.is_valid_batch_margin(Q)
    assert np.array_equal(ok, checker.is_valid_batch(Q))
    assert np.isnan(margin[~ok]).all()
    good = np.nonzero(ok & (margin > 0.002))[0]
    assert len(good) > 100
    for i in good:
        d = rng.normal(size=5)
        d *= 0.999 * margin[i] / float(checker.travel(np.zeros(5), d))
        q2 = Q[i] + d
        if rv2aj.limits.contains(q2):
            assert not checker.in_collision_naive(q2)
    # A lower bound on the true clearance (FCL distance), never above it.
    for i in good[:60]:
        assert margin[i] <= checker.clearance(Q[i], include_self=True).distance + 1e-9


def test_margin_rows_are_the_batch_collision_check_to_the_bit(checker, rv2aj):
    """`is_valid_batch_margin`'s one-pass rows (`broad_phase.margin_rows`) give the hits and
    gaps of `_collide_batch(with_gap=True)`, the separate numpy and compiled steps, row for
    row: free, grazing and colliding configurations (obstacles and the arm itself)."""
    rng = np.random.default_rng(13)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, size=(800, 5))
    Q[:100, 2] = rv2aj.limits.upper[2] - rng.uniform(0.0, 0.05, 100)  # folded elbows
    hit, gap = checker._margin_rows(np.ascontiguousarray(Q))
    want_hit, want_gap = checker._collide_batch(Q, with_gap=True)
    # hits: booleans of random configurations (a flip needs contact within ~1e-15 m)
    assert np.array_equal(hit, want_hit)
    # 1e-12 m: the same sphere/box distances (~0.1-1 m, ~1e-16 relative each), evaluated in
    # one compiled pass or in numpy steps - FMA and vector width may change the last bits
    np.testing.assert_allclose(gap, want_gap, rtol=0, atol=1e-12)
    assert 50 < hit.sum() < 750 and (gap <= 0).sum() > hit.sum()  # near but free, too


def test_certified_rows_skip_the_exact_check_but_not_the_limits(checker, rv2aj):
    Q = np.random.default_rng(5).uniform(rv2aj.limits.lower, rv2aj.limits.upper, (200, 5))
    q_hit = Q[checker.in_collision_batch(Q)][0]
    out_of_limits = rv2aj.limits.upper + 0.1
    ok, margin = checker.is_valid_batch_margin(np.array([q_hit, out_of_limits]),
                                               certified=np.array([True, True]))
    # Certified means "the caller proved it free": no FCL; the joint limits still count.
    assert ok.tolist() == [True, False]
    assert np.isnan(margin).all()
    ok, margin = checker.is_valid_batch_margin(q_hit[None])
    assert not ok[0] and np.isnan(margin[0])


def _reference_certified(checker: CollisionChecker, Q: np.ndarray, g: np.ndarray,
                         slack: float = 1e-9) -> np.ndarray:
    """Rows of motions' samples that a checked neighbour's margin proves free (by more than
    `slack`, m), as numpy array expressions (the code before `broad_phase.certify_samples`)."""
    n, k = len(Q), np.arange(len(Q))
    first, last = np.r_[True, g[1:] != g[:-1]], np.r_[g[1:] != g[:-1], True]
    start = np.maximum.accumulate(np.where(first, k, 0))
    coarse = ((k - start) % checker.CERTIFY_STRIDE == 0) | last
    ci = np.flatnonzero(coarse)
    inside = checker.robot.limits.contains_batch(Q)
    valid_c, margin_c = checker.is_valid_batch_margin(Q[ci])
    margin_c = np.where(valid_c, margin_c, -np.inf)
    prev = np.searchsorted(ci, k, side="right") - 1
    nxt = np.minimum(prev + 1, len(ci) - 1)
    rest = np.flatnonzero(~coarse & inside)
    p, q = prev[rest], nxt[rest]
    free = ((margin_c[p] > checker.travel(Q[ci[p]], Q[rest]) + slack)
            | (margin_c[q] > checker.travel(Q[ci[q]], Q[rest]) + slack))
    out = np.zeros(n, dtype=bool)
    out[rest[free]] = True
    return out


def test_certified_motion_samples_answer_like_the_plain_batch(checker, rv2aj):
    """`is_valid_samples` gives exactly `is_valid_batch`'s answers for the samples of many
    motions at once (free, grazing, crossing the boxes, leaving the joint limits), and checks
    fewer rows exactly: the margins of every fourth sample cover the ones around it."""
    rng = np.random.default_rng(23)
    lo, hi = rv2aj.limits.lower, rv2aj.limits.upper
    Q, G, rows = _random_motions(checker, rng, lo, hi, 40, 0.4)  # some leave the limits
    plain = checker.is_valid_batch(Q)
    assert 0.2 < plain.mean() < 0.95  # both answers are well represented
    assert np.array_equal(checker.is_valid_samples(Q, G), plain)
    _, status, _, _, _ = checker._certify(Q, G)
    # 43 % of the rows had a broad phase of their own (every fourth row of a motion and
    # its last always do); without the certificates every row inside the limits would (82 %).
    checked = (status == FREE) | (status == ASK_FCL)
    assert checked.mean() < 0.55
    # The certified rows are those of the numpy formulation before the kernel, where that is
    # clear of its threshold (margin > travel + 1e-9 m): the kernel computes margins and
    # travels in its own order (margins of the two passes agree within 1e-12 m, above), so
    # rows whose answer changes when the slack moves 1e-10 m either way are left out.
    ref = _reference_certified(checker, Q, G)
    clear = (_reference_certified(checker, Q, G, 1e-9 - 1e-10)
             == _reference_certified(checker, Q, G, 1e-9 + 1e-10))
    assert clear.mean() > 0.99  # nearly every row is compared
    assert np.array_equal((status == CERTIFIED)[clear], ref[clear])
    assert (status == CERTIFIED).any() and (status == ASK_FCL).any()
    assert np.array_equal(status == OUTSIDE_LIMITS,
                          ~rv2aj.limits.contains_batch(Q))
    # One motion (no groups) and motions too short to skip anything answer alike.
    one = rows[0]
    assert np.array_equal(checker.is_valid_samples(one), checker.is_valid_batch(one))
    assert np.array_equal(checker.is_valid_samples(one[:2]), checker.is_valid_batch(one[:2]))


def test_first_only_samples_give_each_motions_first_invalid_row(checker, rv2aj, monkeypatch):
    """With `first_only` every motion's first invalid row (limits, FCL, or a row the caller
    refuses) is the plain batch's, rows after it are invalid, and FCL skips those rows."""
    rng = np.random.default_rng(29)
    lo, hi = rv2aj.limits.lower, rv2aj.limits.upper
    # any labels, as long as motions are runs
    Q, G, _ = _random_motions(checker, rng, lo, hi, 60, 0.25, label_step=7)
    refused = rng.random(len(Q)) < 0.002  # e.g. recorded collision postures
    plain = checker.is_valid_batch(Q) & ~refused
    import fcl

    calls = [0]
    collide = fcl.collide

    def counting(*args):
        calls[0] += 1
        return collide(*args)

    monkeypatch.setattr(fcl, "collide", counting)
    full = checker.is_valid_samples(Q, G, known_invalid=refused)
    asked = [calls[0]]
    first = checker.is_valid_samples(Q, G, first_only=True, known_invalid=refused)
    asked.append(calls[0] - asked[0])
    assert np.array_equal(full, plain)
    invalid_motions = 0
    for g in np.unique(G):
        i = np.flatnonzero(G == g)
        if plain[i].all():
            assert first[i].all()
            continue
        invalid_motions += 1
        k = int(np.argmin(plain[i]))
        assert np.array_equal(first[i[: k + 1]], plain[i[: k + 1]])
        assert not first[i[k:]].any()
    assert 10 < invalid_motions < 55  # both kinds of motion are well represented
    assert asked[1] < 0.5 * asked[0]  # FCL skipped the rows behind each first hit (290/799)


def test_compiled_frames_and_limits_are_the_robots_to_the_bit(checker, rv2aj, cell_obstacles):
    """The certification computes the RV-2AJ's link frames itself, only for the rows it
    checks (`broad_phase.certify_samples`), and the limit test (`motion_rows.rows_inside`):
    the same bits as `batch_link_poses` and `contains_batch`; and a robot without the DH
    hook (frames from `batch_link_poses`) gets the same answers from `is_valid_samples`."""
    from assistant.collision.motion_rows import rows_inside

    rng = np.random.default_rng(31)
    lo, hi = rv2aj.limits.lower, rv2aj.limits.upper
    Q = rng.uniform(lo - 0.2, hi + 0.2, (300, 5))
    inside = rows_inside(Q, lo, hi)
    assert np.array_equal(inside, rv2aj.limits.contains_batch(Q))
    assert 0.1 < inside.mean() < 0.9
    Qm, Gm, _ = _random_motions(checker, rng, lo, hi, 30, 0.3)
    frames, status, _, _, _ = checker._certify(Qm, Gm)
    posed = (status == FREE) | (status == ASK_FCL)
    # 1e-12 (m, and unitless rotation entries): a chain of 5 DH 4x4 products, each ~1e-16
    # relative, compiled separately (FMA/vector width may differ between the two kernels)
    np.testing.assert_allclose(frames[posed], rv2aj.batch_link_poses(Qm[posed]), rtol=0,
                               atol=1e-12)
    assert (status == CERTIFIED).mean() > 0.2  # rows never posed: their margin sufficed

    class NoHook:  # the RV-2AJ seen through the plain Robot interface only
        def __getattr__(self, name):
            if name == "dh_fixed_stack":
                raise AttributeError(name)
            return getattr(rv2aj, name)

    plain = CollisionChecker(NoHook(), cell_obstacles)
    assert plain._chain_F is None and checker._chain_F is not None
    Q, G, _ = _random_motions(checker, rng, lo, hi, 30, 0.3)
    for first_only in (False, True):
        a = checker.is_valid_samples(Q, G, first_only=first_only)
        assert np.array_equal(a, plain.is_valid_samples(Q, G, first_only=first_only))
        assert 0.2 < a.mean() < 0.95


def test_exact_phase_poses_are_einsums_to_the_bit(checker, rv2aj):
    """`shape_poses` (the exact phase's compiled posing) gives the batched product it
    replaced, bit for bit: FCL sees the same transforms, so it gives the same answers."""
    from assistant.collision.shape_poses import shape_poses

    rng = np.random.default_rng(5)
    Q = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, (60, 5))
    frames = rv2aj.batch_link_poses(Q)
    R, t = shape_poses(frames, checker._shape_link, checker._shape_T)
    T = np.einsum("nrij,rjk->nrik", frames[:, checker._shape_link], checker._shape_T)
    assert len(checker._shape_link) >= 5
    # 1e-15: one 4x4 product of unit-scale rotations and sub-metre offsets (a few ULPs of 1;
    # FMA or numpy's BLAS kernel may round the 4-term dot products differently)
    np.testing.assert_allclose(R, T[..., :3, :3], rtol=0, atol=1e-15)
    np.testing.assert_allclose(t, T[..., :3, 3], rtol=0, atol=1e-15)
    assert R.flags.c_contiguous and t.flags.c_contiguous


def test_compiled_path_samples_are_the_numpy_ones(checker, rv2aj):
    """`motion_rows.path_samples` (what `check_path` asks) against the numpy form it
    replaced: segments, fractions and joints to the bit, trusted segments left out
    (none, some, the last, all)."""
    from assistant.collision.motion_rows import path_samples

    rng = np.random.default_rng(4)
    for n in (2, 3, 7):
        A = rng.uniform(rv2aj.limits.lower, rv2aj.limits.upper, (n, 5))
        S0, F0, counts = checker._path_samples(A, None)
        for trusted in (None, rng.random(n - 1) < 0.5, np.arange(n - 1) == n - 2,
                        np.ones(n - 1, dtype=bool)):
            keep = np.ones(len(S0), bool) if trusted is None else ~trusted[S0]
            S, F = S0[keep], F0[keep]
            Q = A[S] + F[:, None] * (A[S + 1] - A[S])
            got = path_samples(A, counts, np.zeros(0, bool) if trusted is None else trusted)
            assert np.array_equal(got[0], S)  # segment indices: integers
            # 1e-15: a fraction k / n (one division) and a + f (b - a) on joints of a few
            # rad - a few ULPs, where FMA may contract f (b - a) + a
            np.testing.assert_allclose(got[1], F, rtol=0, atol=1e-15)
            np.testing.assert_allclose(got[2], Q.reshape(-1, 5), rtol=0, atol=1e-14)
