#!/usr/bin/env python3
"""Compares two icefem binaries on the shipped scenes: bit-for-bit results and run times.

    same_results.py OLD_BINARY NEW_BINARY [--scenes S1.toml S2.toml ...] [--workdir DIR]
                    [--timing N]

Each scene is run once with each binary (`icefem -q run SCENE --output DIR/old/NAME.h5
--force`, the same for new). Every dataset and every attribute of the two files, in all groups
(also those reached through hard links), is then compared bit for bit: same dtype, same shape,
same bytes. A difference is reported per dataset with the largest absolute difference and that
difference relative to the dataset's largest absolute value; across frames, one line per field
(`/frames/*/NAME`) gives the first differing frame and the largest difference over frames.
Objects present in only one file are differences. Wall-clock timings and the attributes that
name a path or a version (EXCLUDED_* below) are left out, and the script says which.

Scene files name their meshes (and `[initial] file`) relative to the scene file, so each
scene is copied into DIR/old and DIR/new and the files it names are linked beside it. An
`[initial] file` that is not beside the scene is taken from the same folder, where an earlier
scene of the list writes it: beam_released.toml reads the beam_bent.h5 that the same binary
wrote, so beam_bent.toml must come before it in --scenes.

--timing N then runs each scene N more times, alternating old, new, old, new, ..., and prints
the median wall time of each binary and their ratio.

Run both binaries on the same machine with the same threads: freezing_container_1e5 (a
single-precision Cholesky factor kept as CG's preconditioner) gives other bits with
RAYON_NUM_THREADS=1 than with 2, though the same bits run after run at a given count.

Exit code 0 when every scene gives identical files, 1 otherwise (also when a run fails).
Needs h5py and numpy.
"""

import argparse
import re
import shutil
import statistics
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import h5py
import numpy as np

REPO = Path(__file__).resolve().parent.parent

# The scenes that run in under 5 minutes with the release build, in the order they are run
# (beam_bent before beam_released, which starts from its result), with the wall time of one
# run on 2 cores shared with two compilations (load average 2.5-6, so the times are long and
# noisy). Left out: scenes/freezing_container_fine.toml, over 5 minutes (stopped at 300 s at
# t = 27.3 s of its 80 s).
DEFAULT_SCENES = [
    "scenes/cantilever.toml",                         #   1.7 s
    "scenes/drop_into_container.toml",                #   0.5 s
    "scenes/freezing_container.toml",                 #   3.3 s
    "scenes/freezing_container_1e5.toml",             # 152 s
    "scenes/freezing_container_fracture.toml",        #   9.3 s
    "scenes/freezing_container_fracture_1728.toml",   #  86 s
    "scenes/freezing_container_thermal.toml",         #   0.9 s
    "scenes/pulled_bar.toml",                         #   0.5 s
    "scenes/slide_down_ramp.toml",                    #   0.7 s
    "scenes/stacked_cubes.toml",                      #   1.1 s
    "scenes/static_block.toml",                       #   0.05 s
    "scenes/gallery/beam_bent.toml",                  #   0.08 s
    "scenes/gallery/beam_released.toml",              #   3.1 s
    "scenes/gallery/thrown_cube_paddle.toml",         #   1.9 s
    "scenes/gallery/two_material_block.toml",         #   0.8 s
    "scenes/gallery/water_sphere_in_cup.toml",        #  28 s
    "scenes/gallery/water_sphere_thermal.toml",       #   3.3 s
    "scenes/gallery/glass_column.toml",               #  33 s
    "scenes/gallery/bottle_thermal.toml",             #  10 s
    "scenes/gallery/ball_cracking_in_cup.toml",       # 120 s
]

# /stats columns that hold wall-clock seconds (docs/output.md): they differ from run to run.
# `time` (simulated time, s) and `dt` are results and are compared.
EXCLUDED_STATS = {
    "t_assembly", "t_factorization", "t_solve", "t_step",
    "t_fracture", "t_remesh", "t_resolve", "t_heat",
}
# Root attributes that are not results: the scene file's absolute path (each binary's copy
# lies in its own folder) and the version string of the binary. `scene` (the scene's text) and
# `format_version` (the file layout) are compared. No attribute holds a date or a host name.
EXCLUDED_ROOT_ATTRS = {"scene_path", "icefem_version"}

