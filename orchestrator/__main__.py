"""``python -m pulseform.orchestrator`` is the ``pulseform`` command."""

import sys

from .cli import entry

sys.exit(entry())
