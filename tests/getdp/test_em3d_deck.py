"""The 3D case deck's default physical ids repeat the ones of ``mesh3d`` (the deck also runs alone),
and the runner passes the Python ones with ``-setnumber``: both must stay equal."""
import re
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.mesh3d import Mesh3D
from pulseform.solvers.getdp.solver3d import DECK3D, Coil3D, EM3DModel, model_numbers
from pulseform.solvers.getdp import DampedSine


def test_deck_default_ids_equal_python_ids(tmp_path):
    text = Path(DECK3D).read_text()
    defaults = {k: float(v) for k, v in re.findall(r"^\s*(Phys_\w+)\s*=\s*([0-9.]+)", text, re.M)}
    mesh = Mesh3D(points=np.eye(4, 3), tets=np.array([[0, 1, 2, 3]]), tet_ids=np.array([1]),
                  tet_tags=np.array([101]), path=tmp_path / "x.msh", sector_deg=90.0)
    numbers, _ = model_numbers(EM3DModel(coils=[Coil3D(1, waveform=DampedSine(1.0, 0.0, 0.0), section=1e-6)],
                                         sector_deg=90.0), mesh)
    passed = {k: v for k, v in numbers.items() if k.startswith("Phys_")}
    assert len(defaults) == 11 and passed == defaults   # 11: Phys_Core_Base (issue 35)
