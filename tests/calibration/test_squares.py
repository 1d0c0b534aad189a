"""UMBmark and the heading method on recorded squares (calibration.squares): the directions come
from the data."""

from __future__ import annotations

import pytest

from odocal.calibration.squares import fit_recorded_squares
from odocal.errors import CalibrationError
from tests.support.recorded_runs import (
    NOMINAL,
    TRUE,
    make_run,
    square,
)


def test_heading_and_umbmark_on_recorded_squares_directions_from_the_data():
    side = 3.0
    # labels deliberately wrong on one run: the direction comes from the total rotation
    runs = [make_run(f"cw{i}", square("cw", side), label="cw", side=side) for i in range(2)]
    runs += [make_run("ccw0", square("ccw", side), label="cw", side=side)]
    runs += [make_run("ccw1", square("ccw", side), label="ccw", side=side)]
    true_ratio = TRUE.diameter_ratio
    fit = fit_recorded_squares(runs, "heading", nominal=NOMINAL)
    # the heading method is exact under the model (model.md); it keeps the nominal mean
    # diameter, so compare the scale-free quantities
    assert fit.geometry.diameter_ratio == pytest.approx(true_ratio, rel=1e-9)
    assert fit.geometry.wheelbase_m / fit.geometry.mean_diameter_m == pytest.approx(
        TRUE.wheelbase_m / TRUE.mean_diameter_m, rel=1e-9
    )
    assert fit.geometry.mean_diameter_m == pytest.approx(NOMINAL.mean_diameter_m)
    assert any("ccw0" in w and "CCW" in w for w in fit.warnings)
    um = fit_recorded_squares(runs, "umbmark", nominal=NOMINAL)
    # UMBmark is small-angle: E_b 2 %, E_d 0.4 % on a 3 m square are reproduced to ~1e-3
    assert um.geometry.diameter_ratio == pytest.approx(true_ratio, rel=1e-3)
    with pytest.raises(CalibrationError, match="not a closed square"):
        fit_recorded_squares(runs + [make_run("line", [("straight", 2.0)], side=side)], "heading")


@pytest.mark.parametrize(
    ("side", "sides", "needle"),
    [
        (10.0, 4, "the wheels travel 12 m, where 4 sides of 10 m are 40 m"),
        (2.0, 4, "travel 12 m, where 4 sides of 2 m are 8 m"),
        (3.0, 3, "travel 12 m, where 3 sides of 3 m are 9 m"),
        (
            2.4,
            5,
            "halfway along side 3 the odometry has turned 180 deg, where a 5-gon has turned 144",
        ),
    ],
)
def test_the_heading_method_compares_sides_and_side_length_with_the_recorded_motion(
    side, sides, needle
):
    # 3 m squares given as 10 m squares or triangles: the heading method's E_b and E_d would be
    # off without a word (the 0.7-2.4 % of a real trial); the wheels say what was driven
    runs = [make_run(d, square(d, 3.0)) for d in ("cw", "ccw")]
    with pytest.raises(CalibrationError, match="not the track given") as info:
        fit_recorded_squares(runs, "heading", nominal=NOMINAL, side_m=side, sides=sides)
    assert needle in str(info.value)
    fit_recorded_squares(runs, "heading", nominal=NOMINAL, side_m=3.0)  # the right track passes
