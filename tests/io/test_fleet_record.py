"""The fleet's calibration record: typed, versioned, read back into the same type; older
versions through their upgrade (version 0: the ``fit --json`` the fleet stored up to schema 2),
a newer one or a missing key one clear error."""

from __future__ import annotations

import copy
import json

import pytest

from odocal.calibration.route_answer import ParameterEstimate
from odocal.core.model import WheelGeometry
from odocal.errors import InputError
from odocal.io.fleet_record import (
    RECORD_VERSION,
    CalibrationRecord,
    RecordError,
    StoredCovariance,
    StoredOffset,
)
from tests.support.fleet import NOMINAL, fake_result

KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def _record(**kw) -> CalibrationRecord:
    base = dict(
        odocal_version="0.1.0",
        route="slam",
        model="equal-diameters",
        parameters=(
            ParameterEstimate(KEYS[0], 0.0502, 3e-5, "tied"),
            ParameterEstimate(KEYS[1], 0.0498, 3e-5, "tied"),
            ParameterEstimate(KEYS[2], 0.2512, 2.5e-4, "estimated"),
        ),
        heading_ratio=None,
        heading_ratio_std_error=None,
        enough=True,
        reasons=(),
        time_offsets=(
            StoredOffset("slam", 0.1, 0.002, True),
            StoredOffset("scan", 1e-4, None, False),
        ),
        covariance=StoredCovariance(8.4e-8, 8.4e-8, 0.415, 1.0, 0.2),
        nominal=WheelGeometry(0.05, 0.05, 0.25),
    )
    base.update(kw)
    return CalibrationRecord(**base)


def _gyro(enough=True) -> CalibrationRecord:
    return _record(
        route="gyro",
        model="heading-ratio",
        parameters=(
            ParameterEstimate(KEYS[0], 0.05, None, "held"),
            ParameterEstimate(KEYS[1], 0.05, None, "held"),
            ParameterEstimate(KEYS[2], 0.2512, 2.5e-4, "estimated"),
        ),
        heading_ratio=0.9952,
        heading_ratio_std_error=0.001,
        enough=enough,
        reasons=() if enough else ("gyro: it measured a heading ratio only",),
        covariance=None,
    )


@pytest.mark.parametrize("record", [_record(), _gyro(False), _record(route=None, model=None,
                         parameters=None, enough=False, reasons=("no route",), time_offsets=(),
                         covariance=None)])  # fmt: skip
def test_a_record_round_trips_through_json(record):
    d = json.loads(json.dumps(record.as_dict()))
    assert d["record_version"] == RECORD_VERSION == 1
    back = CalibrationRecord.from_dict(d)
    assert back == record
    assert back.as_dict() == record.as_dict()


def test_a_newer_version_is_one_clear_error():
    d = _record().as_dict()
    d["record_version"] = RECORD_VERSION + 1
    with pytest.raises(
        RecordError, match="record version 2 was written by a newer odocal.*upgrade"
    ):
        CalibrationRecord.from_dict(d)
    assert issubclass(RecordError, InputError)  # one line and exit status 2 from the command


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (lambda d: d.pop("enough"), "record has no 'enough'"),
        (
            lambda d: d["parameters"][2].pop("std_error"),
            r"record.parameters\[2\] has no 'std_error'",
        ),
        (lambda d: d["parameters"][0].update(status="guessed"), "'guessed' is none of"),
        (lambda d: d["covariance"].pop("window_s"), "record.covariance has no 'window_s'"),
        (lambda d: d.update(enough="yes"), r"record.enough is 'yes', not true or false"),
        (lambda d: d.pop("record_version"), "record has no 'record_version'"),
        (lambda d: d.update(route="lidar"), "'lidar' is none of"),
    ],
)
def test_a_key_missing_or_of_the_wrong_type_is_named(edit, said):
    d = _record().as_dict()
    edit(d)
    with pytest.raises(RecordError, match=said):
        CalibrationRecord.from_dict(d)


def test_a_held_parameter_has_no_standard_error_and_a_ratio_holds_the_diameters():
    with pytest.raises(RecordError, match="held: it has no standard error"):
        _record(
            parameters=(ParameterEstimate(KEYS[0], 0.05, 0.0, "held"), *_record().parameters[1:])
        )
    with pytest.raises(RecordError, match="ratio-only answer holds the wheel diameters"):
        _record(heading_ratio=0.99)


def test_only_what_a_trustworthy_answer_estimated_is_a_measurement():
    r = _record()
    assert r.measurement(KEYS[2]) == (0.2512, 2.5e-4)
    assert r.measurement(KEYS[0]) is None and r.measurement(KEYS[1]) is None  # tied
    assert _record(enough=False, reasons=("x",)).measurement(KEYS[2]) is None
    g = _gyro()  # a ratio-only answer: its diameters are held, never a measurement
    assert g.ratio_only and g.measurement(KEYS[0]) is None and g.measurement(KEYS[1]) is None
    assert g.measurement(KEYS[2]) == (0.2512, 2.5e-4)
    free = tuple(ParameterEstimate(p.name, p.value, p.std_error, "estimated") for p in r.parameters)
    full = _record(model="full", parameters=free)
    assert full.measurement(KEYS[0]) == (0.0502, 3e-5)


