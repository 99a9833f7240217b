"""Named worlds of the ``ugv-uav`` kind: the ideal one and the lab of seed 001 (scenarios layer).

A profile is a set of :class:`~quatform.scenarios.ugv_uav.UgvUavScenario` keys with values,
each with the place its value comes from. A scenario selects one with ``profile = "lab"``
(its TOML) or ``--profile lab`` (a run); a new profile is one entry of :data:`PROFILES`.

``ideal`` sets nothing: the scenario's own values (the defaults: a perfect motion capture,
a Pioneer that follows its commands at once), the world every existing result was made in.

``lab`` is Marciano 2021's lab as far as the thesis and its hardware document it. The thesis
(seed 001) gives the Bebop's identified model (Table 2, already the Bebop of every world), the
Bebop's state updated every 200 ms (§3.1.2, already the odometry of every world), and its
motion capture's hardware: eight OptiTrack cameras, four Prime 13 and four Prime 41 (§3.2);
it gives no frame rate, latency, noise, control period, command delay, nor any Pioneer
dynamics (§3.1.2: "its dynamics ... is not considered"). The lab profile takes the missing
numbers from the named hardware's own documentation (cited per key below) and leaves out
what nothing documents: the control period (the scenario's), the orientation noise, the
Wi-Fi and ROS delays of the commands, the Bebop's odometry noise and any mismatch between
the real Bebop and Table 2's model. No value is fitted to the errors it produces
(``docs/scenarios.md``, "Seed 001 magnitudes").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .. import checks
from ..errors import InvalidInputError

__all__ = ["Setting", "Profile", "PROFILES", "DEFAULT_PROFILE", "profile_named"]


@dataclass(frozen=True)
class Setting:
    """One scenario key a profile sets.

    Attributes
    ----------
    key : str
        A :class:`~quatform.scenarios.ugv_uav.UgvUavScenario` field.
    value : float
        Its value, in the field's units.
    source : str
        Where the value comes from (the thesis's section, or the hardware's documentation).
    """

    key: str
    value: float
    source: str


@dataclass(frozen=True)
class Profile:
    """A named world: ``settings`` over the scenario's keys, and a one-line ``summary``."""

    name: str
    summary: str
    settings: tuple = ()

    def values(self) -> dict:
        """``{key: value}`` of the settings."""
        return {s.key: s.value for s in self.settings}


#: The eight cameras (seed 001 §3.2: four Prime 13, four Prime 41) run at one frame rate;
#: the Prime 41's largest is 180 frames/s (the Prime 13's 240).
_OPTITRACK_RATE_HZ = 180.0
#: The slower camera's latency, the Prime 41's 5.5 ms (the Prime 13's 4.2 ms).
_OPTITRACK_LATENCY_S = 0.0055
#: The coarser camera's 3D accuracy, the Prime 13's +-0.20 mm (the Prime 41's +-0.10 mm),
#: read as the standard deviation of each coordinate.
_OPTITRACK_NOISE_M = 0.0002

#: The registered profiles by name.
PROFILES = {
    "ideal": Profile("ideal", "the scenario's own values: a perfect motion capture, a Pioneer without inertia"),
    "lab": Profile(
        "lab", "Marciano 2021's lab: OptiTrack Prime 13/41 rate, latency and noise; the Pioneer 3-DX's "
               "acceleration limits",
        (
            Setting("mocap_rate_hz", _OPTITRACK_RATE_HZ,
                    "seed 001 §3.2 (4 Prime 13 + 4 Prime 41); OptiTrack Prime 41 specifications: 180 FPS"),
            Setting("mocap_latency_s", _OPTITRACK_LATENCY_S,
                    "seed 001 §3.2; OptiTrack Prime 41 specifications: 5.5 ms latency"),
            Setting("mocap_noise_m", _OPTITRACK_NOISE_M,
                    "seed 001 §3.2; OptiTrack Prime 13 specifications: 3D accuracy +-0.20 mm"),
            Setting("odometry_period_s", 0.2, "seed 001 §3.1.2: the Bebop's state updated every 200 ms"),
            Setting("pioneer_accel_m_s2", 0.3,
                    "seed 001 §3.1.1 (Pioneer 3-DX); Pioneer 3 Operations Manual, ARCOS FLASH defaults: "
                    "TransAccel = TransDecel = 300 mm/s^2"),
            Setting("pioneer_accel_rad_s2", math.radians(100.0),
                    "seed 001 §3.1.1 (Pioneer 3-DX); Pioneer 3 Operations Manual, ARCOS FLASH defaults: "
                    "RotAccel = RotDecel = 100 deg/s^2"),
        )),
}
#: The profile of a scenario that names none (every existing result's world).
DEFAULT_PROFILE = "ideal"


def profile_named(name, where: str = "profile") -> Profile:
    """The registered profile ``name``; an unknown one is refused in one line naming the valid ones.

    Raises
    ------
    InvalidInputError
    """
    if not isinstance(name, str) or name not in PROFILES:
        raise InvalidInputError(f"{where}: profile = {name!r} is not one of {', '.join(PROFILES)}"
                                f"{checks.nearest(str(name), PROFILES)}")
    return PROFILES[name]
