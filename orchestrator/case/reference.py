"""Generate the case-file reference (Markdown) from the schema declarations in :mod:`.case`.

``python -m pulseform.orchestrator.case.reference`` prints it; the README holds a copy between the
markers ``<!-- case-reference:start -->`` and ``<!-- case-reference:end -->``, kept in step by a test.
"""

from __future__ import annotations

import sys

from .model import Case
from .schema import reference_rows

START, END = "<!-- case-reference:start -->", "<!-- case-reference:end -->"


def case_reference_markdown() -> str:
    """The table of every case key: key path, allowed values, unit, default, meaning."""
    lines = ["| key | allowed | unit | default | meaning |", "|---|---|---|---|---|"]
    for key, *cells in reference_rows(Case):
        allowed, unit, default, doc = (c.replace("|", "\\|") for c in cells)
        lines.append(f"| `{key}` | {allowed} | {unit} | {default} | {doc} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # pragma: no cover
    sys.stdout.write(case_reference_markdown())
