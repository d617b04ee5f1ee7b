#!/usr/bin/env python3
"""Users' fracture scenes on Gmsh meshes and their variants, run with one or more icefem binaries.

    users_fracture.py BINARY [BINARY ...] [--workdir DIR] [--markdown FILE] [--end-time T]
                      [--only NAME ...]

Builds variants of three gallery scenes (scenes/gallery/glass_column.toml,
ball_cracking_in_cup.toml and bottle_thermal.toml; VARIANTS below): as shipped, another
fracture toughness, another plastic elastic limit, the ball meshed finer, the column without
its glass and without gravity. Each variant is written as DIR/scenes/NAME.toml (DIR:
./users_fracture), the shipped text with the changed lines substituted, comments kept, and a
first comment line saying what changed; the meshes it names are copied beside it. The finer
ball, DIR/scenes/water_sphere_fine.msh, is scenes/gallery/make_meshes.py's water_sphere() at
Gmsh size 0.009 instead of 0.012; without gmsh that variant is left out, with a note.

Each variant is then run once with each binary by validation/newton_iterations.py's measure
(staged into DIR/runs/<binary index>/, output NAME.h5 there), one line printed per run as it
ends, and a markdown table printed: per variant and binary, whether the run reached its end
(or the time of its last step and the error it stopped with), steps, Newton iterations per
step (median / 99th percentile / largest), steps halved, elements and crack polygons after
the last step (`/stats/elements`, `/stats/crack_polygons`) and the wall time. With
--markdown the table is also written to FILE under a short header (the command line, the
machine's cores and load).

--end-time T sets every variant's `end_time` to T, or to two of its steps if that is longer
(the bottle's steps are 60 s: --end-time 0.5 runs it to 120 s), for quick checks.
--only NAME ... runs only the named variants.

Exit code 0 when every run reached its end, 1 otherwise.
Needs h5py and numpy; gmsh (with make_meshes.py's meshio) for ball_in_cup_fine.
"""

import argparse
import os
import re
import shlex
import shutil
import sys
import tomllib
from pathlib import Path

import h5py

sys.path.insert(0, str(Path(__file__).resolve().parent))
from same_results import REPO  # noqa: E402
from newton_iterations import measure  # noqa: E402

GALLERY = REPO / "scenes" / "gallery"
FINE = "ball_in_cup_fine"
FINE_SIZE = 0.009  # make_meshes.water_sphere() uses 0.012
FINE_MESH = "water_sphere_fine.msh"


def toughness(value):
    """The edit of `[fracture] toughness` (the line's comment kept)."""
    return r"^toughness = \S+", f"toughness = {value}"


def elastic_limit(value):
    """The edit of `[plasticity] elastic_limit = 3e-5`."""
    return r"^elastic_limit = 3e-5$", f"elastic_limit = {value}"


# The [[obstacle]] table: its header line, the lines up to the next blank line or table.
NO_OBSTACLE = r"^\[\[obstacle\]\].*\n(?:[^\[\n].*\n)*\n?", ""
NO_GRAVITY = r"^gravity = \[0\.0, 0\.0, -9\.81\]", "gravity = [0.0, 0.0, 0.0]"
FINE_BODY = (r'^file = "water_sphere\.msh".*$',
             f'file = "{FINE_MESH}"  # make_meshes.water_sphere() at Gmsh size {FINE_SIZE}')

