"""Where a sweep member's wall time goes outside its run loop (issue 31, item 3).

Runs ``pulseform sweep ARGS`` in this process (the console script's entry, so the same environment)
with a timer around each member (``workflows.sweep.run_member``: from the moment the sweep hands the
member out to the moment it has the member's metrics), and splits each member's time by the
timestamps of its ``run.log``:

  start     the member's process up to the runner's first line (a cold member: Python start-up, the
            CLI's and the runner's imports, the case loaded and checked; a warm member: the fork from
            the warm process, the case loaded and checked)
  imports   the runner's first line to "driver imported" (DOLFINx, numba, the driver: ~0 when warm)
  set-up    to "loop from" (EM mesh, DOLFINx mesh and forms, getdp start, the first outputs)
  loop      to "mechanics: ... steps" (the run loop: EM and mechanical steps, outputs, checkpoints)
  pictures  to "... pictures in" (or to "done in" without pictures; includes the metrics)
  end       to the sweep having the member's result (metrics.json, process exit, the answer)

``outside`` = the member's time - loop. The study's own time (the sweep's wall minus what its
members' timers cover, e.g. the warm process's start and the sweep's plots) is printed apart, with
the load average beside the timings (the machine is shared).

Usage: python bench/sweep_split.py [--repeat 1] -- sweep ARGS...
e.g.   python bench/sweep_split.py -- cases/emf_sheet_bulge --param coupling.n=10,20,40 --jobs 2 --out /tmp/sw --force
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from datetime import datetime
from pathlib import Path

MARKS = (("start", " -> "), ("imports", "driver imported"), ("set-up", "loop from t ="),
         ("loop", "mechanics: "), ("pictures", " pictures in "))


def _stamp(line: str) -> float:
    return datetime.strptime(line[:23], "%Y-%m-%d %H:%M:%S,%f").timestamp()


def split(folder: Path, t_start: float, t_end: float) -> dict[str, float]:
    """The member's phases (s) from its run.log (its last run only) and the sweep's timer."""
    lines = (folder / "run.log").read_text(errors="replace").splitlines()
    first = max(i for i, ln in enumerate(lines) if " case " in ln and " -> " in ln)
    lines = [ln for ln in lines[first:] if ln[:4].isdigit()]
    out, t = {}, t_start
    for name, mark in MARKS:
        hit = next((ln for ln in lines if mark in ln), None)
        if hit is None:  # no pictures
            out[name] = 0.0
            continue
        out[name] = _stamp(hit) - t
        t = _stamp(hit)
    out["end"] = t_end - t
    out["member"] = t_end - t_start
    out["outside"] = out["member"] - out["loop"]
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeat", type=int, default=1)
    p.add_argument("sweep", nargs=argparse.REMAINDER, help="-- then the arguments of pulseform sweep")
    args = p.parse_args()
    sweep_args = [a for a in args.sweep if a != "--"]
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from pulseform.orchestrator import cli
    from pulseform.orchestrator.workflows import sweep

    times: dict[int, tuple[float, float]] = {}
    folders: dict[int, Path] = {}
    lock = threading.Lock()
    real = sweep.run_member

    def timed(case, member, *args, **kw):
        t0 = time.time()
        try:
            return real(case, member, *args, **kw)
        finally:
            with lock:
                times[member.index] = (t0, time.time())
                folders[member.index] = member.out

    sweep.run_member = timed
    for rep in range(args.repeat):
        times.clear()
        load0 = os.getloadavg()
        argv = list(sweep_args)
        if args.repeat > 1 and "--out" in argv:  # a folder per repeat
            argv[argv.index("--out") + 1] += f"_{rep + 1}"
        sys.argv = ["pulseform", "sweep", *argv]
        t0 = time.time()
        code = cli.entry()
        wall = time.time() - t0
        load1 = os.getloadavg()
        print(f"\n# repeat {rep + 1}: sweep exit {code}, wall {wall:.2f} s; load average before "
              f"{load0[0]:.2f} {load0[1]:.2f} {load0[2]:.2f}, after {load1[0]:.2f} {load1[1]:.2f} {load1[2]:.2f}")
        cols = [m for m, _ in MARKS] + ["end", "member", "outside"]
        print(f"{'member':<28}" + "".join(f"{c:>10}" for c in cols))
        rows = []
        for i in sorted(times):
            try:
                s = split(folders[i], *times[i])
            except (OSError, ValueError) as exc:
                print(f"{folders[i].name:<28} no split: {exc}")
                continue
            rows.append(s)
            print(f"{folders[i].name[:27]:<28}" + "".join(f"{s[c]:10.2f}" for c in cols))
        if rows:
            mean = {c: sum(r[c] for r in rows) / len(rows) for c in cols}
            print(f"{'mean':<28}" + "".join(f"{mean[c]:10.2f}" for c in cols))
            first = min(t[0] for t in times.values())
            last = max(t[1] for t in times.values())
            print(f"study: {first - t0:.2f} s before the first member, {t0 + wall - last:.2f} s after the last "
                  f"(sweep.csv, plots); members' time {sum(r['member'] for r in rows):.2f} s, their loops "
                  f"{sum(r['loop'] for r in rows):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
