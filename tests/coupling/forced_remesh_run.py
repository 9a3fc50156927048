"""``pulseform`` with the 3D air meshed again before given EM steps, whatever its quality (the tests' way to
remesh a run of a few microseconds: ``RemeshingGetDPLoad3D.remesh_before_steps``, orchestrator/em/remesh3d.py).

Usage: ``python forced_remesh_run.py STEPS [--sigint-in-step=K] ARGS...``: STEPS the 1-based EM steps,
comma-separated; ARGS those of ``pulseform`` (e.g. ``run CASE --out DIR``). With ``--sigint-in-step=K`` the
process sends itself SIGINT as EM step K starts (before its mesh motion): a real signal through the run's
handlers, at a known step (a signal from outside, timed by the checkpoint it waits for, may land before or
after the loop's check at that checkpoint). Exit code, signals and outputs: ``pulseform``'s.
"""
import os
import signal
import sys

SIGINT_OPTION = "--sigint-in-step="

if __name__ == "__main__":
    from pulseform.solvers.getdp.runner import FAST_MPI_ENV

    for key, value in FAST_MPI_ENV.items():   # before mpi4py is imported, as the console script does (cli.entry)
        os.environ.setdefault(key, value)
    from pulseform.orchestrator.cli import main
    from pulseform.orchestrator.em.remesh3d import RemeshingGetDPLoad3D

    RemeshingGetDPLoad3D.remesh_before_steps = frozenset(int(k) for k in sys.argv[1].split(","))
    args = sys.argv[2:]
    if args and args[0].startswith(SIGINT_OPTION):
        sigint_step = int(args.pop(0)[len(SIGINT_OPTION):])
        follow = RemeshingGetDPLoad3D.follow

        def follow_then_signal(self, t0, mechanics):
            if self.state.steps + 1 == sigint_step:
                os.kill(os.getpid(), signal.SIGINT)
            return follow(self, t0, mechanics)

        RemeshingGetDPLoad3D.follow = follow_then_signal
    sys.exit(main(args))
