"""The implicit solver under MPI (solvers/dolfinx/implicit_dist.py; issue 34, item 1): ``mpirun -n 2`` and
``-n 3`` give the serial results of the same cases (tests/mechanics/mpi_implicit_metrics.py: an elastic-plastic
plane-strain plate under a pressure ramp, trapezoidal; an axisymmetric cylinder past yield, HHT; a 3D tet4
cantilever past yield in static steps; a 3D block pressed on a sliding wall; a 2D bar pressed on a wall and pulled
off it; by name, two bars and two plates pressed through a contact pair's soft layer), and ``mpirun -n 2 pulseform
run`` gives the serial history and metrics of the implicit case of test_implicit_run.py and of a press fit whose
springback keeps its contact pair.

The reference is the serial run: one process and a partition differ only in the order of the sums (nodal forces
summed over ranks, the ledger's reductions) and in the pivoting of the sparse LU (MUMPS on one process, or in
parallel on the distributed matrix), i.e. by round-off carried through Newton's iterations. Bounds: probe
displacements, plastic strain, wall force and stress 1e-10 relative (the 2D and 3D explicit MPI checks' bound,
test_mpi.py, test_3d_mpi.py; measured <= 3e-14); ledger entries 1e-10 of the case's largest energy (an entry that
is a difference of large sums, e.g. the trapezoidal rule's algorithmic dissipation, zero to round-off: 1e-11 J
against 1.3 J, carries their round-off); Newton iteration and cut counts and the wall's held node counts equal.
A restart under MPI continues to round-off, not to the same bits: MUMPS's parallel factorisation schedules its
work dynamically, so two parallel runs of the same step differ by ~1e-15 relative (measured); one process: the
same bits.
"""
import copy
import json
import os
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
import tomli_w

from test_implicit_run import CASE, COARSE, EXE
from test_mpi import _run   # this folder is on sys.path (rootdir conftest / rootless test modules)

SCRIPT = Path(__file__).with_name("mpi_implicit_metrics.py")
EXACT = ("newton_iterations", "step_cuts", "held_nodes")
#: the run's timers in metrics.json (s), not results
TIMERS = ("load_time_s", "mech_time_s", "setup_time_s", "wall_time_s")


def _mpirun():
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        pytest.skip("mpirun not found")
    return mpirun


def _env() -> dict:
    return dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                OMPI_MCA_rmaps_base_oversubscribe="1", NUMBA_DISABLE_ERROR_MESSAGE_HIGHLIGHTING="1")


def _compare(serial: dict, par: dict, ranks: int) -> None:
    for case, ref in serial.items():
        if case == "plate_restart":
            continue
        energy = max(abs(v) for k, v in ref.items() if "energy_" in k)
        for key, val in ref.items():
            got = par[case][key]
            if key.endswith("wall_time_s"):
                print(f"{case} {key}: serial {val:.2f} s, {ranks} ranks {got:.2f} s")
                continue
            print(f"{case} {key}: serial {val!r} mpi {got!r}")
            if any(e in key for e in EXACT):
                assert got == val, (case, key)
            elif "energy_" in key:
                assert abs(got - val) <= 1e-10 * energy, (case, key)
            else:
                assert got == pytest.approx(val, rel=1e-10, abs=1e-300), (case, key)


