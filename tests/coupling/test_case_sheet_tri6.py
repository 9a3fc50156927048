"""The demo (cases/emf_sheet_bulge: an axisymmetric 1 mm aluminium sheet bulged by a flat coil, GetDP + DOLFINx) with
a six-node sheet (``bodies[0].element = "tri6"``, issue 34 item 4) against the same case on linear triangles,
through ``pulseform run``.

References: (1) locking and convergence: the shipped mesh has two layers of linear triangles through the sheet, too
stiff in bending (the 2D cantilever of docs/mechanics.md: linear triangles three thick reach 0.42 of beam theory,
six-node ones 1.000); its max deflection is 6.9 % below the value extrapolated from three meshes
(cases/emf_sheet_bulge/reference/convergence.md: 2.56897 mm, linear triangles refined twice). The six-node sheet
on the same mesh must deflect more than the linear one and lie nearer the extrapolated value. (2) The EM side is the
same mesh and load: the force impulse of both runs within 1 % (the sheet's motion feeds back only a little; the
impulse's own discretisation error, -1.7 % on this mesh, is the EM mesh's, convergence.md). (3) The ledgers of the
six-node run: force transfer at round-off, the mechanics' energy balance below 1e-3. (4) A short six-node run whose
air is meshed again (forced by ``em.remesh_quality`` near one as the free sheet moves: once, at 3.4 us), stopped by
SIGINT after its first checkpoint (after the remesh) and resumed, equals the uninterrupted run bit for bit (every
metric but timers; the remesh and the checkpoint's EM mesh carry the six-node body: its cells' EM triangles matched
again). (5) The implicit
integrator's run of the demo with the six-node sheet against the explicit one (the same physics, another time
integrator), as the linear sheet's is checked in tests/coupling/test_implicit_coupled.py. (6) Planar: the forces
scale with the depth exactly (cases/emf_corner_fill, a six-node blank).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

from pulseform.orchestrator.run.history import History

from .resume_check import sigint_then_resume
from warm_cli import pulseform_cli

pytestmark = [pytest.mark.slow, pytest.mark.getdp]

REPO = Path(__file__).resolve().parents[2]
CASE = REPO / "cases" / "emf_sheet_bulge"
EXE = str(Path(sys.executable).with_name("pulseform"))
#: the max deflection extrapolated from the linear sheet on 0.5 / 0.25 / 0.125 mm (reference/convergence.md)
CONVERGED_MM = 2.56897


def _args(out: Path, element: str, *sets: str) -> list[str]:
    return ["run", str(CASE), "--out", str(out), "--quiet"] + [
        a for s in (f"bodies[0].element='{element}'", *sets) for a in ("--set", s)]


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, dict]:
    root = tmp_path_factory.mktemp("sheet_tri6")
    out = {}
    for element in ("tet4", "tri6"):
        r = pulseform_cli(_args(root / element, element, "output.plots=false"))
        assert r.returncode == 0, r.stderr[-3000:]
        out[element] = json.loads((root / element / "metrics.json").read_text())
    return out


def test_six_node_sheet_deflects_more_and_nearer_the_converged_value(runs):
    lin, quad = runs["tet4"], runs["tri6"]
    print(f"\nemf_sheet_bulge, shipped mesh: max deflection linear {lin['max_deflection_mm']:.4f} mm, six-node "
          f"{quad['max_deflection_mm']:.4f} mm, converged {CONVERGED_MM} mm; impulse {lin['force_impulse_Ns']:.5f} / "
          f"{quad['force_impulse_Ns']:.5f} N s;\nplastic work {lin['plastic_work_J']:.3f} / "
          f"{quad['plastic_work_J']:.3f} J; "
          f"energy error {lin['energy_error_rel']:.1e} / {quad['energy_error_rel']:.1e}; ledger "
          f"{quad['conservation_error_rel']:.1e}; mech steps {lin['mech_steps']:.0f} / {quad['mech_steps']:.0f}")
    assert quad["max_deflection_mm"] > lin["max_deflection_mm"]
    assert abs(quad["max_deflection_mm"] - CONVERGED_MM) < abs(lin["max_deflection_mm"] - CONVERGED_MM)
    assert quad["force_impulse_Ns"] == pytest.approx(lin["force_impulse_Ns"], rel=1e-2)


def test_six_node_run_ledgers(runs):
    quad = runs["tri6"]
    assert quad["status"] == "ok" and quad["end_time_s"] == pytest.approx(60e-6, rel=1e-9)
    assert quad["conservation_error_rel"] < 1e-12
    assert quad["energy_error_rel"] < 1e-3


def test_six_node_sheet_implicit_matches_explicit(runs, tmp_path):
    """The implicit integrator takes the six-node sheet in the coupled loop: one implicit step per EM step of 0.45 us
    (as tests/coupling/test_implicit_coupled.py does with the linear sheet) against the explicit run (20 steps per
    EM step of ~0.16 us here): deflection, plastic work and impulse within 0.5 % (measured -0.02 %, +0.11 %,
    +0.01 %)."""
    out = tmp_path / "implicit"
    r = pulseform_cli(_args(out, "tri6", "output.plots=false", "mechanics.integrator=implicit", "coupling.n=1",
                            "mechanics.implicit.dt=0.45e-6"))
    assert r.returncode == 0, r.stderr[-3000:]
    im, ex = json.loads((out / "metrics.json").read_text()), runs["tri6"]
    print("\nsix-node sheet implicit vs explicit: " + ", ".join(
        f"{k} {im[k]:.6g} / {ex[k]:.6g}" for k in ("max_deflection_mm", "plastic_work_J", "force_impulse_Ns")))
    assert im["conservation_error_rel"] < 1e-12
    for key in ("max_deflection_mm", "plastic_work_J", "force_impulse_Ns"):
        assert im[key] == pytest.approx(ex[key], rel=0.005), key


def test_six_node_run_remeshes_stops_and_resumes_bit_for_bit(tmp_path):
    # the air is meshed again at 3.4 us (measured), before the first checkpoint (4 us): the resume restores a
    # remeshed EM mesh and matches the six-node cells to it again
    sets = ("time.end=6e-6", "output.field_interval=4e-6", "bodies.sheet.fixed=[]", "em.remesh_quality=0.99999")
    ref = tmp_path / "ref"
    r = pulseform_cli(_args(ref, "tri6", *sets, "output.plots=false"))
    assert r.returncode == 0, r.stderr[-3000:]
    want = json.loads((ref / "metrics.json").read_text())
    h = History.read(ref / "history.csv")
    remeshes = h.column("em_remeshes")
    t_remesh = float(h.column("time_s")[remeshes > 0][0])   # the first EM step on a remeshed mesh ends here
    out = tmp_path / "stopped"
    proc, err, stopped, resumed = sigint_then_resume([EXE] + _args(out, "tri6", *sets), out, delay=0.0)
    assert proc.returncode == 130 and "interrupted at t = " in err, err
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    got = json.loads((out / "metrics.json").read_text())
    print(f"\nsix-node free sheet, {want['em_steps']:.0f} EM steps, {remeshes[-1]:.0f} air remeshes (first at "
          f"{t_remesh:.3g} s): stopped at {stopped['end_time_s']:.3g} s, resumed: "
          f"max deflection {got['max_deflection_mm']!r} mm (uninterrupted {want['max_deflection_mm']!r})")
    assert t_remesh < stopped["end_time_s"] < want["end_time_s"]
    for k, v in want.items():
        if k.endswith("_s") and k != "end_time_s":   # wall-clock timings differ
            continue
        assert got[k] == v, k


def test_planar_six_node_blank_forces_scale_with_the_depth(tmp_path):
    """Plane strain (cases/emf_corner_fill: a six-node blank, a linear steel die, contact; 20 us, coarse): GetDP's
    forces are per metre of depth and the mechanics' thickness multiplies them and the six-node masses alike, so the
    blank's motion is the same and the impulse scales exactly (as tests/coupling/test_multibody.py checks for linear
    bodies); the ledger at round-off."""
    case = REPO / "cases" / "emf_corner_fill"
    sets = ["bodies[0].element='tri6'", "time.end=20e-6", "geometry.mesh_size_coil=3e-3",
            "geometry.mesh_size_die=5e-3", "geometry.mesh_size_air=0.05", "output.plots=false"]
    m = {}
    for depth in (1.0, 2.5):
        out = tmp_path / f"d{depth}"
        r = pulseform_cli(["run", str(case), "--out", str(out), "--quiet"]
                          + [a for s in (*sets, f"mechanics.thickness={depth}") for a in ("--set", s)])
        assert r.returncode == 0, r.stderr[-3000:]
        m[depth] = json.loads((out / "metrics.json").read_text())
    a, b = m[1.0], m[2.5]
    print(f"\nplanar six-node blank: impulse {a['force_impulse_Ns']:.6g} / {b['force_impulse_Ns']:.6g} N s "
          f"(ratio {b['force_impulse_Ns'] / a['force_impulse_Ns']:.12f}), max uy {a['blank_max_uy_mm']:.6g} / "
          f"{b['blank_max_uy_mm']:.6g} mm, ledger {a['conservation_error_rel']:.1e}")
    assert a["conservation_error_rel"] < 1e-12 and b["conservation_error_rel"] < 1e-12
    assert a["blank_max_uy_mm"] > 0.0
    assert b["force_impulse_Ns"] == pytest.approx(2.5 * a["force_impulse_Ns"], rel=1e-9)
    assert b["blank_max_uy_mm"] == pytest.approx(a["blank_max_uy_mm"], rel=1e-9)
