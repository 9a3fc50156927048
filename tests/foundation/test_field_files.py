"""Issue 14, field files and mechanical pictures: meshio and h5py read every field file of a short demo
run and of a coarse bar-impact run back as one mesh per body with all fields at exact times; the
stress tensor's components are named and equal the solver's cell values (the run's last checkpoint);
the pictures exist and are not blank; a renderer that crashes costs the pictures, not the run; under
``mpirun -n 2`` the files equal the serial ones."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import meshio
import numpy as np
import pytest

from pulseform.orchestrator.run.checkpoint import load_checkpoint
from pulseform.orchestrator.run.mech_fields import STRESS_COMPONENTS, read_fields

REPO = Path(__file__).resolve().parents[2]
EXE = str(Path(sys.executable).with_name("pulseform"))
BAR = ["--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25"]  # test_run_e2e COARSE
BAR_TIMES = [float(f"{k * 2e-4:.12g}") for k in range(12)]  # 0 .. 2.2 ms every end / 11 (case file)
DEMO = ["--set", "time.end=4e-6", "--set", "output.field_interval=2e-6"]
DEMO_TIMES = [0.0, 2e-6, 4e-6]
POINT = {"displacement_m": 3, "velocity_m_s": 3}
CELL = {"stress_Pa": 6, "von_mises_Pa": 1, "plastic_strain": 1}
#: the demo's sheet has a forming limit curve (cases/emf_sheet_bulge): its forming-limit check's cell fields too
FLC_CELL = {"minor_strain": 1, "major_strain": 1, "flc_margin": 1, "flc_zone": 1}


def _env_without_display() -> dict:
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    return env


def _run(case: str, out: Path, *extra: str, env=None, mpi: bool = False) -> subprocess.CompletedProcess:
    argv = [EXE, "run", str(REPO / "cases" / case), "--out", str(out), "--quiet", *extra]
    if mpi:
        env = dict(env or os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
                   OMPI_MCA_rmaps_base_oversubscribe="1")
        argv = [shutil.which("mpirun"), "-n", "2", *argv]
    r = subprocess.run(argv, capture_output=True, text=True, env=env or _env_without_display(), timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return r


@pytest.fixture(scope="module")
def bar(shared_run):
    """No DISPLAY: the pictures render off-screen. The same run as test_run_e2e's (conftest.py)."""
    return shared_run("bar_impact", BAR)


@pytest.fixture(scope="module")
def demo(shared_run):
    """No DISPLAY. The same run as test_results_and_loads' file-mode test, which runs it under umask 027
    (conftest.py): the umask changes no field, picture or number."""
    return shared_run("emf_sheet_bulge", DEMO, umask=0o027)


def _check_field_files(out: Path, bodies: set[str], times: list[float], cell: dict[str, int] = CELL) -> None:
    """Every field file: meshio's time-series reader gives one triangle mesh and, per step, every
    point and cell field (``cell``: name -> components) at the exact output time; h5py reads the same by name."""
    xdmfs = sorted((out / "fields").glob("*.xdmf"))
    assert {p.stem.split("_")[-1] for p in xdmfs} == bodies
    for xdmf in xdmfs:
        with meshio.xdmf.TimeSeriesReader(xdmf) as r:
            points, cells = r.read_points_cells()
            assert len(cells) == 1 and cells[0].type == "triangle"
            n, c = len(points), len(cells[0].data)
            assert r.num_steps == len(times)
            steps = [r.read_data(k) for k in range(r.num_steps)]
        assert [t for t, _, _ in steps] == times  # exact: 2e-06, not 2.0000000000000003e-06
        with h5py.File(xdmf.with_suffix(".h5"), "r") as f:
            assert list(f["times"][...]) == times
            assert np.array_equal(f["Mesh/points"][...], points)
            assert np.array_equal(f["Mesh/triangles"][...], cells[0].data)
            assert f["Step_0000/stress_Pa"].attrs["components"] == " ".join(STRESS_COMPONENTS)
            for k, (t, pd, cd) in enumerate(steps):
                g = f[f"Step_{k:04d}"]
                assert g.attrs["time"] == t
                assert {k_: v.shape for k_, v in pd.items()} == {k_: (n, m) for k_, m in POINT.items()}
                assert set(cd) == set(cell)
                for name, m in cell.items():
                    assert len(cd[name]) == 1 and cd[name][0].shape == ((c, m) if m > 1 else (c,))
                    assert np.array_equal(g[name][...], cd[name][0])
                for name in POINT:
                    assert np.array_equal(g[name][...], pd[name])
                s = cd["stress_Pa"][0]
                assert not s[:, 4:].any()  # yz = xz = 0 in 2D models
                d = s[:, :3] - s[:, :3].mean(axis=1, keepdims=True)
                vm = np.sqrt(1.5 * ((d ** 2).sum(axis=1) + 2 * s[:, 3] ** 2))
                assert np.allclose(vm, cd["von_mises_Pa"][0], rtol=1e-12, atol=1e-9 * max(vm.max(), 1.0))


