"""What a 3D run needs of the machine's memory, measured: the guard before a run that would not fit."""

from __future__ import annotations

#: memory of a run (bytes): the Python process and libraries, then per EM tetrahedron (getdp with its LU
#: ~5.5 kB at 46k tets and growing, plus the air motion's factorisation, meshes and solver); a lower
#: estimate from the runs measured (getdp 255 MB at 46k tets, the run's Python process ~350 MB)
MEMORY_BASE = 0.4e9
MEMORY_PER_TET = 8e3


def available_memory() -> float | None:
    """Bytes of memory available to a new process (``MemAvailable`` of /proc/meminfo); None if unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


def memory_needed(tets: float) -> float:
    """Bytes a coupled 3D run of ``tets`` EM tetrahedra needs at least (:data:`MEMORY_BASE`, :data:`MEMORY_PER_TET`)."""
    return MEMORY_BASE + MEMORY_PER_TET * tets
