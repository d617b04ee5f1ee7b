#!/usr/bin/env python3
"""Check an icefem HDF5 output file and its XDMF sidecar with third-party readers.

What it checks
--------------
* h5py opens ``RUN.h5``; the root attributes, ``/mesh``, every frame's
  datasets (shapes, dtypes, tet indices in range) and the ``/stats`` columns
  follow the layout documented in ``docs/output.md``; frames that did not
  change topology share ``tets`` / ``rest_positions`` with the previous frame
  through hard links (same HDF5 object).
* every symmetric tensor (``stress``, 6-column fields) is in ``tensors/`` as
  3 × 3 matrices equal to its Voigt rows.
* meshio's XDMF ``TimeSeriesReader`` reads ``RUN.xdmf``: one step per complete
  frame, with the frame's time, and point/cell data equal to the HDF5 data
  (tensors as their ``tensors/`` matrices). (meshio reads the mesh of the first
  frame only; after a topology change its mesh no longer matches the data,
  which is a meshio limitation.)
* If ParaView's ``pvbatch`` is on PATH (Debian: ``apt-get install paraview``),
  ParaView's default XDMF reader (Xdmf3ReaderS) loads every time step with
  the right point / cell counts, tetrahedra and array component counts.
  Skipped with a note otherwise.

How to run
----------
    python3 -m venv venv
    venv/bin/pip install meshio h5py numpy
    venv/bin/python validation/check_output.py path/to/run.h5

``RUN.xdmf`` must sit next to ``RUN.h5`` (``OutputWriter::finish`` or
``output::write_xdmf`` writes it). Exit status 0 means every check passed;
failures are listed on stderr with exit status 1.
"""

import argparse
import os
import sys

import h5py
import numpy as np

FAILURES = []


def check(cond, msg):
    if not cond:
        FAILURES.append(msg)
        print("FAIL:", msg, file=sys.stderr)
    return cond


def frame_names(f):
    names = [n for n in f["frames"] if n.isdigit()]
    return sorted(names, key=int)


def is_complete(g):
    return "complete" in g.attrs and int(g.attrs["complete"]) == 1