# name: (gallery scene, what changed, [(regular expression of one line, its replacement)])
VARIANTS = {
    "glass_column": ("glass_column.toml", "as shipped", []),
    "glass_column_t1.2": ("glass_column.toml", "toughness 1.2e6 Pa (shipped 1.5e6)",
                          [toughness("1.2e6")]),
    "glass_column_y1e-4": ("glass_column.toml", "elastic_limit 1e-4 (shipped 3e-5)",
                           [elastic_limit("1e-4")]),
    "column_free": ("glass_column.toml", "no [[obstacle]] (the glass), gravity 0: a free column",
                    [NO_OBSTACLE, NO_GRAVITY]),
    "ball_in_cup": ("ball_cracking_in_cup.toml", "as shipped", []),
    "ball_in_cup_t1.2": ("ball_cracking_in_cup.toml", "toughness 1.2e6 Pa (shipped 1.5e6)",
                         [toughness("1.2e6")]),
    "ball_in_cup_t2.0": ("ball_cracking_in_cup.toml", "toughness 2.0e6 Pa (shipped 1.5e6)",
                         [toughness("2.0e6")]),
    "ball_in_cup_y1e-4": ("ball_cracking_in_cup.toml", "elastic_limit 1e-4 (shipped 3e-5)",
                          [elastic_limit("1e-4")]),
    "ball_in_cup_y1e-5": ("ball_cracking_in_cup.toml", "elastic_limit 1e-5 (shipped 3e-5)",
                          [elastic_limit("1e-5")]),
    FINE: ("ball_cracking_in_cup.toml",
           f"ball meshed at Gmsh size {FINE_SIZE}: {{tets}} tets (shipped 0.012: 969)",
           [FINE_BODY]),
    "bottle": ("bottle_thermal.toml", "as shipped", []),
    "bottle_t1.2": ("bottle_thermal.toml", "toughness 1.2e6 Pa (shipped 2e6)",
                    [toughness("1.2e6")]),
}


def fine_sphere(path):
    """Write make_meshes.water_sphere()'s ball at FINE_SIZE to `path`; its tets, or None
    (with a printed note) when gmsh or the other modules make_meshes.py needs cannot be
    imported."""
    sys.path.insert(0, str(GALLERY))
    try:
        import gmsh
        import make_meshes
    except (ImportError, OSError) as error:  # OSError: gmsh's shared library or its deps
        print(f"note: {FINE} left out, make_meshes.py cannot be imported ({error})", flush=True)
        return None
    finally:
        sys.path.remove(str(GALLERY))
    # water_sphere() itself, its size and file swapped: the same construction, no copy of it
    begin, finish = make_meshes.begin, make_meshes.finish
    tets = []

    def finish_here(name):
        tets.append(len(gmsh.model.mesh.getElementsByType(4)[0]))
        finish(str(path.resolve()))  # absolute: os.path.join(HERE, name) keeps it

    make_meshes.begin = lambda name, size: begin(name + "_fine", FINE_SIZE)
    make_meshes.finish = finish_here
    try:
        make_meshes.water_sphere()
    finally:
        make_meshes.begin, make_meshes.finish = begin, finish
    return tets[0]


def substitute(text, pattern, replacement, name):
    """`text` with the one line matching `pattern` replaced; exits if not exactly one matches."""
    new, count = re.subn(pattern, lambda _: replacement, text, flags=re.MULTILINE)
    if count != 1:
        sys.exit(f"{name}: {count} lines match {pattern!r} in the shipped scene, not one")
    return new


def write_variant(name, what, folder, end_time):
    """Write variant `name` (`what` changed) into `folder` with the meshes it names; its path."""
    source, _, edits = VARIANTS[name]
    text = (GALLERY / source).read_text()
    for pattern, replacement in edits:
        text = substitute(text, pattern, replacement, name)
    if end_time is not None:
        shipped = tomllib.loads(text)["time"]
        end = max(end_time, 2 * shipped["dt"])
        text = substitute(text, r"^end_time = .*$", f"end_time = {end!r}  # users_fracture.py "
                          f"--end-time {end_time:g} (shipped {shipped['end_time']!r})", name)
    text = (f"# users_fracture.py variant {name} of scenes/gallery/{source}: {what}.\n"
            + text)
    scene = tomllib.loads(text)  # the edited text must still parse
    for table in scene.get("body", []) + scene.get("obstacle", []):
        mesh = table["file"]
        if (GALLERY / mesh).exists():
            shutil.copyfile(GALLERY / mesh, folder / mesh)
        elif not (folder / mesh).exists():
            sys.exit(f"{name}: mesh {mesh} neither in scenes/gallery nor in {folder}")
    path = folder / f"{name}.toml"
    path.write_text(text)
    return path


def last_row(output):
    """(time, elements, crack polygons) after the last step in `output`, None when unknown."""
    if not output.exists():
        return None, None, None
    with h5py.File(output, "r") as f:
        stats = f.get("stats", {})
        return tuple(stats[c][-1].item() if c in stats and len(stats[c]) else None
                     for c in ("time", "elements", "crack_polygons"))


