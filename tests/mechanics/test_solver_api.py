"""API behaviour: exact restart, penetration error, field output, follower pressure, validation."""
import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ContactPairSpec, ContactPenetrationError,
                                       ExplicitSolver, FieldWriter, Material)
from pulseform.solvers.dolfinx.verification import PAPER_BAR_MATERIAL as MAT


def _two_bars(v=10.0, k=1e8, h0=0.01, friction=0.0, viscosity=0.0, two_pass=False, n=(16, 8),
              soft=False):
    comm = MPI.COMM_SELF
    left = dmesh.create_rectangle(comm, [np.array([0.0, 0.0]), np.array([4.0, 2.0])], list(n))
    right = dmesh.create_rectangle(comm, [np.array([4.0 + h0, 0.3]), np.array([8.0 + h0, 2.3])],
                                   list(n))
    mat = Material(2800.0, 26.5e9, 65.1e9, 0.24e9 if not soft else 1e7, 0.56e9)
    pair = ContactPairSpec("left", "right", k, h0, friction=friction, viscosity=viscosity,
                           two_pass=two_pass)
    return ExplicitSolver([BodySpec("left", left, mat, initial_velocity=(v, 1.0)),
                           BodySpec("right", right, mat)], formulation="plane_strain",
                          contact_pairs=(pair,), comm=comm)


@pytest.mark.parametrize("opts", [dict(), dict(friction=0.3, viscosity=1e4, two_pass=True,
                                                 soft=True)])
def test_restart_is_bitwise(opts):
    a = _two_bars(**opts)
    dt = a.stable_time_step()
    a.advance(dt, 60)
    state = {k: np.array(v, copy=True) for k, v in a.state_dict().items()}
    a.advance(dt, 80)
    b = _two_bars(**opts)
    b.load_state_dict(state)
    b.advance(dt, 80)
    for n in a.bodies:
        for key in ("x", "v", "a", "cell_stress", "eps_p"):
            assert np.array_equal(getattr(a.bodies[n], key), getattr(b.bodies[n], key)), key
    assert a.energies() == b.energies()
    assert a.time == b.time and a.step_count == b.step_count
    if opts:
        assert a.bodies["left"].eps_p.max() > 0 and a.energies()["contact_dissipated_J"] > 0


def test_penetration_raises_with_time_node_bodies():
    """k far too small for 500 m/s: the layer is crossed and the run must stop loudly."""
    s = _two_bars(v=500.0, k=1e3)
    dt = s.stable_time_step()
    with pytest.raises(ContactPenetrationError) as exc:
        for _ in range(2000):
            s.advance(dt)
    msg = str(exc.value)
    assert "t=" in msg and "'left'" in msg and "'right'" in msg and "node" in msg


def test_friction_and_viscosity_dissipate_and_conserve_momentum():
    s = _two_bars(friction=0.3, viscosity=1e5, two_pass=True)
    dt = s.stable_time_step()
    p0 = sum((b.mass[:, None] * b.v).sum(axis=0) for b in s.bodies.values())
    s.advance(dt, 150)
    e = s.energies()
    assert e["contact_dissipated_J"] > 0
    assert abs(e["balance_error_J"]) < 0.01 * s.initial_energy
    p = sum((b.mass[:, None] * (b.v + 0.5 * dt * b.a)).sum(axis=0) for b in s.bodies.values())
    assert np.allclose(p, p0, rtol=0, atol=1e-9 * np.abs(p0).max())


def test_pressure_nodal_forces_resultant():
    """Sum of the consistent nodal forces of a pressure = p x loaded area, pointing inward."""
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([1.0, 0.0]), np.array([2.0, 0.5])],
                                 [8, 4])
    for form, area in (("plane_strain", 0.5 * 2.0), ("axisymmetric", 2 * np.pi * 1.0 * 0.5)):
        s = ExplicitSolver([BodySpec("b", msh, MAT)], formulation=form, thickness=2.0,
                           comm=msh.comm)
        f = s.pressure_nodal_forces("b", lambda x: np.isclose(x[0], 1.0), 3e6)
        assert f[:, 0].sum() == pytest.approx(3e6 * area, rel=1e-12)
        assert abs(f[:, 1].sum()) < 1e-6 * 3e6 * area


def test_field_writer(tmp_path):
    """One mesh per body, all fields per output time, exact times, the stress tensor per cell equal
    to the solver's cell values; meshio's time-series reader and h5py read the same."""
    import h5py
    import meshio

    s = _two_bars()
    w = FieldWriter(s, tmp_path / "fields")
    w.write(0.0)
    expect = {}
    for t_out in (3e-5, 6e-5):
        s.advance(s.stable_time_step(), 5)
        w.write(t_out + 3.5e-20)  # a milestone reached by summed steps
        expect[t_out] = {n: (b.u.copy(), b.cell_stress.copy(), b.von_mises.copy(), b.eps_p.copy())
                         for n, b in s.bodies.items()}
    w.close()
    for n, b in s.bodies.items():
        xdmf = tmp_path / f"fields_{n}.xdmf"
        with meshio.xdmf.TimeSeriesReader(xdmf) as r:
            points, cells = r.read_points_cells()
            assert len(cells) == 1 and cells[0].type == "triangle"
            assert np.array_equal(points[:, :2], b.X0) and np.array_equal(cells[0].data, b.cells)
            assert r.num_steps == 3
            for k, t_out in enumerate((0.0, 3e-5, 6e-5)):
                t, pd, cd = r.read_data(k)
                assert t == t_out  # exact, not 6.0000000000000035e-05
                assert set(pd) == {"displacement_m", "velocity_m_s"}
                assert set(cd) == {"stress_Pa", "von_mises_Pa", "plastic_strain"}
                if k:
                    u, st, vm, ep = expect[t_out][n]
                    assert np.array_equal(pd["displacement_m"][:, :2], u)
                    assert np.array_equal(cd["stress_Pa"][0][:, :4], st)
                    assert not cd["stress_Pa"][0][:, 4:].any()
                    assert np.array_equal(cd["von_mises_Pa"][0], vm)
                    assert np.array_equal(cd["plastic_strain"][0], ep)
        with h5py.File(tmp_path / f"fields_{n}.h5", "r") as f:
            assert list(f["times"][:]) == [0.0, 3e-5, 6e-5]
            d = f["Step_0002/stress_Pa"]
            assert d.attrs["components"] == "xx yy zz xy yz xz"
            assert np.array_equal(d[:, :4], expect[6e-5][n][1])
            assert f.attrs["body"] == n and f.attrs["formulation"] == "plane_strain"