def _history_equal(hs, hp) -> float:
    """Assert every column of the MPI run's history ``hp`` equals the serial ``hs`` to 1e-8 relative (ledger
    columns: 1e-8 of the external work); returns that work (J)."""
    work = float(np.abs(hs["energy_external_work_J"]).max())
    for col in hs.dtype.names:
        err = float(np.abs(hp[col] - hs[col]).max())
        scale = work if col.startswith("energy_") else float(np.abs(hs[col]).max())
        print(f"history {col}: largest |mpi - serial| {err:.3g} (scale {scale:.3g})")
        assert err <= 1e-8 * scale, col
    return work


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [2, 3])
def test_ranks_match_serial(ranks):
    """Every case of mpi_implicit_metrics.py on ``ranks`` processes equals the serial run (bounds in the module
    docstring); the cases are those they claim to be (plastic, walls taking and releasing nodes); a restart from the
    state after 4 of the plate's 8 steps continues to the same bits serially and to round-off under MPI."""
    mpirun = _mpirun()
    serial = _run([sys.executable, str(SCRIPT)])
    par = _run([mpirun, "-n", str(ranks), sys.executable, str(SCRIPT)])
    for case in ("plate", "cylinder_hht", "cantilever3d_static"):
        assert serial[case]["eps_p_max"] > 1e-3, case                  # past yield
    assert serial["bar_off_wall2d"]["held_nodes_pressed"] == 3 and serial["bar_off_wall2d"]["held_nodes_released"] == 0
    # the block's mean stress is the uniaxial one of the wall test in test_implicit_contact.py: -E d / (L - d/2)
    k_bulk, g = 58.3e9, 26.9e9
    e_mod = 9 * k_bulk * g / (3 * k_bulk + g)
    assert serial["block_on_wall3d"]["sigma_xx_mean_Pa"] == pytest.approx(-e_mod * 1e-5 / (0.1 - 0.5e-5), rel=1e-10)
    _compare(serial, par, ranks)
    rs, rp = serial["plate_restart"], par["plate_restart"]
    print(f"restart: serial dx {rs['restart_dx_max']:.3g} m dv {rs['restart_dv_max']:.3g} m/s; {ranks} ranks dx "
          f"{rp['restart_dx_max']:.3g} m (of {rp['u_max']:.3g}) dv {rp['restart_dv_max']:.3g} m/s "
          f"(of {rp['v_max']:.3g})")
    assert rs["restart_dx_max"] == 0.0 and rs["restart_dv_max"] == 0.0 and rs["restart_same_energies"] == 1.0
    assert rp["restart_dx_max"] <= 1e-10 * rp["u_max"] and rp["restart_dv_max"] <= 1e-10 * rp["v_max"]


@pytest.mark.mpi
@pytest.mark.parametrize("steps", [[], ["--set", "mechanics.implicit.adaptive=true",
                                        "--set", "mechanics.implicit.error_tol=1e-3"]], ids=["fixed", "adaptive"])
def test_pulseform_run_on_two_ranks_matches_serial(tmp_path, steps):
    """``mpirun -n 2 pulseform run`` of the implicit cantilever (test_implicit_run.py's case, coarse), with fixed
    and with adaptive steps (the error estimate reduced over the ranks: both take the serial run's steps): every
    column of history.csv and every physics metric equal the serial run's to 1e-8 relative (ledger columns: 1e-8 of
    the external work)."""
    mpirun = _mpirun()
    case = tmp_path / "case.toml"
    case.write_text(tomli_w.dumps(CASE))
    env = _env()
    runs = {}
    for name, prefix in (("serial", []), ("mpi", [mpirun, "-n", "2"])):
        out = tmp_path / name
        r = subprocess.run([*prefix, EXE, "run", str(case), "--out", str(out), "--quiet", *COARSE, *steps,
                            "--set", "output.plots=false"], capture_output=True, text=True, env=env, timeout=900)
        assert r.returncode == 0, r.stderr[-3000:]
        runs[name] = (np.genfromtxt(out / "history.csv", delimiter=",", names=True),
                      json.loads((out / "metrics.json").read_text()))
    (hs, ms), (hp, mp) = runs["serial"], runs["mpi"]
    assert hs.dtype.names == hp.dtype.names and hs.shape == hp.shape
    assert hs.shape == (21,) if not steps else hs.shape[0] > 5
    work = _history_equal(hs, hp)
    for key, val in ms.items():
        if isinstance(val, float) and key not in TIMERS:
            print(f"metric {key}: serial {val!r} mpi {mp[key]!r}")
            assert mp[key] == pytest.approx(val, rel=1e-8, abs=1e-8 * work), key
    print(f"wall time: serial {ms['wall_time_s']:.2f} s, 2 ranks {mp['wall_time_s']:.2f} s")


