"""``pulseform`` with the 3D air meshed again before given EM steps, whatever its quality (the tests' way to
remesh a run of a few microseconds: ``RemeshingGetDPLoad3D.remesh_before_steps``, orchestrator/em/remesh3d.py).

Usage: ``python forced_remesh_run.py STEPS ARGS...``: STEPS the 1-based EM steps, comma-separated; ARGS
those of ``pulseform`` (e.g. ``run CASE --out DIR``). Exit code, signals and outputs: ``pulseform``'s.
"""
import os
import sys

if __name__ == "__main__":
    from pulseform.solvers.getdp.runner import FAST_MPI_ENV

    for key, value in FAST_MPI_ENV.items():   # before mpi4py is imported, as the console script does (cli.entry)
        os.environ.setdefault(key, value)
    from pulseform.orchestrator.cli import main
    from pulseform.orchestrator.em.remesh3d import RemeshingGetDPLoad3D

    RemeshingGetDPLoad3D.remesh_before_steps = frozenset(int(k) for k in sys.argv[1].split(","))
    sys.exit(main(sys.argv[2:]))
