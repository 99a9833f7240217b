"""Runs as ROS 2 bags, Foxglove layouts and Rerun recordings (bags layer, beside the report).

* :func:`write_mcap` - one world of a log as one ``run.mcap`` (every run writes it;
  ``docs/ecosystem.md``: topics, types, rates, frames, quaternion orders);
* :func:`run_messages` - the same messages by topic, CDR-encoded (what a live run streams);
* :func:`read_log` - that file back into the :class:`~quatform.sim.log.Log`, exactly;
* :func:`read_poses` - a user's ROS 2 bag of ``PoseStamped`` / ``Odometry`` topics as
  :class:`PoseTrack` arrays (``quatform replay``);
* :func:`foxglove_layout` / :func:`write_foxglove_layout` - a run's Foxglove layout (its kind's
  plots, registered with its scene in :data:`SCENES`, of topics its ``run.mcap`` has);
* :mod:`quatform.bags.rerun` - the same scene as a Rerun recording (extra ``rerun``; imported
  only when used).
"""

from .foxglove import FOXGLOVE_LAYOUT_FILE, foxglove_layout, write_foxglove_layout
from .mcap import CHANNEL_PREFIX, INFO_TOPIC, MCAP_FILE, RunMessages, channel_topic, read_log, run_messages, write_mcap
from .scene import SCENES, Scene, SceneKind, scene_of
from .user_bags import POSE_TYPES, PoseTrack, pose_topics, read_poses

__all__ = ["write_mcap", "run_messages", "RunMessages", "read_log", "read_poses", "pose_topics", "PoseTrack", "POSE_TYPES", "MCAP_FILE",
           "INFO_TOPIC", "CHANNEL_PREFIX", "channel_topic", "Scene", "SceneKind", "SCENES", "scene_of", "foxglove_layout",
           "write_foxglove_layout", "FOXGLOVE_LAYOUT_FILE"]
