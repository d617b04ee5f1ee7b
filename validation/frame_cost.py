#!/usr/bin/env python3
"""What writing frames costs: prints the table of docs/output.md#what-a-frame-costs.

1. The paper's fractured container (scenes/freezing_container_fracture.toml, 2 400 steps) with a
   frame every step against one frame at the end (`output_every` 1 and 2 400): wall time,
   medians of --repeat runs, and the ratio.
2. The 3 840-tet cantilever (scenes/cantilever.toml, a frame every step): bytes a frame adds to
   the file with the default `[output]` and with everything in double precision and the derived
   copies, from two run lengths (so the file's header and mesh cancel out).

Usage: python3 validation/frame_cost.py [--icefem target/release/icefem] [--repeat 3]
Standard library only; run it on an otherwise idle machine.
"""

import argparse
import os
import re
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def run(icefem, scene, out, end_time=None):
    """Runs `scene` to `out`; the wall time (s)."""
    cmd = [str(icefem), "-q", "run", str(scene), "--output", str(out), "--force"]
    if end_time is not None:
        cmd += ["--end-time", str(end_time)]
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def variant(work, source, name, replace=(), append=""):
    """A copy of scene `source` in `work` with its text changed."""
    text = source.read_text()
    for pattern, new in replace:
        text, n = re.subn(pattern, new, text, flags=re.M)
        assert n == 1, f"{pattern} not found once in {source}"
    path = work / name
    path.write_text(text + append)
    return path


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--icefem", default=ROOT / "target/release/icefem")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        paper = ROOT / "scenes/freezing_container_fracture.toml"
        rows = []
        for every in (1, 2400):
            scene = variant(work, paper, f"paper_{every}.toml", [(r"^output_every = 10\b", f"output_every = {every}")])
            times = [run(args.icefem, scene, work / f"paper_{every}.h5") for _ in range(args.repeat)]
            frames = 2401 if every == 1 else 2
            size = os.path.getsize(work / f"paper_{every}.h5")
            rows.append((every, frames, statistics.median(times), times, size))
        print(f"paper's fractured container, 2 400 steps, {os.cpu_count()} cores, medians of {args.repeat}")
        print("| frames | wall time (s) | runs (s) | file (MB) |")
        print("|---|---|---|---|")
        for every, frames, median, times, size in rows:
            runs = " / ".join(f"{t:.2f}" for t in times)
            print(f"| {frames} (output_every = {every}) | {median:.2f} | {runs} | {size / 1e6:.1f} |")
        print(f"ratio: {rows[0][2] / rows[1][2]:.2f}")
        print()

        bar = ROOT / "scenes/cantilever.toml"
        full = "\n[output]\ndrawn_precision = \"double\"\nderived_scalars = true\ntensor_matrices = true\n"
        print("3 840-tet cantilever, a frame every step: bytes a frame adds (19 frames against 7)")
        print("| output | bytes per frame |")
        print("|---|---|")
        for label, append in (("default", ""), ("double precision, derived copies", full)):
            scene = variant(work, bar, "bar.toml", append=append)
            sizes = []
            for end in (0.2, 0.6):
                out = work / f"bar_{end}.h5"
                run(args.icefem, scene, out, end_time=end)
                sizes.append(os.path.getsize(out))
            print(f"| {label} | {(sizes[1] - sizes[0]) / 12 / 1e3:.0f} KB |")


if __name__ == "__main__":
    main()
