"""scripts/test.sh's numba prewarm (tests/numba_prewarm.py) finds a cold cache: an empty folder, and index files numba
would not use (the source's modification time or numba's version changed: a fresh checkout of the same sources)."""

from __future__ import annotations

import os
import pickle
from pathlib import Path

import numba

import pulseform.solvers  # noqa: F401 - points numba's cache at its folder now, not inside the test
from numba_prewarm import _fresh, cold_families


def test_an_empty_cache_folder_is_cold_for_both_families(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    assert cold_families() == ["2d", "3d"]


def test_an_index_is_fresh_only_for_its_source_stamp_and_numba_version(tmp_path):
    source = tmp_path / "kernels.py"
    source.write_text("x = 1\n")
    st = source.stat()
    index = tmp_path / "kernels.f-1.py311.nbi"
    with open(index, "wb") as f:  # numba's layout: its version, then the pickled (source stamp, overloads)
        pickle.dump(numba.__version__, f)
        f.write(pickle.dumps(((st.st_mtime, st.st_size), {})))
    assert _fresh(index, source, numba.__version__)
    assert not _fresh(index, source, "0.0.0")                    # another numba
    os.utime(source, (st.st_atime, st.st_mtime + 10.0))         # a checkout: same contents, a new time
    assert not _fresh(index, source, numba.__version__)
    assert not _fresh(tmp_path / "missing.nbi", source, numba.__version__)
    assert not _fresh(index, Path(tmp_path / "gone.py"), numba.__version__)
