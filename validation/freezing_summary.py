#!/usr/bin/env python3
"""Summarise a freezing run written by `icefem run`: per chosen step (paper frame), the share
of frozen elements, the largest plastic strain, the top surface's rise (min / mean / max) and
the largest principal stress.

    validation/.venv/bin/python validation/freezing_summary.py RUN.h5 [--steps 1200,2400]
"""
import argparse

import h5py
import numpy as np


def frobenius(voigt):
    """Frobenius norm of symmetric tensors stored as Voigt rows xx yy zz yz xz xy."""
    v = np.asarray(voigt)
    return np.sqrt((v[:, :3] ** 2).sum(1) + 2.0 * (v[:, 3:] ** 2).sum(1))


def largest_principal(voigt):
    v = np.asarray(voigt)
    m = np.empty((len(v), 3, 3))
    m[:, 0, 0], m[:, 1, 1], m[:, 2, 2] = v[:, 0], v[:, 1], v[:, 2]
    m[:, 1, 2] = m[:, 2, 1] = v[:, 3]
    m[:, 0, 2] = m[:, 2, 0] = v[:, 4]
    m[:, 0, 1] = m[:, 1, 0] = v[:, 5]
    return np.linalg.eigvalsh(m)[:, -1].max()


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("file")
    ap.add_argument("--steps", default="1200,1600,2000,2400")
    args = ap.parse_args()
    wanted = [int(s) for s in args.steps.split(",")]
    with h5py.File(args.file, "r") as f:
        rest = f["mesh/rest_positions"][:]
        top = np.isclose(rest[:, 2], rest[:, 2].max())
        by_step = {int(g.attrs["step"]): g for g in f["frames"].values()}
        print("| frame (step) | time (s) | frozen | max ‖ε_p‖ | top rise min / mean / max (mm) | max principal σ (Pa) |")
        print("|---|---|---|---|---|---|")
        for step in wanted:
            g = by_step.get(step)
            if g is None:
                print(f"| {step} | (not written) | | | | |")
                continue
            rise = g["displacement"][:][top, 2] * 1e3
            frozen = (g["freeze_state"][:] >= 1.0).mean() if "freeze_state" in g else float("nan")
            plastic = frobenius(g["plastic_strain"][:]).max() if "plastic_strain" in g else 0.0
            print(
                f"| {step} | {g.attrs['time']:.2f} | {100 * frozen:.1f} % | {plastic:.3e} | "
                f"{rise.min():.3f} / {rise.mean():.3f} / {rise.max():.3f} | {largest_principal(g['stress'][:]):.3e} |"
            )
        t = f["stats/t_step"][:]
        it = f["stats/newton_iterations"][:]
        print(f"\n{len(t)} steps: {t.sum():.1f} s stepping (median {np.median(t) * 1e3:.1f} ms/step), "
              f"{it.mean():.1f} Newton iterations per step, {int((f['stats/substeps'][:] > 1).sum())} steps halved")


if __name__ == "__main__":
    main()
