"""A conductivity that follows temperature (issue 33, item 3): the laws, and GetDP's σ per element.

Reference: a conductor whose temperature is prescribed is, for GetDP, a conductor of the equivalent constant σ.
A disk cut in two regions, each at its own prescribed temperature through the per-element list
(``Cond_SigmaList_k`` read with ``InterpolationLinear[ElementNum[]]``), must give the same coil current,
forces and Joule power per element as the same mesh with each region's σ(T) as a constant — to round-off
(the same assembly: the values are the same doubles). Likewise a coil with a σ(T) law held at a fixed
temperature (a huge heat capacity) against the constant σ(T0).
"""

from __future__ import annotations

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Coil, Conductor, EMModel, GetDPSolver, Rect, coil_conductor_mesh
from pulseform.solvers.getdp.conductivity import ConductivityTable, LinearResistivity, element_list_line, step_inputs
from pulseform.solvers.getdp.mesh import conductor_tag

from getdp_testlib import needs_getdp, ten_turn_coil


def test_laws():
    table = ConductivityTable((300.0, 500.0), (4e7, 2e7))
    assert table(400.0) == pytest.approx(3e7, rel=1e-15)
    assert table(250.0) == 4e7 and table(900.0) == 2e7          # end values held
    lin = LinearResistivity(sigma_ref=5.8e7, alpha=3.9e-3, reference_temperature=293.15)
    assert lin(293.15) == 5.8e7
    assert 1 / lin(393.15) == pytest.approx((1 + 0.39) / 5.8e7, rel=1e-14)   # ρ linear in T
    with pytest.raises(ValueError):
        lin(293.15 - 1 / 3.9e-3 - 1.0)                             # resistivity would be negative
    for bad in (((300.0, 300.0), (1e7, 1e7)), ((300.0, 400.0), (1e7, -1.0)), ((300.0,), (1e7, 2e7))):
        with pytest.raises(ValueError):
            ConductivityTable(*bad)
    line = element_list_line("L", np.array([7, 3]), np.array([2.0, 1.0]))
    assert line.replace("\n", "").replace(" ", "") == "L()={3,1,7,2};"
    assert element_list_line("L", [5], [1.5]).replace("\n", "").replace(" ", "") == "L()={5,1.5,6,1.5};"


@pytest.mark.getdp
@needs_getdp
def test_prescribed_temperatures_equal_constant_conductivities(tmp_path):
    halves = [Rect(0.0, 0.0035, 0.03, 0.0045), Rect(0.03, 0.0035, 0.06, 0.0045)]   # a disk in two regions
    mesh = coil_conductor_mesh([ten_turn_coil()], halves, r_domain=0.1, r_shell=0.125, h_fine=2e-3,
                               h_coarse=2.5e-2, h_conductor=1.5e-3)
    circuit = Circuit(100e-6, 5e3, 5e-3, 2e-6)
    law = LinearResistivity(3.5e7, 4.0e-3, 293.15)
    coil_law = ConductivityTable((250.0, 500.0), (6.5e7, 3.0e7))
    temps = (350.0, 520.0)
    constant = EMModel(True, coils=[Coil(10, sigma=float(coil_law(330.0)))],
                       conductors=[Conductor(float(law(t))) for t in temps], circuit=circuit, shell=(0.1, 0.125))
    following = EMModel(True, coils=[Coil(10, conductivity_law=coil_law, initial_temperature=330.0,
                                          heat_capacity=1e300)],
                        conductors=[Conductor(1.0, conductivity_law=law) for _ in temps], circuit=circuit,
                        shell=(0.1, 0.125))
    a, b = GetDPSolver(constant, tmp_path / "a"), GetDPSolver(following, tmp_path / "b")
    rows = [np.flatnonzero(mesh.tri_tags == conductor_tag(k)) for k in (1, 2)]
    b.set_element_temperatures(np.concatenate(rows), np.concatenate([np.full(len(r), t) for r, t in zip(rows, temps)]))
    sa, sb = a.initial_state(), b.initial_state()
    for k in range(2):
        ra, sa = a.step(mesh, sa, (k + 1) * 4e-6, 4)
        rb, sb = b.step(mesh, sb, (k + 1) * 4e-6, 4)
        np.testing.assert_allclose(rb.coil_current, ra.coil_current, rtol=1e-13, atol=0)
        np.testing.assert_allclose(rb.force_density, ra.force_density, rtol=1e-12, atol=1e-12 * np.abs(ra.force_density).max())
        np.testing.assert_allclose(rb.joule_density, ra.joule_density, rtol=1e-12, atol=1e-12 * ra.joule_density.max())
        np.testing.assert_allclose(rb.coil_power, ra.coil_power, rtol=1e-13)
    # the two halves really differ: a hotter region conducts less
    assert ra.conductor_power[-1, 0] != pytest.approx(ra.conductor_power[-1, 1], rel=0.05)
    # the element list reached GetDP: an element left out takes the conductor's initial temperature (293.15 K)
    b.set_element_temperatures(rows[0], np.full(len(rows[0]), temps[0]))
    numbers, lines = step_inputs(following, mesh, sb, 1e-6, b._elem_temperature)
    assert numbers["Cond_SigmaElem_2"] == 1 and f"{law(293.15):.17g}" in lines[1]
