#!/usr/bin/env python3
"""Check `icefem export` output against its run with readers that are not icefem's.

What it checks
--------------
For each exported frame, h5py reads the run's frame and numpy recomputes what the export
should hold: the boundary faces of the frame's tets (faces of one tet only), the crack
triangles (``cracks/triangles``), hence the outer faces (boundary less crack), and every
node's volume-weighted average of the element fields (von Mises stress from ``stress``,
the Frobenius norm of ``plastic_strain``, ``freeze_state``; weights the tets' rest volumes)
and the nodes' ``temperature`` where the run has it; the rigid obstacles' triangles from the
stored scene (a container 10, a plane 2, a mesh obstacle its ``/obstacles`` surface).

* USD (``RUN.usda``): ``pxr.Usd`` opens the stage; up axis Z, metres, time codes
  (t − t0) × fps / speed (fps the stage's framesPerSecond = timeCodesPerSecond, speed its
  ``icefem_speed``); ``/World/Ice`` and ``/World/Cracks`` have one time
  sample per frame of points, face counts and indices, velocities and each primvar (vertex
  interpolation), with the counts above; attribute values equal the VTU's (f32).
* VTU (``RUN_export/RUN_{ice,cracks}_NNNNNN.vtu`` and ``RUN.pvd``): meshio reads each file;
  the ``.pvd`` (xml.etree) lists every object of every frame at the frame's time. Ice
  points sit exactly on nodes, and each point's attributes equal that node's velocity (1e-12
  relative) and averages (1e-6 of the field's size: the run stores what is only drawn in
  single precision). meshio 5.3.5 cannot read a grid with no cells (an IndexError in
  ``vtk_cells_from_data``), so empty crack files are checked with xml.etree instead. VTK's
  own ``vtkXMLUnstructuredGridReader`` (ParaView's; the ``vtk`` wheel of requirements.txt)
  reads every file too, the empty ones included: point and cell counts, triangles, arrays.
* PLY (``RUN_{ice,cracks}_NNNNNN.ply``): meshio reads each; counts as above; vertex
  properties equal the VTU's (f32).
* OBJ (``RUN_NNNNNN.obj``): meshio reads each (it merges the file's objects): its triangles
  are all the frame's boundary faces, its points the ice's and the cracks'; the ``o ice`` /
  ``o cracks`` lines are counted from the text.

Fields the run does not have (no freezing, no plasticity) must be absent.

How to run
----------
    validation/setup_venv.sh
    icefem export RUN.h5 --format usd   # and obj, ply, vtu, with the same --frames
    validation/.venv/bin/python validation/check_export.py RUN.h5 [--frames A:B:S]

Exports not found are skipped with a note. Ends with an ``N passed, N failed`` line; exit
status 1 if a check failed.
"""

import argparse
import os
import sys
import xml.etree.ElementTree as ET

import h5py
import meshio
import numpy as np

RESULTS = {"passed": 0, "failed": 0}

SCALARS = ["freeze_state", "plastic_strain", "von_mises", "temperature"]
TET_FACES = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]


def check(cond, msg):
    if cond:
        RESULTS["passed"] += 1
    else:
        RESULTS["failed"] += 1
        print("FAIL:", msg, file=sys.stderr)
    return cond


def frame_range(spec, available):
    """The frames of ``--frames A:B:S`` (as icefem parses it) among ``available``."""
    if spec is None:
        return list(available)
    parts = (spec.split(":") + ["", ""])[:3]
    first = int(parts[0]) if parts[0] else available[0]
    last = int(parts[1]) if parts[1] else available[-1]
    step = int(parts[2]) if parts[2] else 1
    return list(range(first, last + 1, step))


def obstacle_triangles(f):
    """Triangles of the run's rigid obstacles as the export writes them (docs/output.md): a
    container's floor and walls (10), a plane's square (2), a mesh obstacle's stored surface;
    None for a run without obstacles."""
    import tomllib

    scene = tomllib.loads(f.attrs["scene"])
    total = 0
    for index, o in enumerate(scene.get("obstacle", [])):
        kind = o["type"]
        if kind == "container":
            total += 10
        elif kind == "halfspace":
            total += 2
        else:
            total += f[f"obstacles/{index}/triangles"].shape[0]
    return total if scene.get("obstacle") else None


def objects_of(e):
    """The export's objects for expected frame ``e``: ice, cracks and, where the run had
    them, the obstacles."""
    return ["ice", "cracks"] + (["obstacles"] if e["obstacles"] is not None else [])


def faces_of(e, obj):
    return {"ice": e["outer"], "cracks": e["cracks"], "obstacles": e["obstacles"]}[obj]


