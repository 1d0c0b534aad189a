"""The relative-motion routes (app.fit_relative): what they refuse before anything is written."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import pytest

from odocal.app.common import Exports
from odocal.app.fit import fit
from odocal.app.fit_relative import fit_relative, fit_tuple_files
from odocal.calibration.relative_motions import overlapping_sources
from odocal.core.model import WheelGeometry
from odocal.errors import CalibrationError, InputError
from odocal.io.outputs import OutputPlan
from odocal.io.robot_file import load_params
from tests.support.relative_intervals import motions, tuple_text

KHEPERA = WheelGeometry(0.042, 0.042, 0.089)


def test_tuples_in_degrees_per_second_are_refused_and_nothing_is_written(tmp_path):
    # wheel speeds in deg/s: 0.7 mm wheels on an 89 mm wheelbase, a PARAMS.yaml the robot-file
    # reader refuses; no nominal geometry to compare with, the plausibility check still applies
    path = tmp_path / "deg.tuple"
    path.write_text(tuple_text(geometry=KHEPERA, speed_scale=180 / math.pi))
    out = tmp_path / "PARAMS.yaml"
    plan = OutputPlan([path])
    exports = Exports(out=out)
    exports.register(plan)
    with pytest.raises(CalibrationError, match="not a plausible robot.*rad/s, not deg/s"):
        fit_tuple_files([path], plan, exports=exports)
    assert not out.exists()


def test_tuples_in_radians_per_second_give_a_params_file_that_reads_back(tmp_path):
    path = tmp_path / "rad.tuple"
    path.write_text(tuple_text(geometry=KHEPERA))
    out = tmp_path / "PARAMS.yaml"
    plan = OutputPlan([path])
    exports = Exports(out=out)
    exports.register(plan)
    res = fit_tuple_files([path], plan, exports=exports)
    assert load_params(out).wheelbase_m == pytest.approx(0.089, rel=1e-3)
    assert res.fit.geometry.diameter_right_m == pytest.approx(0.042, rel=1e-3)


@pytest.mark.parametrize(
    ("source", "hint"),
    [("scan", "scan header"), ("slam", "--truth-frames"), ("tuples", "rad/s")],
)
def test_an_absurd_result_names_what_its_source_can_get_wrong(source, hint):
    # not "the wheels and the ticks" for every route: a scan route's cause can be its header
    nominal = WheelGeometry(0.2, 0.2, 0.35)  # the data's wheelbase is 0.52 m: +49 %
    with pytest.raises(CalibrationError, match=hint):
        fit_relative([motions(n=60)], nominal, sensor_pose=(0, 0, 0), source=source)


def test_two_bags_covering_the_same_time_are_refused():
    # the same SLAM bag twice (a copy under another name): its intervals would count twice and
    # shrink the standard errors by sqrt 2 without a word
    a = motions(n=60, seed=0)
    with pytest.raises(InputError, match="a.bag and b.bag cover the same time.*count twice"):
        fit_relative([a, a], None, sensor_pose=(0, 0, 0), names=["a.bag", "b.bag"])
    later = replace(a, start_s=a.start_s + 60.0, end_s=a.end_s + 60.0)  # the next hour's bag
    fit, _ = fit_relative([a, later], None, sensor_pose=(0, 0, 0), names=["a.bag", "b.bag"])
    assert fit.tuples_used == 120
    # a log and its second half: the half's intervals are the log's
    half = replace(a, **{f: getattr(a, f)[30:] for f in ("phi_right_rad", "phi_left_rad",
                                                         "sensor_motion", "start_s", "end_s")},
                   increments=tuple(x[30:] for x in a.increments))  # fmt: skip
    with pytest.raises(InputError, match="b.bag cover the same time .30 s of it"):
        fit_relative([a, half], None, sensor_pose=(0, 0, 0), names=["a.bag", "b.bag"])


def test_two_recordings_that_only_share_a_clock_are_both_used():
    # a simulator whose time restarts at zero, a robot without a clock that starts at the same
    # date at every boot: two runs on the same stamps, but different measurements
    a, b = motions(n=60, seed=0), motions(n=60, seed=1)
    assert (a.start_s == b.start_s).all()
    fit, _ = fit_relative([a, b], None, sensor_pose=(0, 0, 0), names=["a.bag", "b.bag"])
    assert fit.tuples_used == 120
    # standing still on the same stamps is no shared measurement either
    still = replace(b, sensor_motion=0.0 * b.sensor_motion)
    assert overlapping_sources([replace(a, sensor_motion=0.0 * a.sensor_motion), still]) is None


def test_a_folder_of_tuple_files_is_fitted_as_its_files(tmp_path):
    folder = tmp_path / "tuples"
    folder.mkdir()
    for seed in (1, 2):
        (folder / f"run{seed}.tuple").write_text(tuple_text(n=40, geometry=KHEPERA, seed=seed))
    res = fit(folder)
    assert res.source == "tuples"
    assert [Path(t.path).name for t in res.tuple_files] == ["run1.tuple", "run2.tuple"]
    assert res.fit.geometry.wheelbase_m == pytest.approx(0.089, rel=1e-3)
