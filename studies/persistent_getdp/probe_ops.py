"""Evidence: which Resolution operations this getdp build has and how they behave (issue 15).

Runs tiny decks on a 2-triangle mesh and prints, for each operation, what happened and the cost
per call ((T(K calls) - T(1 call)) / (K - 1), whole getdp runs, median of 3):
  build options (getdp -info), GmshRead (not in this build), SystemCommand (fork + /bin/sh per call),
  Sleep, Python[] (embedded interpreter), While + runtime variables, GetNumberRunTime /
  SetNumberRunTime without a ONELAB server, ReadSolution from a file written by Python (binary
  .res, the header's time and step set $Time and $TimeStep), DeformMesh (adds the displacement to
  the CURRENT coordinates: applied twice it moves twice; the area integral follows).

Usage: .venv/bin/python studies/persistent_getdp/probe_ops.py
"""
from __future__ import annotations

import os
import re
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from pulseform.solvers.getdp.runner import FAST_MPI_ENV, child_preexec, find_getdp

MSH = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 1 0 0
3 1 1 0
4 0 1 0
$EndNodes
$Elements
2
1 2 2 1 1 1 2 3
2 2 2 1 1 1 3 4
$EndElements
"""

HEAD = """
Group { Dom = Region[{1}]; }
Jacobian { { Name J; Case { { Region All; Jacobian Vol; } } } }
Integration { { Name I; Case { { Type Gauss; Case { { GeoElement Triangle; NumberOfPoints 3; } } } } } }
FunctionSpace {
  { Name H; Type Form0; BasisFunction { { Name s; NameOfCoef v; Function BF_Node; Support Dom; Entity NodesOf[All]; } } }
  { Name Hu; Type Vector; BasisFunction {
      { Name sx; NameOfCoef ux; Function BF_NodeX; Support Dom; Entity NodesOf[All]; }
      { Name sy; NameOfCoef uy; Function BF_NodeY; Support Dom; Entity NodesOf[All]; } } }
}
Formulation {
  { Name F; Type FemEquation; Quantity { { Name v; Type Local; NameOfSpace H; } }
    Equation { Galerkin { [ Dof{v} - 1, {v} ]; In Dom; Jacobian J; Integration I; } } }
  { Name D; Type FemEquation; Quantity { { Name u; Type Local; NameOfSpace Hu; } }
    Equation { Galerkin { [ Dof{u}, {u} ]; In Dom; Jacobian J; Integration I; } } }
}
PostProcessing { { Name P; NameOfFormulation F; Quantity {
    { Name area; Value { Integral { [ 1 ]; In Dom; Jacobian J; Integration I; } } } } } }
PostOperation { { Name Area; NameOfPostProcessing P;
    Operation { Print[ area[Dom], OnGlobal, Format Table, File > "area.txt" ]; } } }
