#!/usr/bin/env python3
"""Time per step of linear dynamics: icefem against scikit-fem on the same mesh and problem.

The cantilever of validation/report.py (0.4 x 0.04 x 0.04 m ice, clamped at x = 0, released
from rest under gravity, linear model, row-sum lumped mass) on 40 x 4 x 4 cells (3 840 tets),
dt = 1e-4 s, 200 steps, with backward Euler, the trapezoidal rule (icefem "newmark") and BDF2.
Each code runs `--repeats` times (default 3) in this process; the table gives medians.

    validation/.venv/bin/python validation/linear_steps.py --icefem target/release/icefem

icefem per step = sum(/stats/t_step) / steps (assembly, factorisation, solves, bookkeeping);
its wall time includes start-up, set-up and the two frames written. scikit-fem per step =
(assembly + factorisation + steps) / steps, and the steps alone (a right-hand side and a pair
of triangular solves of the fixed factor each).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import report  # noqa: E402

CELLS = (40, 4, 4)
DT = 1e-4
T_END = 0.02
SCHEMES = [("backward Euler", "BE", None), ("trapezoidal / Newmark", "TR", "newmark"),
           ("BDF2", "BDF2", "bdf2")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--icefem", type=Path, default=report.ROOT / "target/release/icefem")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    mesh = report.box_mesh((report.BEAM_L, report.BEAM_W, report.BEAM_H), CELLS)
    body = report.ice_material() + report.ice_gravity() + report.ice_dirichlet(0)
    rows = []
    with tempfile.TemporaryDirectory(prefix="icefem-linear-steps-") as work:
        ice = report.Icefem(args.icefem.resolve(), Path(work), 1)
        for label, sk_scheme, ice_scheme in SCHEMES:
            runs = [ice.run(f"bar_{sk_scheme}", mesh, body, "dynamic", DT, T_END,
                            scheme=ice_scheme) for _ in range(args.repeats)]
            if any(r is None for r in runs):
                print("\n".join(ice.messages), file=sys.stderr)
                return 1
            peers = [report.sk_dynamics(mesh, DT, T_END, sk_scheme)
                     for _ in range(args.repeats)]
            steps = runs[0]["steps"]
            diff = float(np.linalg.norm(runs[0]["u"] - peers[0]["u"])
                         / np.linalg.norm(peers[0]["u"]))
            rows.append((label, steps,
                         statistics.median(r["t_solver"] for r in runs) / steps,
                         statistics.median(r["wall"] for r in runs),
                         statistics.median(p["t_asm"] + p["t_sol"] for p in peers) / steps,
                         statistics.median(p["t_sol"] for p in peers) / steps, diff))
    print(f"\n{CELLS[0]} x {CELLS[1]} x {CELLS[2]} cells ({6 * np.prod(CELLS)} tets), "
          f"dt = {DT:g} s, medians of {args.repeats}; {report.machine()}\n")
    print("| scheme | steps | icefem ms/step | icefem wall (s) | scikit-fem ms/step "
          "(with assembly) | scikit-fem ms/step (steps only) | relative difference |")
    print("|---|---|---|---|---|---|---|")
    for label, steps, ice_step, wall, sk_step, sk_only, diff in rows:
        print(f"| {label} | {steps} | {ice_step * 1e3:.3f} | {wall:.2f} | {sk_step * 1e3:.3f} "
              f"| {sk_only * 1e3:.3f} | {diff:.1e} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