FRAME = re.compile(r"^/frames/\d+(?=[/@])")


def stage(scene, folder):
    """Copy `scene` into `folder` and link the files it names beside the copy."""
    folder.mkdir(parents=True, exist_ok=True)
    copy = folder / scene.name
    shutil.copyfile(scene, copy)

    def named_files(node):
        if isinstance(node, dict):
            for key, value in node.items():
                if key == "file" and isinstance(value, str):
                    yield value
                else:
                    yield from named_files(value)
        elif isinstance(node, list):
            for item in node:
                yield from named_files(item)

    for name in named_files(tomllib.loads(scene.read_text())):
        source = (scene.parent / name).resolve()
        link = folder / name
        if source.suffix != ".h5" and source.exists():
            link.parent.mkdir(parents=True, exist_ok=True)
            link.unlink(missing_ok=True)
            link.symlink_to(source)
    return copy


def run(binary, scene, output, timeout=None):
    """Run one scene; return (wall seconds, None) or (wall seconds, error message)."""
    output.unlink(missing_ok=True)
    command = [str(binary), "-q", "run", str(scene), "--output", str(output), "--force"]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return time.perf_counter() - start, f"killed after {timeout} s"
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        tail = (done.stderr.strip() or done.stdout.strip()).splitlines()[-1:] or [""]
        return seconds, f"exit code {done.returncode}: {tail[0]}"
    return seconds, None


def objects(f):
    """Every group and dataset of an open file by path, hard links included ({path: object})."""
    found = {"/": f}

    def walk(group, prefix):
        for name in group:
            obj = group[name]
            path = prefix + name
            found[path] = obj
            if isinstance(obj, h5py.Group):
                walk(obj, path + "/")

    walk(f, "/")
    return found


def same_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return False
    if a.dtype.kind == "O":  # variable-length strings
        return a.tolist() == b.tolist()
    return a.tobytes() == b.tobytes()


def difference(a, b):
    """Describe how two unequal values differ: (max abs diff, relative) or a sentence."""
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype != b.dtype or a.shape != b.shape:
        return f"{a.dtype}{list(a.shape)} vs {b.dtype}{list(b.shape)}"
    if a.dtype.kind not in "biuf":
        return "values differ"
    a, b = a.astype(np.float64), b.astype(np.float64)
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    if (nan_a != nan_b).any():
        return f"NaN in {nan_a.sum()} vs {nan_b.sum()} values"
    both = ~nan_a
    diff = np.abs(a[both] - b[both])
    if diff.size == 0 or diff.max() == 0:  # only the bits of NaNs or the sign of zeros differ
        return "equal values, different bits (NaN payload or signed zero)"
    scale = np.abs(a[both]).max()
    return diff.max(), (diff.max() / scale if scale > 0 else np.inf), int((diff > 0).sum())


def compare(old_file, new_file):
    """Return ({path: difference}, [excluded paths]) for two output files."""
    diffs, excluded = {}, []
    with h5py.File(old_file, "r") as fo, h5py.File(new_file, "r") as fn:
        old, new = objects(fo), objects(fn)
        for path in sorted(old.keys() | new.keys()):
            if path.startswith("/stats/") and path[len("/stats/"):] in EXCLUDED_STATS:
                excluded.append(path)
                continue
            if path not in new or path not in old:
                diffs[path] = "only in " + ("old" if path in old else "new")
                continue
            o, n = old[path], new[path]
            if isinstance(o, h5py.Dataset) != isinstance(n, h5py.Dataset):
                diffs[path] = "a dataset in one file, a group in the other"
                continue
            if isinstance(o, h5py.Dataset) and not same_bits(o[()], n[()]):
                diffs[path] = difference(o[()], n[()])
            for name in sorted(o.attrs.keys() | n.attrs.keys()):
                where = f"{path}@{name}"
                if path == "/" and name in EXCLUDED_ROOT_ATTRS:
                    excluded.append(where)
                elif name not in n.attrs or name not in o.attrs:
                    diffs[where] = "only in " + ("old" if name in o.attrs else "new")
                elif not same_bits(o.attrs[name], n.attrs[name]):
                    diffs[where] = difference(o.attrs[name], n.attrs[name])
    return diffs, excluded