# ---- version 0: the fit --json stored up to schema 2


def _v0(fit, version="0.1.0"):
    return {"record_version": 0, "odocal_version": version, "fit": fit}


def _without_statuses(fit):
    """The fit --json of the fleet's first version (before the route answers had a status and
    a model)."""
    old = copy.deepcopy(fit)
    old.pop("answer_model")
    for p in old["parameters"].values():
        p.pop("status")
    return old


def test_the_fit_json_of_the_first_fleet_reads_with_its_statuses_inferred():
    fit = _without_statuses(fake_result("/b", (0.0505, 0.0495, 0.25), (5e-5, 5e-5, 0.0)))
    fit["covariance"] = {"k_r_m": 1e-7, "k_l_m": 1e-7, "wheelbase_m": 0.25, "speed_m_s": 0.4,
                         "distance_m": 1.0, "window_s": 0.2, "pose_covariance_diagonal": [],
                         "twist_covariance_diagonal": [], "process_noise_per_s": {}}  # fmt: skip
    fit["time_offsets"] = [{"source": "slam", "offset_s": 0.05, "stderr_s": 0.01, "how": "x",
                            "applied": True, "intervals": 40, "warnings": []}]  # fmt: skip
    r = CalibrationRecord.from_dict(_v0(fit, "0.0.9"))
    assert r.odocal_version == "0.0.9" and r.route == "slam" and r.model is None
    assert [p.status for p in r.parameters] == ["estimated", "estimated", "held"]
    assert r.parameters[2].std_error is None  # a held b (an error of 0 then) is no measurement
    assert r.covariance == StoredCovariance(1e-7, 1e-7, 0.4, 1.0, 0.2)
    assert r.time_offsets == (StoredOffset("slam", 0.05, 0.01, True),)
    assert r.nominal == NOMINAL and r.enough and r.reasons == ()
    none = _without_statuses(fake_result("/b", (0.05, 0.05, 0.2512), (None, None, 2.5e-4)))
    assert [p.status for p in CalibrationRecord.from_dict(_v0(none)).parameters] == [
        "held", "held", "estimated"]  # fmt: skip


def test_the_fit_json_of_today_keeps_its_statuses_model_and_ratio():
    fit = fake_result("/b", (0.05, 0.05, 0.2512), (None, None, 2.5e-4), enough=False)
    fit["answer_route"], fit["answer_model"] = "gyro", "heading-ratio"
    fit["routes"] = [{"name": "gyro", "used": True, "reason": "x", "model": "heading-ratio",
                      "heading_ratio": {"value": 0.9952, "std_error": None}}]  # fmt: skip
    fit["parameters"]["wheel_diameter_left_m"]["status"] = "held"
    r = CalibrationRecord.from_dict(_v0(fit))
    assert r.route == "gyro" and r.model == "heading-ratio" and r.ratio_only
    assert (r.heading_ratio, r.heading_ratio_std_error) == (0.9952, None)
    assert not r.enough and r.reasons == ("simulated doubt",)
    tied = fake_result("/b", (0.0502, 0.0498, 0.25), (3e-5, 3e-5, 2e-4))
    tied["parameters"]["wheel_diameter_right_m"]["status"] = "tied"
    tied["parameters"]["wheel_diameter_left_m"]["status"] = "tied"
    r = CalibrationRecord.from_dict(_v0(tied))
    assert [p.status for p in r.parameters] == ["tied", "tied", "estimated"]
    assert r.measurement(KEYS[0]) is None and r.measurement(KEYS[2]) == (0.25, 2e-4)


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (lambda f: f.update(params=f.pop("parameters")), "record.fit has no 'parameters'"),
        (lambda f: f["parameters"]["wheelbase_m"].pop("std_error"),
         "record.fit.parameters.wheelbase_m has no 'std_error'"),
        (lambda f: f["verdict"].pop("enough"), "record.fit.verdict has no 'enough'"),
        (lambda f: f.pop("covariance"), "record.fit has no 'covariance'"),
        (lambda f: f["parameters"].update(b=f["parameters"].pop("wheelbase_m")),
         "record.fit.parameters has no 'wheelbase_m'"),
    ],
)  # fmt: skip
def test_a_renamed_or_missing_key_of_an_old_row_is_named_not_dropped(edit, said):
    """The readers took these keys with .get(): a row with 'params' for 'parameters' left the
    drift history without a word. Its upgrade names the key instead."""
    fit = fake_result("/b", (0.05, 0.05, 0.25), (5e-5, 5e-5, 2.5e-4))
    edit(fit)
    with pytest.raises(RecordError, match=said):
        CalibrationRecord.from_dict(_v0(fit))