def expected_frame(g):
    """What the export of HDF5 frame group ``g`` should hold, computed with numpy."""
    tets = g["tets"][:]
    rest = g["rest_positions"][:]
    positions = g["positions"][:]
    faces = tets[:, TET_FACES].reshape(-1, 3)
    _, counts = np.unique(np.sort(faces, axis=1), axis=0, return_counts=True)
    boundary = int((counts == 1).sum())
    cracks = int(g["cracks/triangles"].shape[0]) if "cracks" in g else 0
    # Volume-weighted nodal averages of the element fields.
    x = rest[tets]
    volume = np.abs(np.einsum("ij,ij->i", np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), x[:, 3] - x[:, 0])) / 6
    elements = {}
    # What is only drawn (stress, ‖ε_p‖) is stored in single precision: computed here in double
    # from the values as stored, the von Mises stress is within a few f32 ulps of the stress's
    # size (6e-8 |σ|) of the exporter's (which is from the run's double stress).
    s = g["stress"][:].astype(np.float64)
    scales = {"von_mises": float(np.abs(s).max(initial=0.0))}
    mean = s[:, :3].mean(axis=1, keepdims=True)
    dev = s[:, :3] - mean
    elements["von_mises"] = np.sqrt(1.5 * ((dev ** 2).sum(axis=1) + 2 * (s[:, 3:] ** 2).sum(axis=1)))
    if "plastic_strain" in g:
        e = g["plastic_strain"][:]
        elements["plastic_strain"] = np.sqrt((e[:, :3] ** 2).sum(axis=1) + 2 * (e[:, 3:] ** 2).sum(axis=1))
    if "freeze_state" in g:
        elements["freeze_state"] = g["freeze_state"][:]
    n = len(positions)
    weight = np.zeros(n)
    np.add.at(weight, tets, volume[:, None])
    nodal = {}
    for name, values in elements.items():
        total = np.zeros(n)
        np.add.at(total, tets, (volume * values)[:, None])
        nodal[name] = total / np.where(weight > 0, weight, 1)
    if "temperature" in g:
        nodal["temperature"] = g["temperature"][:].reshape(-1)
    return {
        "time": float(g.attrs["time"]),
        "outer": boundary - cracks,
        "cracks": cracks,
        "positions": positions,
        "velocities": g["velocities"][:],
        "nodal": nodal,
        "scales": {name: max(scales.get(name, 0.0), float(np.abs(v).max(initial=0.0))) for name, v in nodal.items()},
    }


def triangles_of(mesh):
    return sum(len(c.data) for c in mesh.cells if c.type == "triangle")


def check_vtu(folder, stem, expected):
    """meshio reads every VTU; returns {(number, object): point data} for the other formats."""
    pvd = os.path.join(folder, f"{stem}.pvd")
    if not os.path.exists(pvd):
        print(f"note: {pvd} not found, VTU skipped")
        return None
    datasets = ET.parse(pvd).getroot().find("Collection").findall("DataSet")
    check(len(datasets) == len(objects_of(expected[0])) * len(expected), f"{pvd}: {len(datasets)} data sets for {len(expected)} frames")
    out = {}
    for k, e in enumerate(expected):
        for part, obj in enumerate(objects_of(e)):
            name = f"{stem}_{obj}_{k:06d}.vtu"
            d = [x for x in datasets if x.get("file") == name]
            if not check(len(d) == 1, f"{pvd}: no data set {name}"):
                continue
            check(int(d[0].get("part")) == part, f"{name}: part {d[0].get('part')}")
            check(abs(float(d[0].get("timestep")) - e["time"]) <= 1e-12 * max(1, e["time"]), f"{name}: time")
            path = os.path.join(folder, name)
            faces = faces_of(e, obj)
            fields = set() if obj == "obstacles" else set(e["nodal"])
            if faces == 0:
                check_with_vtk(path, 0, 0, fields)
                piece = ET.parse(path).getroot().find("UnstructuredGrid/Piece")
                check(piece.get("NumberOfCells") == "0" and piece.get("NumberOfPoints") == "0", f"{name}: not empty")
                out[(k, obj)] = None
                continue
            check_with_vtk(path, faces, 3 * faces if obj == "cracks" else None, fields)
            m = meshio.read(path)
            check(triangles_of(m) == faces, f"{name}: {triangles_of(m)} triangles, expected {faces}")
            if obj == "cracks":
                check(len(m.points) == 3 * faces, f"{name}: {len(m.points)} points for {faces} triangles")
            data = {key: np.asarray(v).reshape(len(m.points), -1) for key, v in m.point_data.items()}
            check(set(data) == {"velocity"} | fields, f"{name}: point data {sorted(data)}")
            if obj == "ice":
                check_ice_values(name, m.points, data, e)
            out[(k, obj)] = (m.points, data)
    return out


