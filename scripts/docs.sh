#!/usr/bin/env bash
# Build the documentation site into site/ (open site/index.html). Installs what is missing, like
# scripts/setup.sh: Debian's mkdocs packages (as root), then the venv (scripts/setup.sh, whose Python
# imports pulseform for the generated pages); regenerates the generated reference pages; then
# `mkdocs build --strict`: any warning (a broken link, a page missing from the nav) fails the build.
# Extra arguments go to `mkdocs build`, e.g. `bash scripts/docs.sh --site-dir /tmp/site`.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"

DOCS_APT_PACKAGES=(mkdocs mkdocs-material mkdocstrings mkdocstrings-python-handlers)

# shellcheck source=scripts/apt_install.sh
source "$here/scripts/apt_install.sh"
apt_install_missing "pulseform docs" "${DOCS_APT_PACKAGES[@]}"

bash scripts/setup.sh

.venv/bin/python scripts/update_reference.py   # docs/reference/case-file.md and cli.md

start=$(date +%s.%N)
log=$(mktemp)
trap 'rm -f "$log"' EXIT
set +e
NO_COLOR=1 .venv/bin/python -m mkdocs build --strict "$@" 2>&1 | tee "$log"
rc=${PIPESTATUS[0]}
set -e
seconds=$(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
warnings=$(grep -c 'WARNING' "$log" || true)
if [ "$rc" -ne 0 ]; then
  echo "pulseform docs: build FAILED after ${seconds} s (${warnings} warnings; --strict stops at any)" >&2
  exit "$rc"
fi
site=site
prev=""
for a in "$@"; do
  case "$prev" in -d|--site-dir) site="$a" ;; esac
  case "$a" in --site-dir=*) site="${a#--site-dir=}" ;; esac
  prev="$a"
done
echo "pulseform docs: built in ${seconds} s, ${warnings} warnings: open ${site}/index.html"
