#!/usr/bin/env bash
# Install what pulseform needs, only if it is missing: Debian packages, then .venv, then the package.
# Idempotent and quiet when everything is already there. Used by `make demo` and `make test`.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

APT_PACKAGES=(getdp gmsh python3-gmsh python3-dolfinx python3-meshio python3-h5py python3-scipy
  python3-pytest python3-pytest-xdist python3-mpi4py python3-numba python3-matplotlib python3-hypothesis python3-tqdm
  python3-tomli-w python3-jsonschema python3-dask python3-distributed python3-venv python3-pip python3-setuptools python3-dev gcc
  openmpi-bin libegl1 libegl-mesa0 libgl1-mesa-dri)  # the last three: VTK's off-screen rendering through Mesa (EGL)

# shellcheck source=scripts/apt_install.sh
source "$here/scripts/apt_install.sh"
apt_install_missing "pulseform setup" "${APT_PACKAGES[@]}"

if [ ! -x .venv/bin/python ]; then
  echo "pulseform setup: creating .venv from /usr/bin/python3 (--system-site-packages)"
  /usr/bin/python3 -m venv --system-site-packages .venv
fi

stamp=.venv/.pulseform-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ] || ! .venv/bin/python -c "import pulseform.orchestrator" 2>/dev/null; then
  echo "pulseform setup: pip install -e . (constrained to Debian's numpy)"
  # --no-deps in both: pyproject.toml lists what the code imports, but Debian provides it (apt above);
  # pip resolving that list would download h5py and gmsh again (Debian ships them without pip's names)
  .venv/bin/python -m pip install -q --no-build-isolation --no-deps --no-index -c constraints.txt -e . \
    || .venv/bin/python -m pip install -q --no-build-isolation --no-deps -c constraints.txt -e .
  touch "$stamp"
fi

# 3D pictures (orchestrator/run/pictures_mech.py): pyvista and VTK, which Debian 12 lacks, from PyPI,
# constrained to Debian's numpy (constraints.txt pins them too); VTK renders off-screen through
# Mesa's EGL (apt above), no display needed.
if ! .venv/bin/python -c "import importlib.util as u, sys; sys.exit(not (u.find_spec('pyvista') and u.find_spec('vtk')))"; then
  echo "pulseform setup: pip install pyvista vtk (constrained to Debian's numpy)"
  # --no-warn-conflicts: pip would report the Debian-provided h5py and gmsh of pulseform's own list as
  # missing (Debian ships them without pip metadata)
  .venv/bin/python -m pip install -q --no-warn-conflicts -c constraints.txt pyvista vtk
fi
