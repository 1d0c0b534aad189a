"""Designing for a robot whose errors are not known yet: a design over a range of plausible errors.

A new robot's E_b, E_d and k are what the calibration is for, so the technician cannot give them
to the design. A robot file without a ``systematic`` section (or without ``nonsystematic``) is
therefore designed over the TYPICAL ranges below instead of as a perfect robot (which calibration
can only make worse). For every combination of the levels (a grid of plausible robots, the given
geometry and instrument kept) the analytic design gives the expected error after calibration of
every candidate. The *regret* of a candidate in one scenario is its error over the best
candidate's error, minus 1. The recommendation is the smallest candidate that, in every scenario,
no larger candidate beats by more than the tolerance (the single-robot rule of
:mod:`odocal.design.recommend`, applied to each plausible robot at once: a candidate beats it by
more than 5 % when its error is less than 95 % of the recommended one's). The report states how
close it stays in the rule's own terms, its worst-case *shortfall* (1 - best error / its error =
regret / (1 + regret)): "whatever the robot's errors in these ranges, no size beats this one by
more than X % of its error", so that X <= the tolerance whenever the best size is a larger one
(a regret of 5.1 % is a shortfall of 4.9 %: within a 5 % rule).

Typical ranges (documented with their sources in docs/design.md, "A new robot"):

- E_b 0.97 .. 1.03: Jung et al. 2014 (TETRA-DS II, 1.025 .. 1.028), Borenstein & Feng 1996
  (their example, 0.989), the OptiOdom robot (Sousa et al. 2022, published calibration: 1.005).
- E_d 0.995 .. 1.005: the same sources give 0.999 .. 1.0017 (0.999, 1.0017, 1.0008, 0.9992).
- k 1e-7 .. 3e-6 m (per wheel, Siegwart form): Chong & Kleeman 1997 measured 0.00040 and
  0.00058 m^0.5 on a parquet floor (1.6e-7 and 3.4e-7 m); Jung et al. use 1e-6 .. 2.89e-6 m.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.model import NonSystematicError, Robot
from .analytic import analytic_design, analytic_reference
from .result import Candidate, ValidationTrack, rounded, shape_name
from .spec import DesignSpec, Method

__all__ = [
    "TYPICAL_E_B",
    "TYPICAL_E_D",
    "TYPICAL_K_M",
    "unknown_errors",
    "plausible_robots",
    "RangeDesign",
    "range_design",
]

#: Levels of the grid of plausible robots (module docstring for the sources).
TYPICAL_E_B = (0.97, 0.99, 1.01, 1.03)
TYPICAL_E_D = (0.995, 0.999, 1.005)
TYPICAL_K_M = (1e-7, 5.5e-7, 3e-6)


def unknown_errors(robot: Robot) -> tuple[str, ...]:
    """Which error classes the robot leaves unknown: 'systematic' when it has none (E_b = E_d =
    E_s = 1), 'nonsystematic' when its wheels have no noise (k = 0). A real robot has both."""
    out = []
    s = robot.systematic
    if s.E_b == 1.0 and s.E_d == 1.0 and s.E_s == 1.0:
        out.append("systematic")
    if robot.nonsystematic.is_zero:
        out.append("nonsystematic")
    return tuple(out)


def plausible_robots(
    robot: Robot, unknown: Sequence[str], levels: dict | None = None
) -> list[tuple[dict, Robot]]:
    """The grid of plausible robots: ``robot`` with each unknown error class set to every
    combination of its typical levels (``levels`` {'E_b', 'E_d', 'k_m': sequences} replaces
    them). Returns (levels, robot) pairs."""
    lv = {"E_b": TYPICAL_E_B, "E_d": TYPICAL_E_D, "k_m": TYPICAL_K_M} | (levels or {})
    eb = lv["E_b"] if "systematic" in unknown else (robot.systematic.E_b,)
    ed = lv["E_d"] if "systematic" in unknown else (robot.systematic.E_d,)
    ks = lv["k_m"] if "nonsystematic" in unknown else (None,)
    out = []
    for b in eb:
        for d in ed:
            for k in ks:
                sysn = dataclasses.replace(robot.systematic, E_b=b, E_d=d)
                noise = robot.nonsystematic if k is None else NonSystematicError(k, k)
                levels = {"E_b": b, "E_d": d}
                levels["k_m"] = (
                    k if k is not None else 0.5 * (noise.k_r_m + noise.k_l_m)  # as given
                )
                out.append(
                    (levels, dataclasses.replace(robot, systematic=sysn, nonsystematic=noise))
                )
    return out


@dataclass(frozen=True)
class RangeDesign:
    """A design over plausible robots (module docstring).

    Attributes
    ----------
    candidates : tuple of Candidate
        The candidate tracks (their statistics are those of the first scenario; use ``errors``).
    scenarios : tuple of dict
        The levels (E_b, E_d, k_m) of each plausible robot.
    errors : ndarray, shape (scenarios, candidates)
        Expected final position error after calibration on each candidate (m).
    uncalibrated, floor : ndarray, shape (scenarios,)
        Expected error without calibration, and with the true parameters (m).
    index : int
        The recommended candidate.
    within : float
        Its worst-case shortfall, in the rule's terms: 1 - best candidate's error / its error,
        over the scenarios (at most the tolerance when the best is a larger candidate).
    worst_scenario : int
        Where that worst case is.
    accepted : bool
        False when no candidate passes the rule (``index`` then minimises the worst-case
        regret; cannot happen while the largest candidate has finite errors).
    unknown : tuple of str
        The error classes designed over ('systematic', 'nonsystematic').
    tolerance : float
    validation : ValidationTrack
    method : str
    runs_per_direction : int
    """

    candidates: tuple[Candidate, ...]
    scenarios: tuple[dict, ...]
    errors: np.ndarray
    uncalibrated: np.ndarray
    floor: np.ndarray
    index: int
    within: float
    worst_scenario: int
    accepted: bool
    unknown: tuple[str, ...]
    tolerance: float
    validation: ValidationTrack
    method: Method
    runs_per_direction: int

    @property
    def recommended(self) -> Candidate:
        """The recommended candidate."""
        return self.candidates[self.index]

    @property
    def regret(self) -> np.ndarray:
        """error / best error - 1, shape (scenarios, candidates)."""
        return self.errors / np.nanmin(self.errors, axis=1, keepdims=True) - 1.0

    @property
    def shortfall(self) -> np.ndarray:
        """1 - best error / error, shape (scenarios, candidates): by how much (a fraction of this
        candidate's error) the best candidate beats it, the measure of the rule's tolerance."""
        return 1.0 - np.nanmin(self.errors, axis=1, keepdims=True) / self.errors

    @property
    def worst_shortfall(self) -> np.ndarray:
        """Each candidate's largest shortfall over the scenarios, shape (candidates,)."""
        return np.nanmax(self.shortfall, axis=0)

    @property
    def worst_regret(self) -> np.ndarray:
        """Each candidate's largest regret over the scenarios, shape (candidates,)."""
        return np.nanmax(self.regret, axis=0)

    @property
    def error_min_m(self) -> np.ndarray:
        """Each candidate's smallest expected error over the scenarios (m), shape (candidates,)."""
        return np.nanmin(self.errors, axis=0)

    @property
    def error_max_m(self) -> np.ndarray:
        """Each candidate's largest expected error over the scenarios (m), shape (candidates,)."""
        return np.nanmax(self.errors, axis=0)

    @property
    def uncalibrated_range_m(self) -> tuple[float, float]:
        """Smallest and largest uncalibrated error over the scenarios (m)."""
        return float(np.min(self.uncalibrated)), float(np.max(self.uncalibrated))

    @property
    def floor_range_m(self) -> tuple[float, float]:
        """Smallest and largest floor (true parameters) over the scenarios (m)."""
        return float(np.min(self.floor)), float(np.max(self.floor))

    def level_range(self, key: str) -> tuple[float, float]:
        """Smallest and largest level of ``key`` ('E_b', 'E_d' or 'k_m') over the scenarios."""
        return min(s[key] for s in self.scenarios), max(s[key] for s in self.scenarios)

    @property
    def no_gain(self) -> np.ndarray:
        """Scenarios in which calibrating on the recommended track does not beat the
        uncalibrated robot, shape (scenarios,) of bool."""
        return ~(self.errors[:, self.index] < self.uncalibrated)

    @property
    def warnings(self) -> tuple[str, ...]:
        """The design's warnings: no candidate within the tolerance everywhere, and the plausible
        robots that calibrating would not help."""
        out = []
        if not self.accepted:
            out.append(
                f"no candidate is within the {100 * self.tolerance:g} % tolerance for every "
                f"plausible robot; the recommended one has the smallest worst case "
                f"(beaten by {100 * self.within:.1f} %)"
            )
        bad = int(self.no_gain.sum())
        if bad:
            out.append(
                f"for {bad} of the {len(self.scenarios)} plausible robots (the smallest errors), "
                "calibrating on the recommended track would not beat the uncalibrated robot: a "
                "robot that good needs a more precise instrument or more runs"
            )
        return tuple(out)

    def as_dict(self) -> dict:
        """The JSON of ``odocal design --json`` over a range of errors: the ranges and scenarios,
        every candidate's worst regret and error range (m), the recommendation, the uncalibrated
        and floor errors (m) and the settings."""
        r = self.recommended
        ranges = {k: self.level_range(k) for k in ("E_b", "E_d", "k_m")}
        worst, lo, hi = self.worst_regret, self.error_min_m, self.error_max_m
        short = self.worst_shortfall
        return {
            "error_range": {
                "unknown": list(self.unknown),
                "ranges": {k: [rounded(v[0]), rounded(v[1])] for k, v in ranges.items()},
                "scenarios": [{k: rounded(v) for k, v in s.items()} for s in self.scenarios],
                "engine": "analytic",
            },
            "candidates": [
                {
                    "sides": c.sides,
                    "side_m": rounded(c.side_m),
                    "travel_m": rounded(c.travel_m),
                    "worst_regret": rounded(float(worst[i])),
                    "worst_shortfall": rounded(float(short[i])),
                    "post_error_min_m": rounded(float(lo[i])),
                    "post_error_max_m": rounded(float(hi[i])),
                }
                for i, c in enumerate(self.candidates)
            ],
            "recommended": {
                "sides": r.sides,
                "side_m": rounded(r.side_m),
                "travel_m": rounded(r.travel_m),
                "within_best": rounded(self.within),
                "worst_case": {
                    k: rounded(v) for k, v in self.scenarios[self.worst_scenario].items()
                },
                "accepted": self.accepted,
            },
            "uncalibrated_m": [rounded(float(v)) for v in self.uncalibrated],
            "floor_m": [rounded(float(v)) for v in self.floor],
            "tolerance": self.tolerance,
            "method": self.method,
            "runs_per_direction": self.runs_per_direction,
            "validation": self.validation.as_dict(),
            "warnings": list(self.warnings),
        }

    def describe(self) -> str:
        """One line: the recommended track and how close to the best it stays over the ranges (its
        worst case)."""
        r = self.recommended
        w = self.scenarios[self.worst_scenario]
        return (
            f"{shape_name(r.sides)}, side {r.side_m:g} m ({r.travel_m:g} m travel per run): "
            f"whatever the robot's errors in these ranges, no size beats it by more than "
            f"{100 * self.within:.1f} % of its error (worst case E_b {w['E_b']:g}, "
            f"E_d {w['E_d']:g}, k {w['k_m']:.2g} m)"
        )


def range_design(
    robot: Robot,
    spec: DesignSpec,
    *,
    unknown: Sequence[str] | None = None,
    progress: Callable[[int, int, str], None] | None = None,
    levels: dict | None = None,
) -> RangeDesign:
    """The design over plausible robots (module docstring), by the analytic engine, over the
    candidates of ``spec`` (sizes it leaves open scaled to the robot; its rule's tolerance;
    ``spec.trials``, ``alpha`` and ``criterion`` play no part). ``unknown``: the error classes
    designed over (default :func:`unknown_errors`); ``levels`` replaces the typical levels (see
    :func:`plausible_robots`)."""
    from .sweep import equal_travel_side_lengths

    spec = spec.for_wheelbase(float(robot.nominal.wheelbase_m))
    validation, tolerance = spec.validation_track, spec.tolerance
    runs_per_direction, method = spec.runs_per_direction, spec.method
    unknown = tuple(unknown_errors(robot) if unknown is None else unknown)
    grid = plausible_robots(robot, unknown, levels)
    track = validation.track()
    shapes = equal_travel_side_lengths(spec.lengths_m, spec.sides)
    errors, uncal, floor = [], [], []
    candidates: list[Candidate] = []
    for k, (levels, r) in enumerate(grid):
        cands = []
        for N, lengths in shapes.items():
            # intervals only where they are reported: the robot as given (k == 0)
            cands += analytic_design(
                r, N, lengths, runs_per_direction, method, track, intervals=k == 0
            )
        if k == 0:
            candidates = cands
        errors.append([c.post_error_mean_m for c in cands])
        ref = analytic_reference(r, track)
        uncal.append(ref.uncalibrated_m)
        floor.append(ref.floor_m)
        if progress is not None:
            progress(k + 1, len(grid), f"E_b {levels['E_b']:g} E_d {levels['E_d']:g}")
    E = np.array(errors, dtype=float)
    order = sorted(
        range(len(candidates)), key=lambda i: (candidates[i].travel_m, candidates[i].sides)
    )
    regret = E / np.nanmin(E, axis=1, keepdims=True) - 1.0
    scale = 1.0 - tolerance
    index, accepted = None, True
    for pos, i in enumerate(order):
        larger = [j for j in order[pos + 1 :] if candidates[j].travel_m > candidates[i].travel_m
                  or candidates[j].sides != candidates[i].sides]  # fmt: skip
        if not np.all(np.isfinite(E[:, i])):
            continue
        beaten = any(bool(np.any(E[:, j] < scale * E[:, i])) for j in larger)
        if not beaten:
            index = i
            break
    if index is None:  # pragma: no cover - the largest candidate has no rival
        index, accepted = int(np.nanargmin(np.nanmax(regret, axis=0))), False
    shortfall = regret / (1.0 + regret)  # the rule's measure: 1 - best / this error
    worst = np.nanmax(shortfall[:, index])
    return RangeDesign(
        tuple(candidates),
        tuple(levels for levels, _ in grid),
        E,
        np.array(uncal),
        np.array(floor),
        int(index),
        float(worst),
        int(np.nanargmax(shortfall[:, index])),
        accepted,
        unknown,
        tolerance,
        validation,
        method,
        runs_per_direction,
    )
