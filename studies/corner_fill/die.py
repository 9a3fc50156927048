"""Die profile of the corner-filling cases, printed as case-file points.

    .venv/bin/python studies/corner_fill/die.py [--depth 0.02] [--radius 0.003] ...

prints :func:`pulseform.orchestrator.run.analyses.corner_fill_die.die_polygon`; paste the output into
``[[bodies]] shape.points`` of cases/corner_fill*/case.toml.
"""

from __future__ import annotations

import argparse

from pulseform.orchestrator.run.analyses.corner_fill_die import die_polygon


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--depth", type=float, default=0.02)
    ap.add_argument("--radius", type=float, default=0.003)
    ap.add_argument("--entry-radius", type=float, default=0.005)
    ap.add_argument("--x-end", type=float, default=0.145)
    ap.add_argument("--thickness", type=float, default=0.02)
    ap.add_argument("--gap", type=float, default=1.5e-4)
    ap.add_argument("--bottom-half-width", type=float, default=0.0)
    args = ap.parse_args()
    pts = die_polygon(args.depth, args.radius, args.entry_radius, args.x_end, args.thickness, args.gap,
                      bottom_half_width=args.bottom_half_width)
    print("points = [" + ", ".join(f"[{x:.7g}, {y:.7g}]" for x, y in pts) + "]")


if __name__ == "__main__":
    main()