def cells(r):
    """The table's cells of one run, from measure's row with last_row's columns added."""
    if r["error"] is None:
        end = "yes"
    elif r["time"] is None:
        end = f"stopped before its first step ({r['error']})"
    else:
        end = f"stopped at t = {r['time']:g} s ({r['error']})"
    if "steps" in r:
        stats = [r["steps"], f"{r['median']:g} / {r['p99']:.0f} / {r['max']}", r["halved"]]
    else:
        stats = ["–", "–", "–"]
    unknown = lambda value: "–" if value is None else value
    return [end.replace("|", "/"), *stats, unknown(r["elements"]),
            unknown(r["crack_polygons"]), f"{r['wall']:.1f}"]


def table(rows):
    """The markdown table of `rows`: [(variant, what changed, binary, measured row)]."""
    lines = [
        "| variant | what changed | binary | reached the end | steps | "
        "iterations median / p99 / max | halved steps | elements at the end | "
        "crack polygons at the end | wall (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, what, binary, r in rows:
        lines.append("| " + " | ".join(str(c) for c in [name, what, binary, *cells(r)]) + " |")
    return "\n".join(lines)


def header(args):
    command = [Path(sys.argv[0]).resolve()] + sys.argv[1:]
    if command[0].is_relative_to(REPO):
        command[0] = command[0].relative_to(REPO)
    end = (f" Each scene's `end_time` set to {args.end_time:g} s or two of its steps if longer "
           "(`--end-time`)." if args.end_time is not None else "")
    return (
        "# Users' fracture scenes on Gmsh meshes and their variants\n\n"
        "Gallery scenes (scenes/gallery: glass_column, ball_cracking_in_cup, bottle_thermal) "
        "and variants of them\n(another toughness or elastic limit, a finer ball, the column "
        "without glass or gravity), each run once\nper binary; Newton iterations per step from "
        "`/stats/newton_iterations`, elements and crack polygons\nafter the last step from "
        f"`/stats/elements` and `/stats/crack_polygons`.{end}\n\n"
        f"Command: `{shlex.join(str(c) for c in command)}`\n\n"
        f"Machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start.\n\n"
    )


def main():
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n")[0],
        epilog="variants: " + ", ".join(VARIANTS))
    parser.add_argument("binaries", nargs="+", type=Path)
    parser.add_argument("--workdir", type=Path, default=Path("users_fracture"), metavar="DIR",
                        help="where the variants, meshes and outputs go (default: "
                             "./users_fracture)")
    parser.add_argument("--markdown", type=Path, metavar="FILE",
                        help="also write the table to FILE, under a short header")
    parser.add_argument("--end-time", type=float, metavar="T",
                        help="set every scene's end_time to T s, or to two of its steps if "
                             "that is longer (the bottle's steps are 60 s: it runs to 120 s "
                             "for T < 120), for quick checks")
    parser.add_argument("--only", nargs="+", metavar="NAME", choices=list(VARIANTS),
                        help="run only these variants")
    args = parser.parse_args()
    names = [n for n in VARIANTS if args.only is None or n in args.only]
    workdir = args.workdir.resolve()  # the runs' working directory is the repository
    scenes = workdir / "scenes"
    scenes.mkdir(parents=True, exist_ok=True)
    top = header(args)  # the load average before the runs

    tets = None
    if FINE in names:
        tets = fine_sphere(scenes / FINE_MESH)
        if tets is None:
            names.remove(FINE)
        else:
            print(f"{FINE_MESH}: {tets} tets", flush=True)
    whats = {name: VARIANTS[name][1].format(tets=tets) for name in names}
    variants = {name: (write_variant(name, whats[name], scenes, args.end_time), whats[name])
                for name in names}

    rows = []
    for name, (scene, what) in variants.items():
        for b, binary in enumerate(args.binaries):
            folder = workdir / "runs" / str(b)
            r = measure(binary.resolve(), scene, folder)
            r.update(zip(("time", "elements", "crack_polygons"),
                         last_row(folder / (scene.stem + ".h5"))))
            rows.append((name, what, binary, r))
            print(f"{name} [{binary}]: " + ", ".join(
                f"{h} {c}" for h, c in zip(("reached the end", "steps", "iterations", "halved",
                                           "elements", "crack polygons", "wall s"), cells(r))),
                  flush=True)
    text = table(rows)
    print(text, flush=True)
    if args.markdown:
        args.markdown.write_text(top + text + "\n")
    return 0 if all(r["error"] is None for *_, r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
