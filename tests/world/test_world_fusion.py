"""Fusion formulas on hand-computed examples (thesis eqs. 8-12, per source)."""

from __future__ import annotations

import numpy as np
import pytest

from assistant.world.fusion import (
    FusionConfig,
    OccupancyFusion,
    Source,
    SourceParams,
    source_probability,
)


def cfg() -> FusionConfig:
    return FusionConfig({
        Source.CAD: SourceParams(0.5, 1),
        Source.BUTTON: SourceParams(1.0, 1),
        Source.SENSOR: SourceParams(0.6, 5),
        Source.CAMERA: SourceParams(0.4, 5),
    }, threshold=0.5)


def test_single_source_sma_reliability_and_product():
    # [1, 1, 1, 1, 0]: SMA 0.8; |diffs| 0,0,0,1 -> mean 0.25 -> reliability 0.75; P 0.6
    assert source_probability([1, 1, 1, 1, 0]) == pytest.approx((0.8, 0.75, 0.6))
    assert source_probability([1.0]) == (1.0, 1.0, 1.0)
    assert source_probability([]) == (0.0, 1.0, 0.0)


def test_button_registers_at_once_even_against_the_cad_model():
    f = OccupancyFusion(cfg())
    f.observe(Source.CAD, [7], 0.0)  # the model says free
    up = f.observe(Source.BUTTON, [7], 1.0)
    # (0.5 * 0 + 1.0 * 1) / (0.5 + 1.0) = 2/3
    assert up.after[0] == pytest.approx(2 / 3)
    assert up.flipped.tolist() == [7]
    # a cell only the button saw is certain
    assert f.observe(Source.BUTTON, [8], 1.0).after[0] == 1.0


def test_reliability_drops_with_flicker():
    f = OccupancyFusion(cfg())
    for v in (1, 1, 1, 1, 1):
        f.observe(Source.SENSOR, [1], v)
    for v in (1, 0, 1, 0, 1):
        f.observe(Source.SENSOR, [2], v)
    steady, flicker = f.probability([1, 2])
    assert steady == 1.0
    # SMA 0.6, every step changes: reliability 1 - 1 = 0
    assert flicker == 0.0
    sma, rel, p = f.breakdown(2)["sensor"]
    assert (sma, rel, p) == pytest.approx((0.6, 0.0, 0.0))


def test_sources_are_weighted_by_reliability_and_windows_slide():
    f = OccupancyFusion(cfg())
    for _ in range(5):
        f.observe(Source.SENSOR, [3], 1.0)
        f.observe(Source.CAMERA, [3], 0.0)
    # (0.6 * 1 + 0.4 * 0) / 1.0
    assert f.probability([3])[0] == pytest.approx(0.6)
    # five new sensor zeros push every old one out of its window of 5
    for _ in range(5):
        f.observe(Source.SENSOR, [3], 0.0)
    assert f.probability([3])[0] == 0.0
    # a cell nobody observed is empty and not stored
    assert f.probability([99])[0] == 0.0
    assert 99 not in f.cells().tolist()


def test_forgetting_a_source_removes_its_vote():
    f = OccupancyFusion(cfg())
    f.observe(Source.CAD, [5, 6], 1.0)
    f.observe(Source.CAMERA, [5], 0.0)
    assert f.probability([5])[0] == pytest.approx(0.5 / 0.9)
    up = f.forget(Source.CAD, [5, 6])
    assert np.allclose(up.after, [0.0, 0.0])
    assert f.cells().tolist() == [5]


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError):
        SourceParams(1.5, 1)
    with pytest.raises(ValueError):
        SourceParams(0.5, 0)
    with pytest.raises(KeyError):
        OccupancyFusion(FusionConfig({})).observe(Source.CAD, [1], 1.0)
