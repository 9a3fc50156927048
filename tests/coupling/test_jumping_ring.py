"""A jumping ring: a thin aluminium ring (3 x 3 mm at r = 41.5 mm, 6.3 g) 10 mm above a coil with a
50 Hz current of 5 kA-turns, released as a rigid body under gravity; GetDP's eddy-current force on
the moving ring (persistent getdp, BDF2, 40 EM steps per period, the air mesh moved and remeshed
around the ring) against the lumped model's ODE (orchestrator/em/lumped.py: the ring an R-L loop
with the section-averaged M(z) and dM/dz of Maxwell's formula, Rosa's L; solved by scipy's Radau to
1e-8): the height history within 3 % of the maximum height (issue 17). Measured: max height
14.556 mm FE vs 14.522 mm lumped, largest difference 1.39 % of it; two remeshes on the way up.
Also: the rigid-body participant restarts exactly."""
import math

import numpy as np
import pytest

from pulseform.orchestrator.coupling.loop import LoopOptions, StaggeredLoop
from pulseform.orchestrator.em.lumped import (RingCircuit, ring_resistance, ring_self_inductance,
                                              section_mutual_inductance)
from pulseform.orchestrator.em.participant import ConductorBody, GetDPLoad
from pulseform.orchestrator.mech.rigid import RigidMechanics
from pulseform.orchestrator.mesh.em_geometry import EMGeometry
from pulseform.orchestrator.mesh.shared import conductor_submesh
from pulseform.solvers.dolfinx.rigid import EndStop, RigidBody
from pulseform.solvers.getdp import Coil, Conductor, DampedSine, EMModel, Rect, coil_conductor_mesh

F, N_TURNS, I0, PER = 50.0, 100, 50.0, 40
COIL = (0.040, -0.002, 0.044, 0.002)  # (r0, z0, r1, z1), m
RING = (0.040, 0.0085, 0.043, 0.0115)
SIGMA, RHO, G = 3.5e7, 2700.0, 9.81


@pytest.mark.getdp
def test_released_ring_follows_the_lumped_ode(tmp_path):
    w = 2 * math.pi * F
    mesh = coil_conductor_mesh([[Rect(*COIL)]], [Rect(*RING)], r_domain=0.25, r_shell=0.3125, h_fine=1e-3,
                               h_coarse=2.5e-2, h_conductor=5e-4, names={101: "coil", 201: "workpiece"})
    geo = EMGeometry(mesh, {"coil": 101, "workpiece": 201}, [Rect(*COIL)])
    sub = conductor_submesh(mesh, 201)
    model = EMModel(True, coils=[Coil(N_TURNS, waveform=DampedSine(I0, 0.0, w))], conductors=[Conductor(SIGMA)],
                    shell=(0.25, 0.3125))
    load = GetDPLoad(geo, model, tmp_path / "em", [ConductorBody("ring", 201, sub, sub.em_nodes)],
                     sizes=(1e-3, 2.5e-2), time_scheme="bdf2", getdp_process="persistent")
    rc, wc, hc = 0.5 * (RING[0] + RING[2]), RING[2] - RING[0], RING[3] - RING[1]
    mass = RHO * 2 * math.pi * rc * wc * hc
    ring = RigidBody("ring", sub.points, mass, gravity=(0.0, -G), stops=(EndStop(1, 0.0),))  # resting on a support
    mech = RigidMechanics([ring], 1.0 / (F * PER))
    t, z = [0.0], [0.0]

    def record(row):
        t.append(mech.time)
        z.append(ring.u[1])

    try:
        StaggeredLoop(load, mech, LoopOptions(n=1, landing="last")).run_until(0.06, record)
    finally:
        load.close()
    t, z = np.array(t), np.array(z)

    z0 = 0.5 * (RING[1] + RING[3]) - 0.5 * (COIL[1] + COIL[3])

    def coupling(zz):  # the ring's section moved to height zz
        return section_mutual_inductance(COIL, (RING[0], RING[1] + zz - z0, RING[2], RING[3] + zz - z0), n=3)

    lumped = RingCircuit(0.5 * (COIL[0] + COIL[2]), rc, ring_resistance(rc, wc, hc, SIGMA),
                         ring_self_inductance(rc, wc, hc), mass=mass, gravity=G, coupling=coupling)
    sol = lumped.solve(lambda s: (N_TURNS * I0 * math.sin(w * s), N_TURNS * I0 * w * math.cos(w * s)), t[-1], z0,
                       t_eval=t, rtol=1e-8)
    zl = sol.y[0] - z0
    err = np.abs(z - zl).max() / zl.max()
    print(f"\n{len(t) - 1} EM steps; max height FE {z.max() * 1e3:.3f} mm, lumped {zl.max() * 1e3:.3f} mm; "
          f"max |dz| / max height {err:.2%}; remeshes {load.remeshes}")
    assert zl.max() > 5e-3 and np.all(z >= 0.0)  # it jumps; never below its support
    assert err < 0.03


def test_rigid_participant_restarts_exactly():
    nodes = np.array([[0.04, 0.0], [0.043, 0.0], [0.043, 0.003]])
    make = lambda: RigidMechanics([RigidBody("ring", nodes, 0.01, gravity=(0.0, -G), stops=(EndStop(1, 0.0, 1, 0.4),))],  # noqa: E731
                                  1e-4)
    a, b = make(), make()
    f = {"ring": np.array([[0.0, 0.05], [0.0, 0.04], [0.0, 0.03]])}
    for _ in range(30):
        a.advance(1e-4, 5, f)
    for _ in range(15):
        b.advance(1e-4, 5, f)
    c = make()
    c.load_state_dict({k: v.copy() for k, v in b.state_dict().items()})
    for _ in range(15):
        c.advance(1e-4, 5, f)
    assert np.array_equal(a.positions()["ring"], c.positions()["ring"])
    assert a.history() == c.history() and a.time == c.time and a.step_count == c.step_count
    assert a.history()["ring_force_y_N"] == pytest.approx(0.12)
    with pytest.raises(ValueError, match="unique"):
        RigidMechanics([RigidBody("r", nodes, 1.0), RigidBody("r", nodes, 1.0)], 1e-4)
