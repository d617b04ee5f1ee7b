#!/usr/bin/env python3
"""Time per step of a run written by `icefem run`, from its /stats table: for each range of
steps, the median, mean and largest wall time of a step, and the Newton iterations, Newton
solves (the step's and its friction re-solves; files written before /stats/newton_solves
existed: "–"), linear (CG) iterations and factorisations per step (medians), with the time
split into assembly, factorisation and solve (means). Prints a markdown table.

    validation/.venv/bin/python validation/step_times.py RUN.h5 [--ranges 1-38,39-51,52-90]

Default ranges: thirds of the run. A range A-B holds steps A to B inclusive (1-based, as
/stats/step counts them); ranges beyond the file's last step are cut at it.
"""
import argparse

import h5py
import numpy as np


def parse_ranges(text, last):
    ranges = []
    for part in text.split(","):
        a, b = (int(v) for v in part.split("-"))
        if a > b:
            raise SystemExit(f"--ranges: {part}: the first step must not exceed the last")
        ranges.append((a, min(b, last)))
    return ranges


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run", help="HDF5 file written by icefem run")
    parser.add_argument("--ranges", help="comma-separated step ranges A-B (default: thirds)")
    args = parser.parse_args()
    with h5py.File(args.run, "r") as f:
        stats = {k: f["stats"][k][:] for k in f["stats"]}
    step = stats["step"].astype(int)
    if len(step) == 0:
        raise SystemExit(f"{args.run}: no steps in /stats")
    last = int(step.max())
    if args.ranges:
        ranges = parse_ranges(args.ranges, last)
    else:
        cuts = np.linspace(step.min(), last + 1, 4).astype(int)
        ranges = [(int(cuts[i]), int(cuts[i + 1]) - 1) for i in range(3)]
    ranges.append((int(step.min()), last))
    print("| steps | n | step median (s) | mean (s) | max (s) | Newton it. | Newton solves "
          "| CG it. | factorisations | assembly / factorisation / solve, mean (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for a, b in ranges:
        sel = (step >= a) & (step <= b)
        if not sel.any():
            continue
        t = stats["t_step"][sel]
        med = lambda k: np.median(stats[k][sel])
        mean = lambda k: stats[k][sel].mean()
        label = f"{a}–{b}" if (a, b) != ranges[-1] else f"all ({a}–{b})"
        # Rows from before the column existed hold 0 (a step always takes one solve).
        solves = stats.get("newton_solves", np.zeros_like(step))[sel]
        solves = f"{np.median(solves):g}" if (solves > 0).all() else "–"
        print(f"| {label} | {sel.sum()} | {np.median(t):.3f} | {t.mean():.3f} | {t.max():.2f} "
              f"| {med('newton_iterations'):g} | {solves} | {med('linear_iterations'):g} "
              f"| {med('factorizations'):g} (total {int(stats['factorizations'][sel].sum())}) "
              f"| {mean('t_assembly'):.3f} / {mean('t_factorization'):.3f} / {mean('t_solve'):.3f} |")


if __name__ == "__main__":
    main()
