"""The coupled racetrack with a ten-node sheet (``bodies.sheet.element = "tet10"``, issue 34 item 4) against the
same case on linear tetrahedra, through ``pulseform run`` on the coarse mesh (tests/coupling/racetrack_coarse.py's
sizes: 2 tetrahedra through the sheet), the whole case: 60 µs, the sheet drawn into the die's groove through soft
contact (explicit; first contact 35.5 µs ten-node, 38.2 µs linear).

References: (1) the checkerboard index of the sheet's cell plastic strain over its plastically strained cells
(orchestrator/mech/checkerboard.py; measured at 60 µs 0.276 linear, 0.130 ten-node; studies/emf_racetrack_groove/
element_study.py): the ten-node sheet's must be below 0.6 of the linear one's; (2) locking and convergence: the
linear sheet, two cells thick, is far too stiff in bending (the cantilever of docs/mechanics.md: 0.41 of beam theory
with three through the thickness, ten-node 0.999), so it draws less than the ten-node one (2.46 mm against 4.04 mm),
and the ten-node coarse draw must be nearer the draw of the case's design mesh on linear tetrahedra (4.394 mm,
studies/emf_racetrack_groove/reference/racetrack_metrics.json: 4.5x the cells, 3 through the thickness) than the
linear coarse draw is; (3) the ledgers of the ten-node run (force transfer at round-off, the mechanics' energy
balance below 1e-3 of the external work); (4) a short ten-node run whose air is meshed again before EM steps 3 and
4 (forced, tests/coupling/forced_remesh_run.py), stopped by SIGINT after step 3 and resumed, equals the
uninterrupted one bit for bit (the remesh carries the ten-node body: its cells' EM tetrahedra matched again).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pulseform.orchestrator.mech.checkerboard import checkerboard_index
from pulseform.orchestrator.run.mech_fields import read_fields

from .racetrack_coarse import CASE, COARSE_SIZES
from .resume_check import assert_coupled3d_outputs_bitwise, checkpoint_arrays, interrupted_run
from warm_cli import pulseform_cli

pytestmark = [pytest.mark.slow, pytest.mark.getdp]

T_END = 60e-6
#: the case's draw on its design mesh, linear tetrahedra (the study's reference run)
DESIGN_DRAW_MM = json.loads((Path(__file__).resolve().parents[2] / "studies/emf_racetrack_groove/reference/"
                             "racetrack_metrics.json").read_text())["max_deflection_into_groove_mm"]
HELPER = str(Path(__file__).with_name("forced_remesh_run.py"))


def _args(out: Path, element: str, t_end: float, *extra: str) -> list[str]:
    sets = [*COARSE_SIZES, f"time.end={t_end}", "output.field_interval=10e-6", f"bodies.sheet.element='{element}'",
            *extra]
    return ["run", str(CASE), "--out", str(out), "--quiet"] + [a for s in sets for a in ("--set", s)]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("racetrack_tet10")
    out = {}
    for element in ("tet4", "tet10"):
        out[element] = root / element
        r = pulseform_cli(_args(out[element], element, T_END, "output.plots=false"))
        assert r.returncode == 0, r.stderr[-3000:]
    return out


def _plastic(folder: Path):
    sheet = read_fields(folder)["sheet"]
    k = int(np.argmin(np.abs(sheet.times - T_END)))
    assert sheet.times[k] == pytest.approx(T_END, rel=1e-9)
    return sheet, sheet.read(k, ("plastic_strain",))["plastic_strain"]


def test_ten_node_sheet_shows_no_checkerboard(runs):
    index = {}
    for element, folder in runs.items():
        sheet, p = _plastic(folder)
        assert (p > 0).sum() > 500   # the sheet over the winding has yielded
        index[element] = checkerboard_index(sheet.points, sheet.triangles, p)
    print(f"\ncheckerboard index of the sheet's plastic strain at {T_END * 1e6:.0f} us: linear {index['tet4']:.3f}, "
          f"ten-node {index['tet10']:.3f}")
    assert index["tet10"] < 0.6 * index["tet4"]


def test_ten_node_sheet_draws_more_than_the_locking_linear_one(runs):
    m = {e: json.loads((f / "metrics.json").read_text()) for e, f in runs.items()}
    draw = {e: v["sheet_max_uz_mm"] for e, v in m.items()}
    q = m["tet10"]
    fine = DESIGN_DRAW_MM
    print(f"\ndraw at {T_END * 1e6:.0f} us: linear {draw['tet4']:.4f} mm, ten-node {draw['tet10']:.4f} mm; the design "
          f"mesh's linear {fine:.4f} mm; ten-node ledgers: transfer {q['conservation_error_rel']:.1e}, energy "
          f"{q['energy_error_rel']:.1e}; first contact {q['first_contact_s'] * 1e6:.1f} us")
    assert draw["tet10"] > draw["tet4"]
    assert abs(draw["tet10"] - fine) < abs(draw["tet4"] - fine)
    assert q["status_ok"] == 1.0 and q["conservation_error_rel"] < 1e-13 and q["sheet_ledger_rel"] < 1e-13
    assert abs(q["energy_error_rel"]) < 1e-3 and q["first_contact_s"] < T_END
    import h5py

    with h5py.File(next(Path(runs["tet10"], "fields").glob("*_sheet.h5"))) as f:
        assert f["Mesh/tetrahedra10"].shape[1] == 10


def _remesh_argv(out: Path, *flags: str, sigint_in_step: int = 0) -> list[str]:
    """A 4 µs ten-node run whose air is meshed again before EM steps 3 and 4 (tests/coupling/forced_remesh_run.py),
    optionally stopping itself as step ``sigint_in_step`` starts (``flags``: e.g. ``--resume``)."""
    signal_at = [f"--sigint-in-step={sigint_in_step}"] if sigint_in_step else []
    return [sys.executable, HELPER, "3,4", *signal_at] + _args(out, "tet10", 4e-6, "output.plots=false",
                                                              "output.field_interval=1e-6") + list(flags)


def test_ten_node_run_remeshes_its_air_and_resumes_bit_for_bit(tmp_path):
    ref = tmp_path / "ref"
    r = subprocess.run(_remesh_argv(ref), capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    m = json.loads((ref / "metrics.json").read_text())
    assert m["status"] == "ok" and m["em_remeshes"] == 2.0
    assert m["conservation_error_rel"] < 1e-12 and m["sheet_ledger_rel"] < 1e-12
    out = tmp_path / "cut"
    interrupted_run(_remesh_argv(out, sigint_in_step=3), out)   # stops after step 3, whose start remeshed
    assert int(checkpoint_arrays(out)["load/remesh/count"]) == 1
    r = subprocess.run(_remesh_argv(out, "--resume"), capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    got = assert_coupled3d_outputs_bitwise(ref, out)
    print(f"\nten-node sheet, air remeshed at 2 and 3 us: ledger {m['conservation_error_rel']:.1e}; stopped at 3 us "
          f"and resumed: draw {got['sheet_max_uz_mm']!r} mm (bitwise the uninterrupted run's)")
