"""quatform: singularity-free formation and teleoperation control with quaternions.

Layers (data flows one way, lower layers never import higher ones; ``tests/test_layers.py``
checks it)::

    algebra -> formations, planning, teleop -> robots -> control, references -> sim
            -> scenarios -> report -> runs, plan_runs, cli

(``errors``, ``checks``, ``tomlio`` and ``papers`` sit below all of them.) Where a new piece
goes: a formation in ``formations/``, a robot model in ``robots/``, a feedback law in
``control/``, a plant in ``sim/plants/``, a measurement model in ``sim/measurement.py``, a
scenario kind in ``scenarios/<kind>.py`` (registered in ``quatform.scenarios.KINDS``), its
figures in ``report/<kind>_...py`` (registered in ``quatform.report.FIGURES``), a file
writer in ``report/writers.py``.

Conventions used everywhere (see ``docs/conventions.md``):

* quaternions are arrays ``(..., 4)`` ordered ``(w, x, y, z)``, Hamilton product;
* dual quaternions are arrays ``(..., 8)``: primary (rotation) part, then dual part,
  a pose being ``q + eps * 1/2 * t * q`` with ``t`` the translation in the parent frame.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
