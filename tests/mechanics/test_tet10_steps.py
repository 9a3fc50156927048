"""The compiled steps of a ten-node body (``ExplicitSolver3D(compiled_steps=True)``, :mod:`.tet10_steps`) against
the Python step loop (``compiled_steps=False``): the same bits for what the steps touch — plasticity with
hardening, bulk viscosity, a constant nonzero prescribed velocity, held tip forces changed between blocks, kinetic
damping switched on between blocks — exact restart through the compiled steps, the same events (a step above the
critical one, an inverted cell) with the same messages and states, and the solvers that fall back to the Python
loop. Each comparison is ``np.array_equal`` (bitwise) or ``==``; nothing is compared to a tolerance."""
import numpy as np
import pytest

from pulseform.solvers.dolfinx import BodySpec, ExplicitSolver3D, Material, RigidWallSpec
from cantilever_strip import Strip, strip_body, tip_load

E, NU = 200e9, 0.3
G, K = E / (2 * (1 + NU)), E / (3 * (1 - 2 * NU))
STEEL = Material(7800.0, G, K, 250e6, 2e9)
ST = Strip(length=0.004, width=0.002, n_length=4, n_width=1, n_thick=2)


def _pulled(compiled: bool) -> ExplicitSolver3D:
    """The short strip (ten-node), its root as in the cantilever tests, its tip face x = L pulled up at a constant
    2 m/s (a prescribed velocity that is not zero)."""
    spec = strip_body(ST, STEEL, "tet10")
    tip = (lambda x: np.abs(x[0] - ST.length) < 1e-12, (2,), 2.0)
    spec = BodySpec(spec.name, spec.mesh, STEEL, initial_velocity=(0.0, 0.0, 0.0), fixed=spec.fixed + (tip,),
                    element="tet10")
    return ExplicitSolver3D([spec], cfl=0.8, compiled_steps=compiled)


def _loaded(compiled: bool) -> ExplicitSolver3D:
    return ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], cfl=0.8, compiled_steps=compiled)


def _state(s: ExplicitSolver3D):
    b = s.bodies["strip"]
    return ([b.x, b.v, b.a, b.cell_stress, b.eps_p, b.temperature],
            [s.time, s.step_count, s._dt_prev, s._dt_crit, s._ke_half["strip"]] + sorted(s.energies().items()))


def _assert_same(s1: ExplicitSolver3D, s2: ExplicitSolver3D) -> None:
    (a1, f1), (a2, f2) = _state(s1), _state(s2)
    assert all(np.array_equal(u, w) for u, w in zip(a1, a2))
    assert f1 == f2


def _drive(s: ExplicitSolver3D) -> None:
    """Tip forces past first yield, changed between blocks, kinetic damping switched on for the last two."""
    b = s.bodies["strip"]
    dt = s.stable_time_step()
    s.advance(dt, 300, {"strip": tip_load(b, ST, 40.0)})
    s.advance(dt, 200, {"strip": tip_load(b, ST, 80.0)})
    s.kinetic_damping = True
    s.advance(0.9 * s.stable_time_step(), 400, {"strip": tip_load(b, ST, 60.0)})
    s.advance(s.stable_time_step(), 300)


def test_compiled_steps_give_the_python_loops_bits():
    """Held tip forces (plastic, bulk viscosity), kinetic damping, and a pulled tip: the compiled steps and the
    Python loop end in the same bits (positions, velocities, accelerations, Gauss-point stress, plastic strain,
    temperature, time, steps, the critical step and every ledger entry)."""
    s1, s2 = _loaded(True), _loaded(False)
    assert s1._steps is not None and s2._steps is None
    _drive(s1)
    _drive(s2)
    assert s1.bodies["strip"].eps_p.max() > 0 and s1.energies()["kinetic_damping_J"] > 0
    _assert_same(s1, s2)
    p1, p2 = _pulled(True), _pulled(False)
    for s in (p1, p2):
        s.advance(s.stable_time_step(), 300)
        s.kinetic_damping = True                  # zeroed velocities, the prescribed one put back
        s.advance(s.stable_time_step(), 300)
    assert p1.energies()["kinetic_damping_J"] > 0
    assert p1.bodies["strip"].eps_p.max() > 0
    _assert_same(p1, p2)


def test_restart_through_the_compiled_steps_is_exact():
    """A state written after compiled blocks and loaded into a fresh solver (kinetic damping on in both) continues
    as the uninterrupted run."""
    s1 = _loaded(True)
    _drive(s1)
    saved = s1.state_dict()
    s1.advance(s1.stable_time_step(), 200, {"strip": tip_load(s1.bodies["strip"], ST, 70.0)})
    s2 = _loaded(True)
    s2.load_state_dict(saved)
    s2.kinetic_damping = True                     # a setting, not state
    s2.advance(s2.stable_time_step(), 200, {"strip": tip_load(s2.bodies["strip"], ST, 70.0)})
    _assert_same(s1, s2)


def test_events_raise_the_python_loops_message_and_state():
    """A step above the critical one, and a node flung through its cell (an inverted cell): the same message and the
    same state as the Python loop."""
    for event in ("dt", "inverted"):
        msgs, solvers = [], []
        for compiled in (True, False):
            s = _loaded(compiled)
            s.advance(s.stable_time_step(), 50, {"strip": tip_load(s.bodies["strip"], ST, 40.0)})
            if event == "dt":
                dt = 1.01 * s._dt_crit
            else:
                b = s.bodies["strip"]
                b.v[int(np.argmax(b.X0[:, 0] + b.X0[:, 2])), 2] = -1e6   # m/s: across its cell in a few steps
                dt = s.stable_time_step()
            with pytest.raises(RuntimeError) as err:
                s.advance(dt, 100)
            msgs.append(str(err.value))
            solvers.append(s)
        assert ("exceeds the critical step" if event == "dt" else "inverted") in msgs[0]
        assert msgs[0] == msgs[1]
        _assert_same(*solvers)


def test_solvers_the_compiled_steps_do_not_run_fall_back_to_the_python_loop():
    """Linear tetrahedra, two bodies, a rigid wall, a time-dependent prescribed velocity and ``compiled_steps=False``
    run the Python loop."""
    assert ExplicitSolver3D([strip_body(ST, STEEL, "tet4")])._steps is None
    assert ExplicitSolver3D([strip_body(ST, STEEL, "tet10"), strip_body(ST, STEEL, "tet10", "other")])._steps is None
    wall = RigidWallSpec(point=(0.0, 0.0, -1e-3), normal=(0.0, 0.0, 1.0))
    assert ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], rigid_walls=[wall])._steps is None
    spec = strip_body(ST, STEEL, "tet10")
    ramp = BodySpec("strip", spec.mesh, STEEL, initial_velocity=(0.0, 0.0, 0.0),
                    fixed=spec.fixed + ((lambda x: x[0] > ST.length - 1e-12, (2,), lambda t: t),), element="tet10")
    assert ExplicitSolver3D([ramp])._steps is None
    assert ExplicitSolver3D([strip_body(ST, STEEL, "tet10")], compiled_steps=False)._steps is None
