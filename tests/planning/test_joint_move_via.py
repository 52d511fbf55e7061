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
