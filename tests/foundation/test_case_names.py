"""Case names in the user's own language (issue 32, item 12): ``case.name`` names the folder ``results/<name>``,
so any portable folder name is accepted -- letters of any script, digits, spaces, ``. _ -`` -- NFC-normalised;
everything else is refused with one line that says which characters are allowed (orchestrator/case/names.py).
The refused names are in test_bad_input.py (``name_*``); here the accepted ones, the message and real runs."""

from __future__ import annotations

import json
import tomllib
import unicodedata
from pathlib import Path

import meshio
import pytest

from pulseform.orchestrator.case.names import FOLDER_NAME_CHARACTERS, MAX_NAME_BYTES
from pulseform.orchestrator.cli import main
from warm_cli import pulseform_cli

REPO = Path(__file__).resolve().parents[2]
#: accepted case names: German with a space, Japanese, Greek, Devanagari (its vowel signs are combining marks),
#: Arabic-Indic digits, a dotted version, the ASCII names the old rule refused
ACCEPTED = ["Blechumformung Prüfstand", "名前", "Ελασματουργία", "नामा", "تجربة ٣", "Prüfstand v1.2_b-3",
            "bar impact", "stoß", "_draft", "ab" * 50]
#: (as typed, as its folder is named): a decomposed ü (u + U+0308, as macOS may hand it over) is composed
NFD = ("Pru\u0308fstand", "Prüfstand")


def _check(name: str, capsys) -> tuple[int, str, str]:
    rc = main(["check", str(REPO / "cases/bar_impact"), "--set", f"case.name={json.dumps(name)}"])
    out, err = capsys.readouterr()
    return rc, out, err


@pytest.mark.parametrize("name", ACCEPTED)
def test_case_names_in_any_language(name, capsys):
    rc, out, err = _check(name, capsys)
    assert rc == 0, err
    assert tomllib.loads(out.split("\n", 1)[1])["case"]["name"] == name


def test_decomposed_name_is_composed(capsys):
    """One spelling, one folder: the resolved case (and so results/<name>) holds the NFC form."""
    typed, folder = NFD
    assert typed != folder and unicodedata.normalize("NFC", typed) == folder
    rc, out, err = _check(typed, capsys)
    assert rc == 0, err
    assert tomllib.loads(out.split("\n", 1)[1])["case"]["name"] == folder


def test_refusal_names_the_character_and_the_allowed_ones(capsys):
    rc, _, err = _check("Prüfstand/1", capsys)
    assert rc == 2
    line = err.strip()
    assert "case.name" in line and "'/' (U+002F) is not allowed" in line and FOLDER_NAME_CHARACTERS in line, line
    assert FOLDER_NAME_CHARACTERS == "letters of any script, digits, spaces, '.', '_', '-'"
    rc, _, err = _check("名" * 34, capsys)  # 102 bytes: the limit is in bytes, the file system's unit
    assert rc == 2 and f"102 bytes in UTF-8); at most {MAX_NAME_BYTES} bytes" in err, err
    assert _check("名" * 33, capsys)[0] == 0


@pytest.mark.getdp
def test_coupled_run_in_a_folder_named_in_japanese_and_german(tmp_path):
    """The default results folder of a coupled run (gmsh and getdp work inside it) named
    ``名前 Prüfstand``, typed decomposed: 2 EM steps of the jumping ring (the pictures: the deformable run below)."""
    name = "名前 " + NFD[0]
    r = pulseform_cli(["run", str(REPO / "cases/jumping_ring"), "--quiet", "--set", f"case.name={json.dumps(name)}",
                       "--set", "time.end=1e-3", "--set", "output.field_interval=5e-4", "--set", "output.plots=false"],
                      cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert [p.name for p in (tmp_path / "results").iterdir()] == ["名前 Prüfstand"]
    out = tmp_path / "results" / "名前 Prüfstand"
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["status_ok"] == 1.0 and metrics["em_steps"] == 2
    assert (out / "fields" / "em" / "em.pvd").is_file()


def test_deformable_run_writes_its_fields_under_the_name(tmp_path):
    """The field files fields/<case>_<body>.xdmf of a name with a space and an umlaut, read back by meshio
    (the .xdmf names its .h5 by that name)."""
    name = "Blechumformung Prüfstand"
    r = pulseform_cli(["run", str(REPO / "cases/bar_impact"), "--quiet", "--set", f"case.name={json.dumps(name)}",
                       "--set", "bodies.left.mesh_size=0.25", "--set", "bodies.right.mesh_size=0.25",
                       "--set", "time.end=1e-4", "--set", "output.field_interval=5e-5", "--set", "output.plots=false"],
                      cwd=tmp_path, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    fields = tmp_path / "results" / name / "fields"
    assert {f"{name}_left.xdmf", f"{name}_left.h5", f"{name}_right.xdmf"} <= {p.name for p in fields.iterdir()}
    with meshio.xdmf.TimeSeriesReader(fields / f"{name}_left.xdmf") as reader:
        points, _ = reader.read_points_cells()
        t, point_data, _ = reader.read_data(reader.num_steps - 1)
    assert t == pytest.approx(1e-4) and point_data["velocity_m_s"].shape[0] == points.shape[0]
