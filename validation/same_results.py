#!/usr/bin/env python3
"""Compares two icefem binaries on the shipped scenes: bit-for-bit results.

    validation/same_results.py OLD_BINARY NEW_BINARY [SCENE.toml ...] [--workdir DIR]

Runs both binaries on each scene (default: every scene in scenes/ and scenes/gallery/ but the
two that take over 5 minutes on 2 cores) from the scene's folder, then compares every dataset
of the two HDF5 files — /frames, /stats, /cracks, all of them — bit for bit (NaN equal to NaN).
Wall-time columns of /stats (names starting with `t_`) are left out. Prints one line per
scene; exits 1 if any differs. Needs h5py and numpy.
"""
import argparse
import pathlib
import subprocess
import sys

import h5py
import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
# Over 5 minutes each on the 2-core machine.
LONG = {"freezing_container_1e5", "freezing_container_fine"}


def is_timing(name):
    return name.startswith("t_")


def differences(a, b, path=""):
    """(path, what) of every dataset that differs between the groups a and b."""
    out = []
    if set(a.keys()) != set(b.keys()):
        out.append((path, f"members differ: {sorted(set(a.keys()) ^ set(b.keys()))}"))
    for key in sorted(set(a.keys()) & set(b.keys())):
        x, y, where = a[key], b[key], f"{path}/{key}"
        if isinstance(x, h5py.Group):
            out += differences(x, y, where)
            continue
        if path.startswith("/stats") and is_timing(key):
            continue
        X, Y = x[()], y[()]
        if x.dtype.names:
            for n in x.dtype.names:
                if not is_timing(n) and not np.array_equal(X[n], Y[n], equal_nan=True):
                    out.append((f"{where}:{n}", "values"))
        elif np.shape(X) != np.shape(Y):
            out.append((where, f"shape {np.shape(X)} vs {np.shape(Y)}"))
        elif x.dtype.kind in "fiub":
            if not np.array_equal(X, Y, equal_nan=True):
                out.append((where, f"max |diff| {np.max(np.abs(X.astype(float) - Y.astype(float))):.3e}"))
        elif not np.all(X == Y):
            out.append((where, "values"))
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old")
    parser.add_argument("new")
    parser.add_argument("scenes", nargs="*")
    parser.add_argument("--workdir", default="/tmp/icefem_same_results")
    args = parser.parse_args()
    scenes = [pathlib.Path(s).resolve() for s in args.scenes] or [
        p for p in sorted((ROOT / "scenes").glob("*.toml")) + sorted((ROOT / "scenes/gallery").glob("*.toml"))
        if p.stem not in LONG
    ]
    work = pathlib.Path(args.workdir)
    work.mkdir(parents=True, exist_ok=True)
    failed = False
    for scene in scenes:
        files = []
        for label, binary in (("old", args.old), ("new", args.new)):
            out = work / f"{label}-{scene.stem}.h5"
            run = subprocess.run(
                [str(pathlib.Path(binary).resolve()), "-q", "run", scene.name, "--output", str(out), "--force"],
                cwd=scene.parent, capture_output=True, text=True,
            )
            files.append((out, run.returncode, run.stderr.strip().splitlines()[-1:] ))
        codes = [f[1] for f in files]
        if any(codes):
            same = codes[0] == codes[1] and files[0][2] == files[1][2]
            print(f"{scene.stem}: both runs stop with the same error" if same else f"{scene.stem}: runs end differently {files}")
            failed |= not same
            continue
        with h5py.File(files[0][0]) as a, h5py.File(files[1][0]) as b:
            diff = differences(a, b)
        print(f"{scene.stem}: identical" if not diff else f"{scene.stem}: DIFFERS {diff[:8]}")
        failed |= bool(diff)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