def _check_last_step_equals_checkpoint(out: Path) -> None:
    """The last output's cell stress and plastic strain are the solver's own cell values (the
    checkpoint written at the same milestone), bit for bit; displacement = x - X0."""
    arrays, _ = load_checkpoint(out / "checkpoint.npz")
    for name, bf in read_fields(out).items():
        last = bf.read(len(bf.times) - 1)
        assert np.array_equal(last["stress_Pa"][:, :4], arrays[f"solver/{name}/cell_stress"])
        assert np.array_equal(last["plastic_strain"], arrays[f"solver/{name}/eps_p"])
        x = arrays[f"solver/{name}/x"]
        assert np.allclose(bf.points[:, :2] + last["displacement_m"][:, :2], x, rtol=0, atol=1e-12 * np.abs(x).max())


def _check_pictures(out: Path, n_times: int) -> None:
    import matplotlib.image as mpimg

    plots = out / "plots"
    for name in ("shapes.png", "deformed_von_mises.png", "deformed_plastic_strain.png"):
        assert (plots / name).is_file(), name
    frames = sorted((plots / "mechanics").glob("*.png"))
    assert len(frames) == 2 * n_times
    for path in (plots / "shapes.png", plots / "deformed_von_mises.png", frames[-1]):
        img = mpimg.imread(path)[..., :3]
        colours = np.unique((img.reshape(-1, 3) * 255).round().astype(np.uint8), axis=0)
        drawn = (img.min(axis=2) < 0.9).mean()  # not the white background
        assert len(colours) > 50 and drawn > 0.02, (path.name, len(colours), drawn)


def test_bar_field_files(bar):
    _check_field_files(bar, {"left", "right"}, BAR_TIMES)
    _check_last_step_equals_checkpoint(bar)


def test_bar_pictures(bar):
    """Also: in the last frame both bars are coloured (each body's picture follows the times)."""
    import matplotlib.image as mpimg

    _check_pictures(bar, len(BAR_TIMES))
    img = mpimg.imread(sorted((bar / "plots" / "mechanics").glob("von_mises_*.png"))[-1])[..., :3]
    h, w, _ = img.shape
    body = img[int(0.12 * h):int(0.9 * h), :int(0.8 * w)]  # without the title and the colour bar
    cols = np.flatnonzero((body.min(axis=2) < 0.9).mean(axis=0) > 0.2)  # columns through the bars
    mid = (cols[0] + cols[-1]) // 2
    for half in (body[:, cols[0]:mid - 3], body[:, mid + 3:cols[-1]]):
        drawn = half[half.min(axis=2) < 0.9]
        assert len(np.unique((drawn * 255).round().astype(np.uint8), axis=0)) > 20


@pytest.mark.getdp
def test_demo_field_files(demo):
    _check_field_files(demo, {"sheet"}, DEMO_TIMES, {**CELL, **FLC_CELL})
    _check_last_step_equals_checkpoint(demo)


@pytest.mark.getdp
def test_demo_pictures(demo):
    _check_pictures(demo, len(DEMO_TIMES))


@pytest.mark.parametrize("alive", [pytest.param(True, marks=pytest.mark.slow), False])
def test_pictures_from_a_renderer_started_early(bar, tmp_path, alive):
    """The 3D renderer a run starts ahead of time (pictures_mech.Renderer) draws the same pictures;
    one that died meanwhile is replaced by a new child, and the pictures are still drawn. [True] is in the
    slow tier: every run with pictures draws them with its renderer started early (run/runner._early_renderer),
    checked on the bar run by test_bar_pictures."""
    import shutil

    from pulseform.orchestrator.run.pictures_child import Renderer
    from pulseform.orchestrator.run.pictures_mech import draw_mechanics

    out = tmp_path / "bar"
    shutil.copytree(bar, out)
    shutil.rmtree(out / "plots")
    renderer = Renderer()
    waiting = renderer.child
    if not alive:
        waiting.kill()
        waiting.wait()
    try:
        paths = draw_mechanics(out, renderer=renderer)
    finally:
        renderer.close()
    assert renderer.child is None
    assert waiting.returncode == (0 if alive else -9)
    assert {p.name for p in paths} >= {"shapes.png", "deformed_von_mises.png", "deformed_plastic_strain.png"}
    _check_pictures(out, len(BAR_TIMES))


