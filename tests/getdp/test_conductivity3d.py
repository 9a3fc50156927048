"""A conductivity that follows temperature in 3D (issue 33, item 3): the per-step 3D getdp (:mod:`...stepper3d`).

References:

* a conductor whose temperature is prescribed is, for GetDP, a conductor of the equivalent constant σ: a disk sector
  in two regions, each at its own temperature through the per-element list (``Cond_SigmaList_k`` read by
  ``em_case3d.pro`` with ``InterpolationLinear[ElementNum[]]`` at the tetrahedra's gmsh ids), equals the same mesh
  with each region's σ(T) as a constant to round-off; a coil with a law held at a fixed temperature (a huge heat
  capacity) likewise;
* a heating coil in air is a series R(T)-L-C circuit: the bank discharging into a 30° sector of the demo's coil whose
  resistivity grows linearly with its lumped temperature. Its L and R(T_ref) are GetDP's own on the same mesh
  (L = 2 W s / I², R = P s / I², s = 12, a constant-σ run, as tests/getdp/test_em3d_circuit.py), m c_p = ρ c_p × the
  sector's coil volume (sum of its tetrahedra). The circuit is then solved here with numpy, implicit Euler like the
  deck, with the lumped model's rule (σ of step n at the temperature predicted for its middle from the power at its
  start, T_{n-1} + P_{n-1} dt / (2 m c_p); heat += P_n dt): the currents, coil powers and temperatures must agree to
  1e-8, and the coil power differ from the constant-σ run's by more than 10 % (its resistance grows by ~60 %).
"""

from __future__ import annotations

import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, Rect
from pulseform.solvers.getdp.conductivity import LinearResistivity, coil_temperature
from pulseform.solvers.getdp.mesh import coil_tag, conductor_tag
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel
from pulseform.solvers.getdp.stepper3d import EM3DStepper

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns

pytestmark = [pytest.mark.getdp]


@needs_getdp
def test_prescribed_temperatures_equal_constant_conductivities_3d(work):
    halves = [Rect(0.0, 0.0, 0.028, 0.001), Rect(0.032, 0.0, 0.06, 0.001)]
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), halves, sector_deg=10.0, h_coil=3e-3,
                            h_conductor=2.5e-3, h_air=0.02)
    circuit = Circuit(50e-6, 6e3, 0.01, 2e-6)
    law = LinearResistivity(3.5e7, 4.0e-3, 293.15)
    coil_law = LinearResistivity(5.8e7, 3.9e-3, 293.15)
    temps = (350.0, 520.0)
    constant = EM3DModel(coils=[Coil3D(5, sigma=float(coil_law(330.0)))],
                         conductors=[Conductor(float(law(t))) for t in temps], circuit=circuit, shell=(0.1, 0.125),
                         sector_deg=10.0)
    following = EM3DModel(coils=[Coil3D(5, conductivity_law=coil_law, initial_temperature=330.0, heat_capacity=1e300)],
                          conductors=[Conductor(1.0, conductivity_law=law) for _ in temps], circuit=circuit,
                          shell=(0.1, 0.125), sector_deg=10.0)
    a, b = EM3DStepper(constant, work / "a", "euler"), EM3DStepper(following, work / "b", "euler")
    rows = [np.flatnonzero(mesh.tet_tags == conductor_tag(k)) for k in (1, 2)]
    b.set_element_temperatures(np.concatenate(rows), np.concatenate([np.full(len(r), t) for r, t in zip(rows, temps)]))
    sa, sb = a.initial_state(), b.initial_state()
    heat = 0.0
    for k in range(2):
        ra, sa = a.step(mesh, sa, (k + 1) * 2e-6)
        rb, sb = b.step(mesh, sb, (k + 1) * 2e-6)
        heat += rb.coil_power[-1, 0] * 2e-6
        np.testing.assert_allclose(rb.coil_current, ra.coil_current, rtol=1e-12, atol=0)
        np.testing.assert_allclose(rb.force_density, ra.force_density, rtol=1e-11,
                                   atol=1e-11 * np.abs(ra.force_density).max())
        np.testing.assert_allclose(rb.joule_density, ra.joule_density, rtol=1e-11, atol=1e-11 * ra.joule_density.max())
        np.testing.assert_allclose(rb.conductor_power, ra.conductor_power, rtol=1e-11)
    # the two regions really differ, and a list that did not reach GetDP (σ = 1 S/m) would carry no eddy current
    assert ra.conductor_power[-1, 0] != pytest.approx(ra.conductor_power[-1, 1], rel=0.05)
    assert rb.conductor_power[-1].min() > 1e-3 * abs(rb.coil_power[-1, 0])
    # the coil's lumped temperature stays at 330 K (m c_p huge), its heat is the sector's Σ P_end dt (implicit Euler)
    assert coil_temperature(following, mesh, sb)[0] == 330.0
    assert sb.coil_heat[0] == pytest.approx(heat, rel=1e-14) and heat > 0


