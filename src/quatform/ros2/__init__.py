"""The ROS 2 bridge: a scenario's controller on real robots, and offline on recorded bags.

Top layer (beside :mod:`quatform.runs`). rclpy (:mod:`.rclpy_transport`) and Cyclone DDS
(:mod:`.dds`) are imported only when a node is built on them; everything else runs without ROS:

* :mod:`.robots_file` - ``robots.toml``: each robot's pose and command topics, types, frames
  and stale-pose timeout;
* :mod:`.robot_io` - a measured pose to a robot model's state, its commands to twists;
* :mod:`.frames` - REP-103 (ENU/FLU) against PX4's NED/FRD;
* :mod:`.px4` - the ``px4_msgs`` definitions on rosbags' type store and their builders;
* :mod:`.endpoints` - the pose readers and command writers, by type name;
* :mod:`.bridge` - :class:`FormationBridge`: poses in, one control tick, commands out (stale
  poses, e-stop, the reference time);
* :mod:`.transport` - what a node needs from its middleware, and ROS 2's QoS profiles by name;
* :mod:`.rclpy_transport`, :mod:`.dds` - the transports: rclpy, and DDS on the wire without ROS;
* :mod:`.node` - the bridge's node, on either transport;
* :mod:`.local_bridge`, :mod:`.local_node` - one robot's node of a network scenario
  (decentralised: its pose and its neighbours' messages in, its command and its message out);
* :mod:`.bag_poses`, :mod:`.replay` - ``quatform replay``;
* :mod:`.cli` - the ``ros2`` and ``replay`` subcommands.

See ``docs/ros2.md``.
"""

from .bridge import FormationBridge, Tick, experiment_for
from .local_bridge import LocalBridge, RobotTick
from .robots_file import RobotsFile, read_robots_file

__all__ = ["FormationBridge", "Tick", "experiment_for", "LocalBridge", "RobotTick", "RobotsFile", "read_robots_file"]