def check_with_vtk(path, cells, points, fields):
    """VTK's XML reader: ``cells`` triangles, ``points`` points (unless None), the arrays."""
    try:
        from vtkmodules.vtkIOXML import vtkXMLUnstructuredGridReader
    except ImportError:
        return
    reader = vtkXMLUnstructuredGridReader()
    reader.SetFileName(path)
    reader.Update()
    grid = reader.GetOutput()
    check(grid.GetNumberOfCells() == cells, f"VTK {path}: {grid.GetNumberOfCells()} cells, expected {cells}")
    check(points is None or grid.GetNumberOfPoints() == points, f"VTK {path}: {grid.GetNumberOfPoints()} points")
    check(all(grid.GetCellType(c) == 5 for c in range(grid.GetNumberOfCells())), f"VTK {path}: not triangles")
    data = grid.GetPointData()
    names = {data.GetArrayName(k) for k in range(data.GetNumberOfArrays())}
    check(names == {"velocity"} | fields, f"VTK {path}: arrays {sorted(names)}")


def check_ice_values(name, points, data, e):
    """Each ice point sits on a node and carries that node's averages and velocity."""
    index = {}
    for i, x in enumerate(map(tuple, e["positions"])):
        index.setdefault(x, []).append(i)
    bad = 0
    for p, x in enumerate(map(tuple, points)):
        nodes = index.get(x, [])
        ok = False
        for i in nodes:
            same = np.allclose(data["velocity"][p], e["velocities"][i], rtol=1e-12, atol=0)
            # The element values behind the averages are stored in single precision (only
            # drawn): the exporter's and these averages agree to a few f32 ulps (6e-8) of the
            # field's scale (see expected_frame).
            for key, values in e["nodal"].items():
                same &= abs(data[key][p, 0] - values[i]) <= 1e-6 * e["scales"][key] + 1e-300
            ok |= bool(same)
        bad += not ok
    check(bad == 0, f"{name}: {bad} of {len(points)} points off a node or with other values")


def check_ply(folder, stem, expected, vtu):
    first = os.path.join(folder, f"{stem}_ice_000000.ply")
    if not os.path.exists(first):
        print(f"note: {first} not found, PLY skipped")
        return
    for k, e in enumerate(expected):
        for obj in objects_of(e):
            name = f"{stem}_{obj}_{k:06d}.ply"
            m = meshio.read(os.path.join(folder, name))
            faces = faces_of(e, obj)
            fields = set() if obj == "obstacles" else set(e["nodal"])
            check(triangles_of(m) == faces, f"{name}: {triangles_of(m)} triangles, expected {faces}")
            check(set(m.point_data) == {"vx", "vy", "vz"} | fields, f"{name}: properties {sorted(m.point_data)}")
            if vtu and vtu.get((k, obj)):
                points, data = vtu[(k, obj)]
                check(np.allclose(m.points, points, rtol=1e-6, atol=1e-9), f"{name}: points differ from the VTU's")
                velocity = np.stack([m.point_data[c] for c in ["vx", "vy", "vz"]], axis=1)
                same = np.allclose(velocity, data["velocity"], rtol=1e-6, atol=1e-30)
                for key in fields:
                    same &= np.allclose(m.point_data[key], data[key][:, 0], rtol=1e-6, atol=1e-30)
                check(same, f"{name}: attributes differ from the VTU's")


def check_obj(folder, stem, expected):
    first = os.path.join(folder, f"{stem}_000000.obj")
    if not os.path.exists(first):
        print(f"note: {first} not found, OBJ skipped")
        return
    for k, e in enumerate(expected):
        path = os.path.join(folder, f"{stem}_{k:06d}.obj")
        m = meshio.read(path)
        total = sum(faces_of(e, obj) for obj in objects_of(e))
        check(triangles_of(m) == total, f"{path}: {triangles_of(m)} triangles, expected {total}")
        with open(path) as f:
            objects = [line.split()[1] for line in f if line.startswith("o ")]
        check(objects == objects_of(e), f"{path}: objects {objects}")


