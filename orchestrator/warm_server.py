"""``python -m pulseform.orchestrator.warm_server``: a study's warm process (:mod:`.run.warm`). The libraries
are imported once; each member's ``pulseform`` arguments then run through the CLI's :func:`~.cli.main` in a
child forked from it. Started by a study (sweep, converge, validate, compare), never by a user."""

import sys

from .cli import _parser, main
from .console_log import setup_console_logging
from .run.warm_process import serve


def _setup() -> None:
    """The CLI's console log (before DOLFINx is imported) and its parser, built once."""
    setup_console_logging(quiet=False)
    _parser()


if __name__ == "__main__":
    sys.exit(serve(main, _setup))
