#!/usr/bin/env bash
# README command 1: install what is missing, then run the main demo case into results/demo.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$here/scripts/setup.sh"
cd "$here"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
DEMO_CASE="${DEMO_CASE:-cases/emf_sheet_bulge}"
exec .venv/bin/pulseform run "$DEMO_CASE" --out results/demo --force "$@"
