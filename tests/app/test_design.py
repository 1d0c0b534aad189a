"""``odocal.app.design.design`` and the DesignSpec it passes whole to the engines, tested on
their typed results (what the CLI prints is read from these fields, never recomputed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.common import make_robot
from odocal.app.design import design
from odocal.app.measured import MeasuredRobot
from odocal.core.model import MeasurementNoise
from odocal.design.recommend import recommend
from odocal.design.robust import RangeDesign
from odocal.design.spec import CRITERIA, ENGINES, METHODS, DesignSpec, scaled_sizes
from odocal.design.sweep import DesignResult
from odocal.errors import ModelError


def test_the_spec_is_validated_once_and_normalised():
    spec = DesignSpec(sides=(4, 8, 4), side_lengths_m=np.array([1.0, 2.0]))
    assert spec.sides == (4, 8) and spec.side_lengths_m == (1.0, 2.0)
    assert spec.scaled  # the validation track is left open
    resolved = spec.for_wheelbase(0.385)
    assert not resolved.scaled and resolved.validation == scaled_sizes(0.385)[1]
    assert resolved.for_wheelbase(0.16) is resolved  # nothing left to scale
    assert METHODS == ("heading", "umbmark") and CRITERIA == ("error", "residual")
    assert ENGINES == ("monte-carlo", "analytic")
    for bad, needle in (
        (dict(alpha=1.0), "alpha"),
        (dict(tolerance=-0.1), "tolerance"),
        (dict(criterion="median"), "criterion"),
        (dict(method="bcpt"), "method"),
        (dict(sides=(8,), method="umbmark"), "squares"),
        (dict(trials=1), "trials"),
        (dict(side_lengths_m=(1.0, -2.0)), "side_lengths_m"),
    ):
        with pytest.raises(ModelError, match=needle):
            DesignSpec(**bad)
    with pytest.raises(ModelError, match="for_wheelbase"):
        _ = DesignSpec().lengths_m


def test_the_analytic_design_carries_the_other_criterion_and_the_gain():
    run = design(spec=DesignSpec(side_lengths_m=(0.5, 1.0, 1.5, 2.0, 4.0)), engine="analytic")
    res = run.result
    assert isinstance(res, DesignResult) and run.seed is None and run.engine == "analytic"
    assert res.recommendation.criterion == "error"
    assert res.other is not None and res.other.criterion == "residual"
    assert res.other.index == recommend(res.candidates, criterion="residual").index
    assert res.other_recommended is res.candidates[res.other.index]
    assert res.gain_m == res.uncalibrated.mean_m - res.recommended.post_error_mean_m
    assert res.stability is None and res.failed_trials == 0  # expected values: no trials
    assert [c.sides for c in res.shape_picks] == [4]
    for comp in res.recommendation.neighbours:
        ratio = res.candidates[comp.other].post_error_mean_m / res.recommended.post_error_mean_m
        assert res.error_ratio(comp) == ratio
    d = run.as_dict()
    assert d["recommended_by_other_criterion"]["side_m"] == res.other_recommended.side_m
    assert d["stability"] is None and d["engine"] == "analytic"


def test_the_rule_of_the_spec_travels_to_the_engine():
    spec = DesignSpec(side_lengths_m=(0.5, 1.0, 2.0), criterion="residual", tolerance=0.2)
    res = design(spec=spec, engine="analytic").result
    assert isinstance(res, DesignResult)
    assert res.recommendation.criterion == "residual" and res.recommendation.tolerance == 0.2
    assert res.other is not None and res.other.criterion == "error"


def test_the_monte_carlo_stability_is_a_typed_field():
    spec = DesignSpec(side_lengths_m=(0.5, 1.0, 2.0), trials=60)
    run = design(spec=spec, seed=4)
    res = run.result
    assert isinstance(res, DesignResult) and run.seed == 4 and res.paired
    st = res.stability
    assert st is not None and st.resamples == res.recommendation.resamples
    assert math.isclose(sum(p.share for p in st.picks), 1.0)
    assert st.range_m[0] <= st.range_m[1] and st.range_travel_m == (
        4 * st.range_m[0],
        4 * st.range_m[1],
    )
    assert st.indistinguishable == (st.range_m[0] != st.range_m[1])
    assert run.as_dict()["stability"] == st.as_dict()


def test_the_range_design_exposes_its_ranges():
    bare = make_robot(0.066, 0.160, sigma_xy_m=0.01, sigma_theta_deg=1.0)
    run = design(bare, DesignSpec(side_lengths_m=(0.4, 0.8, 1.6, 3.2)))
    d = run.result
    assert isinstance(d, RangeDesign) and run.engine == "analytic" and run.seed is None
    assert d.level_range("E_b") == (0.97, 1.03) and d.level_range("k_m") == (1e-7, 3e-6)
    np.testing.assert_array_equal(d.worst_regret, np.nanmax(d.regret, axis=0))
    assert np.all(d.error_min_m <= d.error_max_m)
    lo, hi = d.uncalibrated_range_m
    assert lo == float(np.min(d.uncalibrated)) and hi == float(np.max(d.uncalibrated))
    j = run.as_dict()
    assert j["error_range"]["ranges"]["E_b"] == [0.97, 1.03]
    assert [c["worst_regret"] for c in j["candidates"]] == pytest.approx(list(d.worst_regret))


def test_design_robot_from_recordings(realdata):
    sq = realdata / "optiodom_diff" / "square" / "231220200029"
    spec = DesignSpec(side_lengths_m=(0.5, 1.0, 1.5), trials=30)
    run = design(spec=spec, robot_from=[sq], measurement=MeasurementNoise.from_degrees(0.0, 0.5))
    m = run.measured
    assert isinstance(m, MeasuredRobot)
    assert m.measurement_source == "given"
    assert math.degrees(m.robot.measurement.sigma_theta_rad) == pytest.approx(0.5)
    assert m.robot.nominal.wheelbase_m == 0.2
    assert m.robot.systematic.E_b > 1.0  # the robot turns less than nominal says
    assert run.robot.startswith("robot measured from")
    d = run.as_dict()
    assert d["robot_measured"] == m.as_dict() and d["robot"] == run.robot
