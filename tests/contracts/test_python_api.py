"""The Python API checks what the command line checks: a string, None, an array, a fraction where
a count belongs or a negative seed is refused where it enters, by a ModelError (or InputError)
naming the argument, never a numpy error later."""

from __future__ import annotations

import numpy as np
import pytest

import odocal
from odocal.errors import OdocalError

ROBOT = odocal.make_robot(0.066, 0.16, sigma_xy_m=0.01, sigma_theta_deg=1.0)


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"wheel_diameter_m": "0.066", "wheelbase_m": "0.16"}, "wheel_diameter_m"),
        ({"wheel_diameter_m": 0.066, "wheelbase_m": None}, "wheelbase_m"),
        ({"wheel_diameter_m": 0.066, "wheelbase_m": 0.16, "E_b": "1.02"}, "E_b"),
        ({"wheel_diameter_m": 0.066, "wheelbase_m": 0.16, "E_d": np.nan}, "E_d"),
        ({"wheel_diameter_m": np.array([0.066, 0.07]), "wheelbase_m": 0.16}, "wheel_diameter_m"),
        ({"wheel_diameter_m": 0.066, "wheelbase_m": 0.16, "k_r_m": -1e-6}, "k_r_m"),
        ({"wheel_diameter_m": 0.066, "wheelbase_m": 0.16, "sigma_theta_deg": "1"}, "sigma_theta"),
    ],
)
def test_make_robot_refuses_what_is_not_one_number(kwargs, name):
    with pytest.raises(OdocalError) as exc:
        odocal.make_robot(**kwargs)
    assert name in str(exc.value)


def test_a_negative_diameter_is_called_negative_not_a_unit_slip():
    with pytest.raises(OdocalError) as exc:
        odocal.make_robot(-0.066, 0.16)
    msg = str(exc.value)
    assert "wheel_diameter_m" in msg and "negative" in msg and "units" not in msg


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"runs": 2.5}, "runs"),
        ({"runs": 0}, "runs"),
        ({"side_m": "1"}, "side_m"),
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"sides": 2}, "sides"),
        ({"max_step_m": 0.0}, "max_step_m"),
        ({"directions": "cw"}, "directions"),
    ],
)
def test_simulate_refuses_bad_arguments_where_they_enter(kwargs, name, tmp_path):
    with pytest.raises(OdocalError) as exc:
        odocal.simulate(ROBOT, out=tmp_path / "runs.csv", **kwargs)
    assert name in str(exc.value)
    assert not (tmp_path / "runs.csv").exists()


@pytest.mark.parametrize(
    "kwargs,name",
    [
        ({"tolerance": "0.05"}, "tolerance"),
        ({"tolerance": None}, "tolerance"),
        ({"tolerance": 1.0}, "tolerance"),
        ({"alpha": "0.05"}, "alpha"),
        ({"runs_per_direction": 2.5}, "runs_per_direction"),
        ({"sides": (4.5,)}, "sides"),
        ({"side_lengths_m": ("1", "2")}, "side_lengths_m"),
    ],
)
def test_the_design_spec_refuses_bad_arguments(kwargs, name):
    with pytest.raises(OdocalError) as exc:
        odocal.DesignSpec(**kwargs)
    assert name in str(exc.value)


def test_the_design_over_error_ranges_checks_its_seed_and_spec():
    # ROBOT gives no errors: the design runs over their typical ranges (analytic)
    with pytest.raises(OdocalError, match="seed"):
        odocal.design_track(ROBOT, seed=-1)
    with pytest.raises(OdocalError, match="spec"):
        odocal.design_track(ROBOT, {"tolerance": 0.05})
