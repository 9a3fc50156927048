"""The ``pulseform`` console script starts its MPI singleton with the fast settings getdp uses
(orchestrator/cli.entry; ~0.4 s -> ~0.07 s per process), never under mpirun and never over a
user's own setting."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

PROBE = ("import os, sys; import pulseform.orchestrator.cli as c; "
         "c.main = lambda: print(os.environ.get('OMPI_MCA_pml'), os.environ.get('OMPI_MCA_btl'), "
         "'mpi4py.MPI' in sys.modules) or 0; sys.exit(c.entry())")


def _probe(**env) -> str:
    clean = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMI", "HWLOC_"))}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**clean, **env}, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip()


@pytest.mark.parametrize("env,want", [
    ({}, "ob1 self False"),                                   # a process of its own: fast singleton
    ({"OMPI_COMM_WORLD_SIZE": "2"}, "None None False"),       # launched by mpirun: untouched
    ({"OMPI_MCA_btl": "self,vader"}, "ob1 self,vader False"),  # the user's own setting wins
])
def test_entry_sets_the_singleton_settings_only_for_a_process_of_its_own(env, want):
    assert _probe(**env) == want
