"""The linear least-squares fit (calibration.linear): exact on noise-free runs, refused without
independent runs."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration.linear import fit_linear
from odocal.errors import CalibrationError
from tests.support.recorded_runs import (
    NOMINAL,
    TRUE,
    make_run,
    mixed_runs,
    values,
)


def test_linear_is_exact_on_noise_free_data():
    fit = fit_linear(mixed_runs(), NOMINAL)
    # exact up to floating point: the estimator is linear and the data noise-free
    np.testing.assert_allclose(values(fit.geometry), values(TRUE), rtol=1e-9)
    assert fit.linear.wheelbase_from_right_m == pytest.approx(TRUE.wheelbase_m, rel=1e-9)
    assert fit.linear.wheelbase_from_left_m == pytest.approx(TRUE.wheelbase_m, rel=1e-9)


def test_linear_needs_independent_runs():
    runs = [make_run("a", [("straight", 2.0)]), make_run("b", [("straight", 3.0)])]
    with pytest.raises(CalibrationError, match="independent"):
        fit_linear(runs, NOMINAL)
