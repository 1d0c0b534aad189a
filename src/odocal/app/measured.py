"""The paper's steps 2 and 3 from recordings: a robot's systematic errors, its wheel noise and its
tracker's precision, measured from tracked runs and put together as a :class:`Robot` (what
``odocal design --robot-from`` designs for and ``odocal noise --robot-out`` writes)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from ..calibration.noise import RecordedNoise, estimate_k_from_recordings, tracker_noise
from ..calibration.result import GeometryFit
from ..calibration.trajectory import fit_trajectory
from ..core.model import (
    MeasurementNoise,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from ..core.recording import Recording
from ..errors import InputError

__all__ = ["MeasuredRobot", "measure_robot"]


@dataclass(frozen=True)
class MeasuredRobot:
    """A robot measured from recordings.

    Attributes
    ----------
    robot : Robot
        Nominal geometry; systematic errors (the trajectory fit relative to nominal); wheel noise
        (k_r, k_l from :func:`estimate_k_from_recordings`, each (k_r + k_l)/2 where the runs
        cannot split it); the instrument (given, else the tracker's jitter, counted twice: a
        final pose is measured relative to a measured start pose).
    fit : GeometryFit
        The trajectory fit behind the systematic errors.
    noise : RecordedNoise
    tracker : MeasurementNoise
        The tracker's per-sample noise, measured from the recordings' jitter.
    measurement_source : str
    """

    robot: Robot
    fit: GeometryFit
    noise: RecordedNoise
    tracker: MeasurementNoise
    measurement_source: str

    def describe(self) -> tuple[str, ...]:
        """Header lines saying where each number came from (for ROBOT.yaml)."""
        s, k, m = self.robot.systematic, self.robot.nonsystematic, self.robot.measurement
        lo, hi = self.noise.k_sum_ci95_m
        return (
            f"measured from {len(self.fit.runs)} recorded run(s) by odocal",
            f"systematic: {self.fit.method} fit relative to nominal (E_b {s.E_b:.6f}, E_d "
            f"{s.E_d:.6f}, E_s {s.E_s:.6f})",
            f"nonsystematic: k_r + k_l = {self.noise.k_sum_m:.3g} m (95 % {lo:.3g}-{hi:.3g}) "
            f"from {self.noise.runs} repeated runs ({self.noise.dof} dof); "
            + (
                "k_r, k_l split by the data"
                if self.noise.k_r_m is not None
                else "split evenly (not identifiable)"
            ),
            f"measurement: {self.measurement_source} (sigma_xy {m.sigma_xy_m:.3g} m, "
            f"sigma_theta {math.degrees(m.sigma_theta_rad):.3g} deg)",
        ) + (("k_r, k_l in metres",) if k.k_r_m else ())

    def as_dict(self) -> dict:
        """JSON-ready: the measured robot (nominal geometry in m, systematic errors, wheel noise k
        in m, the instrument's noise and its source), the tracker's jitter, the calibrated
        geometry and the k estimate (``robot`` in ``odocal noise --json``, ``robot_measured`` in
        ``odocal design --json``)."""
        r = self.robot
        return {
            "nominal": r.nominal.as_dict(),
            "systematic": {
                "E_b": r.systematic.E_b,
                "E_d": r.systematic.E_d,
                "E_s": r.systematic.E_s,
            },
            "nonsystematic": {"k_r_m": r.nonsystematic.k_r_m, "k_l_m": r.nonsystematic.k_l_m},
            "measurement": {
                "sigma_xy_m": r.measurement.sigma_xy_m,
                "sigma_theta_deg": math.degrees(r.measurement.sigma_theta_rad),
                "source": self.measurement_source,
            },
            "tracker_jitter": {
                "sigma_xy_m": self.tracker.sigma_xy_m,
                "sigma_theta_deg": math.degrees(self.tracker.sigma_theta_rad),
            },
            "calibrated": self.fit.geometry.as_dict(),
            "noise": self.noise.as_dict(),
        }


def measure_robot(
    recordings: Sequence[Recording],
    nominal: WheelGeometry,
    *,
    measurement: MeasurementNoise | None = None,
    noise_recordings: Sequence[Recording] | None = None,
    force: bool = False,
    fit: GeometryFit | None = None,
) -> MeasuredRobot:
    """Measure a robot from tracked runs (steps 2-3 of the paper's procedure).

    ``recordings``: runs for the systematic errors (trajectory fit, any motion);
    ``noise_recordings``: the repeated runs for k (default the same runs); ``measurement``:
    the instrument (default: the tracker's jitter, times sqrt(2)); ``force``: estimate k even
    when a group's heading errors drift with run order (a warning); ``fit``: a calibration of
    the same runs to use instead of the trajectory fit (e.g. ``odocal fit``'s own result)."""
    recs = list(recordings)
    if not recs:
        raise InputError("no recorded runs to measure the robot from")
    if fit is None:
        fit = fit_trajectory(recs, nominal=nominal)
    tracker = tracker_noise(recs)
    if measurement is None:
        measurement = MeasurementNoise(
            math.sqrt(2.0) * tracker.sigma_xy_m, math.sqrt(2.0) * tracker.sigma_theta_rad
        )
        source = "the tracker's jitter in the recordings, x sqrt(2) (start and end measured)"
    else:
        source = "given"
    # the noise estimate subtracts the tracker's heading noise (start and end)
    noise = estimate_k_from_recordings(
        list(noise_recordings) if noise_recordings is not None else recs,
        fit.geometry,
        MeasurementNoise(
            measurement.sigma_xy_m / math.sqrt(2.0), measurement.sigma_theta_rad / math.sqrt(2.0)
        ),
        strict=not force,
    )
    if noise.k_r_m is not None and noise.k_l_m is not None:
        k = NonSystematicError(noise.k_r_m, noise.k_l_m)
    else:
        k = NonSystematicError(noise.k_sum_m / 2.0, noise.k_sum_m / 2.0)
    robot = Robot(
        nominal,
        SystematicError.between(fit.geometry, nominal),
        k,
        measurement,
    )
    return MeasuredRobot(robot, fit, noise, tracker, source)
