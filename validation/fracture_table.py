#!/usr/bin/env python3
"""The fracture measures of an icefem run, from its HDF5 file, beside the paper's values.

    validation/.venv/bin/python validation/fracture_table.py RUN.h5 [RUN2.h5 ...] [--json]
    validation/.venv/bin/python validation/fracture_table.py --compare A.h5 B.h5 [--json]

Per file: elements, crack triangles, crack polygons and crack area at steps 1200 and 2400 (the
frame whose `step` is that, or the last one before), their growth, the onset of fracture, how
far the flowing (plastically deforming) elements' von Mises stress is from the yield stress,
the fracture-criterion columns of /stats when the file has them, and the wall time.
`--compare` adds the mesh-dependence measures of two runs of one scene.

Crack faces are rebuilt from each frame's `tets`, `rest_positions` and `origin` as icefem
builds them (src/fracture/cracks.rs): boundary faces of the current mesh that do not lie on a
boundary face of their scene element. Their count equals the rows of `cracks/triangles`.
"""
import argparse
import json
import sys
import tomllib

import h5py
import numpy as np

PAPER = {"elements": (215, 238), "crack_polygons": (35, 74), "polygon_growth": 2.1}
STEPS = (1200, 2400)
# Faces of a tetrahedron (a, b, c, d): the one opposite each vertex.
TET_FACES = np.array([[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]])


# ---------------------------------------------------------------- geometry

def tet_volumes(x, tets):
    """Unsigned volumes of tetrahedra `tets` over points `x` (m³)."""
    p = x[tets]
    return np.abs(np.einsum("ij,ij->i", p[:, 1] - p[:, 0],
                            np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))) / 6.0


def triangle_areas(p):
    """Areas of triangles p[t, 3, 3] (m²)."""
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


def boundary_faces(tets):
    """Faces (node triples) that belong to one tetrahedron only, that tetrahedron, and its
    vertex opposite the face."""
    faces = tets[:, TET_FACES].reshape(-1, 3)
    owner = np.repeat(np.arange(len(tets)), 4)
    _, index, counts = np.unique(np.sort(faces, axis=1), axis=0, return_index=True,
                                 return_counts=True)
    once = index[counts == 1]
    return faces[once], owner[once], tets.reshape(-1)[once]


class SceneBoundary:
    """The boundary planes of the scene's mesh, per scene element (up to four each)."""

    def __init__(self, rest, tets):
        faces, owner, _ = boundary_faces(tets)
        p = rest[faces]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        normal /= np.linalg.norm(normal, axis=1)[:, None]
        slot = np.zeros(len(faces), dtype=int)  # rank of each face among its element's
        order = np.argsort(owner, kind="stable")
        first = np.searchsorted(owner[order], owner[order])
        slot[order] = np.arange(len(faces)) - first
        self.point = np.full((len(tets), 4, 3), np.nan)
        self.normal = np.full((len(tets), 4, 3), np.nan)
        self.point[owner, slot] = p[:, 0]
        self.normal[owner, slot] = normal
        self.tolerance = 1e-9 * np.linalg.norm(rest.max(0) - rest.min(0))

    def contains(self, origin, points):
        """Whether each rest triangle points[t, 3, 3], lying in scene element origin[t], is on
        a boundary face of that element (all three points on one of its planes)."""
        d = np.einsum("tkjc,tkc->tkj", points[:, None, :, :] - self.point[origin][:, :, None, :],
                      self.normal[origin])
        return (np.abs(d) <= self.tolerance).all(axis=2).any(axis=1)


