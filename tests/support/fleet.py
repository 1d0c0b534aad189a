"""Simulated fleets for ``odocal fleet`` (tests and benchmarks/bench_fleet.py): one folder per
robot with its robot.yaml and small synthetic ROS 2 bags (tests/support/synthetic_robot.py: the
room tour once, joint states and odometry at 50 Hz, a SLAM ``map -> odom`` at 2 Hz with noise,
an 8-ray laser the scan route declines, no IMU): about 0.36 MB and 0.2-0.3 s of
``fit --method auto`` each."""

from __future__ import annotations

import json
import sqlite3
from dataclasses import replace
from pathlib import Path

import numpy as np

from odocal.calibration.route_answer import ParameterEstimate
from odocal.core.model import WheelGeometry
from odocal.io.fleet_record import CalibrationRecord
from tests.support.synthetic_robot import Laser, default_track, simulate_robot, write_ros2_bag

NOMINAL = WheelGeometry.symmetric(0.050, 0.250)
DAY_NS = 86400 * 10**9


def robot_yaml(folder: Path, nominal: WheelGeometry = NOMINAL) -> Path:
    """Write ``folder/robot.yaml`` with the nominal geometry (the robot runs with it)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "robot.yaml"
    path.write_text(
        f"wheel_diameter_right_m: {nominal.diameter_right_m!r}\n"
        f"wheel_diameter_left_m: {nominal.diameter_left_m!r}\n"
        f"wheel_diameter_m: {nominal.mean_diameter_m!r}\nwheelbase_m: {nominal.wheelbase_m!r}\n"
    )
    return path


def write_bag(
    path: Path,
    true: WheelGeometry,
    day: int,
    rng: np.random.Generator,
    *,
    believed: WheelGeometry = NOMINAL,
    slam_noise: tuple[float, float] = (0.002, 0.001),
) -> Path:
    """One bag of a robot whose true geometry is ``true``, recorded ``day`` days after the
    simulation's epoch (its stamps shifted)."""
    run = simulate_robot(default_track(), true, believed, laser=Laser(every=10, n_rays=8))
    run = replace(run, time_ns=run.time_ns + day * DAY_NS)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_ros2_bag(path, run, map_odom_every=25, imu=False, slam_noise=slam_noise, rng=rng)
    return path


KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def _model(std_errors) -> str | None:
    """'full' when every parameter has a standard error; else no model of the bag route's."""
    return "full" if all(s is not None for s in std_errors) else None


def fake_result(bag: str, values, std_errors, *, enough: bool = True) -> dict:
    """A ``fit --method auto`` JSON with the given (D_R, D_L, b) and standard errors (None: the
    parameter is held): the bag's report (for databases filled without bags)."""
    params = {k: {"value": float(v), "std_error": None if s is None else float(s),
                  "status": "held" if s is None else "estimated"}
              for k, v, s in zip(KEYS, values, std_errors, strict=True)}  # fmt: skip
    return {
        "method": "auto", "bag": bag, "answer_route": "slam",
        "answer_model": _model(std_errors), "parameters": params,
        "routes": [{"name": "slam", "used": True, "reason": "simulated"}],
        "nominal": NOMINAL.as_dict(), "time_offsets_s": {}, "time_offsets": [],
        "heldout": None, "cross_checks": [], "noise": None, "covariance": None,
        "verdict": {"enough": enough, "reasons": [] if enough else ["simulated doubt"]},
        "warnings": [], "written": [],
    }  # fmt: skip


def fake_record(values, std_errors, *, enough: bool = True) -> CalibrationRecord:
    """The calibration record of :func:`fake_result` (the SLAM route's answer; a parameter
    without a standard error held)."""
    p0, p1, p2 = (
        ParameterEstimate(k, float(v), None if s is None else float(s),
                          "held" if s is None else "estimated")
        for k, v, s in zip(KEYS, values, std_errors, strict=True)
    )  # fmt: skip
    return CalibrationRecord(
        odocal_version="test", route="slam", model=_model(std_errors), parameters=(p0, p1, p2),
        heading_ratio=None, heading_ratio_std_error=None, enough=enough,
        reasons=() if enough else ("simulated doubt",), time_offsets=(), covariance=None,
        nominal=NOMINAL,
    )  # fmt: skip


