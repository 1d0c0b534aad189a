"""Why the real experiment came out as it did: the checks behind docs/real-experiment.md's
explanation (issue 20.11), on the wheels' clock.

The per-band effective wheelbase (:mod:`odocal.calibration.turning`) compares rotations over
segments a second or two long; a spot turn at 1 rad/s moves 0.05 rad per 20 Hz sample, so the
truth's clock offset against the wheels enters it directly. :func:`on_wheel_clock` moves each
data set's truth by its own estimated offset (:func:`odocal.calibration.time_offset.truth_offset`,
applied whatever its significance, plus ``extra_s`` to probe the sensitivity), and
:func:`mixture_gain_ratio` says how much of a difference between two calibrations' turning gains
their runs' mix of spot and arc turning can explain.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from ..calibration.time_offset import shift_truth, truth_offset
from ..calibration.turning import BANDS, EffectiveWheelbase
from ..core.recording import Recording
from ..errors import CalibrationError

__all__ = ["truth_offsets_s", "on_wheel_clock", "mixture_gain_ratio"]


def truth_offsets_s(runs: Sequence[Recording]) -> dict[str, float]:
    """Data set -> the truth's estimated clock offset against the wheels (s); 0 where it cannot
    be estimated."""
    by_set: dict[str, list[Recording]] = {}
    for r in runs:
        by_set.setdefault(r.dataset, []).append(r)
    out = {}
    for name, group in by_set.items():
        try:
            out[name] = float(truth_offset(group).offset_s)
        except CalibrationError:
            out[name] = 0.0
    return out


def on_wheel_clock(
    runs: Sequence[Recording], offsets_s: Mapping[str, float], extra_s: float = 0.0
) -> list[Recording]:
    """The runs with their truth moved by their data set's offset plus ``extra_s`` (s)."""
    return [shift_truth(r, offsets_s.get(r.dataset, 0.0) + extra_s) for r in runs]


def mixture_gain_ratio(
    first: EffectiveWheelbase, second: EffectiveWheelbase, wheelbase_m: Mapping[str, float]
) -> float:
    """The ratio of turning gains (first / second - 1) that the two runs' mixes of motion
    (shares of their rotation per band) imply if the robot turned in every band with the same
    ``wheelbase_m`` (band -> m; a band without one takes the nearest band's, as the banded
    model does): rotation per wheel rotation sum_j share_j / b_j."""
    known = [i for i, n in enumerate(BANDS) if n in wheelbase_m]
    if not known:
        raise CalibrationError("mixture: no band has a wheelbase")

    def b(i: int) -> float:
        return float(wheelbase_m[BANDS[min(known, key=lambda j: (abs(j - i), j))]])

    def gain(t: EffectiveWheelbase) -> float:
        shares = t.motion_mix
        return sum(shares[n] / b(i) for i, n in enumerate(BANDS))

    return gain(first) / gain(second) - 1.0
