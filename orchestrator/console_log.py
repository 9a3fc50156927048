"""The command line's console logging: pulseform's own records from INFO (WARNING with ``--quiet``), other
libraries' from WARNING, one handler on the root logger (:func:`setup_console_logging`; the CLI and the warm
study server install it)."""
from __future__ import annotations

import logging
import sys

__all__ = ["setup_console_logging"]


class _ConsoleFilter(logging.Filter):
    """pulseform's own records from INFO (WARNING with --quiet); other libraries' from WARNING."""

    def __init__(self, quiet: bool) -> None:
        super().__init__()
        self.own_level = logging.WARNING if quiet else logging.INFO

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name == "pulseform" or record.name.startswith("pulseform."):
            return record.levelno >= self.own_level
        return record.levelno >= logging.WARNING


def setup_console_logging(quiet: bool) -> None:
    """One console handler on the root logger. Installed before dolfinx is imported, it also
    turns FFCx's ``logging.basicConfig()`` into a no-op, so JIT compiler chatter stays off the
    terminal (it still reaches run.log)."""
    root = logging.getLogger()
    for old in [h for h in root.handlers if getattr(h, "pulseform_console", False)]:
        root.removeHandler(old)  # main() called again in the same process (tests): one console handler
    handler = logging.StreamHandler(sys.stderr)
    handler.pulseform_console = True
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    handler.addFilter(_ConsoleFilter(quiet))
    root.addHandler(handler)
    logging.getLogger("pulseform").setLevel(logging.INFO)
