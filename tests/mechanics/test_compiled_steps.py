"""The compiled block path (``ExplicitSolver(compiled_steps=True)``, :mod:`.block`) against the
Python step loop (``compiled_steps=False``): the same bits for every feature the steps touch —
soft contact with a deformable master (one and two passes, friction, contact viscosity), rigid
walls (sticking and sliding), plasticity, kinetic damping, held external (pressure) forces that
change between blocks, plane strain and axisymmetry — exact restart through the compiled path,
and the same events (step above the critical one, inverted cell, penetration) with the same
messages.

Each comparison is ``np.array_equal`` (bitwise) on x, v, a, stress, plastic strain, every ledger
entry, the contact outputs and the wall pressures; nothing is compared to a tolerance."""
import math

import numpy as np
import pytest
from dolfinx import mesh as dmesh
from mpi4py import MPI

from pulseform.solvers.dolfinx import (BodySpec, ContactPairSpec, ContactPenetrationError,
                                       ExplicitSolver, Material, RigidWallSpec)

AL = Material(2735.0, 26.5e9, 65.1e9, 195e6, 520e6)
STEEL = Material(7800.0, 76.9e9, 166e9, 620e6, 1020e6)
COMM = MPI.COMM_SELF


def _die_case(compiled: bool, friction=0.2, viscosity=2e3, two_pass=True, v=-150.0, k=1e6):
    """A 1 mm Al blank, 0.12 mm above a steel die, flying onto it at ``v`` m/s normal and 40 m/s
    tangential; the set-up rotated by 20 deg; plane strain."""
    blank = dmesh.create_rectangle(COMM, [np.array([-0.012, 1.2e-4]),
                                          np.array([0.012, 1.12e-3])], [24, 2])
    die = dmesh.create_rectangle(COMM, [np.array([-0.02, -0.01]), np.array([0.02, 0.0])], [10, 3])
    th = math.radians(20.0)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    for m in (blank, die):
        m.geometry.x[:, :2] = m.geometry.x[:, :2] @ R.T
    fixed = lambda x: x[0] * math.sin(th) - x[1] * math.cos(th) > 0.008  # noqa: E731
    return ExplicitSolver(
        [BodySpec("blank", blank, AL, initial_velocity=tuple(R @ (40.0, v))),
         BodySpec("die", die, STEEL, fixed=((fixed, (0, 1)),))],
        formulation="plane_strain",
        contact_pairs=(ContactPairSpec("blank", "die", k, 1e-4, friction=friction,
                                       viscosity=viscosity, two_pass=two_pass),),
        comm=COMM, compiled_steps=compiled)


def _axi_case(compiled: bool):
    """Two solid cylinders impacting along the axis (contact with viscosity), the lower one resting
    on a sticking wall z >= 0 that it is pushed onto, the upper one plastic."""
    h0 = 0.005
    a = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([0.5, 1.0])], [5, 10])
    b = dmesh.create_rectangle(COMM, [np.array([0.0, 1.0 + h0]), np.array([0.5, 2.0 + h0])], [5, 10])
    soft = Material(2800.0, 26.5e9, 65.1e9, 5e6, 0.56e9)
    return ExplicitSolver([BodySpec("a", a, soft, initial_velocity=(0.0, -20.0)),
                           BodySpec("b", b, soft, initial_velocity=(0.0, -60.0))],
                          formulation="axisymmetric",
                          contact_pairs=(ContactPairSpec("a", "b", 1e8, h0, viscosity=1e4),),
                          rigid_walls=(RigidWallSpec((0.0, 0.0), (0.0, 1.0), bodies=("a",)),),
                          comm=COMM, compiled_steps=compiled)


def _press_case(compiled: bool):
    """A plane-strain block pressed by a follower pressure onto a tilted sliding wall (given
    before the block's body order in ``bodies``), with a second, free body to exercise the body
    offsets; kinetic damping on."""
    m1 = dmesh.create_rectangle(COMM, [np.array([0.0, 1e-7]), np.array([0.02, 0.01])], [8, 4])
    m2 = dmesh.create_rectangle(COMM, [np.array([0.03, 0.0]), np.array([0.05, 0.01])], [4, 2])
    soft = Material(2800.0, 26.5e9, 65.1e9, 60e6, 0.5e9)
    s = ExplicitSolver([BodySpec("free", m2, soft, initial_velocity=(1.0, -2.0)),
                        BodySpec("block", m1, soft, initial_velocity=(3.0, -1.0),
                                 fixed=((lambda x: x[0] < 1e-9, (0,)),))],
                       formulation="plane_strain",
                       rigid_walls=(RigidWallSpec((0.0, -0.001), (-0.1, 2.0), bodies=("block", "free"),
                                                  sliding=True),),
                       comm=COMM, compiled_steps=compiled)
    s.kinetic_damping = True
    return s


