"""``odocal bag-info``: the topics, duration and frame tree of a ROS 1 or ROS 2 bag."""

from __future__ import annotations

from .common import print_json


def add_parser(sub) -> None:
    """Add ``odocal bag-info``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "bag-info",
        description="List the topics (name, message type, count), the duration and the frame "
        "tree of /tf and /tf_static of a ROS 1 .bag or a ROS 2 bag (.mcap, .db3 or a rosbag2 "
        "folder), to choose --joint-topic, --truth-topic, --imu-topic, --odom-topic and "
        "--truth-frames.",
    )
    p.add_argument("bag", metavar="BAG", help="a .bag, .mcap or .db3 file or a rosbag2 folder")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``odocal bag-info`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.bag_info import bag_info

    info = bag_info(args.bag)
    if args.json:
        print_json(info.as_dict())
        return 0
    print(info.text())
    return 0
