"""The ``quatform ros2`` and ``quatform replay`` subcommands (ROS 2 bridge layer, called by :mod:`quatform.cli`)."""

from __future__ import annotations

import json
import math

__all__ = ["ros2_arguments", "replay_arguments", "run_ros2", "run_replay", "robot_index", "make_transport",
           "auto_transport", "BOTH_MISSING"]


def ros2_arguments(p) -> None:
    """The description and options of ``quatform ros2`` on its parser ``p``."""
    p.description = (
        "Start a ROS 2 node that subscribes to each robot's pose (robots.toml), runs the controller "
        "of SCENARIO at --rate on its reference (or a plan.npz) and publishes each robot's commands (Twist, "
        "TwistStamped, MAVROS or PX4 velocity setpoints). Stale poses zero and hold every command; a robot "
        "without a pose within [bridge] start_timeout_s stops the start; the e-stop topic/service latches zero "
        "commands until released. With --robot, a network scenario's node of one robot (one per robot): its "
        "pose in, its neighbours' messages from /<their namespace>/quatform/message, its command and its "
        "message out (docs/networks.md, \"One robot's node\"). --transport rclpy needs a sourced ROS 2 "
        "installation; --transport dds speaks ROS 2 on the wire through Cyclone DDS without one (pip install -e "
        "\".[dds]\"; ROS_DOMAIN_ID, CYCLONEDDS_URI); --transport auto (the default) takes rclpy where it is "
        "importable, else dds. See docs/ros2.md.")
    p.add_argument("--scenario", required=True, metavar="SCENARIO", help="built-in name or file.toml")
    p.add_argument("--robots", required=True, metavar="ROBOTS_TOML", help="robots file (docs/ros2.md)")
    p.add_argument("--controller", metavar="NAME", help="the kind's controller (ugv-uav: its formation)")
    p.add_argument("--rate", type=float, metavar="HZ", help="control rate (default: the scenario's control rate)")
    p.add_argument("--reference", metavar="PLAN_NPZ", help="a plan.npz to follow instead of the scenario's path")
    from .transport import TRANSPORTS

    p.add_argument("--transport", choices=("auto", *TRANSPORTS), default="auto",
                   help="rclpy (a sourced ROS 2), dds (Cyclone DDS, no ROS installation) or auto (the default: "
                   "rclpy where it is importable, else dds, saying which on stderr)")
    p.add_argument("--use-sim-time", action="store_true",
                   help="the node's clock is /clock's (ROS's use_sim_time: a simulator's time)")
    p.add_argument("--robot", metavar="I", help="run robot I's node of a network scenario (its number 1..N in the "
                   "scenario's and the robots file's order, or its name there)")


def robot_index(robot: str, robots, n: int, where: str) -> int:
    """The 0-based index of ``--robot`` (a number 1..n or a name of the robots file ``robots``)."""
    from ..errors import InvalidInputError

    names = robots.names
    if robot in names:
        return names.index(robot)
    try:
        k = int(robot)
    except ValueError:
        raise InvalidInputError(f"--robot {robot!r} is neither a robot number (1..{n}) nor a robot of "
                                f"{robots.where} ({', '.join(names)})") from None
    if not 1 <= k <= n:
        raise InvalidInputError(f"--robot {k} is out of range: {where} has robots 1..{n}")
    return k - 1


def replay_arguments(p) -> None:
    """The description and options of ``quatform replay`` on its parser ``p``."""
    p.description = (
        "Read every robot's poses from BAG (a rosbag2 folder or .mcap file; topics from robots.toml), "
        "run the controller of SCENARIO on them as the ROS 2 node would (same stale rule, same reference time) "
        "and write DIR/commands.csv, DIR/commands.mcap (the messages on their topics), DIR/commands.png "
        "(commanded vs measured) and DIR/metrics.json. No ROS needed.")
    p.add_argument("bag", metavar="BAG")
    p.add_argument("--scenario", required=True, metavar="SCENARIO", help="built-in name or file.toml")
    p.add_argument("--robots", required=True, metavar="ROBOTS_TOML", help="robots file (docs/ros2.md)")
    p.add_argument("--controller", metavar="NAME", help="the kind's controller (ugv-uav: its formation)")
    p.add_argument("--reference", metavar="PLAN_NPZ", help="a plan.npz to follow instead of the scenario's path")
    p.add_argument("--rate", type=float, metavar="HZ", help="tick rate (default: at each pose time of any robot)")
    p.add_argument("--stamps", choices=("header", "log"), default="header",
                   help="pose times: header stamps (default) or the bag's receive times")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--no-plots", action="store_true", help="no commands.png")


