"""Evidence: GetDP's ONELAB client mode with gmsh (Python API) as the ONELAB server.

getdp runs as a ONELAB client (``gmsh.onelab.run``): GetNumberRunTime[]{"pf/x"} reads the server's
value at run time, so a scalar set by another Python thread while getdp runs reaches it.  Shows
(1) ``gmsh.onelab.run`` blocks the calling thread for the whole getdp run; (2) the runtime exchange
is scalar (GetNumberRunTime returns one number; no runtime accessor of a vector of values in 3.2.0),
so node displacements cannot travel this way; the FIFO + ReadSolution design needs no server.

Usage: .venv/bin/python studies/persistent_getdp/probe_onelab.py
"""
from __future__ import annotations

import os
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from probe_ops import MSH, deck  # noqa: E402

from pulseform.solvers.getdp.runner import FAST_MPI_ENV, find_getdp  # noqa: E402


def main():
    import gmsh

    os.environ.update(FAST_MPI_ENV)   # gmsh starts getdp itself: the environment is inherited
    with tempfile.TemporaryDirectory(prefix="pgdp_onelab_") as tmp:
        d = Path(tmp)
        (d / "m.msh").write_text(MSH)
        (d / "p.pro").write_text(deck('Evaluate[$x = GetNumberRunTime[-1]{"pf/x"}]; Print[{$x}, Format "first x=%g"]; '
                                      'Sleep[2]; Evaluate[$y = GetNumberRunTime[-1]{"pf/x"}]; '
                                      'Print[{$y}, Format "after 2 s x=%g"];'))
        gmsh.initialize(readConfigFiles=False)
        gmsh.onelab.setNumber("pf/x", [1.0])
        t0 = time.perf_counter()
        events = []

        def later():
            time.sleep(0.5)
            gmsh.onelab.setNumber("pf/x", [2.0])
            events.append(f"thread set pf/x = 2 at {time.perf_counter() - t0:.2f} s")

        th = threading.Thread(target=later)
        th.start()
        gmsh.onelab.run("GetDP", f"{find_getdp()} {d / 'p.pro'} -msh {d / 'm.msh'} -solve R -v 3")
        events.append(f"gmsh.onelab.run returned after {time.perf_counter() - t0:.2f} s (getdp sleeps 2 s)")
        th.join()
        gmsh.finalize()
    print("\n".join(events))
    print("getdp's lines 'first x=1' and 'after 2 s x=2' above (gmsh's Info output) show the runtime read")


if __name__ == "__main__":
    main()
