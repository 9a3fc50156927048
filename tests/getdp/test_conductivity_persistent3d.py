"""A conductivity that follows temperature on the persistent 3D getdp (issue 33): the step messages carry σ per
element (``decks/Lib_PersistentSigma.pro``, shared with 2D: ``PF_SigmaElem``, ``BF_One`` on the tetrahedra).

References:

* a conductor whose temperature is prescribed is, for GetDP, a conductor of the equivalent constant σ: a disk
  sector in two regions, each at its own temperature, and a coil with a law held at a fixed temperature (a huge heat
  capacity), all through the messages, equal the same persistent run with each region's σ(T) as a constant to
  round-off (the same assembly: the values are the same doubles);
* the per-step 3D path (:class:`~...stepper3d.EM3DStepper`: one getdp per EM step, σ per element through the
  ``InterpolationLinear[ElementNum[]]`` list of ``run.pro``, checked against constant conductivities and a discrete
  R(T)-L-C circuit in tests/getdp/test_conductivity3d.py) on the same moved meshes with the same temperatures: the
  same BDF2 scheme, so to round-off (1e-12, the bound of tests/getdp/test_persistent3d.py);
* kept LU factors while σ changes every step: GCR solves each step's own matrix (assembled with its σ) to the
  tolerance, so their distance to a factorisation per step is of the solve's order, as at constant σ; a resume from
  a checkpoint rebuilds the factors of the σ the interrupted process factorised with (``FactorRecord.sigma``, the
  prime message) and repeats the run bit for bit.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pulseform.solvers.getdp import Conductor, Rect
from pulseform.solvers.getdp.conductivity import ConductivityTable, LinearResistivity
from pulseform.solvers.getdp.mesh import conductor_tag
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.persistent3d import PersistentEM3DStepper
from pulseform.solvers.getdp.persistent_process import FactorReuse
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel
from pulseform.solvers.getdp.stepper3d import EM3DStepper

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns
from test_persistent3d import BANK, SECTOR, TIMES, Bulge, _mesh

pytestmark = [pytest.mark.getdp, needs_getdp]

#: the coil's σ from a table, its heat capacity small so that its σ falls by a few % over the steps; the disk's
#: resistivity linear in T (α = 4e-3 /K)
COIL_LAW = ConductivityTable((250.0, 800.0), (6.5e7, 2.0e7))
DISK_LAW = LinearResistivity(3.5e7, 4.0e-3, 293.15)


def _model(coil_law=COIL_LAW, disk_law=DISK_LAW, heat_capacity=0.03):
    return EM3DModel(coils=[Coil3D(5, sigma=5.8e7, conductivity_law=coil_law, heat_capacity=heat_capacity)],
                     conductors=[Conductor(3.5e7, conductivity_law=disk_law)], circuit=BANK, shell=(0.1, 0.125),
                     sector_deg=SECTOR)


def _temperatures(mesh, k, n):
    """The disk's tetrahedra and their temperatures at step k of n (K): 293 K at the axis, up to +400 K at the rim
    by the last step."""
    rows = np.flatnonzero(mesh.tet_tags == conductor_tag(1))
    r = np.hypot(*mesh.points[mesh.tets[rows]].mean(axis=1)[:, :2].T)
    return rows, 293.15 + 400.0 * (r / 0.06) * (k + 1) / n


def _march(stepper, meshes, times, swap_at=None):
    """Step through ``times`` with the disk's temperatures of :func:`_temperatures`; per step one row (coil current,
    capacitor voltage, coil power, coil heat, the disk's Joule power and F_z, the force density per element).
    ``swap_at`` (k, new stepper): at step k the state goes through ``complete_state`` (a checkpoint) to the new
    stepper (a resume: a new process seeded from it)."""
    state, rows = stepper.initial_state(), []
    for k, t in enumerate(times):
        if swap_at is not None and k == swap_at[0]:
            state = stepper.complete_state(state)
            stepper.close()
            stepper = swap_at[1]
        mesh = meshes(k, t)
        stepper.set_element_temperatures(*_temperatures(mesh, k, len(times)))
        r, state = stepper.step(mesh, state, float(t))
        rows.append(np.concatenate([[r.coil_current[-1, 0], r.capacitor_voltage[-1], r.coil_power[-1, 0],
                                     state.coil_heat[0], r.conductor_power[-1, 0], r.conductor_force[-1, 0, 2]],
                                    r.force_density[-1].ravel()]))
    if hasattr(stepper, "close"):
        stepper.close()
    return np.array(rows), state


def _rel(a, b):
    """Largest difference relative to each scalar's largest magnitude over the run (the first 6 columns) and to the
    largest force density component (the rest)."""
    d = np.abs(a - b)
    return float(max((d[:, :6].max(axis=0) / np.abs(a[:, :6]).max(axis=0)).max(), d[:, 6:].max() / np.abs(a[:, 6:]).max()))


def _bulging(work):
    mesh = _mesh(work / "disk.msh")
    bulge, moved = Bulge(mesh, work), {}

    def meshes(k, t):
        if k not in moved:
            moved[k] = bulge(k, t)
        return moved[k]
    return meshes


def test_prescribed_temperatures_equal_constant_conductivities(work):
    """Two disk halves at 350 K and 520 K and a coil held at 330 K, their σ(T) through the step messages, equal the
    constant σ(T) run of the same persistent getdp to 1e-13 (coil current, capacitor voltage, coil and disk Joule
    power, F_z, force per element; measured 0: the same doubles), and the halves really differ."""
    halves = [Rect(0.0, 0.0, 0.028, 0.001), Rect(0.032, 0.0, 0.06, 0.001)]
    mesh = ring_sector_mesh(work / "halves.msh", demo_coil_turns(), halves, sector_deg=SECTOR, h_coil=3e-3,
                            h_conductor=2.5e-3, h_air=0.02)
    temps = (350.0, 520.0)
    constant = EM3DModel(coils=[Coil3D(5, sigma=float(COIL_LAW(330.0)))],
                         conductors=[Conductor(float(DISK_LAW(t))) for t in temps], circuit=BANK, shell=(0.1, 0.125),
                         sector_deg=SECTOR)
    following = EM3DModel(coils=[Coil3D(5, conductivity_law=COIL_LAW, initial_temperature=330.0, heat_capacity=1e300)],
                          conductors=[Conductor(1.0, conductivity_law=DISK_LAW) for _ in temps], circuit=BANK,
                          shell=(0.1, 0.125), sector_deg=SECTOR)
    rows = [np.flatnonzero(mesh.tet_tags == conductor_tag(k)) for k in (1, 2)]
    out = []
    for model, name in ((constant, "constant"), (following, "following")):
        st = PersistentEM3DStepper(model, work / name)
        st.set_element_temperatures(np.concatenate(rows), np.concatenate([np.full(len(r), t) for r, t in zip(rows, temps)]))
        state, got = st.initial_state(), []
        for t in TIMES[:3]:
            r, state = st.step(mesh, state, float(t))
            got.append(np.concatenate([[r.coil_current[-1, 0], r.capacitor_voltage[-1], r.coil_power[-1, 0],
                                        *r.conductor_power[-1], *r.conductor_force[-1, :, 2]], r.force_density[-1].ravel()]))
        st.close()
        out.append(np.array(got))
    d = np.abs(out[0] - out[1]).max(axis=0) / np.maximum(np.abs(out[0]).max(axis=0), 1e-300)
    print(f"\nσ(T) at prescribed temperatures vs constant σ, persistent 3D: max rel diff {d.max():.1e}")
    assert d.max() < 1e-13
    assert out[0][-1, 3] != pytest.approx(out[0][-1, 4], rel=0.05)   # the halves' Joule powers differ


def test_persistent_3d_with_conductivity_per_element_equals_the_per_step_path(work):
    """The bulging, sliding disk whose temperatures change every step (hotter outwards) under a heating coil,
    variable steps: the persistent 3D getdp (σ in the messages) vs a getdp per step (σ in ``run.pro``): every
    output (current, capacitor voltage, coil power and heat, the disk's Joule power and F_z, force per element)
    to 1e-12 (measured 4e-15), the last step's coil σ the same number, fallen by more than 1 % (that getdp reads the
    messages' σ at all: test_prescribed_temperatures_equal_constant_conductivities)."""
    meshes, times = _bulging(work), TIMES[:5]   # steps of 0.5, 0.5, 0.5, 0.37, 1.4 us
    ref, s_ref = _march(EM3DStepper(_model(), work / "per_step", "bdf2"), meshes, times)
    got, s_got = _march(PersistentEM3DStepper(_model(), work / "persistent"), meshes, times)
    print(f"\nσ(T) 3D: persistent vs per step {_rel(ref, got):.1e} over {len(times)} steps; coil σ "
          f"{s_got.coil_sigma[0]:.6g} S/m")
    assert _rel(ref, got) < 1e-12
    assert s_got.coil_sigma[0] == pytest.approx(s_ref.coil_sigma[0], rel=1e-13)
    assert s_got.coil_sigma[0] < 0.99 * float(COIL_LAW(293.15))   # the coil heated: its σ fell


# slow (10 s: five runs of 7 steps); the default tier checks σ in the messages against constants and the per-step path
@pytest.mark.slow
def test_kept_factors_and_a_resume_with_conductivity_per_element_3d(work):
    """Kept LU factors (tol 1e-10) while σ changes every step: each step's own system solved by GCR, so the distance
    to a factorisation per step stays within 3x of the constant-σ run's on the same steps and meshes (and below the
    1e-8 of tests/getdp/test_persistent3d.py), with fewer factorisations than steps; a checkpoint at step 4 and a
    new process seeded from it (its prime message carrying the σ the factors were made with) repeat the kept-factor
    run bit for bit, with no factorisation after the first."""
    meshes = _bulging(work)
    times = 0.5e-6 * np.arange(1, 8)
    keep = FactorReuse(tol=1e-10)
    const = replace(_model(), coils=[Coil3D(5, sigma=float(COIL_LAW(293.15)))],
                    conductors=[Conductor(float(DISK_LAW(293.15)))])
    fresh, _ = _march(PersistentEM3DStepper(_model(), work / "fresh"), meshes, times)
    kept, state = _march(PersistentEM3DStepper(_model(), work / "kept", factor_reuse=keep), meshes, times)
    fresh_c, _ = _march(PersistentEM3DStepper(const, work / "fresh_c"), meshes, times)
    kept_c, state_c = _march(PersistentEM3DStepper(const, work / "kept_c", factor_reuse=keep), meshes, times)
    seeded = PersistentEM3DStepper(_model(), work / "seeded", factor_reuse=keep)
    resumed, s_res = _march(PersistentEM3DStepper(_model(), work / "first", factor_reuse=keep), meshes, times,
                            swap_at=(4, seeded))
    tm, tc = state.timers, state_c.timers
    print(f"\nkept factors vs a factorisation per step, 3D: σ(T) {_rel(fresh, kept):.1e} "
          f"({tm['getdp_factorisations']:.0f} factorisations, {tm['getdp_corrections']:.0f} corrections in "
          f"{len(times)} steps); constant σ {_rel(fresh_c, kept_c):.1e} ({tc['getdp_factorisations']:.0f}, "
          f"{tc['getdp_corrections']:.0f}); resumed vs uninterrupted max |diff| {np.abs(resumed - kept).max():.1e}")
    assert tm["getdp_factorisations"] < len(times) and tm["getdp_corrections"] > 0
    assert 0 < _rel(fresh, kept) < min(3.0 * _rel(fresh_c, kept_c), 1e-8)
    assert np.array_equal(resumed, kept) and seeded.segment == 1
    assert s_res.timers["getdp_factorisations"] == tm["getdp_factorisations"]
