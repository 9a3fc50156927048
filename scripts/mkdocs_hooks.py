"""MkDocs hooks of pulseform's documentation site (mkdocs.yml: ``hooks:``; MkDocs >= 1.4).

1. The API reference (mkdocstrings, griffe's static analysis) needs the package ``pulseform`` as a
   folder: the sources are ``orchestrator/`` and ``solvers/``, mapped to ``pulseform.orchestrator`` and
   ``pulseform.solvers`` by setuptools' package-dir (pyproject.toml), which griffe 0.25 cannot follow. A
   copy of their ``.py`` files under ``<tmp>/pulseform/`` is made for each build and removed after it.
2. Pictures kept next to the cases and studies (``cases/*/reference/*.png``,
   ``studies/*/reference/*.png``) are added to the site at the same paths, so the pages show them
   without a second copy in docs/ (a page at the top of docs/ links them as ``cases/...``).
3. ``pymdownx.snippets`` (the changelog page includes the root CHANGELOG.md) resolves from the
   repository root whatever the working directory.
4. The docstrings' Sphinx roles (:func:`name`, :class:`~.mod.Name`), which the numpy-style parser
   leaves as text, are shown as code: ``name``, ``Name``.

Nothing here imports pulseform: the site builds with Debian's ``/usr/bin/mkdocs`` too.
"""

from __future__ import annotations

import re
import shutil
import tempfile
from pathlib import Path

from mkdocs.structure.files import File

REPO = Path(__file__).resolve().parents[1]
PICTURES = ("cases/*/reference/*.png", "studies/*/reference/*.png")
_tmp: Path | None = None


def _copy_package(root: Path) -> None:
    pkg = root / "pulseform"
    pkg.mkdir()
    (pkg / "__init__.py").write_text('"""pulseform: coupled GetDP + DOLFINx simulation of pulsed metal forming."""\n')
    for name in ("orchestrator", "solvers"):
        shutil.copytree(REPO / name, pkg / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))


def on_config(config, **_):
    global _tmp
    if _tmp is None or not _tmp.exists():
        _tmp = Path(tempfile.mkdtemp(prefix="pulseform-api-"))
        _copy_package(_tmp)
    python = config["plugins"]["mkdocstrings"].config["handlers"].setdefault("python", {})
    python["paths"] = [str(_tmp)]
    config["mdx_configs"].setdefault("pymdownx.snippets", {})["base_path"] = [str(REPO)]
    return config


def on_files(files, config, **_):
    site = config["site_dir"]
    for pattern in PICTURES:
        for path in sorted(REPO.glob(pattern)):
            files.append(File(path.relative_to(REPO).as_posix(), str(REPO), site, config["use_directory_urls"]))
    return files


def on_post_build(config, **_):
    global _tmp
    if _tmp is not None:
        shutil.rmtree(_tmp, ignore_errors=True)
        _tmp = None


def on_build_error(error, **_):
    on_post_build(None)


_ROLE = re.compile(r":(?:py:)?(?:mod|func|class|meth|attr|data|exc|obj|const):<code>([^<]*)</code>")


def _role_text(match: re.Match) -> str:
    target = match.group(1)
    text = target[1:].rsplit(".", 1)[-1] if target.startswith("~") else target.lstrip(".")
    return f"<code>{text}</code>"


def on_page_content(html, **_):
    """The docstrings' Sphinx roles (:func:`name`, :class:`~.mod.Name`) as code text."""
    return _ROLE.sub(_role_text, html)
