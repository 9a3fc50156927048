"""Helpers shared by the GetDP verification tests."""
import shutil

import pytest

from pulseform.solvers.getdp import Rect

needs_getdp = pytest.mark.skipif(shutil.which("getdp") is None, reason="getdp executable not installed")


def ten_turn_coil(r0: float = 0.020, z_shift: float = 0.0) -> list:
    """Two layers of five 2 mm x 2 mm turns, inner radius r0, centred on z = z_shift."""
    return [Rect(r0 + i * 0.003, z0 + z_shift, r0 + 0.002 + i * 0.003, z0 + 0.002 + z_shift)
            for i in range(5) for z0 in (-0.0025, 0.0005)]