def test_input_validation():
    msh = dmesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    with pytest.raises(ValueError):
        Material(-1.0, 1.0, 1.0, 1.0, 0.0)
    with pytest.raises(ValueError):
        ExplicitSolver([BodySpec("a", msh, MAT)], formulation="3d", comm=msh.comm)
    with pytest.raises(ValueError):
        ExplicitSolver([BodySpec("a", msh, MAT), BodySpec("a", msh, MAT)], comm=msh.comm)
    with pytest.raises(ValueError):
        ContactPairSpec("a", "b", stiffness=-1.0, h0=0.01)
    s = ExplicitSolver([BodySpec("a", msh, MAT)], comm=msh.comm)
    with pytest.raises(ValueError):
        s.advance(-1.0)
    with pytest.raises(RuntimeError):
        s.advance(3.0 * s.stable_time_step() / s.cfl)
    with pytest.raises(ValueError):
        s.advance(s.stable_time_step(), external_forces={"a": np.zeros((3, 2))})


def test_stable_step_follows_the_deforming_mesh():
    """A block crushed on a rigid wall: the stable step shrinks with the flattened cells."""
    from pulseform.solvers.dolfinx import RigidWallSpec
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([0.01, 0.01])],
                                 [10, 10])
    mat = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
    s = ExplicitSolver([BodySpec("b", msh, mat, initial_velocity=(-300.0, 0.0))],
                       formulation="plane_strain", comm=msh.comm,
                       rigid_walls=(RigidWallSpec((0.0, 0.0), (1.0, 0.0)),))
    dt0 = s.stable_time_step()
    while s.time < 4e-6:
        s.advance(s.stable_time_step())
    assert s.stable_time_step() < 0.9 * dt0
    assert s.bodies["b"].eps_p.max() > 0.05
    e = s.energies()
    assert e["plastic_J"] > 0 and abs(e["balance_error_J"]) < 0.01 * s.initial_energy


def test_axisymmetric_axis_nodes_stay_on_axis():
    """Solid cylinder (r from 0) under external pressure: u_r = 0 on the axis, finite fields."""
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([0.05, 0.02])],
                                 [10, 4])
    s = ExplicitSolver([BodySpec("c", msh, MAT)], formulation="axisymmetric", comm=msh.comm)
    b = s.bodies["c"]
    axis = np.flatnonzero(b.X0[:, 0] == 0.0)
    assert axis.size == 5
    f = s.pressure_nodal_forces("c", lambda x: np.isclose(x[0], 0.05), 50e6)
    s.advance(s.stable_time_step(), 300, external_forces={"c": f})
    assert np.all(b.x[axis, 0] == 0.0)
    assert np.all(np.isfinite(b.cell_stress))
    assert b.u[:, 0].min() < 0      # the cylinder is squeezed


def test_tunnelling_through_the_whole_layer_is_detected():
    """h0 = 0.5 mm and 2000 m/s: a node crosses the layer within one step (dt ~ 1e-5 s); it must
    still be reported, from the previous step's contact."""
    s = _two_bars(v=2000.0, k=1e6, h0=5e-4)
    dt = s.stable_time_step()
    with pytest.raises(ContactPenetrationError):
        for _ in range(200):
            s.advance(dt)


def test_external_force_blocks_give_their_impulse_without_lag():
    """Forces given to advance() act from its first step: after blocks of n_k steps with total
    forces F_k, the half-step momentum is p0 + dt (sum n_k F_k - F_1 / 2) (central differences
    start with v^{1/2} = v^0 + dt/2 a^0)."""
    msh = dmesh.create_rectangle(MPI.COMM_SELF, [np.array([0.0, 0.0]), np.array([1.0, 0.5])],
                                 [6, 3])
    s = ExplicitSolver([BodySpec("b", msh, MAT, initial_velocity=(1.0, 0.0))],
                       formulation="plane_strain", comm=msh.comm)
    b = s.bodies["b"]
    M = b.total_mass()
    dt = s.stable_time_step()
    blocks = [((1e6, 0.0), 7), ((-5e5, 3e5), 4), ((2e5, 2e5), 9)]
    for F, n in blocks:
        f = np.outer(b.mass / M, F)          # uniform acceleration: rigid translation
        s.advance(dt, n, external_forces={"b": f})
    p = (b.mass[:, None] * b.v).sum(axis=0)
    expect = np.array([M * 1.0, 0.0]) + dt * (sum(n * np.array(F) for F, n in blocks)
                                              - 0.5 * np.array(blocks[0][0]))
    assert np.allclose(p, expect, rtol=1e-12, atol=1e-9 * np.abs(expect).max())
    e = s.energies()
    assert abs(e["balance_error_J"]) < 1e-6 * e["kinetic_J"]