@needs_getdp
def test_heating_coil_is_a_discrete_r_of_t_lc_circuit(work):
    sector, rho, cp = 30.0, 8960.0, 0.5   # a tiny heat capacity: the coil heats by ~150 K in 20 µs
    mesh = ring_sector_mesh(work / "coil.msh", demo_coil_turns(), [], sector_deg=sector, r_air=0.1, r_shell=0.125,
                            h_coil=3e-3, h_air=0.02)
    C, V0, R_EXT, L_EXT = 100e-6, 5e3, 5e-3, 2e-6
    law = LinearResistivity(5.8e7, 3.9e-3, 293.15)
    n, t_end = 10, 20e-6
    dt = t_end / n

    def model(**coil) -> EM3DModel:
        return EM3DModel(coils=[Coil3D(5, density=rho, heat_capacity=cp, **coil)],
                         circuit=Circuit(C, V0, R_EXT, L_EXT), shell=(0.1, 0.125), sector_deg=sector)

    def run(m: EM3DModel, folder: str):
        st = EM3DStepper(m, work / folder, "euler")
        state, out = st.initial_state(), []
        for k in range(1, n + 1):
            res, state = st.step(mesh, state, k * dt)
            out.append((res.coil_current[-1, 0], res.coil_power[-1, 0], res.magnetic_energy[-1],
                        coil_temperature(m, mesh, state)[0]))
        return np.array(out)

    const = run(model(), "constant")
    s = 360.0 / sector
    L = 2 * const[:, 2] * s / const[:, 0] ** 2
    R = const[:, 1] * s / const[:, 0] ** 2                   # the whole coil's, at σ_ref = 5.8e7 S/m
    assert np.ptp(L) < 1e-8 * L.mean() and np.ptp(R) < 1e-8 * R.mean()
    L, r_ref = L[-1], R[-1]
    heat_cap = rho * cp * mesh.volumes(np.flatnonzero(mesh.tet_tags == coil_tag(1))).sum() * s   # whole coil (J/K)
    got = run(model(conductivity_law=law), "following")
    ref, v, i, temp, p = [], V0, 0.0, 293.15, 0.0
    for _ in range(n):
        r = r_ref * law(293.15) / law(temp + 0.5 * dt * p / heat_cap)
        i, v = np.linalg.solve([[r + R_EXT + (L + L_EXT) / dt, -1.0], [dt / C, 1.0]], [(L + L_EXT) / dt * i, v])
        p = r * i * i
        temp += p * dt / heat_cap
        ref.append((i, temp, p))
    ref = np.array(ref)
    err_i = np.abs(got[:, 0] - ref[:, 0]).max() / np.abs(ref[:, 0]).max()
    err_t = np.abs(got[:, 3] - ref[:, 1]).max() / (ref[-1, 1] - 293.15)
    err_p = np.abs(got[:, 1] * s - ref[:, 2]).max() / ref[:, 2].max()
    dev = np.abs(got[:, 1] - const[:, 1]).max() / const[:, 1].max()
    print(f"\n{mesh.n_tets} tets: L {L * 1e6:.4f} uH, R(T_ref) {r_ref * 1e3:.4f} mOhm, m c_p {heat_cap:.4f} J/K; "
          f"coil {got[-1, 3]:.2f} K at {t_end * 1e6:.0f} us; vs the discrete R(T)-L-C: current {err_i:.1e}, "
          f"temperature {err_t:.1e}, coil power {err_p:.1e}; the coil power at constant sigma {dev:.1%} away")
    assert ref[-1, 1] > 293.15 + 50.0
    assert err_i < 1e-8 and err_t < 1e-8 and err_p < 1e-8
    assert dev > 0.1