#: The line ``--transport auto`` gives where neither middleware is importable.
BOTH_MISSING = ("quatform ros2 needs a ROS 2 middleware and neither is importable here: source your ROS 2 "
                "installation for rclpy (e.g. source /opt/ros/humble/setup.bash; rclpy is not a pip dependency), or "
                "install Cyclone DDS's Python binding to speak ROS 2 on the wire without ROS: "
                "pip install -e \".[dds]\"")


def auto_transport() -> str:
    """``--transport auto``'s middleware: ``rclpy`` where it is importable, else ``dds`` where
    ``cyclonedds`` is, said in one stderr line; neither is one line naming both installs."""
    import sys

    from ..errors import MissingDependencyError
    from .dds import import_cyclonedds
    from .rclpy_transport import import_rclpy

    for name, load, what in (("rclpy", import_rclpy, "rclpy, a sourced ROS 2"),
                             ("dds", import_cyclonedds, "dds, Cyclone DDS on the wire without ROS: rclpy is not "
                              "importable here")):
        try:
            load()
        except MissingDependencyError:
            continue
        print(f"quatform: --transport auto: {what}", file=sys.stderr, flush=True)
        return name
    raise MissingDependencyError(BOTH_MISSING)


def make_transport(name: str, use_sim_time: bool = False):
    """The :class:`~.transport.Transport` of ``--transport`` (its middleware imported only here;
    ``auto``: :func:`auto_transport`)."""
    if name == "auto":
        name = auto_transport()
    if name == "dds":
        from .dds import DdsTransport

        return DdsTransport(use_sim_time=use_sim_time)
    from .rclpy_transport import RclpyTransport

    return RclpyTransport(use_sim_time=use_sim_time)


def run_ros2(args) -> None:
    """``quatform ros2``: build the bridge (refusing bad files before the middleware is touched), then
    the node on ``--transport``: every robot's (:class:`~.node.BridgeNode`), or with ``--robot`` one
    robot's of a network scenario (:class:`~.local_node.LocalNode`)."""
    from ..errors import InvalidInputError
    from .bridge import FormationBridge, experiment_for
    from .node import BridgeNode
    from .robots_file import read_robots_file

    if args.rate is not None and not (math.isfinite(args.rate) and args.rate > 0):
        raise InvalidInputError(f"--rate {args.rate!r} must be a positive number of Hz")
    robots = read_robots_file(args.robots)
    experiment = experiment_for(args.scenario, args.controller, args.reference)
    where = str(experiment.scenario.name)
    if getattr(args, "robot", None) is not None:
        from .local_bridge import LocalBridge, local_experiment
        from .local_node import LocalNode

        ctrl = local_experiment(experiment, where)
        bridge = LocalBridge(experiment, robot_index(args.robot, robots, ctrl.n, where), robots)
        rate = args.rate if args.rate is not None else 1.0 / ctrl.period_s
        node = LocalNode(bridge, rate, make_transport(args.transport, args.use_sim_time))
    else:
        if experiment.meta.get("kind") == "network":
            raise InvalidInputError(f"{where} is a network scenario: every robot runs its own node; start one per "
                                    f"robot with --robot I (docs/networks.md, \"One robot's node\")")
        bridge = FormationBridge(experiment, robots)
        rate = args.rate if args.rate is not None else 1.0 / bridge.ref_dt
        node = BridgeNode(bridge, rate, make_transport(args.transport, args.use_sim_time))
    try:
        node.start()
    except BaseException:
        node.close()
        raise
    node.spin()


def run_replay(args) -> None:
    """``quatform replay``: one line of results and the folder."""
    from .replay import replay

    result = replay(args.bag, args.scenario, args.robots, args.out, controller=args.controller,
                    reference=args.reference, rate_hz=args.rate, stamps=args.stamps, plots=not args.no_plots)
    m = result.metrics
    print(json.dumps({k: m[k] for k in ("ticks", "ok_ticks", "stale_ticks", "stale_robots") if k in m}))
    print(f"files in {args.out}/ (commands.csv, commands.mcap, {'commands.png, ' if not args.no_plots else ''}"
          "metrics.json)")
