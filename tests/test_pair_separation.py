"""The two-robot formations refuse robots on each other.

* ``singularity_measure`` of coincident robots is a DegenerateInputError naming them.
"""

from __future__ import annotations

import numpy as np
import pytest

from quatform.errors import DegenerateInputError
from quatform.formations import TEAM_FORMATIONS, DualQuaternionPair, EuclideanPair, QuaternionPair, RobotSpace


# -- coincident robots --------------------------------------------------------------------

@pytest.mark.parametrize("F", [EuclideanPair(), QuaternionPair(), DualQuaternionPair()], ids=lambda F: F.name)
def test_singularity_measure_of_coincident_robots_names_them(F):
    """It said "r contains nan ... check the measurement" for a finite input."""
    with pytest.raises(DegenerateInputError, match=r"^r: robots 1 and 2 coincide"):
        F.singularity_measure(np.zeros(8))
    r = np.array([[0, 0, 1, 0, 1, 0, 1, 0.3], [2, 2, 2, 0.1, 2, 2, 2, 0.2]])
    with pytest.raises(DegenerateInputError, match=r"robots 1 and 2 coincide.*at index \(1,\)"):
        F.singularity_measure(r)
    assert 0 < F.singularity_measure(r[0]) <= 1


def test_singularity_measure_of_robot_space_needs_no_separation():
    """The robot space has no special set and no length to divide by: 1 for any robots."""
    assert RobotSpace().singularity_measure(np.zeros(8)) == 1.0


@pytest.mark.parametrize("name", sorted(TEAM_FORMATIONS))
def test_team_singularity_measure_of_coincident_robots_names_them(name):
    F = TEAM_FORMATIONS[name](3)
    with pytest.raises(DegenerateInputError, match=r"^r: robots 1 and 2 coincide"):
        F.singularity_measure(np.zeros(F.n_r))