def _assert_same(a: ExplicitSolver, b: ExplicitSolver) -> None:
    assert a.compiled is not None and b.compiled is None
    assert a.time == b.time and a.step_count == b.step_count
    assert a.stable_time_step() == b.stable_time_step()
    for n in a.bodies:
        for key in ("x", "v", "a", "cell_stress", "eps_p"):
            assert np.array_equal(getattr(a.bodies[n], key), getattr(b.bodies[n], key)), (n, key)
    ea, eb = a.energies(), b.energies()
    assert ea == eb, {k: ea[k] - eb[k] for k in ea}
    for i in range(len(a.contact_pairs)):
        for u, w in zip(a.contact_pressure(i), b.contact_pressure(i)):
            assert np.array_equal(u, w)
    for iw, w in enumerate(a.rigid_walls):
        for n in (w.bodies or a.bodies):
            for u, q in zip(a.wall_pressure(iw, n), b.wall_pressure(iw, n)):
                assert np.array_equal(u, q)
    for key in a._active:
        assert all(np.array_equal(u, w) for u, w in zip(a._active[key], b._active[key]))


def _run_both(make, blocks, forces=None):
    """Run the two paths through the same blocks [(n_steps, dt factor)]; ``forces(solver, k)``
    gives the held external forces of block k."""
    a, b = make(True), make(False)
    _assert_same(a, b)
    a.max_in_contact = 0
    for k, (n, fac) in enumerate(blocks):
        dt = fac * a.stable_time_step()
        fa = forces(a, k) if forces else None
        fb = forces(b, k) if forces else None
        a.advance(dt, n, fa)
        b.advance(dt, n, fb)
        _assert_same(a, b)
        if a.contact_pairs:
            a.max_in_contact = max(a.max_in_contact, len(a.contact_pressure(0)[0]))
    return a, b


def test_deformable_master_two_pass_friction_viscosity_bitwise():
    a, _ = _run_both(_die_case, [(1, 1.0), (4, 1.0), (6, 0.9), (5, 1.0), (60, 1.0)])
    e = a.energies()
    assert a.bodies["blank"].eps_p.max() > 0 and e["contact_dissipated_J"] > 0
    assert a.max_in_contact > 5          # the comparison saw nodes in contact


def test_one_pass_contact_without_friction_bitwise():
    a, _ = _run_both(lambda c: _die_case(c, friction=0.0, viscosity=0.0, two_pass=False),
                     [(6, 1.0), (6, 1.0), (50, 1.0)])
    assert a.max_in_contact > 5


def test_axisymmetric_contact_and_sticking_wall_bitwise():
    a, _ = _run_both(_axi_case, [(30, 1.0), (30, 0.8), (40, 1.0)])
    e = a.energies()
    assert e["wall_dissipated_J"] > 0 and a.max_in_contact > 0
    assert a.bodies["b"].eps_p.max() > 0
    assert len(a.wall_pressure(0, "a")[0]) > 0


def test_pressure_loads_kinetic_damping_sliding_wall_bitwise():
    def forces(s, k):
        p = (40e6, 40e6, -10e6, 0.0, 25e6)[k]
        top = lambda x: x[1] > 0.01 - 1e-9  # noqa: E731
        f = {"block": s.pressure_nodal_forces("block", top, p)}
        if k == 1:
            f["free"] = np.full((s.bodies["free"].n_local, 2), 3.0)
        return f
    a, _ = _run_both(_press_case, [(20, 1.0), (15, 1.0), (25, 0.7), (10, 1.0), (30, 1.0)], forces)
    e = a.energies()
    assert e["kinetic_damping_J"] > 0 and e["wall_dissipated_J"] > 0
    assert e["external_work_J"] != 0 and a.bodies["block"].eps_p.max() > 0


def test_restart_through_the_compiled_path_is_exact():
    """state_dict of a compiled run, loaded into a fresh compiled solver and into a Python-loop
    solver: both continue bit for bit like the uninterrupted run."""
    a = _die_case(True)
    dt = a.stable_time_step()
    a.advance(dt, 50)
    state = {k: np.array(v, copy=True) for k, v in a.state_dict().items()}
    a.advance(dt, 40)
    for compiled in (True, False):
        b = _die_case(compiled)
        b.advance(0.5 * dt, 3)                  # a different state before loading
        b.load_state_dict(state)
        b.advance(dt, 40)
        for n in a.bodies:
            for key in ("x", "v", "a", "cell_stress", "eps_p"):
                assert np.array_equal(getattr(a.bodies[n], key), getattr(b.bodies[n], key))
        assert a.energies() == b.energies() and a.time == b.time


def _raised(s: ExplicitSolver, dt_factor: float, n: int, exc_type):
    dt = dt_factor * s.stable_time_step()
    with pytest.raises(exc_type) as info:
        for _ in range(n):
            s.advance(dt, 10)
    return str(info.value)


def test_dt_above_critical_raises_the_same_message():
    msgs = [_raised(_die_case(c), 2.5 / 0.5, 1, RuntimeError) for c in (True, False)]
    assert "exceeds the critical step" in msgs[0] and msgs[0] == msgs[1]


