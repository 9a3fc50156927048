"""Whole-domain EM fields (PostOperation EM_Field): B on every triangle and the nodal potential.

Printed in the run (``step(field_output=True)``) or afterwards from the saved solution
(``post_fields``, getdp -pos): both give the same values, B on the conductors equals the per-element
table the coupling uses, and B is the curl of the written potential (GetDP's VolAxiSqu interpolates
r·a_φ linearly in (r²/2, z) on each triangle).
"""
import shutil

import numpy as np
import pytest

from pulseform.solvers.getdp import GetDPSolver
from pulseform.solvers.getdp.mesh import SHELL
from pulseform.solvers.getdp.solver import DECK_DIR

from getdp_testlib import needs_getdp
from test_stepping import mesh_and_models

pytestmark = [pytest.mark.getdp, needs_getdp]


def curl_volaxisqu(points, triangles, u):
    """B (GetDP frame) of the nodal unknown u = r a_z on each triangle: u linear in (ρ = r²/2, z),
    B_r = (∂u/∂z) / r, B_z = -∂u/∂ρ, r = sqrt(2 ρ) at the centre (as GetDP's VolAxiSqu at Depth 0)."""
    p = points[triangles].copy()
    p[:, :, 0] = 0.5 * p[:, :, 0] ** 2
    d1, d2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    uu = u[triangles]
    du1, du2 = uu[:, 1] - uu[:, 0], uu[:, 2] - uu[:, 0]
    g_rho = (du1 * d2[:, 1] - du2 * d1[:, 1]) / det
    g_z = (du2 * d1[:, 0] - du1 * d2[:, 0]) / det
    r = np.sqrt(2.0 * p[:, :, 0].mean(axis=1))
    return np.column_stack([g_z / r, -g_rho])


@pytest.mark.parametrize("scheme", ["euler", "bdf2"])
def test_field_output_in_run_and_from_saved_solution(work, scheme):
    mesh, _, circuit = mesh_and_models()
    solver = GetDPSolver(circuit, work, time_scheme=scheme)
    state = solver.initial_state()
    results = []
    for k in range(3):
        res, state = solver.step(mesh, state, (k + 1) * 1e-6, 1, field_output=(k == 2))
        results.append(res)
    assert results[0].b_cells is None and results[0].a_nodes is None   # only when asked for
    last = results[-1]
    assert last.b_cells.shape == (len(mesh.triangles), 2) and last.a_nodes.shape == (mesh.n_nodes,)
    assert np.all(np.isfinite(last.b_cells)) and np.all(np.isfinite(last.a_nodes))
    # B on the conductors = the per-element table of the coupling
    assert np.abs(last.b_cells[last.elements] - last.flux_density[-1]).max() <= 1e-12 * np.abs(last.b_cells).max()
    # B in the air near the coil is not zero
    air = mesh.tri_tags == 1
    assert np.linalg.norm(last.b_cells[air], axis=1).max() > 0.1
    # B = curl of the written potential (outside the shell, whose coordinates are mapped)
    b = curl_volaxisqu(mesh.points, mesh.triangles, last.a_nodes)
    plain = mesh.tri_tags != SHELL
    err = np.abs(b[plain] - last.b_cells[plain]).max()
    print(f"\n{scheme}: max |curl a - B| = {err:.2e} T of max |B| {np.abs(last.b_cells).max():.3f} T")
    assert err <= 1e-10 * np.abs(last.b_cells).max()
    # afterwards from the saved solution (getdp -pos): the same values
    in_run = (last.b_cells.copy(), last.a_nodes.copy())
    last.b_cells = last.a_nodes = None
    assert solver.post_fields(last, mesh)
    assert np.abs(last.b_cells - in_run[0]).max() <= 1e-12 * np.abs(in_run[0]).max()
    assert np.abs(last.a_nodes - in_run[1]).max() <= 1e-12 * np.abs(in_run[1]).max()
    assert solver.post_fields(results[1], mesh) and results[1].b_cells.shape == (len(mesh.triangles), 2)


def test_deck_without_em_field_keeps_conductor_fields(work, tmp_path):
    """A deck whose library has no EM_Field (a user's own deck): no whole-domain fields, no error."""
    decks = tmp_path / "decks"
    shutil.copytree(DECK_DIR, decks)
    lib = decks / "Lib_PulsedForming.pro"
    text = lib.read_text()
    text = text.replace("PostOperation[EM_Field];", "")
    text = text[:text.index("  { Name EM_Field;")] + "}\n"
    lib.write_text(text)
    mesh, _, circuit = mesh_and_models()
    solver = GetDPSolver(circuit, work, deck=decks / "em_case.pro")
    res, _ = solver.step(mesh, solver.initial_state(), 1e-6, 1, field_output=True)
    assert res.b_cells is None and res.a_nodes is None
    assert res.flux_density.shape[1] == len(res.elements) > 0
    assert solver.post_fields(res, mesh) is False
