"""Versions and origins of the external programs and libraries pulseform runs on."""

from __future__ import annotations

import importlib
import shutil
import subprocess
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Component:
    """One program or library: its version, where it is, and which package installed it."""

    name: str
    version: str
    location: str
    source: str


def _debian_package(path: str) -> str:
    """The Debian package owning ``path`` (``dpkg -S``), or 'not from a Debian package'."""
    if not path or not shutil.which("dpkg-query"):
        return "unknown"
    real = str(Path(path).resolve())
    for candidate in (path, real):
        r = subprocess.run(["dpkg-query", "-S", candidate], capture_output=True, text=True)
        if r.returncode == 0 and r.stdout:
            return "Debian package " + r.stdout.split(":", 1)[0].strip()
    return "not from a Debian package"


def _program(name: str, args: list[str]) -> Component:
    exe = shutil.which(name)
    if exe is None:
        return Component(name, "MISSING", "not on PATH", "install Debian package " + name)
    r = subprocess.run([exe, *args], capture_output=True, text=True, timeout=30)
    text = (r.stdout or r.stderr).strip().splitlines()
    return Component(name, text[0] if text else "?", exe, _debian_package(exe))


def _module(label: str, module: str, version_of=lambda m: getattr(m, "__version__", "?")) -> Component:
    try:
        m = importlib.import_module(module)
    except Exception as exc:  # report any import failure, e.g. a numpy ABI mismatch
        return Component(label, "MISSING", f"import failed: {exc}", "see docs/guide/troubleshooting.md")
    loc = getattr(m, "__file__", "") or ""
    return Component(label, str(version_of(m)), str(Path(loc).parent), _debian_package(loc))


def collect() -> list[Component]:
    """Every component ``pulseform info`` reports."""
    rows = [
        _program("getdp", ["--version"]),
        _program("gmsh", ["--version"]),
        _module("gmsh-py", "gmsh"),
        _module("dolfinx", "dolfinx"),
        _module("PETSc", "petsc4py.PETSc",
                lambda m: ".".join(str(v) for v in m.Sys.getVersion())),
        _module("petsc4py", "petsc4py"),
        _module("meshio", "meshio"),
        _module("numpy", "numpy"),
        _module("scipy", "scipy"),
        _module("numba", "numba"),
        _module("mpi4py", "mpi4py"),
        _program("mpirun", ["--version"]),
    ]
    return rows
