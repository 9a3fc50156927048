"""Checkpoints: everything needed to continue a run exactly, in one atomically written ``.npz``."""

from __future__ import annotations

import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from .results import atomic_write_bytes

CHECKPOINT_NAME = "checkpoint.npz"


def save_checkpoint(path: Path, arrays: dict[str, np.ndarray], meta: dict[str, Any]) -> None:
    """Write ``arrays`` (name -> array) and JSON-able ``meta`` to ``path`` atomically."""
    buf = io.BytesIO()
    payload = {f"a/{k}": np.asarray(v) for k, v in arrays.items()}
    payload["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    np.savez(buf, **payload)
    atomic_write_bytes(path, buf.getvalue())


def load_checkpoint(path: Path) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Read a checkpoint written by :func:`save_checkpoint`."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k[2:]: z[k].copy() for k in z.files if k.startswith("a/")}
        meta = json.loads(bytes(z["meta"]).decode())
    return arrays, meta