def test_penetration_raises_the_same_message():
    """k far too small for 300 m/s: the blank crosses the layer."""
    msgs, states = [], []
    for c in (True, False):
        s = _die_case(c, k=1e2, v=-300.0, viscosity=0.0, friction=0.0)
        msgs.append(_raised(s, 1.0, 200, ContactPenetrationError))
        states.append(s)
    assert "reached h=" in msgs[0] and msgs[0] == msgs[1]
    assert states[0].time == states[1].time


def test_tunnelling_raises_the_same_message():
    """h0 = 0.5 mm at 2000 m/s: a node crosses the whole layer within one step."""
    msgs = []
    for c in (True, False):
        left = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([4.0, 2.0])], [8, 4])
        right = dmesh.create_rectangle(COMM, [np.array([4.0005, 0.3]), np.array([8.0005, 2.3])],
                                       [8, 4])
        mat = Material(2800.0, 26.5e9, 65.1e9, 0.24e9, 0.56e9)
        s = ExplicitSolver([BodySpec("left", left, mat, initial_velocity=(2000.0, 1.0)),
                            BodySpec("right", right, mat)], formulation="plane_strain",
                           contact_pairs=(ContactPairSpec("left", "right", 1e6, 5e-4),),
                           comm=COMM, compiled_steps=c)
        msgs.append(_raised(s, 1.0, 20, ContactPenetrationError))
    assert msgs[0] == msgs[1]


def test_inverted_cell_raises_the_same_message():
    """A node thrown through its cell by a huge point force."""
    msgs = []
    for c in (True, False):
        msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([0.01, 0.01])], [2, 2])
        s = ExplicitSolver([BodySpec("b", msh, AL)], formulation="plane_strain", comm=COMM,
                           compiled_steps=c, bulk_viscosity=False)
        b = s.bodies["b"]
        f = np.zeros((b.n_local, 2))
        f[int(np.argmin(np.hypot(*(b.X0 - 0.005).T)))] = (1e12, 3e11)
        dt = s.stable_time_step()
        with pytest.raises(RuntimeError) as info:
            s.advance(dt, 50, {"b": f})
        msgs.append(str(info.value))
    assert "inverted" in msgs[0] and msgs[0] == msgs[1]


def test_paths_that_cannot_compile_fall_back_to_the_python_loop():
    msh = dmesh.create_rectangle(COMM, [np.array([0.0, 0.0]), np.array([1.0, 0.5])], [4, 2])
    moving = BodySpec("b", msh, AL, motion=((lambda x: x[0] < 1e-9, lambda X, t: X + t),))
    assert ExplicitSolver([moving], comm=COMM).compiled is None
    ramp = BodySpec("b", msh, AL, fixed=((lambda x: x[0] < 1e-9, (0,), lambda t: t),))
    assert ExplicitSolver([ramp], comm=COMM).compiled is None
    assert ExplicitSolver([BodySpec("b", msh, AL)], comm=COMM, kernel="numpy").compiled is None
    assert ExplicitSolver([BodySpec("b", msh, AL)], comm=COMM).compiled is not None


def _numpy_fields(s: ExplicitSolver):
    """The numpy expressions that Body.cell_volumes / elastic_energy / von_mises and
    ExplicitSolver._kinetic used before cell_fields (kept here as the reference)."""
    out, ke = {}, 0.0
    for n, b in s.bodies.items():
        xe = b.x[b.cells]
        a = 0.5 * ((xe[:, 1, 0] - xe[:, 0, 0]) * (xe[:, 2, 1] - xe[:, 0, 1])
                   - (xe[:, 2, 0] - xe[:, 0, 0]) * (xe[:, 1, 1] - xe[:, 0, 1]))
        vol = 2 * np.pi * xe[:, :, 0].mean(axis=1) * a if b.axisymmetric else b.thickness * a
        st = b.cell_stress
        G, K = b.material.shear_modulus, b.material.bulk_modulus
        p = st[:, :3].mean(axis=1)
        d = st[:, :3] - p[:, None]
        w = ((d ** 2).sum(axis=1) + 2 * st[:, 3] ** 2) / (4 * G) + p ** 2 / (2 * K)
        vm = np.sqrt(1.5 * ((d ** 2).sum(axis=1) + 2 * st[:, 3] ** 2))
        out[n] = (vol, float(np.dot(w, vol)), vm)
        no = b.n_owned
        vn = b.v[:no] + 0.5 * s._dt_prev * b.a[:no]
        ke += 0.5 * float(np.sum(b.mass[:no] * np.sum(vn ** 2, axis=1)))
    return out, ke


@pytest.mark.parametrize("make", [_die_case, _axi_case])
def test_output_fields_match_the_numpy_expressions_bitwise(make):
    """Cell volumes, elastic energy, von Mises and the kinetic energy (compiled, cell_fields) give
    the bits of the numpy expressions they replaced, on plastic, moving, stressed states."""
    s = make(True)
    s.advance(s.stable_time_step(), 12)
    ref, ke = _numpy_fields(s)
    assert s._kinetic() == ke and ke > 0
    for n, b in s.bodies.items():
        vol, el, vm = ref[n]
        assert np.array_equal(b.cell_volumes(), vol)
        assert b.elastic_energy() == el and el > 0
        assert np.array_equal(b.von_mises, vm)
