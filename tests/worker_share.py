"""One result for all pytest-xdist workers of a test session: the first worker that asks makes it, the others
wait for it (a file lock) and read it.

A session-scoped fixture runs once per worker; with the tests on every core (``-n auto --dist loadfile``), two
modules that read the same run but land on different workers would each make it. :func:`once` keys the result
by a string and keeps it under the session's common temporary folder (the parent of each worker's own).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
from pathlib import Path
from typing import Any, Callable


def once(tmp_path_factory, key: str, make: Callable[[Path], dict[str, Any]]) -> tuple[Path, dict[str, Any]]:
    """``(folder, info)``: ``make(folder)`` run once per session for ``key``, in a folder of its own; ``info``
    (what ``make`` returned, JSON data) is read back by every later caller, in any worker. Should ``make``
    raise, nothing is recorded and the next caller makes it again (and meets the same error)."""
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # .../pytest-N/popen-gwK -> .../pytest-N: common to the session's workers
    folder = root / "shared" / hashlib.sha256(key.encode()).hexdigest()[:16]
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes (or the worker dies)
        done = folder / "done.json"
        if done.is_file():
            return folder, json.loads(done.read_text())
        info = make(folder)
        tmp = folder / "done.json.tmp"
        tmp.write_text(json.dumps(info))
        tmp.replace(done)
        return folder, info
