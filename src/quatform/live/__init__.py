"""Live runs: a run served over the Foxglove WebSocket protocol while it goes (live layer, beside runs).

* :class:`~quatform.live.session.LiveSession` - a team scenario stepped tick by tick, an
  operator's goal moving its reference, its gains and barrier distance set between ticks,
  its folder written as a run writes it (no dependency beyond quatform's own);
* :mod:`quatform.live.server` - the Foxglove server that streams it (extra ``live``:
  ``pip install -e ".[live]"``; the Foxglove SDK is imported only there).
"""

from .session import GAIN_PREFIX, PAUSED_PARAMETER, SEPARATION_PARAMETER, LiveSession

__all__ = ["LiveSession", "GAIN_PREFIX", "SEPARATION_PARAMETER", "PAUSED_PARAMETER"]
