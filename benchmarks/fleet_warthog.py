"""What the fleet would have said about the Warthog's five recordings (issue 28 item 6): a fleet
of one skid-steer robot whose bags arrive one night at a time, in the order recorded, with the
drift alarms of ``odocal fleet`` on its effective track.

    .venv/bin/python benchmarks/fleet_warthog.py        # about a minute

Reads ``../shared/realdata/norlab_skid`` (links in a temporary folder; nothing is copied), and
prints after each night the track multiplier of the new bag with its standard error, the
verdict, and the fleet's alarms.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SKID = ROOT.parent / "shared" / "realdata" / "norlab_skid"


def main() -> None:
    from odocal.app.fleet import fleet_ingest
    from odocal.app.fleet_status import fleet_status
    from odocal.io.fleet_db import open_db

    bags = sorted(SKID.glob("warthog_wheels_grass*/*_bag"), key=_start_ns)
    with tempfile.TemporaryDirectory() as tmp:
        fleet = Path(tmp) / "fleet" / "warthog"
        fleet.mkdir(parents=True)
        robot = (SKID / "robots" / "warthog.yaml").read_text() + "kinematics: skid_steer\n"
        (fleet / "robot.yaml").write_text(robot)
        db = Path(tmp) / "fleet.db"
        for night, bag in enumerate(bags, 1):
            (fleet / bag.name).symlink_to(bag)
            fleet_ingest(fleet.parent, db)
            with open_db(db, write=False) as store:
                rows = [b for b in store.history("warthog") if b.status == "done"]
            last = rows[-1].record
            b = last.parameters[2]
            m, se = b.value / 1.08, (b.std_error or float("nan")) / 1.08
            status = fleet_status(db).as_dict()["robots"][0]
            alarms = status.get("alarms") or []
            print(
                f"night {night}: {bag.parent.name}: multiplier {m:.4f} +- {se:.4f}, "
                f"{'trustworthy' if last.enough else 'NOT trusted'}; fleet alarms: "
                + (", ".join(f"{a['parameter']} {a['z']:+.1f}" for a in alarms) or "none")
            )
            sys.stdout.flush()


def _start_ns(bag: Path) -> int:
    import yaml

    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    return int(meta["rosbag2_bagfile_information"]["starting_time"]["nanoseconds_since_epoch"])


if __name__ == "__main__":
    main()