@pytest.mark.mpi
@pytest.mark.parametrize("ranks", [2, 3])
def test_contact_pairs_match_serial(ranks):
    """Contact pairs in the implicit solver on ``ranks`` processes (every rank evaluates the passes on the gathered
    surfaces; each pair's tangent given once, by the rank owning its slave node, in the global numbering): two 2D
    bars and two 3D tet4 bars pressed through the soft-contact layer (test_implicit_contact.py's analytic chains,
    partitioned: the contact faces lie in one part), and the same chains pressed across two stacked plates, whose
    contact face the partition cuts (the pairs' tangents given by every rank). Both runs carry the chain's stress in
    every cell and its pressure and gap at every slave node to 1e-9 (measured 3e-10 for the 2D bars: the Newton
    tolerance; <= 2e-11 for the others) with the same nodes in contact and the same number of Newton iterations;
    against the serial run every node's displacement agrees to 1e-12 of the body's largest (measured 2e-13), every
    contact pressure to 1e-12 relative (measured <= 4e-14) and the ledger to 1e-12 of its largest entry (measured
    6e-14)."""
    mpirun = _mpirun()
    nodes = {"bars_contact2d": 3, "bars_contact3d": 9, "plates_contact2d": 21, "plates_contact3d": 21}
    cases = list(nodes)
    serial = _run([sys.executable, str(SCRIPT), *cases])
    par = _run([mpirun, "-n", str(ranks), sys.executable, str(SCRIPT), *cases])
    for case in cases:
        ref, got = serial[case], par[case]
        assert ref["contact_nodes"] == ref["active_pairs"] == nodes[case]
        assert sum(got["tangent_pairs_per_rank"]) == got["active_pairs"] == nodes[case], case
        if case.startswith("plates"):          # the contact face cut by the partition
            assert sum(n > 0 for n in got["tangent_pairs_per_rank"]) == ranks, case
        for run in (ref, got):
            assert run["stress_err_max"] < 1e-9 and run["pressure_err_max"] < 1e-9, case
            assert run["gap_err_max_over_h0"] < 1e-9, case
            assert run["residuals"][-1] < 1e-8, case
        print(f"{case}: stress vs chain {ref['stress_err_max']:.2g} serial, {got['stress_err_max']:.2g} {ranks} ranks; "
              f"pairs per rank {got['tangent_pairs_per_rank']}; Newton {ref['newton_iterations']} / "
              f"{got['newton_iterations']} iterations; residuals "
              + ", ".join(f"{v:.2g}" for v in got["residuals"]))
        assert got["contact_nodes"] == ref["contact_nodes"], case
        assert got["newton_iterations"] == ref["newton_iterations"], case
        assert len(got["residuals"]) == len(ref["residuals"]), case
        for body in ("a", "b"):
            u_ref, u_par = np.array(ref[f"u_{body}_m"]), np.array(got[f"u_{body}_m"])
            dev = float(np.abs(u_par - u_ref).max() / np.abs(u_ref).max())
            print(f"{case} body {body}: displacements |mpi - serial| / max |u| {dev:.2g}")
            assert dev <= 1e-12, (case, body)
        p_ref, p_par = np.array(ref["pressures_Pa"]), np.array(got["pressures_Pa"])
        print(f"{case}: contact pressures |mpi / serial - 1| {float(np.abs(p_par / p_ref - 1).max()):.2g}")
        assert p_par == pytest.approx(p_ref, rel=1e-12), case
        energy = max(abs(v) for k, v in ref.items() if k.startswith("energy_"))
        for key in (k for k in ref if k.startswith("energy_")):
            assert abs(got[key] - ref[key]) <= 1e-12 * energy, (case, key)


