"""Corner-fill results read back frame by frame (field outputs): where the blank touches the die.

    .venv/bin/python studies/corner_fill/frames.py RESULTS_DIR [--spacing 1e-4] [--times t1,t2,...]

For each field output of a corner-fill results folder (``fields/<case>_blank.xdmf/.h5`` and
``_die``, read by ``pulseform.orchestrator.run.mech_fields``) it samples the die's cavity profile (the
die's exterior edges with upward normal below the flange, initial configuration, as
``orchestrator/run/analyses/corner_fill.py``) every ``--spacing`` metres of arc length, moves the
samples with the die's displacement, and measures the distance from each sample to the blank's
boundary (current configuration). A sample counts as touched within ``2 h0`` (the analysis' rule).
Prints per frame: the fine-sampled touched fraction now and so far, the untouched arc-length
intervals so far (mm of profile, with their x, y), and the gap between the blank and the bottom of the 130-degree corner (the deepest point of the corner arc),
plus the blank's kinetic energy within 10 mm of that corner point. Writes RESULTS_DIR/frames.csv.

This is a post-processing study (the fields are written every ``output.field_interval``, so the
"so far" record here is coarser in time than the run's own, every-``history_every``-steps record).
"""

from __future__ import annotations

import argparse
import csv
import tomllib
from pathlib import Path

import numpy as np

from pulseform.orchestrator.run.mech_fields import read_fields

FILL_GAP_FACTOR = 2.0
CORNER_RADIUS_KE = 0.01  # m: blank nodes within this distance of the corner count for its kinetic energy


def boundary_edges(cells: np.ndarray) -> np.ndarray:
    """Edges (E, 2) that belong to exactly one triangle, oriented as in their triangle (counter-clockwise
    triangles give counter-clockwise boundary loops)."""
    e = np.concatenate([cells[:, [0, 1]], cells[:, [1, 2]], cells[:, [2, 0]]])
    key = np.sort(e, axis=1)
    _, idx, cnt = np.unique(key, axis=0, return_index=True, return_counts=True)
    return e[idx[cnt == 1]]


def read_body(folder: Path, case: str, body: str) -> tuple[np.ndarray, np.ndarray, dict[float, np.ndarray]]:
    """(X0 (N, 2) m, triangles (C, 3), {time s: (displacement, velocity) (N, 2) m, m/s}) of one body's
    field files (every part of a resumed run; ``case`` is kept for the callers)."""
    bf = read_fields(folder)[body]
    X = bf.points[:, :2]
    frames = {}
    for k, t in enumerate(bf.times):
        d = bf.read(k, ("displacement_m", "velocity_m_s"))
        frames[float(t)] = (d["displacement_m"][:, :2], d["velocity_m_s"][:, :2])
    # orient triangles counter-clockwise
    cells = bf.triangles
    a, b, c = X[cells[:, 0]], X[cells[:, 1]], X[cells[:, 2]]
    cw = ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])) < 0
    cells = cells.copy()
    cells[cw] = cells[cw][:, [0, 2, 1]]
    return X, cells, frames


