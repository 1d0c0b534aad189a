"""The fleet's change detector (random-walk Kalman level + two-sided CUSUM on standardised
innovations) on simulated estimates with known standard errors."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration.drift import track_parameter
from odocal.errors import ModelError


def test_at_constant_parameters_the_innovations_are_standard_normal_and_no_alarm():
    rng = np.random.default_rng(7)
    se = rng.uniform(0.5e-4, 2e-4, 600)  # each bag its own standard error
    y = 0.05 + se * rng.standard_normal(600)
    t = track_parameter(y, se)
    assert t.alarms == ()
    assert abs(np.mean(t.z[1:])) < 0.15 and np.std(t.z[1:]) == pytest.approx(1.0, abs=0.1)
    # the level converges on the truth, within its own (shrinking) standard error
    assert abs(t.level[-1] - 0.05) < 4 * t.level_se[-1] and t.level_se[-1] < 0.5 * se.mean()


@pytest.mark.parametrize("step_se, max_bags", [(3.0, 8), (5.0, 4)])
def test_a_step_is_found_within_a_few_bags_and_its_size_estimated(step_se, max_bags):
    rng = np.random.default_rng(3)
    se = np.full(60, 1e-4)
    y = 0.05 + se * rng.standard_normal(60)
    y[30:] += step_se * 1e-4
    t = track_parameter(y, se)
    assert len(t.alarms) == 1
    a = t.alarms[0]
    assert 30 <= a.index < 30 + max_bags and 27 <= a.start_index <= a.index
    assert a.size == pytest.approx(step_se * 1e-4, abs=1.5e-4) and a.z > 2
    # after the alarm the level is the new one
    assert abs(t.level[-1] - (0.05 + step_se * 1e-4)) < 4 * t.level_se[-1]


def test_the_detector_does_not_care_about_units():
    rng = np.random.default_rng(5)
    se = rng.uniform(1, 2, 80)
    y = se * rng.standard_normal(80)
    y[40:] += 4
    a, b = track_parameter(y, se), track_parameter(1e-4 * y + 0.26, 1e-4 * se)
    np.testing.assert_allclose(a.z, b.z, rtol=1e-6, atol=1e-9)
    assert [x.index for x in a.alarms] == [x.index for x in b.alarms] != []


def test_linear_wear_is_found():
    rng = np.random.default_rng(11)
    se = np.full(200, 1e-4)
    y = 0.05 - 0.2e-4 * np.arange(200) + se * rng.standard_normal(200)  # 0.2 se per bag
    t = track_parameter(y, se)
    assert t.alarms and t.alarms[0].index < 60 and t.alarms[0].size < 0


def test_one_bag_is_its_own_level():
    t = track_parameter(np.array([0.05]), np.array([1e-4]))
    assert t.level[0] == 0.05 and t.level_se[0] == 1e-4 and t.alarms == ()


@pytest.mark.parametrize(
    "y, se",
    [([0.05, 0.05], [1e-4, 0.0]), ([0.05, np.nan], [1e-4, 1e-4]), ([0.05], [1e-4, 1e-4]),
     ([0.05, 0.05], [1e-4, -1e-4]), ([0.05, 0.05], [1e-4, np.inf])],
)  # fmt: skip
def test_bad_inputs(y, se):
    with pytest.raises(ModelError):
        track_parameter(np.array(y), np.array(se))