@pytest.mark.mpi
def test_stops_are_one_line_on_every_rank():
    """On 2 ranks every rank raises the same one-line stop and keeps the state at t = 0: a static step of an
    unsupported plate (SingularSystemError naming the body and its free motions, from the gathered supports), a
    plastic static step allowed one Newton iteration and one cut (ImplicitConvergenceError), a zero tangent in the
    distributed LU (SingularSystemError from MUMPS)."""
    par = _run([_mpirun(), "-n", "2", sys.executable, str(SCRIPT), "errors"])["errors"]
    want = {"unsupported": ("SingularSystemError", "rotation z"),
            "newton": ("ImplicitConvergenceError", "after 1 cuts"),
            "zero_pivot": ("SingularSystemError", "zero pivot")}
    for name, (kind, part) in want.items():
        msgs = par[name]["messages"]
        print(name, msgs[0])
        assert len(msgs) == 2 and msgs[0] == msgs[1] and msgs[0] is not None, name
        assert msgs[0].startswith(kind) and part in msgs[0] and "\n" not in msgs[0], name
        assert par[name]["time"] == 0.0 and par[name]["steps"] == 0, name


def press_fit_case() -> dict:
    """cases/tube_press_fit in static implicit steps on its coarse cells (0.5 mm): the pulse's pressure pushes the
    inner tube's wall past yield into the outer tube through the contact layer over 20 steps of 2 us and falls to
    4 % of its peak; the case's [springback] keeps the pair (contact = "kept"): the residual contact pressure of a
    press fit (metrics ``springback_contact0_*``). Without its analysis (serial only)."""
    data = tomllib.loads((Path(__file__).resolve().parents[2] / "cases/tube_press_fit/case.toml").read_text())
    data.pop("analysis")
    data["time"]["end"] = 4e-5
    data["mechanics"] = {"formulation": "axisymmetric", "integrator": "implicit",
                         "implicit": {"dt": 2e-6, "scheme": "static"}}
    for body in data["bodies"]:
        body["mesh_size"] = 5e-4
    data["output"] = {"field_interval": 2e-5, "plots": False}
    assert data["springback"]["contact"] == "kept"
    return data


@pytest.mark.mpi
def test_press_fit_with_kept_contact_on_two_ranks_matches_serial(tmp_path):
    """``mpirun -n 2 pulseform run`` of a press fit (:func:`press_fit_case`: a contact pair in implicit static steps,
    then a springback that keeps it) gives the serial run's metrics: the residual contact pressure (mean, largest,
    closed nodes), the springback and residual-stress metrics, the Newton counts and every other physics metric to
    1e-8 relative (1e-15 m absolute: the springback's axial component is round-off, ~5e-12 m; measured: pressures
    <= 4e-11, the rest <= 7e-11 but for that component), and every column of history.csv to 1e-8 relative (ledger
    columns: 1e-8 of the external work)."""
    case = tmp_path / "case.toml"
    case.write_text(tomli_w.dumps(press_fit_case()))
    runs = {}
    for name, prefix in (("serial", []), ("mpi", [_mpirun(), "-n", "2"])):
        out = tmp_path / name
        r = subprocess.run([*prefix, EXE, "run", str(case), "--out", str(out), "--quiet"], capture_output=True,
                           text=True, env=_env(), timeout=900)
        assert r.returncode == 0, r.stderr[-3000:]
        runs[name] = (np.genfromtxt(out / "history.csv", delimiter=",", names=True),
                      json.loads((out / "metrics.json").read_text()))
    (hs, ms), (hp, mp) = runs["serial"], runs["mpi"]
    assert ms["springback_contact0_pressure_mean_Pa"] > 1e7 and ms["springback_contact0_closed_nodes"] >= 3
    assert ms["inner_residual_plastic_strain_max"] > 1e-3 and ms["mech_steps"] == 20
    for key, val in ms.items():
        if isinstance(val, float) and key not in TIMERS:
            print(f"metric {key}: serial {val!r} mpi {mp[key]!r}")
            assert mp[key] == pytest.approx(val, rel=1e-8, abs=1e-15), key
    assert hs.dtype.names == hp.dtype.names and hs.shape == hp.shape
    _history_equal(hs, hp)


