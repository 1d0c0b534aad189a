"""Closed-form design metrics of a polygon test track (model.md, "The paper's design metrics").

For a straight leg of believed length L (m), driven open loop by a robot whose true wheel travel
per believed metre is f_R = D_R / D_hat_R on the right and f_L = D_L / D_hat_L on the left, with
true wheelbase b (m) and wheel noise k_r, k_l (m):

    systematic leg heading error   beta(L)        = L (f_R - f_L) / b                     (rad)
    non-systematic leg heading std sigma_theta(L) = sqrt(k_r f_R L + k_l f_L L) / b        (rad)

For a robot running with its nominal parameters, f_R - f_L = 2 (E_d - 1) / (E_d + 1) (with
E_s = 1) and b = E_b b_n, so beta = 2 L (E_d - 1) / ((E_d + 1) E_b b_n) as in model.md; and
f_R, f_L differ from 1 by well under 1 %, so sigma_theta is model.md's sqrt((k_r + k_l) L) / b.
Both formulas are exact under the simulator's model (the heading change of a leg is the wheel
travel difference over b, and the noise variances of the increments add up to k |s|).

Systematic share (Fig. 4; the paper gives no formula, this is the project's definition): the
share of the variance of the n-run-averaged leg heading error explained by the systematic part,

    share = beta^2 / (beta^2 + sigma_theta^2 / n),

with n the runs per direction (5 in the paper). It reproduces the paper's ~91 % at L = 4 m under
the Fig. 3/4 conditions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.model import Robot

__all__ = [
    "wheel_travel_factors",
    "true_factors",
    "leg_heading_systematic_rad",
    "leg_heading_noise_rad",
    "systematic_share",
    "LegHeadingCurve",
    "leg_heading_curve",
]


def wheel_travel_factors(robot: Robot) -> tuple[float, float]:
    """(f_R, f_L): true wheel travel per believed metre of the right and left wheel."""
    true, hat = robot.true_geometry, robot.believed_geometry
    return (
        float(true.diameter_right_m / hat.diameter_right_m),
        float(true.diameter_left_m / hat.diameter_left_m),
    )


def true_factors(robot: Robot) -> tuple[float, float]:
    """(E_b, E_d) a perfect calibration finds: relative to the parameters the robot runs with,
    b / b_hat and f_R / f_L (dimensionless)."""
    f_r, f_l = wheel_travel_factors(robot)
    b, b_hat = robot.true_geometry.wheelbase_m, robot.believed_geometry.wheelbase_m
    return float(b / b_hat), f_r / f_l


def leg_heading_systematic_rad(robot: Robot, side_m):
    """Signed systematic heading change beta (rad) over a straight leg of ``side_m`` (m).

    ``side_m`` is a float or an array; the result has its shape. The paper's Fig. 3 plots |beta|.
    """
    f_r, f_l = wheel_travel_factors(robot)
    b = float(robot.true_geometry.wheelbase_m)
    return np.asarray(side_m, dtype=float) * (f_r - f_l) / b


def leg_heading_noise_rad(robot: Robot, side_m):
    """Standard deviation sigma_theta (rad) of the random heading change over a straight leg of
    ``side_m`` (m) (shape of ``side_m``)."""
    f_r, f_l = wheel_travel_factors(robot)
    b = float(robot.true_geometry.wheelbase_m)
    k = robot.nonsystematic
    L = np.asarray(side_m, dtype=float)
    return np.sqrt(k.k_r_m * f_r * L + k.k_l_m * f_l * L) / b


def systematic_share(beta_rad, sigma_theta_rad, runs_per_direction: int):
    """beta^2 / (beta^2 + sigma_theta^2 / n) (dimensionless, 0..1); arrays broadcast.

    NaN where both parts are zero (no error at all).
    """
    beta2 = np.square(np.asarray(beta_rad, dtype=float))
    noise2 = np.square(np.asarray(sigma_theta_rad, dtype=float)) / runs_per_direction
    with np.errstate(invalid="ignore", divide="ignore"):
        return beta2 / (beta2 + noise2)


@dataclass(frozen=True)
class LegHeadingCurve:
    """Figs. 3 and 4 for one robot: leg heading errors and the systematic share against L.

    Attributes
    ----------
    side_m : ndarray, shape (k,)
        Leg lengths (m).
    beta_rad, sigma_rad : ndarray, shape (k,)
        |beta(L)| and sigma_theta(L) (rad).
    share : ndarray, shape (k,)
        Systematic share (0..1) with ``runs_per_direction`` runs.
    runs_per_direction : int
    """

    side_m: np.ndarray
    beta_rad: np.ndarray
    sigma_rad: np.ndarray
    share: np.ndarray
    runs_per_direction: int

    def share_at(self, side_m: float) -> float:
        """The systematic share at one leg length (linear interpolation)."""
        return float(np.interp(side_m, self.side_m, self.share))


def leg_heading_curve(robot: Robot, side_lengths_m, runs_per_direction: int = 5) -> LegHeadingCurve:
    """Evaluate the closed forms of this module on ``side_lengths_m`` (m)."""
    L = np.asarray(side_lengths_m, dtype=float)
    beta = np.abs(leg_heading_systematic_rad(robot, L))
    sigma = leg_heading_noise_rad(robot, L)
    return LegHeadingCurve(
        L, beta, sigma, systematic_share(beta, sigma, runs_per_direction), runs_per_direction
    )
