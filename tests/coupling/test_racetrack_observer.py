"""The checkpoint state of the racetrack's observer (orchestrator/run/racetrack_case.py), the bookkeeping of a
case with a ``[racetrack]`` table. No case of the project has that table any more (cases/emf_racetrack_groove
runs on the 3D geometry path: tests/coupling/test_case_racetrack.py); the observer lives until the driver's
racetrack branch is removed: delete this file together with orchestrator/run/racetrack_case.py."""
from pathlib import Path

import numpy as np


def test_the_observer_state_round_trips_with_a_frozen_em_mesh():
    """A checkpoint after the EM mesh froze (a 3 µs test run never freezes: the design's freezes at 36 µs)
    restores the frozen mesh, its time and reason, the recorder's rows, sums and peak snapshot exactly
    (reference: the state written, array for array)."""
    from types import SimpleNamespace

    from pulseform.orchestrator.run.racetrack_case import RacetrackObserver

    rng = np.random.default_rng(7)

    def observer():
        load = SimpleNamespace(frozen_at=None, freeze_reason="", _last_valid=np.zeros((5, 3)))
        rm = SimpleNamespace(clamped={"sheet": np.zeros(4, bool), "die": np.zeros(3, bool)}, load=load, solver=None)
        return RacetrackObserver(rm, None, 42, Path("."))

    a = observer()
    a.rm.load.frozen_at, a.rm.load.freeze_reason = 3.6e-5, "tetrahedron 7 inverted"
    a.rm.load._last_valid = rng.random((5, 3))
    rec = a.rec
    rec.rows = [{"time_s": 1e-6 * k, "force_z_N": rng.random(), "em_mesh_frozen": float(k > 1)} for k in range(3)]
    rec.first_contact_s, rec.peak_current = 2e-6, 4.7e4
    for n in rec.impulse:
        rec.impulse[n], rec.clamp_impulse[n], rec.half_step[n] = rng.random(3), rng.random(3), rng.random(3)
    rec.peak = {"time_s": 2.2e-5, "points": rng.random((5, 3)), "tets": np.arange(8).reshape(2, 4),
                "force_density": rng.random((2, 3)), "coil_current_A": -4.7e4}
    state = a.state_dict()
    b = observer()
    b.load_state_dict({k: np.array(v) for k, v in state.items()})
    assert b.rm.load.frozen_at == 3.6e-5 and b.rm.load.freeze_reason == "tetrahedron 7 inverted"
    assert np.array_equal(b.rm.load._last_valid, a.rm.load._last_valid)
    assert b.rec.rows == rec.rows and (b.rec.first_contact_s, b.rec.peak_current) == (2e-6, 4.7e4)
    for n in rec.impulse:
        for what in ("impulse", "clamp_impulse", "half_step"):
            assert np.array_equal(getattr(b.rec, what)[n], getattr(rec, what)[n])
    assert b.rec.peak["time_s"] == 2.2e-5 and b.rec.peak["coil_current_A"] == -4.7e4
    for k in ("points", "tets", "force_density"):
        assert np.array_equal(b.rec.peak[k], rec.peak[k])