def point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (m) of each point p (P, 2) to the nearest segment a-b (S, 2)."""
    t = b - a
    L2 = np.maximum((t ** 2).sum(axis=1), 1e-300)
    out = np.empty(len(p))
    for i0 in range(0, len(p), 256):
        d = p[i0:i0 + 256, None, :] - a[None]
        xi = np.clip((d * t[None]).sum(axis=2) / L2[None], 0.0, 1.0)
        q = a[None] + xi[..., None] * t[None]
        out[i0:i0 + 256] = np.sqrt(((p[i0:i0 + 256, None, :] - q) ** 2).sum(axis=2)).min(axis=1)
    return out


def profile_samples(X: np.ndarray, edges: np.ndarray, spacing: float):
    """Samples of the cavity profile: (edge index, local coordinate xi, arc length s) per sample."""
    pa, pb = X[edges[:, 0]], X[edges[:, 1]]
    t = pb - pa
    ln = np.linalg.norm(t, axis=1)
    ny = -t[:, 0] / ln
    keep = (ny > 0.1) & (0.5 * (pa[:, 1] + pb[:, 1]) < X[:, 1].max() - 1e-6)
    prof = edges[keep]
    # order the profile edges along x (the profile is a graph over x on the cavity side)
    order = np.argsort(0.5 * (X[prof[:, 0], 0] + X[prof[:, 1], 0]))
    prof, lp = prof[order], ln[keep][order]
    eid, xis, s = [], [], []
    s0 = 0.0
    for k, L in enumerate(lp):
        n = max(1, int(np.ceil(L / spacing)))
        xi = (np.arange(n) + 0.5) / n
        eid += [k] * n
        xis += list(xi)
        s += list(s0 + xi * L)
        s0 += L
    return prof, np.array(eid), np.array(xis), np.array(s), lp


def intervals(mask: np.ndarray, s: np.ndarray, pts: np.ndarray, ds: np.ndarray) -> list[tuple[float, float, float, float]]:
    """Runs of True in mask: (length m, s_start m, x mm, y mm at the run's middle)."""
    out = []
    i = 0
    while i < len(mask):
        if mask[i]:
            j = i
            while j + 1 < len(mask) and mask[j + 1]:
                j += 1
            mid = (i + j) // 2
            out.append((float(ds[i:j + 1].sum()), float(s[i]), float(pts[mid, 0] * 1e3), float(pts[mid, 1] * 1e3)))
            i = j + 1
        else:
            i += 1
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--spacing", type=float, default=1e-4, help="profile sample spacing (m)")
    ap.add_argument("--times", default="", help="only print these frames (s, comma separated; nearest)")
    args = ap.parse_args()
    case = tomllib.loads((args.results / "case.toml").read_text())
    name = case["case"]["name"]
    h0 = next(c for c in case["contact"] if c["slave"] == "blank")["h0"]
    Xd, cd, fd = read_body(args.results, name, "die")
    Xb, cb, fb = read_body(args.results, name, "blank")
    prof, eid, xi, s, lp = profile_samples(Xd, boundary_edges(cd), args.spacing)
    ds = lp[eid] / np.bincount(eid)[eid]
    bseg = boundary_edges(cb)
    # the corner to fill: the rounded 130-degree corner between the flat bottom and the wall; its
    # middle sample (edges inclined between 1 and 49 degrees within 5 mm of the bottom)
    P0 = Xd[prof[eid, 0]] * (1 - xi[:, None]) + Xd[prof[eid, 1]] * xi[:, None]
    tang = Xd[prof[:, 1]] - Xd[prof[:, 0]]
    ang = np.degrees(np.arctan2(np.abs(tang[:, 1]), np.abs(tang[:, 0])))[eid]
    arc = np.flatnonzero((ang > 1.0) & (ang < 49.0) & (P0[:, 1] < P0[:, 1].min() + 5e-3))
    i_corner = int(arc[len(arc) // 2])
    ever = np.zeros(len(s), bool)
    rows = []
    want = [float(t) for t in args.times.split(",") if t]
    for t, (ud, vd) in fd.items():
        ub, vb = fb[t]
        xd, xb = Xd + ud, Xb + ub
        P = xd[prof[eid, 0]] * (1 - xi[:, None]) + xd[prof[eid, 1]] * xi[:, None]
        d = point_segment_distance(P, xb[bseg[:, 0]], xb[bseg[:, 1]])
        now = d <= FILL_GAP_FACTOR * h0
        ever |= now
        near = np.linalg.norm(xb - P[i_corner], axis=1) < CORNER_RADIUS_KE
        row = {"time_s": t, "touched_now": float(ds[now].sum() / ds.sum()), "touched_so_far": float(ds[ever].sum() / ds.sum()),
               "untouched_so_far_mm": float(ds[~ever].sum() * 1e3), "corner_gap_mm": float(d[i_corner] * 1e3),
               "blank_speed_near_corner_max_m_s": float(np.linalg.norm(vb[near], axis=1).max()) if vb is not None and near.any() else np.nan}
        rows.append(row)
        if not want or any(abs(t - w) < 1e-9 + 0.5 * 2.5e-5 for w in want):
            gaps = "; ".join(f"{L * 1e3:.2f} mm at ({x:.1f}, {y:.1f})" for L, _, x, y in intervals(~ever, s, P, ds))
            print(f"t = {t * 1e6:7.1f} us  now {row['touched_now']:.3f}  so far {row['touched_so_far']:.3f}  "
                  f"corner gap {row['corner_gap_mm']:.2f} mm  v_corner {row['blank_speed_near_corner_max_m_s']:.1f} m/s  "
                  f"untouched: {gaps}")
    with open(args.results / "frames.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    print(f"corner sample at ({P0[i_corner, 0] * 1e3:.2f}, {P0[i_corner, 1] * 1e3:.2f}) mm; profile length "
          f"{s[-1] * 1e3 + ds[-1] * 500:.1f} mm; {len(s)} samples")


if __name__ == "__main__":
    main()
