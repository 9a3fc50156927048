"""Which pictures an analysis drew (orchestrator/run/plots.py::_stamps) while the renderer child writes its
own pictures into the same folder (a hidden ``.NAME.tmp.png`` renamed when written): the slow tier's corner-fill
sweep failed once on a temporary file listed and renamed before its stat (FileNotFoundError, the run exit 1)."""
from pathlib import Path

from pulseform.orchestrator.run import plots


def test_stamps_skip_temporary_and_vanished_files(tmp_path, monkeypatch):
    (tmp_path / "shapes.png").write_bytes(b"png")
    (tmp_path / ".deformed_von_mises.tmp.png").write_bytes(b"half")
    gone = tmp_path / "renamed_meanwhile.png"   # listed, then gone before its stat
    listed = list(tmp_path.glob("*.png")) + [gone]
    monkeypatch.setattr(Path, "glob", lambda self, pattern: iter(listed))
    stamps = plots._stamps(tmp_path)
    assert list(stamps) == [tmp_path / "shapes.png"]