def fill_db(
    db, robots: dict, *, now: str = "2026-01-01T00:00:00+00:00", untrusted: tuple = ()
) -> None:
    """Store simulated histories in an open FleetDb without bags: ``robots`` maps each robot id
    to a list of ((D_R, D_L, b), (se, se, se)) per bag, one bag a day; the bags of the robots in
    ``untrusted`` have the verdict 'not to be trusted'."""
    for robot_id, bags in robots.items():
        db.upsert_robot(robot_id, NOMINAL.as_dict(), f"/fleet/{robot_id}", now)
        for i, (values, ses) in enumerate(bags):
            path = f"/fleet/{robot_id}/bag{i:03d}"
            db.store_bag(
                content_hash=f"{robot_id}-{i:04d}".ljust(64, "0"), robot_id=robot_id, path=path,
                size_bytes=1000, span_s=(1.7e9 + 86400.0 * i, 1.7e9 + 86400.0 * i + 60),
                status="done", reason=None, version="test", now=now,
                record=fake_record(values, ses, enough=robot_id not in untrusted),
                report=fake_result(path, values, ses, enough=robot_id not in untrusted),
            )  # fmt: skip


def first_format(fit: dict) -> dict:
    """A fit --json as the fleet's first version stored it: no status per parameter, no model
    (odocal before the route answers had them; a held parameter had an error of 0 or none)."""
    fit = json.loads(json.dumps(fit))
    fit.pop("answer_model")
    for p in (fit["parameters"] or {}).values():
        p.pop("status")
    return fit


def old_database(path: Path, robots: dict, now: str = "2026-01-01T00:00:00+00:00") -> None:
    """A fleet database as the code before the record wrote it: schema 2 (its two migrations),
    rows inserted as its store_bag did, ``result_json`` the fit --json of the time. ``robots``:
    robot id -> list of (status, fit --json or None) in time order."""
    from odocal.io.fleet_db import MIGRATIONS

    con = sqlite3.connect(path)
    schema = f"{MIGRATIONS[0]}{MIGRATIONS[1]} INSERT INTO schema_version VALUES (2);"
    con.executescript(f"CREATE TABLE schema_version (version INTEGER NOT NULL); {schema}")
    for robot_id, bags in robots.items():
        nominal = json.dumps(NOMINAL.as_dict())
        con.execute("INSERT INTO robots VALUES (?, ?, ?, ?, ?)",
                    (robot_id, nominal, f"/fleet/{robot_id}", now, now))  # fmt: skip
        for i, (status, fit) in enumerate(bags):
            h = f"{robot_id}-{i:04d}".ljust(64, "0")
            start = 1.7e9 + 86400.0 * i
            con.execute("INSERT INTO bags VALUES (?, ?, ?, 1000, ?, ?, ?, ?, '0.1.0', ?, 1)",
                        (h, robot_id, f"/fleet/{robot_id}/bag{i:03d}", start, start + 60, status,
                         None if status == "done" else "cannot read the bag", now))  # fmt: skip
            if fit is not None:
                p = fit.get("parameters") or {}  # (its store_bag's _columns)
                cols = [x for k in KEYS for x in (p.get(k, {}).get("value"),
                                                  p.get(k, {}).get("std_error"))]  # fmt: skip
                con.execute("INSERT INTO calibrations VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                            (h, fit["answer_route"], int(fit["verdict"]["enough"]), *cols,
                             json.dumps(fit, sort_keys=True)))  # fmt: skip
    con.commit()
    con.close()


def run_within(seconds: float, fn, *, fifo: Path | None = None):
    """``fn()`` in a thread; an AssertionError (not a wait for ever) when it takes longer than
    ``seconds``. A reader of the FIFO ``fifo`` waits for a writer for ever: its writing end is
    then opened and closed (the reader reads nothing) to free the thread."""
    import os
    import threading

    out: dict = {}

    def run():
        try:
            out["result"] = fn()
        except BaseException as exc:  # noqa: BLE001 - raised again in the caller's thread
            out["error"] = exc

    t = threading.Thread(target=run, daemon=True)
    t.start()
    t.join(seconds)
    if t.is_alive():
        if fifo is not None:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        t.join(30)
        raise AssertionError(f"still running after {seconds} s (waiting on a FIFO?)")
    if "error" in out:
        raise out["error"]
    return out["result"]
