#!/usr/bin/env python3
"""Check an icefem HDF5 output file and its XDMF sidecar with third-party readers.

What it checks
--------------
* h5py opens ``RUN.h5``; the root attributes, ``/mesh``, every frame's
  datasets (shapes, dtypes, tet indices in range) and the ``/stats`` columns
  follow the layout documented in ``src/output.rs``; frames that did not
  change topology share ``tets`` / ``rest_positions`` with the previous frame
  through hard links (same HDF5 object).
* meshio's XDMF ``TimeSeriesReader`` reads ``RUN.xdmf``: one step per complete
  frame, with the frame's time, and point/cell data equal to the HDF5 data.
  (meshio reads the mesh of the first frame only; after a topology change
  its mesh no longer matches the data, which is a meshio limitation.)
* If the ``vtk`` Python package is installed, VTK's ``vtkXdmf3Reader`` — the
  reader ParaView uses for ``.xdmf`` files — loads every time step and the
  cell / point counts match.

How to run
----------
    python3 -m venv venv
    venv/bin/pip install meshio h5py numpy      # optionally: vtk
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
                center = ds.attrs.get("center")
                if isinstance(center, bytes):
                    center = center.decode()
                check(center in ("Cell", "Node"), f"{name}/{k}: center attribute {center!r}")
                rows = m if center == "Cell" else n
                check(ds.shape[0] == rows, f"{name}/{k}: {ds.shape[0]} rows, expected {rows}")
                fields[k] = ds[()]
            frames.append({
                "name": name, "time": float(g.attrs["time"]), "step": int(g.attrs["step"]),
                "n": n, "m": m, "velocities": vel, "stress": g["stress"][()],
                "shared_topology": bool(shared), "fields": fields,
            })

        cols = ["step", "time", "dt", "newton_iterations", "linear_iterations", "residual",
                "energy", "kinetic_energy", "elastic_energy", "potential_energy",
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
            t, point_data, cell_data = reader.read_data(k)
            check(t == fr["time"], f"meshio step {k}: time {t} != {fr['time']}")
            check(np.array_equal(point_data.get("velocity"), fr["velocities"]),
                  f"meshio step {k}: velocity differs")
            check(np.array_equal(cell_data.get("stress", [None])[0], fr["stress"]),
                  f"meshio step {k}: stress differs")
            for name, data in fr["fields"].items():
                got = point_data.get(name)
                if got is None:
                    got = cell_data.get(name, [None])[0]
                check(np.array_equal(got, data), f"meshio step {k}: field {name} differs")
    print(f"meshio: read {len(frames)} time steps from {xdmf}")


def check_vtk(xdmf, frames):
    try:
        from vtkmodules.vtkIOXdmf3 import vtkXdmf3Reader
    except ImportError:
        print("vtk not installed: skipping the ParaView-reader (vtkXdmf3Reader) check")
        return
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline as SDDP

    r = vtkXdmf3Reader()
    r.SetFileName(xdmf)
    r.UpdateInformation()
    times = r.GetOutputInformation(0).Get(SDDP.TIME_STEPS()) or []
    check(len(times) == len(frames), f"vtk: {len(times)} time steps, expected {len(frames)}")
    for fr, t in zip(frames, times):
        r.UpdateTimeStep(t)
        out = r.GetOutputDataObject(0)
        # A temporal collection comes out as an unstructured grid per step.
        check(out.GetNumberOfPoints() == fr["n"] and out.GetNumberOfCells() == fr["m"],
              f"vtk t={t}: {out.GetNumberOfPoints()} points / {out.GetNumberOfCells()} cells, "
              f"expected {fr['n']} / {fr['m']}")
        check(out.GetCellType(0) == 10 if fr["m"] else True, "vtk: cell type is not VTK_TETRA")
        for arr, cen in (("velocity", out.GetPointData()), ("stress", out.GetCellData())):
            a = cen.GetArray(arr)
            check(a is not None, f"vtk t={t}: array {arr} missing")
        for name in fr["fields"]:
            check(out.GetPointData().GetArray(name) is not None
                  or out.GetCellData().GetArray(name) is not None, f"vtk t={t}: field {name} missing")
    print(f"vtk (ParaView's XDMF3 reader): read {len(times)} time steps")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("h5", help="icefem output file (RUN.h5)")
    ap.add_argument("--xdmf", help="sidecar (default: RUN.xdmf next to RUN.h5)")
    args = ap.parse_args()
    xdmf = args.xdmf or os.path.splitext(args.h5)[0] + ".xdmf"
    frames = check_hdf5(args.h5)
    if check(os.path.exists(xdmf), f"{xdmf} does not exist"):
        check_meshio(xdmf, frames)
        check_vtk(xdmf, frames)
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed", file=sys.stderr)
        return 1
    print("all checks passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
