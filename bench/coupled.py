"""Benchmark of the README demo (cases/emf_sheet_bulge) on both EM paths in one run: the persistent
getdp (em.getdp_process = "persistent", the default with BDF2) and a getdp process per EM step
("per_step"); wall time of each split into EM, mechanics and orchestration, the speed-up, the metric
differences between the two paths; then the same case driven by an eq. (7) pressure pulse of equal
impulse through the identical loop, and the difference in max deflection.

Run: .venv/bin/python bench/coupled.py [--out DIR] [--set key=value ...] [--profile] [--no-pressure]
``--set`` goes to every run (e.g. ``--set coupling.n=20``); ``--profile`` runs the persistent coupled
case under cProfile (slower; the split is then not the target's) and prints the largest cumulative
entries.
Targets (issue 15): the demo >= 2.5x faster on the persistent path than per step in the same run;
orchestration overhead (all but getdp and the mechanical steps) < 10 % of the wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXE = str(Path(sys.executable).with_name("pulseform"))
sys.path.insert(0, str(REPO))


def run(out: Path, *sets: str, profile: Path | None = None) -> dict:
    argv = [EXE, "run", str(REPO / "cases/emf_sheet_bulge"), "--out", str(out), "--force", "--quiet"]
    if profile is not None:
        argv = [sys.executable, "-m", "cProfile", "-o", str(profile), "-m", "pulseform.orchestrator"] + argv[1:]
    for s in sets:
        argv += ["--set", s]
    t0 = time.perf_counter()
    subprocess.run(argv, check=True)
    metrics = json.loads((out / "metrics.json").read_text())
    metrics["process_wall_s"] = time.perf_counter() - t0
    return metrics


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=REPO / "results" / "bench_coupled")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="case override for both runs")
    p.add_argument("--profile", action="store_true", help="cProfile the coupled run, print the top entries")
    p.add_argument("--no-pressure", action="store_true", help="skip the equal-impulse pressure run")
    args = p.parse_args()

    prof = args.out / "coupled.prof" if args.profile else None
    if prof is not None:
        args.out.mkdir(parents=True, exist_ok=True)
    m = run(args.out / "coupled", *args.set, "em.getdp_process=persistent", profile=prof)
    ms = run(args.out / "coupled_per_step", *args.set, "em.getdp_process=per_step")
    for name, r in (("persistent getdp", m), ("a getdp process per EM step", ms)):
        _split(name, r)
    speedup = ms["process_wall_s"] / m["process_wall_s"]
    keys = [k for k, v in m.items() if isinstance(v, float) and k.endswith(("_mm", "_Ns", "_A", "_J", "_m_s", "_V"))
            and isinstance(ms.get(k), float)]
    diffs = {k: abs(m[k] - ms[k]) / max(abs(ms[k]), 1e-300) for k in keys}
    worst = max(diffs, key=diffs.get) if diffs else None
    print(f"persistent vs per step: wall {m['process_wall_s']:.2f} s vs {ms['process_wall_s']:.2f} s = "
          f"{speedup:.2f}x faster (target >= 2.5); EM {ms['em_time_s'] / m['em_time_s']:.1f}x faster")
    if worst is not None:
        print(f"  metrics ({len(keys)} physical ones) differ by at most {diffs[worst]:.2e} relative ({worst})")
    if prof is not None:
        import pstats

        pstats.Stats(str(prof)).sort_stats("cumulative").print_stats(r"pulseform|orchestrator|solvers", 30)
    overhead = m["process_wall_s"] - m["em_getdp_process_s"] - m["mech_time_s"]
    if not args.no_pressure:
        _pressure(args, m)
    print(f"bench: coupled speedup_persistent_over_per_step={speedup:.2f} target=2.5 "
          f"(overhead {100 * overhead / m['process_wall_s']:.0f} % of wall, target < 10 %)")


def _split(name: str, m: dict) -> None:
    """Print the wall-time split of one run (metrics.json's timers)."""
    wall = m["process_wall_s"]
    parts = {
        "getdp (process time)": m["em_getdp_process_s"],
        "getdp files (mesh out, tables in)": m["em_getdp_io_s"],
        "EM mesh motion": m["em_mesh_motion_s"],
        "force transfer": m["em_transfer_s"],
        "mechanics (explicit steps)": m["mech_time_s"],
        "setup (meshing, solver, JIT)": m["setup_time_s"],
    }
    parts["rest (python start-up, output, plots)"] = wall - sum(parts.values())
    print(f"demo, {name}: {m['em_steps']:.0f} EM steps, {m['mech_steps']:.0f} mechanical steps, wall {wall:.2f} s")
    for k, v in parts.items():
        print(f"  {k:<40} {v:8.2f} s  {100 * v / wall:5.1f} %")
    overhead = wall - m["em_getdp_process_s"] - m["mech_time_s"]
    print(f"  orchestration overhead (all but getdp and mechanical steps): {overhead:.2f} s = "
          f"{100 * overhead / wall:.1f} % of wall (target < 10 %)")
    # the same overhead split by what it scales with: per step (inside the coupled loop) and per run
    loop = m["em_time_s"] + m["mech_time_s"]
    per_step = loop - m["em_getdp_process_s"] - m["mech_time_s"]
    print(f"    of which per step (the loop's EM and mechanics time minus getdp and the explicit steps): "
          f"{per_step:.2f} s = {100 * per_step / loop:.1f} % of the loop's {loop:.2f} s")
    print(f"    and per run (start-up, imports, setup, output, pictures): {wall - loop:.2f} s")
    print(f"  per EM step: getdp {1e3 * m['em_getdp_process_s'] / m['em_steps']:.1f} ms, "
          f"other EM work {1e3 * (m['em_time_s'] - m['em_getdp_process_s']) / m['em_steps']:.1f} ms")


def _pressure(args, m: dict) -> None:
    """The equal-impulse pressure pulse, eq. (7), uniform on the sheet's lower face over the coil."""
    from pulseform.orchestrator.case.io import load_case
    from pulseform.orchestrator.case.model import Box, PulseSin2
    from pulseform.orchestrator.mech.pulses import pulse_impulse_per_area

    case, _ = load_case(REPO / "cases/emf_sheet_bulge")
    g = case.geometry
    r1 = g.coil_inner_radius
    r2 = g.coil_inner_radius + g.turns * g.turn_width + (g.turns - 1) * g.turn_gap
    zface = g.coil_gap
    box = {"xmin": r1, "xmax": r2, "ymin": zface - 1e-6, "ymax": zface + 1e-6}
    area = _loaded_area(args.out / "coupled", box)  # what the pressure run loads on the mesh
    # force ~ I², I ~ e^(-αt) sin(ω_d t): take ω from the current's first peak time, β = 1e4 1/s
    peak_t = _peak_time(args.out / "coupled" / "history.csv")
    omega = math.pi / (2 * peak_t)
    box = Box(**box)
    unit = PulseSin2(type="pulse_sin2", body="sheet", surface=box, amplitude=1.0, beta=1e4, omega=omega,
                     t_end=case.time.end)
    p0 = m["force_impulse_z_Ns"] / (area * pulse_impulse_per_area(unit))
    load = (f'{{type = "pulse_sin2", body = "sheet", surface = {{xmin = {r1}, xmax = {r2}, ymin = {zface - 1e-6}, '
            f'ymax = {zface + 1e-6}}}, amplitude = {p0:.6g}, beta = 1e4, omega = {omega:.6g}, t_end = {case.time.end}}}')
    mp = run(args.out / "pressure", *args.set, "coupling.load=pressure", f"loads=[{load}]")
    d_c, d_p = m["max_deflection_mm"], mp["max_deflection_mm"]
    print(f"equal-impulse pressure pulse eq. (7): P0 = {p0 / 1e6:.2f} MPa, omega = {omega:.4g} rad/s on "
          f"{r1 * 1e3:.0f}-{r2 * 1e3:.0f} mm; impulse {mp['force_impulse_z_Ns']:.4f} vs coupled "
          f"{m['force_impulse_z_Ns']:.4f} N s")
    print(f"max deflection at t_end: coupled {d_c:.4f} mm, pressure {d_p:.4f} mm, difference "
          f"{d_p - d_c:+.4f} mm ({100 * (d_p - d_c) / d_c:+.1f} %); wall {m['process_wall_s']:.1f} s vs "
          f"{mp['process_wall_s']:.1f} s")


def _loaded_area(folder: Path, box: dict) -> float:
    """The area (m²) the pressure run loads: the coupled run's sheet mesh's segments in ``box``."""
    from pulseform.orchestrator.run.mech_fields import read_fields
    from pulseform.orchestrator.workflows.compare_area import loaded_area_2d

    bf = read_fields(folder)["sheet"]
    return loaded_area_2d(bf.points, bf.triangles, box, axisymmetric=True)


def _peak_time(history: Path) -> float:
    import numpy as np

    h = np.genfromtxt(history, delimiter=",", names=True)
    return float(h["time_s"][np.argmax(np.abs(h["coil_current_A"]))])


if __name__ == "__main__":
    main()
