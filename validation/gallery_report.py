"""Run every scene of scenes/gallery to its end and print a table: wall time, steps, Newton
iterations (total, median and largest per step), the most substeps a step was cut into,
and, for the released beam, its period against the Euler-Bernoulli first bending mode.

    validation/.venv/bin/python validation/gallery_report.py [--icefem target/release/icefem]
        [--repeat 3] [--cells 40,4,4 ...]

The scenes run in a temporary copy of the gallery folder (beam_released starts from
beam_bent's output there). Wall times are medians of --repeat runs. --cells reruns the beam
pair on other meshes (cells along x, y, z) to show the period converging with the mesh.
"""
import argparse
import math
import os
import shutil
import subprocess
import tempfile
import time

import h5py
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
GALLERY = os.path.join(ROOT, "scenes", "gallery")


def run(icefem, folder, name, repeat):
    """Runs one scene `repeat` times; returns the median wall time (s) and the output path."""
    out = os.path.join(folder, name + ".h5")
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        subprocess.run([icefem, "run", name + ".toml", "--output", out, "--force"],
                       cwd=folder, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def stats(path):
    with h5py.File(path, "r") as f:
        s = f["stats"]
        it = s["newton_iterations"][:]
        substeps = int(s["substeps"][:].max())
        return len(it), int(it.sum()), float(np.median(it)), int(it.max()), substeps


def beam_period(path):
    """Mean period (s) of the tip's vertical swing from its zero crossings, and the number of
    half periods it is measured over (the first five, before damping shrinks the swing)."""
    with h5py.File(path, "r") as f:
        rest = f["mesh/rest_positions"][:]
        tip = rest[:, 0] > rest[:, 0].max() - 1e-9
        frames = sorted(f["frames"].keys())
        t = np.array([f["frames"][k].attrs["time"] for k in frames])
        z = np.array([f["frames"][k]["displacement"][:][tip, 2].mean() for k in frames])
    crossings = [t[i] - z[i] * (t[i + 1] - t[i]) / (z[i + 1] - z[i])
                 for i in range(len(z) - 1) if z[i] * z[i + 1] < 0]
    halves = np.diff(crossings)[:5]
    return 2.0 * halves.mean(), len(halves)


def euler_bernoulli_period(lam, mu, rho, h, length):
    young = mu * (3 * lam + 2 * mu) / (lam + mu)
    omega = 1.8751040687**2 * math.sqrt(young * h * h / 12.0 / (rho * length**4))
    return 2 * math.pi / omega


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--icefem", default=os.path.join(ROOT, "target", "release", "icefem"))
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--cells", nargs="*", default=[])
    a = ap.parse_args()
    icefem = os.path.abspath(a.icefem)
    with tempfile.TemporaryDirectory() as folder:
        for f in os.listdir(GALLERY):
            if f.endswith((".toml", ".msh")):
                shutil.copy(os.path.join(GALLERY, f), folder)
        names = sorted(f[:-5] for f in os.listdir(folder) if f.endswith(".toml"))
        print("| scene | wall (s) | steps | Newton total | median / step | max / step | most substeps |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        outputs = {}
        for name in names:
            wall, out = run(icefem, folder, name, a.repeat)
            outputs[name] = out
            n, total, median, most, sub = stats(out)
            print(f"| {name} | {wall:.2f} | {n} | {total} | {median:g} | {most} | {sub} |")
        exact = euler_bernoulli_period(8.64e10, 3.70e10, 916.0, 0.04, 0.4)
        print(f"\nbeam: Euler-Bernoulli first-mode period {exact * 1e3:.4f} ms")
        print("| cells | tets | period (ms) | vs Euler-Bernoulli |")
        print("|---|---:|---:|---:|")
        periods = [("40,4,4", beam_period(outputs["beam_released"]))]
        for cells in a.cells:
            for name in ("beam_bent", "beam_released"):
                path = os.path.join(folder, name + ".toml")
                text = open(os.path.join(GALLERY, name + ".toml")).read()
                open(path, "w").write(text.replace("cells = [40, 4, 4]", f"cells = [{cells}]"))
                _, out = run(icefem, folder, name, 1)
            periods.append((cells, beam_period(out)))
        for cells, (period, halves) in periods:
            tets = 6 * math.prod(int(c) for c in cells.split(","))
            print(f"| {cells} | {tets} | {period * 1e3:.4f} | {period / exact - 1:+.1%} |")


if __name__ == "__main__":
    main()
