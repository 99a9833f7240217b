"""ROS 2 message packages for the fake rclpy: ``geometry_msgs.msg.PoseStamped`` and the rest are
rosbags' classes (quatform.messages.typestore, with px4_msgs registered), and
``std_srvs.srv.SetBool`` a small request/response pair."""

from __future__ import annotations

import sys
import types
from dataclasses import dataclass

PACKAGES = ("geometry_msgs", "nav_msgs", "std_msgs", "builtin_interfaces", "px4_msgs", "sensor_msgs")


@dataclass
class _SetBoolRequest:
    data: bool = False


@dataclass
class _SetBoolResponse:
    success: bool = False
    message: str = ""


class SetBool:
    Request = _SetBoolRequest
    Response = _SetBoolResponse


def _msg_module(pkg):
    mod = types.ModuleType(f"{pkg}.msg")

    def __getattr__(name):
        from quatform.ros2.px4 import register_px4_types

        store = register_px4_types()
        key = f"{pkg}/msg/{name}"
        if key not in store.types:
            raise AttributeError(name)
        return store.types[key]

    mod.__getattr__ = __getattr__
    return mod


def install(monkeypatch) -> None:
    """Put the message packages in ``sys.modules`` for the test (undone by ``monkeypatch``)."""
    for pkg in PACKAGES:
        top = types.ModuleType(pkg)
        top.msg = _msg_module(pkg)
        monkeypatch.setitem(sys.modules, pkg, top)
        monkeypatch.setitem(sys.modules, f"{pkg}.msg", top.msg)
    srv = types.ModuleType("std_srvs.srv")
    srv.SetBool = SetBool
    top = types.ModuleType("std_srvs")
    top.srv = srv
    monkeypatch.setitem(sys.modules, "std_srvs", top)
    monkeypatch.setitem(sys.modules, "std_srvs.srv", srv)
