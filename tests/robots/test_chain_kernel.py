"""The compiled chain loop (`chain_kernel`) against the per-posture product and the numpy forms.

Tolerances: a link frame is a product of at most ~2n rigid transforms with entries <= 1 and
translations < 1 m, so two orders of evaluation differ by ~n eps ~ 1e-15; 1e-12 leaves room
for the trigonometry's last bits. The numpy batch form snaps URDF constants within 1e-11 to
exact 0/+-1 (`batch_chain._SNAP`), which moves a frame by < 1e-10: that comparison uses 1e-9.
"""

from __future__ import annotations

import numpy as np
import pytest
from urdf_builders import _random_q

from assistant.robots import batch_chain
from assistant.robots.batch_chain import BatchChain, ChainJoint, JointKind
from assistant.robots.chain_kernel import chain_link_frames, chain_link_frames_numpy
from assistant.transforms import make_T, rot_x, rot_y, rot_z
from assistant.warmup.steps import KERNELS

SAME_ORDER_TOL = 1e-12
SNAPPED_TOL = 1e-9


def _odd_chain(rng: np.random.Generator) -> BatchChain:
    """Oblique and aligned axes, a prismatic joint, offsets in every direction."""
    joints = []
    for i in range(7):
        T = make_T(rot_z(rng.uniform(-3, 3)) @ rot_y(rng.uniform(-3, 3)) @ rot_x(1.0),
                   rng.uniform(-0.3, 0.3, 3))
        axis = np.eye(3)[i % 3] * (-1) ** i if i % 2 else rng.normal(size=3)
        kind = JointKind.PRISMATIC if i == 3 else JointKind.REVOLUTE
        joints.append(ChainJoint(f"j{i}", kind, T, axis / np.linalg.norm(axis)))
    return BatchChain(tuple(joints), make_T(rot_x(0.3), [0.0, 0.02, 0.1]))


@pytest.mark.parametrize("which", ["ur5", "panda", "odd"])
def test_compiled_frames_equal_the_per_posture_product(which, request):
    rng = np.random.default_rng(7)
    if which == "odd":
        chain = _odd_chain(rng)
        Q = rng.uniform(-3, 3, (50, chain.dof))
    else:
        robot = request.getfixturevalue(which)
        chain, Q = robot.batch_chain, _random_q(robot, 50, seed=7)
    for N in (1, 2, 50):  # one posture (the planners' commonest call), a pair, a batch
        got = chain.link_poses(Q[:N])
        tips = chain.tip_poses(Q[:N])
        for k in range(N):
            ref = chain.link_frames(Q[k])
            assert np.abs(got[k] - ref).max() < SAME_ORDER_TOL
            tip = ref[-1] @ chain.T_last_tip
            assert np.abs(tips.positions[k] - tip[:3, 3]).max() < SAME_ORDER_TOL
            assert np.abs(tips.rotations[k] - tip[:3, :3]).max() < SAME_ORDER_TOL


def test_compiled_loop_and_its_numpy_fallback_agree():
    chain = _odd_chain(np.random.default_rng(3))
    pk = chain.packed
    Q = np.random.default_rng(4).uniform(-4, 4, (300, chain.dof))
    a = np.empty((300, chain.dof + 1, 4, 4))
    b = np.empty_like(a)
    chain_link_frames(Q, pk.M, pk.axes, pk.prismatic, a)
    chain_link_frames_numpy(Q, pk.M, pk.axes, pk.prismatic, b)
    assert np.abs(a - b).max() < SAME_ORDER_TOL


def test_small_and_big_batches_give_the_same_tips(ur5):
    """Either side of `SMALL_BATCH` (compiled loop / numpy form) a posture's tip is the same."""
    n = batch_chain.SMALL_BATCH
    Q = _random_q(ur5, n + 1, seed=9)
    small = ur5.batch_fk(Q[:n])
    big = ur5.batch_fk(Q)
    assert np.abs(small.positions - big.positions[:n]).max() < SNAPPED_TOL
    assert np.abs(small.rotations - big.rotations[:n]).max() < SNAPPED_TOL
    f32 = ur5.batch_fk(Q[:10], dtype=np.float32)  # float32 stays on the numpy form
    assert f32.positions.dtype == np.float32


def test_the_loop_is_warmed_up_with_the_others():
    assert chain_link_frames in KERNELS
