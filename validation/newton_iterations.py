#!/usr/bin/env python3
"""Newton iterations per step of the shipped scenes, for one or more icefem binaries.

    newton_iterations.py BINARY [BINARY ...] [--scenes S1.toml ...] [--workdir DIR]
                         [--markdown FILE]

Runs each scene once with each binary (staged as validation/same_results.py stages it: the
scene copied into DIR/<binary index>/ (DIR: ./newton_iterations), the files it names linked
beside it) and prints, per scene and binary, the Newton iterations per step read from
`/stats/newton_iterations` — median, 99th percentile, maximum and total — with the number of steps, Newton solves,
factorisations, steps solved in more than one substep (halved), the wall time of the run,
and the error message of a run that stopped. With --markdown the table is also written to FILE.

The default scene list is same_results.py's (the shipped scenes that run in under 5
minutes), water_sphere_in_cup and the two 1e5/1728 containers included.
Needs h5py and numpy.
"""

import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from same_results import DEFAULT_SCENES, REPO, run, stage  # noqa: E402


HEADER = """# Newton iterations per step of the shipped scenes

Written by `validation/newton_iterations.py BINARY --markdown FILE` (one run per scene, on the
machine that ran it: 2 cores for the committed file). Iterations per step from
`/stats/newton_iterations`: median / 99th percentile / largest, and the total; "solves" counts
Newton solves (re-solves after friction's re-lag included), "halved steps" the steps retried
at dt/2 or less. `solver_tests/newton_iterations.rs` bounds thirteen of these rows.

"""


def measure(binary, scene, folder):
    """Run `scene` with `binary` in `folder`; the row of the table as a dict."""
    copy = stage(scene, folder)
    output = folder / (scene.stem + ".h5")
    wall, error = run(binary, copy, output)
    row = {"wall": wall, "error": error}
    if not output.exists():
        return row
    with h5py.File(output, "r") as f:
        stats = f["stats"]
        if "newton_iterations" not in stats or len(stats["newton_iterations"]) == 0:
            return row
        its = stats["newton_iterations"][:]
        column = lambda name: int(stats[name][:].sum()) if name in stats else 0
        row.update(
            steps=len(its),
            median=float(np.median(its)),
            p99=float(np.percentile(its, 99)),
            max=int(its.max()),
            total=int(its.sum()),
            solves=column("newton_solves"),
            factorizations=column("factorizations"),
            halved=int((stats["substeps"][:] > 1).sum()) if "substeps" in stats else 0,
        )
    return row


def table(scenes, binaries, rows):
    """The markdown table of `rows[(scene, binary)]`."""
    lines = [
        "| scene | binary | steps | iterations median / p99 / max | total | solves | "
        "factorisations | halved steps | wall (s) | stopped with |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for scene in scenes:
        for b, binary in enumerate(binaries):
            r = rows[(scene, b)]
            name = scene.relative_to(REPO) if scene.is_relative_to(REPO) else scene
            if "steps" in r:
                stats = (
                    f"{r['steps']} | {r['median']:g} / {r['p99']:.0f} / {r['max']} | "
                    f"{r['total']} | {r['solves']} | {r['factorizations']} | {r['halved']}"
                )
            else:
                stats = "– | – | – | – | – | –"
            error = (r["error"] or "").replace("|", "/")
            lines.append(f"| {name} | {binary} | {stats} | {r['wall']:.1f} | {error} |")
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("binaries", nargs="+", type=Path)
    parser.add_argument("--scenes", nargs="+", type=Path)
    parser.add_argument("--workdir", type=Path, default=Path("newton_iterations"))
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args()
    scenes = [s.resolve() for s in args.scenes] if args.scenes else [REPO / s for s in DEFAULT_SCENES]
    rows = {}
    for scene in scenes:
        for b, binary in enumerate(args.binaries):
            rows[(scene, b)] = measure(binary.resolve(), scene, args.workdir / str(b))
            r = rows[(scene, b)]
            print(f"{scene.name} [{binary}]: {r.get('median', '-')} / {r.get('max', '-')} "
                  f"in {r['wall']:.1f} s {r['error'] or ''}", file=sys.stderr)
    text = table(scenes, args.binaries, rows)
    print(text)
    if args.markdown:
        args.markdown.write_text(HEADER + text + "\n")
    return 0 if all(r["error"] is None for r in rows.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