"""


def deck(ops: str, systems: str = "{ Name S; NameOfFormulation F; }") -> str:
    return HEAD + f"Resolution {{ {{ Name R; System {{ {systems} }} Operation {{ {ops} }} }} }}\n"


def run(work: Path, text: str, extra=(), timeout=120) -> tuple[int, str, float]:
    work.mkdir(parents=True, exist_ok=True)
    (work / "m.msh").write_text(MSH)
    (work / "p.pro").write_text(text)
    env = dict(os.environ)
    env.update(FAST_MPI_ENV)
    t0 = time.perf_counter()
    p = subprocess.run([find_getdp(), str(work / "p.pro"), "-msh", str(work / "m.msh"), "-name", str(work / "p"),
                        *extra, "-solve", "R", "-v", "4"], cwd=work, capture_output=True, text=True, env=env,
                       timeout=timeout, preexec_fn=child_preexec)
    return p.returncode, p.stdout + p.stderr, time.perf_counter() - t0


def per_call(work: Path, body: str, k: int = 50, setup: str = "") -> float:
    """Cost of one execution of ``body`` inside a While loop (s): (T(k) - T(1)) / (k - 1), median of 3."""
    est = []
    for rep in range(3):
        ts = []
        for n in (1, k):
            ops = f"{setup} Evaluate[$i = 0]; While[$i < {n}] {{ {body} Evaluate[$i = $i + 1]; }}"
            rc, out, t = run(work / f"{rep}_{n}", deck(ops))
            assert rc == 0, out[-2000:]
            ts.append(t)
        est.append((ts[1] - ts[0]) / (k - 1))
    return float(np.median(est))


def main():
    print(f"load average: {os.getloadavg()}")
    p = subprocess.run([find_getdp(), "-info"], capture_output=True, text=True)
    info = p.stdout + p.stderr
    print("getdp -info:", " | ".join(ln.strip() for ln in info.splitlines() if ln.startswith(("Version", "Build options", "PETSc"))))
    with tempfile.TemporaryDirectory(prefix="pgdp_probe_") as tmp:
        w = Path(tmp)
        rc, out, _ = run(w / "gmshread", deck('GmshRead["x.pos"];'))
        line = next((ln for ln in out.splitlines() if "Gmsh" in ln and ("Error" in ln or "need" in ln)), out[-200:])
        print(f"GmshRead: exit {rc}: {line.strip()}")

        rc, out, _ = run(w / "while", deck('Evaluate[$i = 0]; While[$i < 3] { Print[{$i}, Format "i=%g"]; '
                                           'Evaluate[$i = $i + 1]; } Test[$i == 3] { Print[{$i}, Format "after=%g"]; }'))
        found = " ".join(re.findall(r"(i=\d|after=\d)", out))
        print(f"While + runtime variables: exit {rc}: {found}")

        t = per_call(w / "sys", 'SystemCommand["true"];')
        print(f"SystemCommand[\"true\"]: {t * 1e3:.2f} ms per call (system(): fork of getdp + exec of /bin/sh)")
        t = per_call(w / "sleep", "Sleep[0.001];")
        print(f"Sleep[0.001]: {t * 1e3:.2f} ms per call")
        rc, out, _ = run(w / "py", deck('Evaluate[$x = Python[2, 3]{"output = [input[0] * input[1] + 1]"}]; '
                                        'Print[{$x}, Format "python=%g"];'))
        found = " ".join(re.findall(r"python=[0-9.]+", out))
        print(f"Python[] (embedded interpreter): exit {rc}: {found}")
        t = per_call(w / "pyc", 'Evaluate[$x = Python[$i]{"output = [input[0] + 1]"}];')
        print(f"Python[]{{...}} evaluation: {t * 1e3:.3f} ms per call")
        rc, out, _ = run(w / "onelab", deck('Evaluate[$x = GetNumberRunTime[7]{"pf/x"}]; '
                                            'Evaluate[SetNumberRunTime[5]{"pf/y"}]; '
                                            'Evaluate[$y = GetNumberRunTime[9]{"pf/y"}]; '
                                            'Print[{$x, $y}, Format "get=%g after-set=%g"];'))
        found = " ".join(re.findall(r"get=\S+ after-set=\S+", out))
        print(f"GetNumberRunTime / SetNumberRunTime without ONELAB: exit {rc}: {found} "
              "(the default argument; Set is a no-op)")

        # ReadSolution from a file Python wrote (binary .res): values, $Time and $TimeStep from the header
        d = w / "read"
        d.mkdir()
        (d / "u.res").write_bytes(b"$ResFormat /* probe */\n1.1 1\n$EndResFormat\n$Solution\n0 1.25e-06 0 7\n"
                                  + np.full(4, 2.0).tobytes() + b"\n$EndSolution\n")
        rc, out, _ = run(d, deck('InitSolution[S]; ReadSolution[S]; Print[{$Time, $TimeStep}, Format "t=%g step=%g"]; '
                                 'Print[S];'), extra=("-res", str(d / "u.res")))
        found = " ".join(re.findall(r"t=\S+ step=\S+", out))
        print(f"ReadSolution from a Python-written binary .res: exit {rc}: {found}")

        # DeformMesh: the same displacement applied twice; area integral before and after each
        d = w / "deform"
        d.mkdir()
        u = np.zeros(8)
        (d / "u.res").write_bytes(b"$ResFormat /* probe */\n1.1 1\n$EndResFormat\n$Solution\n1 0 0 1\n"
                                  + u.tobytes() + b"\n$EndSolution\n")
        rc0, _, _ = run(d / "pre", deck("InitSolution[S];", "{ Name S; NameOfFormulation F; } { Name U; NameOfFormulation D; }"))
        pre = (d / "pre" / "p.pre").read_text()
        blk = pre[pre.index("$DofData /* #1 */"):].splitlines()
        rows = np.array([ln.split()[:5] for ln in blk[6:6 + int(blk[5].split()[0])]], dtype=np.int64)
        nt = np.unique(rows[:, 0])
        for nx, node, num in zip(rows[:, 0], rows[:, 1], rows[:, 4]):
            if nx == nt[0] and node in (2, 3):      # x-displacement 0.5 on the nodes at x = 1
                u[num - 1] = 0.5
        (d / "u.res").write_bytes(b"$ResFormat /* probe */\n1.1 1\n$EndResFormat\n$Solution\n1 0 0 1\n"
                                  + u.tobytes() + b"\n$EndSolution\n")
        ops = ("InitSolution[S]; PostOperation[Area]; ReadSolution[U]; DeformMesh[U, u]; PostOperation[Area]; "
               "DeformMesh[U, u]; PostOperation[Area];")
        rc, out, _ = run(d, deck(ops, "{ Name S; NameOfFormulation F; } { Name U; NameOfFormulation D; }"),
                         extra=("-res", str(d / "u.res")))
        areas = [float(ln.split()[-1]) for ln in (d / "area.txt").read_text().splitlines() if ln.strip()]
        print(f"DeformMesh (u_x = 0.5 on the nodes at x = 1, applied twice): exit {rc}: area {areas} "
              "(1 -> 1.5 -> 2: the displacement is added to the current coordinates; integrals follow)")


if __name__ == "__main__":
    main()
