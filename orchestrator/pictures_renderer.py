"""``python -m pulseform.orchestrator.pictures_renderer RESULTS_DIR | --wait``: the child process that renders a
run's 3D pictures off-screen (:mod:`.run.pictures_child` starts it; :func:`.run.pictures_mech.render_fields` draws).
Its standard output is its answer to the parent: one JSON line, the paths it wrote. With ``--wait`` it imports
pyvista/VTK first, then reads the results folder from standard input (a renderer started ahead of the run's end).
A process entry point: its standard output is a protocol channel to the parent (written with ``sys.stdout``), not
messages for a user; bad usage is one line on standard error (only the parent starts it)."""

import json
import sys
from pathlib import Path

from .run.pictures_child import warm_up
from .run.pictures_mech import render_fields


def main(argv: list[str] | None = None) -> int:
    """Render the 3D pictures of ``RESULTS_DIR`` and answer their paths as one JSON line; 2 on bad usage."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        sys.stderr.write("usage: python -m pulseform.orchestrator.pictures_renderer RESULTS_DIR | --wait\n")
        return 2
    if args[0] == "--wait":  # a Renderer: get ready, then read the folder from stdin
        warm_up()
        args = [sys.stdin.readline().strip()]
        if not args[0]:
            return 0
    paths = render_fields(Path(args[0]))
    sys.stdout.write(json.dumps([str(p) for p in paths]) + "\n")   # the answer: one JSON line
    return 0


if __name__ == "__main__":
    sys.exit(main())
