"""``python -m pulseform.orchestrator`` is the ``pulseform`` command."""

import sys

from .cli import main

sys.exit(main())