@pytest.mark.mpi
@pytest.mark.parametrize("supports", ["kept", "minimal"])
def test_springback_on_two_ranks_matches_serial(tmp_path, supports):
    """[springback] after the implicit cantilever's run under ``mpirun -n 2`` (the release's static steps
    distributed; 'minimal': the 3-2-1 supports chosen on the whole body, every rank's nodes gathered): every
    springback metric (largest displacement per component, residual von Mises stress and plastic strain, the tip
    probe's springback) equals the serial run's to 1e-8 relative."""
    data = copy.deepcopy(CASE)
    data["springback"] = {"supports": supports, "steps": 2}
    case = tmp_path / "case.toml"
    case.write_text(tomli_w.dumps(data))
    runs = {}
    for name, prefix in (("serial", []), ("mpi", [_mpirun(), "-n", "2"])):
        out = tmp_path / name
        r = subprocess.run([*prefix, EXE, "run", str(case), "--out", str(out), "--quiet", *COARSE],
                           capture_output=True, text=True, env=_env(), timeout=900)
        assert r.returncode == 0, r.stderr[-3000:]
        runs[name] = json.loads((out / "metrics.json").read_text())
    ms, mp = runs["serial"], runs["mpi"]
    keys = [k for k in ms if "springback" in k or k.startswith("beam_residual")]
    assert "beam_springback_max_m" in keys and "tip_springback_y_m" in keys and ms["beam_springback_max_m"] > 0
    for key in keys:
        print(f"{key}: serial {ms[key]!r} mpi {mp[key]!r}")
        assert mp[key] == pytest.approx(ms[key], rel=1e-8, abs=1e-12), key


@pytest.mark.mpi
def test_staged_preform_on_two_ranks_matches_serial(tmp_path):
    """A staged run under ``mpirun -n 2``: test_stages.py's implicit static preform handed to an explicit stage (the
    hand-over of :mod:`pulseform.solvers.dolfinx.handover` on a partitioned mesh). Every history column equals the
    serial run's: displacements, stresses and the stage column to 1e-10 relative, ledger columns to 1e-10 of the
    external work, the hold's speed and momentum (round-off of the static equilibrium, ~3e-7 m/s) to 1e-12 absolute
    (the explicit MPI checks' bound, test_3d_mpi.py)."""
    from test_stages import preform_case

    data = preform_case()
    case = tmp_path / "case.toml"
    case.write_text(tomli_w.dumps(data))
    hist = {}
    for name, prefix in (("serial", []), ("mpi", [_mpirun(), "-n", "2"])):
        out = tmp_path / name
        r = subprocess.run([*prefix, EXE, "run", str(case), "--out", str(out), "--quiet"], capture_output=True,
                           text=True, env=_env(), timeout=900)
        assert r.returncode == 0, r.stderr[-3000:]
        hist[name] = np.genfromtxt(out / "history.csv", delimiter=",", names=True)
    hs, hp = hist["serial"], hist["mpi"]
    assert hs.dtype.names == hp.dtype.names and hs.shape == hp.shape and hs["stage"].max() == 2
    work = float(np.abs(hs["energy_external_work_J"]).max())
    for col in hs.dtype.names:
        err = float(np.abs(hp[col] - hs[col]).max())
        if col.startswith("energy_"):
            bound = 1e-10 * work
        elif col.endswith(("_speed_m_s", "_momentum_y_Ns", "_momentum_x_Ns")):
            bound = 1e-12
        else:
            bound = 1e-10 * float(np.abs(hs[col]).max())
        print(f"history {col}: largest |mpi - serial| {err:.3g} (bound {bound:.3g})")
        assert err <= bound, col
