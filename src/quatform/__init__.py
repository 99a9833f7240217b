"""quatform: singularity-free formation and teleoperation control with quaternions.

Layers (data flows one way, lower layers never import higher ones)::

    algebra -> formations -> robots, control -> references, planning -> sim -> report, cli
                teleop (beside formations, reuses algebra)

Conventions used everywhere (see ``docs/conventions.md``):

* quaternions are arrays ``(..., 4)`` ordered ``(w, x, y, z)``, Hamilton product;
* dual quaternions are arrays ``(..., 8)``: primary (rotation) part, then dual part,
  a pose being ``q + eps * 1/2 * t * q`` with ``t`` the translation in the parent frame.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
