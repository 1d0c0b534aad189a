"""``odocal fleet``: a fleet's bags calibrated as they arrive, a history per robot, drift alarms
and a dashboard (docs/fleet.md). Subcommands ``ingest``, ``status``, ``export``, ``report``,
``alarms``, ``ack``."""

from __future__ import annotations

import argparse

from ..errors import one_line, quote_path
from .common import ProgressBar, positive_int, print_json, print_table, print_warnings


def add_parser(sub) -> None:
    """Add ``odocal fleet`` and its subcommands to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "fleet",
        description="Watch a fleet: calibrate every new bag of every robot with the bag route "
        "(fit --method auto), keep each robot's history in a database, raise drift alarms, "
        "write a dashboard (docs/fleet.md).",
    )
    fs = p.add_subparsers(dest="fleet_command", metavar="SUBCOMMAND", parser_class=type(p))
    fs.required = True
    ing = fs.add_parser(
        "ingest",
        help="calibrate and store every new bag under ROOT",
        description="ROOT holds one folder per robot: ROOT/<robot_id>/robot.yaml (its nominal "
        "geometry) and its bags anywhere below it (.bag, ROS 2 folders, .mcap, .db3). Bags "
        "already stored (by content, so copies and renames too) are skipped.",
    )
    ing.add_argument("root", metavar="ROOT", help="the fleet's folder (one folder per robot)")
    ing.add_argument(
        "--workers",
        type=positive_int,
        default=1,
        help="worker processes on this machine (default 1: this process)",
    )
    ing.add_argument(
        "--dask",
        metavar="ADDRESS",
        help="run the bags on the Dask distributed scheduler at ADDRESS "
        "(e.g. tcp://10.0.0.5:8786) instead",
    )
    st = fs.add_parser("status", help="one row per robot: bags, current parameters, drift")
    ex = fs.add_parser(
        "export",
        help="write a robot's current parameters for diff_drive_controller (as fit --ros2)",
    )
    ex.add_argument("robot_id", metavar="ROBOT_ID")
    ex.add_argument("--ros2", metavar="FILE", required=True, help="the YAML file to write")
    ex.add_argument(
        "--controller-name",
        default="diff_drive_controller",
        help="the controller's name in the file (default diff_drive_controller)",
    )
    rep = fs.add_parser("report", help="write the static HTML dashboard")
    rep.add_argument("--html", metavar="DIR", required=True, help="the folder to write")
    al = fs.add_parser(
        "alarms",
        help="list the drift alarms: robot, parameter, bag, size, z, raised, acknowledged",
    )
    ack = fs.add_parser(
        "ack",
        help="acknowledge a drift alarm (kept in the history, no longer active)",
        description="Acknowledge one drift alarm: it stays in 'fleet alarms' and the robot's "
        "history, and no longer counts as the robot's drift alarm in 'fleet status' and the "
        "dashboard.",
    )
    ack.add_argument("robot_id", metavar="ROBOT_ID")
    ack.add_argument(
        "parameter",
        metavar="PARAMETER",
        help="wheel_diameter_right_m (D_R), wheel_diameter_left_m (D_L) or wheelbase_m (b)",
    )
    ack.add_argument(
        "bag",
        metavar="BAG",
        nargs="?",
        help="the bag that raised it (its path as 'fleet alarms' lists it, or the start of its "
        "sha256); needed when the parameter has more than one alarm not acknowledged",
    )
    for q in (ing, st, ex, rep, al, ack):
        q.add_argument("--db", metavar="FLEET_DB", required=True, help="the fleet database file")
        q.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def _mm(p: dict | None, key: str) -> str:
    if not p or key not in p:
        return "-"
    return f"{1e3 * p[key]['value']:.3f}"


def run(args: argparse.Namespace) -> int:
    """Run the subcommand; print its result (text or ``--json``)."""
    cmd = args.fleet_command
    if cmd == "ingest":
        from ..app.fleet import fleet_ingest

        bar = ProgressBar("ingest")
        try:
            res = fleet_ingest(
                args.root,
                args.db,
                workers=args.workers,
                dask=args.dask,
                on_stored=lambda o, done, total: bar(done, total, o.status),
            )
        finally:
            bar.close()
        print_warnings(res.warnings)
        if args.json:
            print_json(res.as_dict())
            return 0
        print(
            f"{res.bags_total} bags under {args.root} ({res.robots} robots): {res.bags_new} "
            f"new, {res.bags_failed} failed ({res.bags_retry} to retry), {res.bags_skipped} "
            f"already stored; {res.seconds:.1f} s on {res.engine}"
        )
        for bag, why in res.failures:
            print(one_line(f"  failed: {why if why.startswith(bag) else f'{bag}: {why}'}"))
        for _, why in res.robot_failures:
            print(one_line(f"  robot not ingested: {why}"))
        return 0
    if cmd == "status":
        from ..app.fleet_status import fleet_status

        st = fleet_status(args.db)
        if args.json:
            print_json(st.as_dict())
            return 0
        rows: list[tuple] = [
            ("robot", "bags", "failed", "untrusted", "D_R mm", "D_L mm", "b mm", "drift")
        ]
        for r in st.robots:
            d = r.as_dict()["drift"]
            drift = "-" if d is None else f"{d['parameter']} {d['size_percent']:+.2f}%"
            if not r.trusted:
                drift = "no trusted calibration"
            rows.append(
                (
                    quote_path(r.robot_id),
                    r.bags,
                    r.bags_failed,
                    r.bags_untrusted,
                    *(
                        _mm(r.parameters, k)
                        for k in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
                    ),
                    drift,
                )
            )
        print_table(rows)
        return 0
    if cmd == "export":
        from ..app.fleet_status import fleet_export

        ex = fleet_export(args.db, args.robot_id, args.ros2, controller_name=args.controller_name)
        if args.json:
            print_json(ex.as_dict())
            return 0
        print(
            f"{quote_path(ex.robot_id)}: filtered level of {ex.bags} bags written to "
            f"{quote_path(args.ros2)}"
        )
        return 0
    if cmd == "alarms":
        return _alarms(args)
    if cmd == "ack":
        from ..app.fleet_alarms import fleet_ack

        done = fleet_ack(args.db, args.robot_id, args.parameter, args.bag)
        if args.json:
            print_json(done.as_dict())
            return 0
        a = done.alarm
        word = "already acknowledged" if done.already else "acknowledged"
        print(
            f"{quote_path(a.robot_id)} {a.parameter}: the alarm raised by "
            f"{quote_path(a.bag or a.content_hash)} ({a.raised_at}) {word} at {a.acknowledged_at}"
        )
        return 0
    from ..app.fleet_report import fleet_report

    rep = fleet_report(args.db, args.html)
    if args.json:
        print_json(rep.as_dict())
        return 0
    print(f"dashboard of {rep.robots} robots ({rep.bags} bags): {rep.index}")
    return 0


def _alarms(args: argparse.Namespace) -> int:
    """``odocal fleet alarms``: one row per stored alarm."""
    from ..app.fleet_alarms import fleet_alarms

    res = fleet_alarms(args.db)
    if args.json:
        print_json(res.as_dict())
        return 0
    if not res.alarms:
        print(f"no drift alarm in {quote_path(args.db)}")
        return 0
    rows: list[tuple] = [("robot", "parameter", "bag", "size mm", "z", "raised", "state")]
    for a, active in zip(res.alarms, res.active, strict=True):
        if a.acknowledged:
            state = f"acknowledged {a.acknowledged_at}"
        else:
            state = "ACTIVE" if active else "past (over 30 days before the robot's latest bag)"
        rows.append(
            (
                quote_path(a.robot_id),
                a.parameter,
                quote_path(a.bag or a.content_hash),
                f"{1e3 * a.size:+.3f}",
                f"{a.z:+.1f}",
                a.raised_at,
                state,
            )
        )
    print_table(rows)
    return 0
