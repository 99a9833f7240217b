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
numbers from outside the thesis, each key saying how far its source goes: the motion
capture's three are the cameras' manufacturer's nominal values, not confirmed from an
offline source (the rate the lab ran at is not given either); the Pioneer's two are those
of the MobileRobots simulator's Pioneer model (AMRISim, ``PioneerRobotModels.world.inc``),
the robot's own firmware defaults not having been confirmed. It leaves out what nothing
documents: the control period (the scenario's), the orientation noise, the Wi-Fi and ROS
delays of the commands, the Bebop's odometry noise and any mismatch between the real Bebop
and Table 2's model. No value is fitted to the errors it produces (``docs/scenarios.md``,
"Seed 001 magnitudes").
"""

from __future__ import annotations

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
        Where the value comes from (the thesis's section, or the outside source it was read from)
        and how far that source goes ("not confirmed from an offline source" where it was not).
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


#: The eight cameras (seed 001 §3.2: four Prime 13, four Prime 41) run at one frame rate; the
#: thesis does not say which. 180 frames/s is the Prime 41's largest as OptiTrack lists it
#: (the Prime 13's 240): a manufacturer's nominal value, not confirmed from an offline source.
_OPTITRACK_RATE_HZ = 180.0
#: The slower camera's latency, the Prime 41's 5.5 ms as OptiTrack lists it (the Prime 13's
#: 4.2 ms): nominal, not confirmed from an offline source. OptiTrack's "Latency Measurements"
#: page (docs.optitrack.com/developer-tools/natnet-sdk/latency-measurements) says the
#: camera's latency changes with the frame rate and that Motive's solving and the NatNet
#: streaming add to it, so the controller's delay is at least this, not this.
_OPTITRACK_LATENCY_S = 0.0055
#: The coarser camera's 3D accuracy, the Prime 13's +-0.20 mm as OptiTrack lists it (the
#: Prime 41's +-0.10 mm): nominal, not confirmed from an offline source; reading it as the
#: standard deviation of each coordinate is this profile's choice, not the manufacturer's.
_OPTITRACK_NOISE_M = 0.0002
#: AMRISim (the continuation of the MobileRobots simulator MobileSim),
#: PioneerRobotModels.world.inc, model ``pioneer``, which ``p3dx`` inherits:
#: ``accel [0.3 0 1.74]``, ``decel [0.6 0 1.74]`` (m/s^2, -, rad/s^2);
#: https://github.com/reedhedges/AMRISim/blob/5874607d66240aa7a2c1d4e2664010c878fc7487/
#: PioneerRobotModels.world.inc. ARIA's params/p3dx-sh.p (github.com/reedhedges/AriaCoda)
#: leaves TransAccel/RotAccel at 0: "the parameters from robot flash will be used". The
#: firmware's FLASH defaults (Pioneer 3 Operations Manual) were not confirmed from an offline
#: source. The plant's ramp is one rate both ways, so the translation slows at 0.3 m/s^2,
#: not the model's 0.6.
_PIONEER_SIM_SOURCE = ("seed 001 §3.1.1 (Pioneer 3-DX); AMRISim (MobileSim's continuation) "
                       "PioneerRobotModels.world.inc, model pioneer (inherited by p3dx): ")
_PIONEER_ACCEL_M_S2 = 0.3
_PIONEER_ACCEL_RAD_S2 = 1.74

#: The registered profiles by name.
PROFILES = {
    "ideal": Profile("ideal", "the scenario's own values: a perfect motion capture, a Pioneer without inertia"),
    "lab": Profile(
        "lab", "Marciano 2021's lab: OptiTrack Prime 13/41 nominal rate, latency and noise; the Pioneer "
               "3-DX's acceleration limits (MobileRobots simulator's model)",
        (
            Setting("mocap_rate_hz", _OPTITRACK_RATE_HZ,
                    "seed 001 §3.2 (4 Prime 13 + 4 Prime 41, rate not given); OptiTrack Prime 41 largest "
                    "frame rate 180 FPS: manufacturer's nominal value, not confirmed from an offline source"),
            Setting("mocap_latency_s", _OPTITRACK_LATENCY_S,
                    "seed 001 §3.2; OptiTrack Prime 41 latency 5.5 ms: manufacturer's nominal value, not "
                    "confirmed from an offline source (a lower bound: Motive and NatNet add to it)"),
            Setting("mocap_noise_m", _OPTITRACK_NOISE_M,
                    "seed 001 §3.2; OptiTrack Prime 13 3D accuracy +-0.20 mm: manufacturer's nominal value, "
                    "not confirmed from an offline source, read as a standard deviation (this profile's choice)"),
            Setting("odometry_period_s", 0.2,
                    "seed 001 §3.1.2: the Bebop's state \"updated each 200 ms interval\""),
            Setting("pioneer_accel_m_s2", _PIONEER_ACCEL_M_S2,
                    _PIONEER_SIM_SOURCE + "accel 0.3 m/s^2 (decel 0.6: the plant's one rate is the accel)"),
            Setting("pioneer_accel_rad_s2", _PIONEER_ACCEL_RAD_S2,
                    _PIONEER_SIM_SOURCE + "accel = decel 1.74 rad/s^2"),
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