def check_usd(path, expected, vtu):
    if not os.path.exists(path):
        print(f"note: {path} not found, USD skipped")
        return
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(path)
    n = len(expected)
    check(UsdGeom.GetStageUpAxis(stage) == "Z", "USD: up axis")
    check(UsdGeom.GetStageMetersPerUnit(stage) == 1.0, "USD: metres per unit")
    # Time code of a frame: (t - t0) * fps / speed, rounded to 1e-6 (docs/output.md).
    fps = stage.GetFramesPerSecond()
    speed = stage.GetRootLayer().customLayerData["icefem_speed"]
    t0 = expected[0]["time"]
    codes = [round((e["time"] - t0) * fps / speed, 6) for e in expected]
    check(stage.GetTimeCodesPerSecond() == fps, f"USD: {stage.GetTimeCodesPerSecond()} time codes per second, {fps} frames per second")
    check((stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, codes[-1]), f"USD: time codes {stage.GetStartTimeCode()} … {stage.GetEndTimeCode()}, expected 0 … {codes[-1]}")
    check(bool(stage.GetPrimAtPath("/World/Obstacles")) == (expected[0]["obstacles"] is not None), "USD: /World/Obstacles where the run had obstacles")
    for obj in objects_of(expected[0]):
        prim_path = "/World/" + obj.capitalize()
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(prim_path))
        if not check(bool(mesh), f"USD: no Mesh {prim_path}"):
            continue
        primvars = {pv.GetPrimvarName(): pv for pv in UsdGeom.PrimvarsAPI(mesh).GetPrimvars() if pv.GetInterpolation() == "vertex"}
        fields = set() if obj == "obstacles" else set(expected[0]["nodal"])
        check(set(primvars) == fields, f"USD {prim_path}: primvars {sorted(primvars)}")
        attrs = [mesh.GetPointsAttr(), mesh.GetFaceVertexCountsAttr(), mesh.GetFaceVertexIndicesAttr(), mesh.GetVelocitiesAttr()]
        attrs += [pv.GetAttr() for pv in primvars.values()]
        for a in attrs:
            samples = a.GetTimeSamples()
            # Obstacles that do not move are written once, as values (docs/output.md).
            if obj == "obstacles" and not samples:
                check(a.HasAuthoredValue(), f"USD {a.GetPath()}: neither samples nor a value")
                continue
            check(len(samples) == n and all(abs(x - c) <= 1e-6 for x, c in zip(samples, codes)), f"USD {a.GetPath()}: time samples {samples[:4]}…, expected {codes[:4]}…")
        for k, e in enumerate(expected):
            faces = faces_of(e, obj)
            counts = mesh.GetFaceVertexCountsAttr().Get(codes[k])
            points = np.array(mesh.GetPointsAttr().Get(codes[k])).reshape(-1, 3)
            check(len(counts) == faces and all(c == 3 for c in counts), f"USD {prim_path} @{k}: {len(counts)} faces, expected {faces}")
            check(len(mesh.GetFaceVertexIndicesAttr().Get(codes[k])) == 3 * faces, f"USD {prim_path} @{k}: indices")
            check(len(mesh.GetVelocitiesAttr().Get(codes[k])) == len(points), f"USD {prim_path} @{k}: velocities")
            if vtu and vtu.get((k, obj)):
                vpoints, data = vtu[(k, obj)]
                same = np.allclose(points, vpoints, rtol=1e-6, atol=1e-9)
                same &= np.allclose(np.array(mesh.GetVelocitiesAttr().Get(codes[k])), data["velocity"], rtol=1e-6, atol=1e-30)
                for name, pv in primvars.items():
                    same &= np.allclose(np.array(pv.Get(codes[k])), data[name][:, 0], rtol=1e-6, atol=1e-30)
                check(same, f"USD {prim_path} @{k}: values differ from the VTU's")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("h5", help="the run (RUN.h5)")
    ap.add_argument("--frames", help="the --frames the exports were made with (default: all)")
    ap.add_argument("--usd", help="the stage (default: RUN.usda beside RUN.h5)")
    ap.add_argument("--folder", help="OBJ/PLY/VTU folder (default: RUN_export beside RUN.h5)")
    args = ap.parse_args()
    base, _ = os.path.splitext(args.h5)
    stem = os.path.basename(base)
    with h5py.File(args.h5, "r") as f:
        frames = f["frames"]
        available = sorted(int(k) for k in frames if int(frames[k].attrs.get("complete", 0)) == 1)
        names = {int(k): k for k in frames}
        expected = [expected_frame(frames[names[i]]) for i in frame_range(args.frames, available)]
        obstacles = obstacle_triangles(f)
    for e in expected:
        e["obstacles"] = obstacles
    folder = args.folder or base + "_export"
    vtu = check_vtu(folder, stem, expected)
    check_ply(folder, stem, expected, vtu)
    check_obj(folder, stem, expected)
    check_usd(args.usd or base + ".usda", expected, vtu)
    crack_frames = sum(e["cracks"] > 0 for e in expected)
    print(f"{len(expected)} frames ({crack_frames} with cracks), fields: {sorted(expected[0]['nodal'])}")
    print(f"{RESULTS['passed']} passed, {RESULTS['failed']} failed")
    return 1 if RESULTS["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