def crack_faces(frame, scene_boundary):
    """Rest-position triangles [t, 3, 3] of a frame's crack faces (both sides) and their unit
    normals pointing out of their element; None if the frame has no `origin` (no fracture)."""
    if "origin" not in frame:
        return None
    rest, tets = frame["rest_positions"][:], frame["tets"][:]
    origin = frame["origin"][:].astype(int)
    faces, owner, opposite = boundary_faces(tets)
    crack = ~scene_boundary.contains(origin[owner], rest[faces])
    points = rest[faces[crack]]
    normal = np.cross(points[:, 1] - points[:, 0], points[:, 2] - points[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    inward = np.einsum("ij,ij->i", normal, rest[opposite[crack]] - points[:, 0]) > 0
    normal[inward] *= -1
    return points, normal


def vertex_keys(points):
    """Each triangle's rest vertices sorted lexicographically, as a row of 9 numbers: equal
    for the two sides of a face, whose split nodes share their rest positions bit for bit."""
    order = np.lexsort(points.transpose(2, 0, 1)[::-1], axis=-1)
    return np.take_along_axis(points, order[:, :, None], axis=1).reshape(len(points), 9)


def overlapping(p, n, tolerance):
    """[t, t] whether coplanar triangles p[t, 3, 3] (unit normals n) overlap with interiors:
    all of one's vertices on the other's plane and no separating axis among their edge
    normals in that plane."""
    offset = np.einsum("ic,ic->i", p[:, 0], n)
    coplanar = (np.abs(np.einsum("jvc,ic->ijv", p, n) - offset[:, None, None])
                <= tolerance).all(axis=2)
    axis = np.cross(n[:, None, :], np.roll(p, -1, axis=1) - p)
    axis /= np.linalg.norm(axis, axis=2)[:, :, None]
    other = np.einsum("jvc,ikc->ijkv", p, axis)  # triangle j on triangle i's axes
    own = np.einsum("ivc,ikc->ikv", p, axis)[:, None]
    apart = ((other.max(3) <= own.min(3) + tolerance)
             | (own.max(3) <= other.min(3) + tolerance)).any(axis=2)
    return coplanar & ~(apart | apart.T) & ~np.eye(len(p), dtype=bool)


def count_polygons(points, normal, tolerance):
    """Crack polygons, every crack face counted once: (polygons, pairs).

    The two sides of a crack face are separate triangles. Split nodes keep their rest
    position, so the two sides of a face coincide at rest: such a pair counts once. Where a
    later split subdivided the elements on one side of a face, or both sides differently,
    the sides' triangles differ: the unpaired triangles are grouped into regions (connected
    through coplanar triangles that overlap), and a region counts as many polygons as its
    side with fewer triangles has (its two sides have equal areas)."""
    _, inverse, counts = np.unique(vertex_keys(points), axis=0, return_inverse=True,
                                   return_counts=True)
    single = counts[inverse.ravel()] == 1
    pairs = int((counts >= 2).sum())
    p, n = points[single], normal[single]
    overlap = overlapping(p, n, tolerance)
    label = np.arange(len(p))
    while True:  # connected components: each triangle takes the smallest label it overlaps
        smallest = np.where(overlap, label[None, :], len(p)).min(axis=1, initial=len(p))
        new = np.minimum(label, smallest)
        if np.array_equal(new, label):
            break
        label = new
    polygons = pairs
    for region in np.unique(label):
        side = n[label == region] @ n[label == region][0] > 0
        polygons += int(min(side.sum(), (~side).sum()) or len(side))
    return polygons, pairs


# ---------------------------------------------------------------- one run

def complete_frames(f):
    """The file's complete frames as (step, group), by step."""
    groups = [g for g in f["frames"].values() if g.attrs.get("complete", 1)]
    return sorted(((int(g.attrs["step"]), g) for g in groups), key=lambda sg: sg[0])


def frame_at(frames, step):
    """The frame whose step is `step`, else the last one before it."""
    before = [sg for sg in frames if sg[0] <= step]
    return before[-1] if before else frames[0]


def yield_stress(scene, freeze_state):
    """σ_y = sqrt(3/2)·2·μ_s·γ per element (Pa), μ_s = s μ + (1 − s) μ_w."""
    material, freezing = scene["material"], scene.get("freezing", {})
    if "mu" in material:
        mu = material["mu"]
    else:
        mu = material["youngs_modulus"] / (2.0 * (1.0 + material["poisson_ratio"]))
    water = freezing.get("water_shear_modulus", freezing.get("water_shear", 1e-4 * mu))
    mu_s = freeze_state * mu + (1.0 - freeze_state) * water
    return np.sqrt(1.5) * 2.0 * mu_s * scene["plasticity"]["elastic_limit"]


def voigt_norm(v):
    """Frobenius norm of symmetric tensors in Voigt rows xx yy zz yz xz xy."""
    return np.sqrt((v[:, :3] ** 2).sum(1) + 2.0 * (v[:, 3:] ** 2).sum(1))


def von_mises(stress):
    """sqrt(3/2)·‖dev σ‖_F of Voigt rows (Pa)."""
    dev = stress.copy()
    dev[:, :3] -= stress[:, :3].mean(1, keepdims=True)
    return np.sqrt(1.5) * voigt_norm(dev)


def freeze_state(g):
    """Freeze state per element of frame g: 1 (ice) everywhere without [freezing]."""
    return g["freeze_state"][:] if "freeze_state" in g else np.ones(len(g["tets"]))


def frame_measures(g, boundary, polygons=True):
    """Elements, crack triangles and polygons, one-side crack area (m²), frozen and total
    rest volume (m³) of frame group g."""
    volume = tet_volumes(g["rest_positions"][:], g["tets"][:])
    m = {"step": int(g.attrs["step"]), "elements": len(volume),
         "frozen_volume": float(freeze_state(g) @ volume), "volume": float(volume.sum())}
    faces = crack_faces(g, boundary)
    if faces is None and "cracks" in g:  # no origin: the drawn (current) triangles
        v = g["cracks/vertices"][:]
        faces = (v[g["cracks/triangles"][:]], None)
    points, normal = faces if faces is not None else (np.zeros((0, 3, 3)), np.zeros((0, 3)))
    m["crack_triangles"] = len(g["cracks/triangles"]) if "cracks" in g else 0
    if len(points) != m["crack_triangles"]:
        print(f"warning: step {m['step']}: {len(points)} crack faces rebuilt, "
              f"{m['crack_triangles']} in cracks/triangles", file=sys.stderr)
    m["crack_area"] = float(triangle_areas(points).sum() / 2.0)
    m["crack_area_per_frozen_volume"] = (m["crack_area"] / m["frozen_volume"]
                                         if m["frozen_volume"] > 0 else None)
    if polygons and normal is not None:
        m["crack_polygons"], m["crack_pairs"] = count_polygons(points, normal, boundary.tolerance)
    return m


def flow_ratios(frames, scene):
    """[2, k]: von Mises / σ_y at the later frame of every element whose plastic strain
    changed (‖Δε_p‖_F > 1e-12) between consecutive frames of the same topology, and whether
    its ‖ε_p‖ is at the cap `max_plastic_strain` (where the return map rescales it)."""
    cap = scene["plasticity"].get("max_plastic_strain", np.inf)
    ratios = []
    for (_, a), (_, b) in zip(frames, frames[1:]):
        if "plastic_strain" not in b or a["tets"].shape != b["tets"].shape \
                or not np.array_equal(a["tets"][:], b["tets"][:]):
            continue
        plastic = b["plastic_strain"][:]
        flowing = voigt_norm(plastic - a["plastic_strain"][:]) > 1e-12
        ratio = von_mises(b["stress"][:][flowing]) / yield_stress(scene, freeze_state(b)[flowing])
        ratios.append(np.stack([ratio, voigt_norm(plastic[flowing]) >= (1 - 1e-9) * cap]))
    return np.concatenate(ratios, axis=1) if ratios else np.zeros((2, 0))


def stats_measures(stats, onset_row):
    """/stats measures: onset (row `onset_row`), splits, the fracture-criterion columns where
    present (over the steps after the onset step), the columns crack_area and crack_polygons
    at steps 1200 and 2400, and the wall time: t_step, which times the step's solve, plus the
    fracture phases timed after it (t_fracture, t_remesh, t_resolve)."""
    column = lambda name: stats[name][:] if name in stats else None
    time = column("time")
    after = slice(onset_row + 1, None) if onset_row is not None else slice(0, 0)
    s = {"steps": len(time), "onset_time": float(time[onset_row]) if onset_row is not None else None,
         "onset_step": int(stats["step"][onset_row]) if onset_row is not None else None,
         "splits": int(column("fracture_events").sum()) if "fracture_events" in stats else None}
    parts = [p for p in ("t_step", "t_fracture", "t_remesh", "t_resolve") if p in stats]
    s["wall_time"], s["wall_time_parts"] = float(sum(stats[p][:].sum() for p in parts)), parts
    if {"nodes_above_toughness", "eligible_nodes"} <= set(stats):
        above = column("nodes_above_toughness")[after].astype(float)
        eligible = column("eligible_nodes")[after].astype(float)
        s["steps_none_above"] = float((above == 0).mean()) if len(above) else None
        ok = eligible > 0
        s["mean_below_share"] = float((1.0 - above[ok] / eligible[ok]).mean()) if ok.any() else None
    if "refused_splits" in stats:
        s["refused_splits"] = int(column("refused_splits").sum())
    steps = column("step")
    for name in ("crack_area", "crack_polygons"):
        if name in stats:
            values = column(name)
            s[name + "_stats"] = [float(values[steps <= k][-1]) if (steps <= k).any() else None
                                  for k in STEPS]
    return s


def spread(x):
    """Count, median, 95th percentile and max of x."""
    if len(x) == 0:
        return {"count": 0}
    return {"count": len(x), "median": float(np.median(x)), "p95": float(np.percentile(x, 95)),
            "max": float(x.max())}


def run_measures(path):
    """All measures of one run file, as a dict."""
    with h5py.File(path, "r") as f:
        scene_text = f.attrs["scene"]
        scene = tomllib.loads(scene_text.decode() if isinstance(scene_text, bytes) else scene_text)
        boundary = SceneBoundary(f["mesh/rest_positions"][:], f["mesh/tets"][:])
        frames = complete_frames(f)
        at = [frame_measures(frame_at(frames, k)[1], boundary) for k in STEPS]
        events = f["stats/fracture_events"][:] if "fracture_events" in f["stats"] else np.zeros(0)
        onset_row = int(np.argmax(events > 0)) if (events > 0).any() else None
        r = {"file": path, "initial_elements": len(f["mesh/tets"]), "at": at,
             **stats_measures(f["stats"], onset_row)}
        ratio, capped = flow_ratios(frames, scene) if "plasticity" in scene else np.zeros((2, 0))
    # Growth needs two different frames (a run that ends before step 2400 has none).
    grow = lambda a, b: b / a if a and at[1]["step"] > at[0]["step"] else None
    e0 = r["initial_elements"]
    r["polygon_growth"] = grow(at[0].get("crack_polygons"), at[1].get("crack_polygons") or 0)
    r["element_growth"] = grow(at[0]["elements"] - e0, at[1]["elements"] - e0)
    r["flowing"] = {**spread(ratio), "at_cap": int(capped.sum()),
                    "below_cap": spread(ratio[capped == 0])}
    return r


# ---------------------------------------------------------------- two runs

def crack_curve(path):
    """Per frame: step, frozen fraction (frozen / total rest volume), one-side crack area (m²)
    and crack area per frozen volume (1/m)."""
    with h5py.File(path, "r") as f:
        boundary = SceneBoundary(f["mesh/rest_positions"][:], f["mesh/tets"][:])
        rows = [frame_measures(g, boundary, polygons=False) for _, g in complete_frames(f)]
    step = np.array([m["step"] for m in rows])
    frozen = np.array([m["frozen_volume"] for m in rows])
    area = np.array([m["crack_area"] for m in rows])
    fraction = frozen / np.array([m["volume"] for m in rows])
    return step, fraction, area, np.divide(area, frozen, out=np.zeros_like(area), where=frozen > 0)


def along_fraction(fraction, density, at):
    """Crack area per frozen volume at frozen fractions `at`, interpolated linearly over the
    frames where the frozen fraction first reaches each value."""
    rising = np.r_[True, fraction[1:] > np.maximum.accumulate(fraction)[:-1]]
    return np.interp(at, fraction[rising], density[rising])


def compare(a, b, runs):
    """Mesh-dependence measures of runs a and b (paths), with their run_measures in `runs`."""
    ca, cb = crack_curve(a), crack_curve(b)
    onset = [runs[p]["onset_time"] for p in (a, b)]
    # The frozen fractions of the later half of the run that freezes less, where both reach.
    small = ca if ca[1][-1] <= cb[1][-1] else cb
    lo, hi = max(ca[1][0], cb[1][0]), min(ca[1][-1], cb[1][-1])
    grid = small[1][len(small[1]) // 2:]
    grid = np.unique(grid[(grid > lo) & (grid <= hi)])
    marks = [x for x in (0.5, 0.6, 0.7, 0.8) if lo < x <= hi]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = along_fraction(*cb[1::2], grid) / along_fraction(*ca[1::2], grid)
        at_marks = along_fraction(*cb[1::2], marks) / along_fraction(*ca[1::2], marks)
    common = np.intersect1d(ca[0], cb[0])
    last = int(common[-1])
    area = [float(c[2][c[0] == last][0]) for c in (ca, cb)]
    return {
        "onset_time": onset,
        "onset_ratio": onset[1] / onset[0] if None not in onset and onset[0] else None,
        "density_ratio_at": {f"{x:.1f}": float(r) for x, r in zip(marks, at_marks)},
        "density_ratio_grid": {"fractions": [float(grid[0]), float(grid[-1])] if len(grid) else None,
                               "count": len(grid),
                               **({"median": float(np.median(ratio)), "min": float(ratio.min()),
                                   "max": float(ratio.max())} if len(grid) else {})},
        "last_common_step": last, "crack_area_at_last_common_step": area,
        "crack_area_relative_difference": (area[1] - area[0]) / area[0] if area[0] else None,
    }


# ---------------------------------------------------------------- printing

def fmt(x, spec="g"):
    """x formatted with `spec`, "—" for None, strings as they are."""
    return "—" if x is None else x if isinstance(x, str) else format(x, spec)


def times(x):
    """A growth factor as ×x.xx."""
    return "—" if x is None else f"×{x:.2f}"


def triple(d):
    """median / p95 / max of a spread() dict."""
    return " / ".join(fmt(d.get(k), ".4g") for k in ("median", "p95", "max"))


def print_run(r):
    """The table of one run."""
    a, b = r["at"]
    p = PAPER
    rows = [
        ("frame step used", a["step"], b["step"], ""),
        ("elements", a["elements"], b["elements"], f"{p['elements'][0]} / {p['elements'][1]}"),
        ("crack triangles (both sides)", a["crack_triangles"], b["crack_triangles"], ""),
        ("crack polygons (one side)", fmt(a.get("crack_polygons")), fmt(b.get("crack_polygons")),
         f"{p['crack_polygons'][0]} / {p['crack_polygons'][1]}"),
        ("  of which coincident pairs", fmt(a.get("crack_pairs")), fmt(b.get("crack_pairs")), ""),
        ("crack area, one side (m²)", fmt(a["crack_area"], ".4g"), fmt(b["crack_area"], ".4g"), ""),
        ("frozen fraction", fmt(a["frozen_volume"] / a["volume"], ".3f"),
         fmt(b["frozen_volume"] / b["volume"], ".3f"), ""),
        ("crack area / frozen volume (1/m)", fmt(a["crack_area_per_frozen_volume"], ".4g"),
         fmt(b["crack_area_per_frozen_volume"], ".4g"), ""),
    ]
    if "crack_area_stats" in r:
        rows.append(("/stats crack_area (m²)", *(fmt(x, ".4g") for x in r["crack_area_stats"]), ""))
    if "crack_polygons_stats" in r:
        rows.append(("/stats crack_polygons", *(fmt(x, "g") for x in r["crack_polygons_stats"]), ""))
    print(f"\n{r['file']}  ({r['initial_elements']} initial elements, {r['steps']} steps)\n")
    print(f"| {'measure':34} | {'step 1200':>10} | {'step 2400':>10} | {'paper':>9} |")
    print(f"|{'-' * 36}|{'-' * 12}|{'-' * 12}|{'-' * 11}|")
    for name, x, y, paper in rows:
        print(f"| {name:34} | {str(x):>10} | {str(y):>10} | {paper:>9} |")
    fl = r["flowing"]
    lines = [
        ("growth 1200 → 2400, crack polygons", times(r["polygon_growth"]), f"paper ×{p['polygon_growth']}"),
        ("growth 1200 → 2400, elements beyond initial", times(r["element_growth"]), ""),
        ("onset (first step with fracture_events > 0)",
         f"{r['onset_time']:.3f} s (step {r['onset_step']})" if r["onset_step"] is not None else "none", ""),
        ("node splits in total", fmt(r["splits"]), ""),
        ("flowing elements: von Mises / σ_y, median / p95 / max", triple(fl),
         f"{fl['count']} element-frames, {fl['at_cap']} of them at the plastic cap"),
        ("  those below the cap", triple(fl["below_cap"]), f"{fl['below_cap']['count']} element-frames"),
    ]
    if "steps_none_above" in r:
        lines += [("steps after onset with nodes_above_toughness = 0", fmt(r["steps_none_above"], ".3f"), ""),
                  ("mean of 1 − nodes_above / eligible after onset", fmt(r["mean_below_share"], ".4f"), "")]
    else:
        lines.append(("nodes_above_toughness / eligible_nodes", "not in /stats", ""))
    lines.append(("refused splits in total", fmt(r.get("refused_splits", "not in /stats")), ""))
    lines.append(("wall time", f"{r['wall_time']:.1f} s", "sum of " + " + ".join(r["wall_time_parts"])))
    print()
    for name, value, note in lines:
        print(f"{name:54} {value}{'   (' + note + ')' if note else ''}")


def print_compare(a, b, c):
    """The table of --compare."""
    print(f"\ncompare A = {a}\n        B = {b}\n")
    print(f"onset time: A {fmt(c['onset_time'][0], '.3f')} s, B {fmt(c['onset_time'][1], '.3f')} s, "
          f"B / A = {fmt(c['onset_ratio'], '.3f')}")
    g = c["density_ratio_grid"]
    if g["count"]:
        print(f"crack area per frozen volume, B / A at equal frozen fraction: median {g['median']:.3f}, "
              f"min {g['min']:.3f}, max {g['max']:.3f} over {g['count']} fractions "
              f"{g['fractions'][0]:.3f} … {g['fractions'][1]:.3f}")
    for x, r in c["density_ratio_at"].items():
        print(f"  at frozen fraction {x}: B / A = {r:.3f}")
    area = c["crack_area_at_last_common_step"]
    print(f"crack area at the last common step {c['last_common_step']}: A {area[0]:.4g} m², "
          f"B {area[1]:.4g} m², (B − A) / A = {fmt(c['crack_area_relative_difference'], '.3e')}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="*", help="icefem run files (HDF5)")
    ap.add_argument("--compare", nargs=2, metavar=("A", "B"), help="two runs to compare")
    ap.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    args = ap.parse_args()
    paths = list(dict.fromkeys(args.files + (args.compare or [])))
    if not paths:
        ap.error("give at least one run file")
    runs = {p: run_measures(p) for p in paths}
    result = {"runs": runs}
    if args.compare:
        result["compare"] = compare(*args.compare, runs)
    if args.json:
        json.dump(result, sys.stdout, indent=1)
        print()
        return
    for r in runs.values():
        print_run(r)
    if args.compare:
        print_compare(*args.compare, result["compare"])


if __name__ == "__main__":
    main()
