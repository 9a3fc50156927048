"""3D deck: a transient split in two getdp runs (``-restart -res``) equals one continuous run.

Reference: the continuous run itself (same mesh, same steps); the staggered coupling advances the EM
field one run per EM step this way. Checked with eddy currents in a disk (prescribed current) and
with the capacitor bank (the circuit state handed over with ``circuit_state``).
"""
import numpy as np
import pytest

from pulseform.solvers.getdp import Circuit, Conductor, DampedSine, Rect
from pulseform.solvers.getdp.mesh3d import ring_sector_mesh
from pulseform.solvers.getdp.solver3d import Coil3D, EM3DModel, solve_transient3d

from getdp_testlib import needs_getdp
from test_em3d_static import demo_coil_turns


def continuous_and_split(model, mesh, work, t_end, n):
    full = solve_transient3d(model, mesh, t_end, n, work / "full")
    first = solve_transient3d(model, mesh, t_end / 2, n // 2, work / "first")
    state = None if model.circuit is None else (first.capacitor_voltage[-1], first.circuit_current[-1])
    second = solve_transient3d(model, mesh, t_end, n - n // 2, work / "second", t0=t_end / 2,
                               restart_res=first.res_path, circuit_state=state)
    return full, first, second


# slow (a split run with eddy currents: the same restart, at every step, with the disk's eddy currents and the
# bank, runs in the default tier in tests/getdp/test_em3d_stepper.py::test_per_step_processes_equal_one_process[euler])
@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_restart_with_eddy_currents(work):
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), [Rect(0.0, 0.0, 0.06, 0.001)], sector_deg=10.0,
                            h_coil=3e-3, h_conductor=2e-3, h_air=0.02, conductor_layers=2)
    model = EM3DModel(coils=[Coil3D(5, waveform=DampedSine(20e3, 1e4, 1e5))], conductors=[Conductor(3.5e7)],
                      shell=(0.1, 0.125), sector_deg=10.0)
    full, first, second = continuous_and_split(model, mesh, work, 12e-6, 12)
    split = np.concatenate([first.conductor_force, second.conductor_force])
    np.testing.assert_allclose(np.concatenate([first.times, second.times]), full.times, rtol=1e-12)
    err = np.abs(split - full.conductor_force).max() / np.abs(full.conductor_force).max()
    ferr = np.abs(second.force_density - full.force_density[6:]).max() / np.abs(full.force_density).max()
    print(f"\n{mesh.n_tets} tets: split vs continuous, conductor force {err:.1e}, element force densities {ferr:.1e}")
    assert abs(full.conductor_force[:, 0, 2]).max() > 0
    assert err < 1e-9 and ferr < 1e-9


# slow (a split run with the bank: the same restart, at every step, with the bank's circuit state handed over,
# runs in the default tier in tests/getdp/test_em3d_stepper.py::test_per_step_processes_equal_one_process[euler])
@pytest.mark.slow
@pytest.mark.getdp
@needs_getdp
def test_restart_with_the_bank(work):
    mesh = ring_sector_mesh(work / "coil.msh", demo_coil_turns(), [], sector_deg=30.0, h_coil=3e-3, h_air=0.02)
    model = EM3DModel(coils=[Coil3D(5)], circuit=Circuit(100e-6, 5e3, 5e-3, 2e-6), shell=(0.1, 0.125),
                      sector_deg=30.0)
    full, first, second = continuous_and_split(model, mesh, work, 20e-6, 20)
    i = np.concatenate([first.coil_current[:, 0], second.coil_current[:, 0]])
    v = np.concatenate([first.capacitor_voltage, second.capacitor_voltage])
    err_i = np.abs(i - full.coil_current[:, 0]).max() / np.abs(full.coil_current).max()
    err_v = np.abs(v - full.capacitor_voltage).max() / 5e3
    print(f"\nbank: split vs continuous, current {err_i:.1e}, capacitor voltage {err_v:.1e}")
    assert err_i < 1e-9 and err_v < 1e-9


@pytest.mark.getdp
@needs_getdp
def test_restart_on_moved_nodes_rigid_motion(work):
    """The whole model (coil, disk, air, shell centre) rotated about z by 20 deg and lifted by 3 mm
    between the two runs: the physics does not change (the coil direction is azimuthal about z, the
    shell follows), so the split run must still equal the continuous one -- it checks the moved mesh
    file (same ids, new nodes) and that the edge unknowns carried by the restart stay valid."""
    mesh = ring_sector_mesh(work / "disk.msh", demo_coil_turns(), [Rect(0.0, 0.0, 0.06, 0.001)], sector_deg=10.0,
                            h_coil=3e-3, h_conductor=2e-3, h_air=0.02, conductor_layers=2)
    wave, shift, turn = DampedSine(20e3, 1e4, 1e5), 0.003, np.radians(20.0)
    model = EM3DModel(coils=[Coil3D(5, waveform=wave)], conductors=[Conductor(3.5e7)], shell=(0.1, 0.125),
                      sector_deg=10.0)
    full = solve_transient3d(model, mesh, 12e-6, 12, work / "full")
    first = solve_transient3d(model, mesh, 6e-6, 6, work / "first")
    c, s = np.cos(turn), np.sin(turn)
    p = mesh.points @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) + [0.0, 0.0, shift]
    moved = mesh.moved(p, work / "moved.msh")
    model2 = EM3DModel(coils=[Coil3D(5, waveform=wave)], conductors=[Conductor(3.5e7)], shell=(0.1, 0.125),
                       shell_centre=(0.0, 0.0, shift), sector_deg=10.0)
    second = solve_transient3d(model2, moved, 12e-6, 6, work / "second", t0=6e-6, restart_res=first.res_path)
    fz = np.concatenate([first.conductor_force[:, 0, 2], second.conductor_force[:, 0, 2]])
    err = np.abs(fz - full.conductor_force[:, 0, 2]).max() / np.abs(full.conductor_force[:, 0, 2]).max()
    # the in-plane force turns with the model
    fxy = second.conductor_force[-1, 0, :2]
    fxy_ref = np.array([[c, -s], [s, c]]) @ full.conductor_force[-1, 0, :2]
    print(f"\nrotated 20 deg and lifted 3 mm between the runs: F_z {err:.1e}, in-plane force "
          f"{np.abs(fxy - fxy_ref).max() / np.abs(fxy_ref).max():.1e}")
    assert err < 1e-9
    np.testing.assert_allclose(fxy, fxy_ref, rtol=1e-8, atol=1e-9 * np.abs(fxy_ref).max())
