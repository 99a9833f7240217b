"""Issue 12, the UGV-UAV formation of Marciano 2021 (seed 001), kinematic side: each item
of the hardening brief has its own test here."""

from __future__ import annotations

import numpy as np
import pytest

import quatform.control as control


# -- item 7: the UGV-UAV layouts carry their name ------------------------------------------------

def test_ugv_uav_layout_names_are_not_the_generic_ones():
    assert control.UGV_UAV_MEASURED_NAMES[:3] == ("x_p", "y_p", "psi_p")
    assert len(control.UGV_UAV_MEASURED_NAMES) == 11
    assert control.UGV_UAV_COMMAND_NAMES == ("v_p", "omega_p", "u_x_b", "u_y_b", "u_z_b", "u_psi_b")
    assert not hasattr(control, "COMMAND_NAMES") and not hasattr(control, "MEASURED_NAMES")
    assert "UGV_UAV_COMMAND_NAMES" in control.__all__ and "COMMAND_NAMES" not in control.__all__
