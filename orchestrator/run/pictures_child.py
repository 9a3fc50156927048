"""The child process that renders the 3D pictures of :mod:`.pictures_mech` off-screen (pyvista/VTK
through Mesa's EGL; no display needed): started on demand, or ahead of time by a :class:`Renderer`
so that its imports and the graphics stack's start-up overlap the run. A crash or a hang of the
graphics stack then ends this child, never the run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

__all__ = ["Renderer", "spawn", "warm_up"]

#: the child's entry: ``python -m`` this module's sibling, with RESULTS_DIR or ``--wait``
CHILD_MODULE = "pulseform.orchestrator.pictures_renderer"


def warm_up() -> None:
    """Import pyvista and render a tiny scene: the graphics stack's one-time start-up (~1 s with
    Mesa's software renderer), done by a :class:`Renderer` before it is needed."""
    import pyvista as pv

    pv.OFF_SCREEN = True
    p = pv.Plotter(off_screen=True, window_size=(64, 64))
    p.add_mesh(pv.Sphere())
    p.screenshot(None, return_img=True)
    p.close()


class Renderer:
    """A 3D-picture child process started ahead of time (at the start of a run): it imports
    pyvista/VTK and renders one small scene to initialise the graphics stack (~1 s) while the run
    computes, then waits for the results folder on its standard input. :func:`draw_mechanics`
    hands it the folder; :meth:`close` ends it if it was never used (the run failed or draws no
    pictures). It dies with its parent."""

    def __init__(self) -> None:
        self.child: subprocess.Popen | None = spawn(["--wait"], stdin=subprocess.PIPE)

    def take(self, results_dir: Path) -> subprocess.Popen | None:
        """The waiting child, told to render ``results_dir``; None if it is gone (the caller then
        starts a new one)."""
        child, self.child = self.child, None
        if child is None:
            return None
        try:
            if child.poll() is not None:
                raise OSError("the renderer ended")
            child.stdin.write(f"{Path(results_dir).resolve()}\n")
            child.stdin.close()
            child.stdin = None  # communicate() must not touch it again
        except OSError:  # it died meanwhile
            child.kill()
            child.communicate()
            return None
        return child

    def close(self) -> None:
        """End the child if it was not used."""
        child, self.child = self.child, None
        if child is not None:
            child.kill()
            child.communicate()


def spawn(args: list[str], stdin=None) -> subprocess.Popen:
    """The child ``python -m pulseform.orchestrator.pictures_renderer ARGS`` (off-screen, EGL)."""
    env = dict(os.environ, PYVISTA_OFF_SCREEN="true")
    if not env.get("DISPLAY"):  # straight to EGL (Mesa), without VTK's failed attempt at an X server
        env.setdefault("VTK_DEFAULT_OPENGL_WINDOW", "vtkEGLRenderWindow")
    return subprocess.Popen([sys.executable, "-m", CHILD_MODULE, *args],
                            stdin=stdin, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=_preexec)


def _preexec() -> None:
    from pulseform.solvers.getdp.runner import die_with_parent

    die_with_parent(signal.SIGTERM)
