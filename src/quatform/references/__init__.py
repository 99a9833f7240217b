"""References layer: desired motions of a formation (above formations, robots and control).

A motion is stated once, in the operator's Euclidean cluster variables, and converted to
any description by that description's ``from_euclidean``: the one place where the
paper's conversions between spaces happen.
"""

from .paths import EuclideanPath, Ramp, Step, sample_reference

__all__ = ["EuclideanPath", "Ramp", "Step", "sample_reference"]
