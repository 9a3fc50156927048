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

missing=()
for p in "${DOCS_APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  if [ "$(id -u)" -ne 0 ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "pulseform docs: missing Debian packages: ${missing[*]}" >&2
    echo "Install them as root, then run this command again:" >&2
    echo "  apt-get update && apt-get install -y --no-install-recommends ${missing[*]}" >&2
    exit 1
  fi
  echo "pulseform docs: installing Debian packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

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