def test_a_crashing_renderer_is_a_warning_not_a_failed_run(tmp_path):
    """A pyvista that aborts the process (as a broken OpenGL stack would): the run still exits 0 with
    status ok, shapes.png is drawn, the log carries one warning."""
    fake = tmp_path / "fake"
    fake.mkdir()
    (fake / "pyvista.py").write_text("import os\nos.abort()\n")
    env = _env_without_display()
    env["PYTHONPATH"] = str(fake) + os.pathsep + env.get("PYTHONPATH", "")
    out = tmp_path / "bar"
    _run("bar_impact", out, *BAR, "--set", "time.end=4e-4", env=env)
    assert json.loads((out / "metrics.json").read_text())["status"] == "ok"
    assert (out / "plots" / "shapes.png").is_file()
    assert not (out / "plots" / "deformed_von_mises.png").exists()
    warnings = [ln for ln in (out / "run.log").read_text().splitlines() if "WARNING" in ln and "3D pictures" in ln]
    assert len(warnings) == 1, warnings


@pytest.mark.mpi
def test_two_ranks_write_the_serial_files(bar, tmp_path):
    """Under mpirun -n 2 rank 0 gathers: one file per body, the same mesh (nodes and triangles matched
    by position) and fields as the serial run to round-off."""
    from scipy.spatial import cKDTree

    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not found")
    out = tmp_path / "bar_mpi"
    _run("bar_impact", out, *BAR, mpi=True)
    _check_field_files(out, {"left", "right"}, BAR_TIMES)
    serial, par = read_fields(bar), read_fields(out)
    for name, a in serial.items():
        b = par[name]
        d, ip = cKDTree(b.points).query(a.points)
        assert d.max() < 1e-12
        d, ic = cKDTree(b.points[b.triangles].mean(axis=1)).query(a.points[a.triangles].mean(axis=1))
        assert d.max() < 1e-12
        assert np.array_equal(np.sort(ip[a.triangles], axis=1), np.sort(b.triangles[ic], axis=1))
        for k in range(len(a.times)):
            fa, fb = a.read(k), b.read(k)
            for f, x in fa.items():
                y = fb[f][ip] if f in POINT else fb[f][ic]
                assert np.allclose(x, y, rtol=0, atol=1e-10 * max(np.abs(x).max(), 1e-30)), (name, k, f)


@pytest.mark.getdp
def test_demo_forming_limit_check(demo):
    """Issue 33, item 5, on the coupled demo (its sheet has a forming limit curve): per cell the margin is the
    case's curve (linear between its points, flat beyond) minus the major strain, one of the two strains is
    the hoop strain ln(r / r0) of the cell's centroid (axisymmetry: the hoop direction lies in the sheet),
    the history column is the least margin at each output time (history.csv keeps 10 digits), and metrics,
    summary and picture name the worst cell."""
    from pulseform.orchestrator.case.io import load_resolved_case
    from pulseform.orchestrator.run.history import History
    from pulseform.orchestrator.run.summary import summary_lines

    case = load_resolved_case(demo / "case.toml")
    flc = case.materials["al_blank"].forming_limit
    h = History.read(demo / "history.csv")
    t, col = h.column("time_s"), h.column("sheet_flc_margin_min")
    bf = read_fields(demo)["sheet"]
    for k, time_k in enumerate(bf.times):
        d = bf.read(k)
        minor, major = d["minor_strain"], d["major_strain"]
        limit = np.interp(minor, flc.minor_strain, flc.major_strain)
        assert np.abs(d["flc_margin"] - (limit - major)).max() <= 1e-15
        zone = np.where(d["flc_margin"] < 0, 2, np.where(d["flc_margin"] < flc.safety_margin, 1, 0))
        assert np.array_equal(d["flc_zone"], zone)
        x = bf.points[:, :2] + d["displacement_m"][:, :2]
        hoop = np.log(x[bf.triangles, 0].sum(axis=1) / bf.points[bf.triangles, 0].sum(axis=1))
        assert np.minimum(np.abs(minor - hoop), np.abs(major - hoop)).max() <= 1e-12
        assert np.all(minor <= major)
        assert col[np.flatnonzero(np.isclose(t, time_k, rtol=1e-9))[-1]] == pytest.approx(d["flc_margin"].min(), rel=1e-9)
    m = json.loads((demo / "metrics.json").read_text())
    assert m["sheet_flc_margin_min"] == pytest.approx(col.min(), rel=1e-9)
    assert col[np.isclose(t, m["sheet_flc_worst_time_s"], rtol=1e-9)].min() == pytest.approx(m["sheet_flc_margin_min"], rel=1e-9)
    lines = [ln for ln in summary_lines(case, m, demo) if "least FLC margin, sheet" in ln]
    assert len(lines) == 1 and f"element {int(m['sheet_flc_worst_element'])} at" in lines[0], lines
    assert (demo / "plots" / "sheet_fld.png").is_file()