def check_hdf5(path):
    """Layout checks with h5py; returns the list of complete frames' data."""
    frames = []
    with h5py.File(path, "r") as f:
        for a in ("scene", "scene_path", "icefem_version"):
            check(a in f.attrs, f"root attribute {a!r} missing")
        check("mesh" in f and "frames" in f and "stats" in f, "missing /mesh, /frames or /stats")
        rest = f["mesh/rest_positions"]
        tets = f["mesh/tets"]
        check(rest.ndim == 2 and rest.shape[1] == 3, f"/mesh/rest_positions shape {rest.shape}")
        check(tets.ndim == 2 and tets.shape[1] == 4, f"/mesh/tets shape {tets.shape}")
        check(tets.dtype.kind in "iu", f"/mesh/tets dtype {tets.dtype}")

        # h5py objects compare equal when they are the same HDF5 object,
        # i.e. when one is a hard link to the other.
        prev_tets = f["mesh/tets"]
        prev_rest = f["mesh/rest_positions"]
        for name in frame_names(f):
            g = f["frames"][name]
            if not is_complete(g):
                print(f"note: /frames/{name} is incomplete (skipped)")
                continue
            pos = g["positions"][()]
            n = pos.shape[0]
            vel = g["velocities"][()]
            t = g["tets"][()]
            m = t.shape[0]
            check(pos.shape == (n, 3) and vel.shape == (n, 3), f"{name}: positions/velocities shape")
            check(g["rest_positions"].shape == (n, 3), f"{name}: rest_positions shape")
            check(t.shape == (m, 4), f"{name}: tets shape {t.shape}")
            check(m == 0 or (t.min() >= 0 and t.max() < n), f"{name}: tet index out of range")
            check(g["stress"].shape == (m, 6), f"{name}: stress shape {g['stress'].shape}")
            shared = g["tets"] == prev_tets
            if shared:
                check(g["rest_positions"] == prev_rest,
                      f"{name}: tets hard-linked but rest_positions not")
            prev_tets = g["tets"]
            prev_rest = g["rest_positions"]
            fields = {}
            for k, ds in g.items():
                if k in ("positions", "velocities", "rest_positions", "tets", "stress"):
                    continue
                if k == "cracks":
                    tri, ver, crack = ds["triangles"][()], ds["vertices"][()], ds["crack"][()]
                    check(ver.ndim == 2 and ver.shape[1] == 3, f"{name}/cracks/vertices shape {ver.shape}")
                    check(len(tri) == 0 or (tri.min() >= 0 and tri.max() < len(ver)),
                          f"{name}/cracks/triangles: index out of range")
                    check(crack.shape == (len(tri),), f"{name}/cracks/crack shape {crack.shape}")
                    continue
                if k == "tensors":
                    continue  # checked below, against the Voigt datasets
                center = ds.attrs.get("center")
                if isinstance(center, bytes):
                    center = center.decode()
                if center == "Rows":  # state for resuming (crack_gaps): any row count
                    continue
                check(center in ("Cell", "Node"), f"{name}/{k}: center attribute {center!r}")
                rows = m if center == "Cell" else n
                check(ds.shape[0] == rows, f"{name}/{k}: {ds.shape[0]} rows, expected {rows}")
                fields[k] = ds[()]
            # Symmetric tensors again as 3 × 3 matrices (what the sidecar shows).
            tensors = {}
            voigt = {"stress": g["stress"][()], **{k: v for k, v in fields.items()
                                                  if v.ndim == 2 and v.shape[1] == 6}}
            for k, v in voigt.items():
                if check(f"tensors/{k}" in g, f"{name}: no tensors/{k}"):
                    t9 = g[f"tensors/{k}"][()]
                    check(np.array_equal(t9, v[:, [0, 5, 4, 5, 1, 3, 4, 3, 2]]),
                          f"{name}/tensors/{k} is not the Voigt {k} as 3 x 3 matrices")
                    tensors[k] = t9
            frames.append({
                "name": name, "time": float(g.attrs["time"]), "step": int(g.attrs["step"]),
                "n": n, "m": m, "velocities": vel, "stress": g["stress"][()],
                "shared_topology": bool(shared), "fields": fields, "tensors": tensors,
            })

        cols = ["step", "time", "dt", "newton_iterations", "linear_iterations", "factorizations", "substeps", "residual",
                "energy", "kinetic_energy", "elastic_energy", "potential_energy", "contact_energy",
                "t_assembly", "t_factorization", "t_solve", "t_step"]
        lens = {c: f["stats"][c].shape[0] for c in cols if c in f["stats"]}
        check(len(lens) == len(cols), f"/stats columns missing: {set(cols) - set(lens)}")
        check(len(set(lens.values())) <= 1, f"/stats columns differ in length: {lens}")
        steps = f["stats/step"][()]
        check(bool(np.all(np.diff(steps.astype(np.int64)) > 0)), "/stats/step not increasing")
        print(f"h5py: {len(frames)} complete frames, {len(steps)} stats rows, "
              f"{sum(fr['shared_topology'] for fr in frames)} frames with hard-linked topology")
    return frames


def check_meshio(xdmf, frames):
    import meshio

    with meshio.xdmf.TimeSeriesReader(xdmf) as reader:
        points, cells = reader.read_points_cells()
        check(reader.num_steps == len(frames), f"meshio: {reader.num_steps} steps, expected {len(frames)}")
        if frames:
            check(points.shape == (frames[0]["n"], 3), f"meshio: points shape {points.shape}")
            check(cells[0].type == "tetra" and len(cells[0].data) == frames[0]["m"],
                  f"meshio: cells {cells}")
        for k, fr in enumerate(frames[: reader.num_steps]):
            if (fr["n"], fr["m"]) != (frames[0]["n"], frames[0]["m"]):
                # meshio's time-series reader keeps the first frame's mesh; frames after a
                # topology change (fracture) are checked by h5py above and by ParaView.
                continue
            t, point_data, cell_data = reader.read_data(k)
            check(t == fr["time"], f"meshio step {k}: time {t} != {fr['time']}")
            check(np.array_equal(point_data.get("velocity"), fr["velocities"]),
                  f"meshio step {k}: velocity differs")
            check(np.array_equal(cell_data.get("stress", [None])[0], fr["tensors"].get("stress")),
                  f"meshio step {k}: stress differs from tensors/stress")
            for name, data in fr["fields"].items():
                data = fr["tensors"].get(name, data)
                got = point_data.get(name)
                if got is None:
                    got = cell_data.get(name, [None])[0]
                check(np.array_equal(got, data), f"meshio step {k}: field {name} differs")
    print(f"meshio: read {len(frames)} time steps from {xdmf}")