def report(diffs):
    """Lines describing the differences, frames folded into one line per field."""
    fields = {}
    for path, what in diffs.items():
        fields.setdefault(FRAME.sub("/frames/*", path), []).append((path, what))
    lines = []
    for field, items in fields.items():
        numeric = [w for _, w in items if isinstance(w, tuple)]
        if numeric:
            worst = max(w[0] for w in numeric)
            rel = max(w[1] for w in numeric)
            what = f"max abs diff {worst:.3g}, relative to max abs value {rel:.3g}"
            if len(items) == 1:
                what += f", {numeric[0][2]} values differ"
        else:
            what = items[0][1]
        if len(items) == 1:
            field = items[0][0]
        else:
            what = f"differs in {len(items)} frames, the first {items[0][0]}: {what}"
        lines.append(f"  {field}: {what}")
    return lines


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("old", type=Path, help="the reference icefem binary")
    parser.add_argument("new", type=Path, help="the icefem binary to check")
    parser.add_argument("--scenes", nargs="+", type=Path,
                        default=[REPO / s for s in DEFAULT_SCENES])
    parser.add_argument("--workdir", type=Path, default=Path("same_results"))
    parser.add_argument("--timing", type=int, default=0, metavar="N",
                        help="also run each scene N times per binary, alternating, and "
                             "print the median wall times")
    args = parser.parse_args()
    binaries = {"old": args.old.resolve(), "new": args.new.resolve()}
    scenes = [s.resolve() for s in args.scenes]
    names = [s.stem for s in scenes]
    if len(set(names)) != len(names):
        sys.exit("two scenes have the same file name; outputs would collide")
    workdir = args.workdir.resolve()

    print("excluded from the comparison: /stats columns " + ", ".join(sorted(EXCLUDED_STATS))
          + "; root attributes " + ", ".join(sorted(EXCLUDED_ROOT_ATTRS)))
    summary = []
    all_identical = True
    for scene, name in zip(scenes, names):
        print(f"\n{name}")
        seconds, failed = {}, []
        for side, binary in binaries.items():
            copy = stage(scene, workdir / side)
            seconds[side], error = run(binary, copy, workdir / side / f"{name}.h5")
            print(f"  {side}: {seconds[side]:.1f} s" + (f", FAILED ({error})" if error else ""))
            if error:
                failed.append(side)
        if failed:
            result = " and ".join(failed) + " run failed"
        else:
            diffs, excluded = compare(workdir / "old" / f"{name}.h5",
                                      workdir / "new" / f"{name}.h5")
            print(f"  excluded: {len(excluded)} ("
                  + ", ".join(p.rsplit("/", 1)[-1] for p in excluded) + ")")
            if diffs:
                result = f"{len(diffs)} datasets/attributes differ"
                print("\n".join(report(diffs)))
            else:
                result = "identical"
        print(f"  {result}")
        all_identical &= result == "identical"
        summary.append((scene, name, result, seconds["old"], seconds["new"]))

    width = max(len(n) for n in names)
    print(f"\n{'scene':{width}}  {'old s':>7}  {'new s':>7}  result")
    for _, name, result, t_old, t_new in summary:
        print(f"{name:{width}}  {t_old:7.1f}  {t_new:7.1f}  {result}")

    if args.timing > 0:
        print(f"\ntiming: {args.timing} runs per binary, alternating old and new")
        print(f"{'scene':{width}}  {'median old s':>12}  {'median new s':>12}  {'new/old':>7}")
        for scene, name, result, _, _ in summary:
            if result.endswith("failed"):
                print(f"{name:{width}}  {'(run failed)':>12}")
                continue
            times = {"old": [], "new": []}
            for _ in range(args.timing):
                for side, binary in binaries.items():
                    copy = workdir / side / scene.name
                    t, error = run(binary, copy, workdir / side / f"timing_{name}.h5")
                    if error:
                        sys.exit(f"{name}: {side} run failed during timing ({error})")
                    times[side].append(t)
            t_old, t_new = statistics.median(times["old"]), statistics.median(times["new"])
            print(f"{name:{width}}  {t_old:12.2f}  {t_new:12.2f}  {t_new / t_old:7.3f}")

    sys.exit(0 if all_identical else 1)


if __name__ == "__main__":
    main()