PARAVIEW_SNIPPET = r"""
import json, sys
from paraview.simple import Xdmf3ReaderS, servermanager
r = Xdmf3ReaderS(FileName=[sys.argv[1]])
r.UpdatePipelineInformation()
steps = []
for t in list(r.TimestepValues):
    r.UpdatePipeline(t)
    d = servermanager.Fetch(r)
    if d.IsA("vtkMultiBlockDataSet"):
        d = d.GetBlock(0)
    cd, pd = d.GetCellData(), d.GetPointData()
    steps.append({
        "time": t, "points": d.GetNumberOfPoints(), "cells": d.GetNumberOfCells(),
        "cell_type": d.GetCellType(0) if d.GetNumberOfCells() else None,
        "cell_arrays": {cd.GetArrayName(i): cd.GetArray(i).GetNumberOfComponents()
                        for i in range(cd.GetNumberOfArrays())},
        "point_arrays": {pd.GetArrayName(i): pd.GetArray(i).GetNumberOfComponents()
                         for i in range(pd.GetNumberOfArrays())},
    })
print("ICEFEM_JSON" + json.dumps(steps))
"""


def check_paraview(xdmf, frames):
    """Open the sidecar with ParaView's own XDMF 3 reader through pvbatch, if installed."""
    import json
    import shutil
    import subprocess
    import tempfile

    pvbatch = shutil.which("pvbatch")
    if pvbatch is None:
        print("pvbatch not found: skipping the ParaView check (e.g. apt-get install paraview)")
        return
    with tempfile.NamedTemporaryFile("w", suffix=".py", delete=False) as script:
        script.write(PARAVIEW_SNIPPET)
    try:
        # ParaView's XDMF reader resolves the HDF5 name against the directory
        # of the path it is given, so hand it an absolute path.
        proc = subprocess.run([pvbatch, script.name, os.path.abspath(xdmf)],
                              capture_output=True, text=True, timeout=600)
    finally:
        os.unlink(script.name)
    lines = [l for l in proc.stdout.splitlines() if l.startswith("ICEFEM_JSON")]
    if not check(proc.returncode == 0 and lines, f"pvbatch failed:\n{proc.stdout}\n{proc.stderr}"):
        return
    steps = json.loads(lines[-1][len("ICEFEM_JSON"):])
    check(len(steps) == len(frames), f"ParaView: {len(steps)} time steps, expected {len(frames)}")
    for fr, st in zip(frames, steps):
        t = st["time"]
        check(abs(t - fr["time"]) <= 1e-12 * max(1.0, abs(fr["time"])),
              f"ParaView: time {t} != {fr['time']}")
        check(st["points"] == fr["n"] and st["cells"] == fr["m"],
              f"ParaView t={t}: {st['points']} points / {st['cells']} cells, "
              f"expected {fr['n']} / {fr['m']}")
        check(fr["m"] == 0 or st["cell_type"] == 10, f"ParaView t={t}: cell type is not VTK_TETRA")
        check(st["point_arrays"].get("velocity") == 3, f"ParaView t={t}: velocity {st['point_arrays']}")
        check(st["cell_arrays"].get("stress") == 9, f"ParaView t={t}: stress {st['cell_arrays']}")
        for name, data in fr["fields"].items():
            data = fr["tensors"].get(name, data)
            ncomp = 1 if data.ndim == 1 else data.shape[1]
            got = st["point_arrays"].get(name, st["cell_arrays"].get(name))
            check(got == ncomp, f"ParaView t={t}: field {name} has {got} components, expected {ncomp}")
    print(f"ParaView (Xdmf3ReaderS via pvbatch): read {len(steps)} time steps")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("h5", help="icefem output file (RUN.h5)")
    ap.add_argument("--xdmf", help="sidecar (default: RUN.xdmf next to RUN.h5)")
    args = ap.parse_args()
    xdmf = args.xdmf or os.path.splitext(args.h5)[0] + ".xdmf"
    frames = check_hdf5(args.h5)
    if check(os.path.exists(xdmf), f"{xdmf} does not exist"):
        check_meshio(xdmf, frames)
        check_paraview(xdmf, frames)
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed", file=sys.stderr)
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
