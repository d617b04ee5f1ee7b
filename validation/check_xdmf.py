#!/usr/bin/env python3
"""Check an icefem run's XDMF sidecars with VTK's own XDMF readers, against the HDF5 file.

For RUN.xdmf (the tet mesh) and, with fracture, RUN.cracks.xdmf (the crack surfaces), the
reader is asked for every time step of the series, and for each:

* the time steps are the complete frames' times, in order;
* RUN.xdmf: the number of cells is the frame's tets (all of them VTK_TETRA) and the number of
  points its nodes; `stress` (and `plastic_strain` with plasticity) has n_cells × 9 components
  whose values are the HDF5 Voigt values (xx yy zz yz xz xy) in VTK's 3 × 3 layout
  (xx xy xz / yx yy yz / zx zy zz), element by element and exactly; `von_mises`,
  `max_principal_stress` (and `plastic_strain_norm`) are scalars equal to the HDF5 values and
  to what the Voigt values give; every other attribute has the HDF5 dataset's values and
  column count;
* RUN.cracks.xdmf: the number of cells is the frame's crack triangles (0 before the first
  crack: in particular at t = 0) and `crack` is the frame's crack ids.

The reader is `vtkXdmf3Reader` (the one ParaView opens .xdmf files with) where VTK has it,
else `vtkXdmfReader` (the older XDMF 2 reader; the `vtk` wheels on PyPI ship only this one).
When `pvpython` (ParaView, e.g. Debian's `paraview` + `python3-paraview` + `python3-h5py`) is
on PATH and the script runs without vtkXdmf3Reader, it runs itself again under pvpython, so
both readers are checked.

    validation/.venv/bin/python validation/check_xdmf.py RUN.h5 [--reader xdmf2|xdmf3]

Exit status 0 when every check passed; failures are listed, exit status 1.
"""

import argparse
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

FAILURES = []

# VTK's 3 × 3 component k holds Voigt column VOIGT_OF[k] (xx yy zz yz xz xy = 0 … 5).
VOIGT_OF = [0, 5, 4, 5, 1, 3, 4, 3, 2]
VTK_TETRA, VTK_TRIANGLE = 10, 5


def check(cond, msg):
    if not cond:
        FAILURES.append(msg)
        print("FAIL:", msg)
    return cond


def xdmf_reader(kind):
    """A new reader of `kind` ('xdmf3', 'xdmf2' or 'auto') and its class name."""
    if kind in ("xdmf3", "auto"):
        try:
            from vtkmodules.vtkIOXdmf3 import vtkXdmf3Reader

            return vtkXdmf3Reader(), "vtkXdmf3Reader"
        except ImportError:
            if kind == "xdmf3":
                raise
    from vtkmodules.vtkIOXdmf2 import vtkXdmfReader

    return vtkXdmfReader(), "vtkXdmfReader"


def has_xdmf3():
    try:
        from vtkmodules.vtkIOXdmf3 import vtkXdmf3Reader  # noqa: F401

        return True
    except ImportError:
        return False


def read_series(kind, path):
    """Every time step of the XDMF series at `path`: [(time, dataset)] and the reader's name."""
    from vtkmodules.vtkCommonExecutionModel import vtkStreamingDemandDrivenPipeline

    reader, name = xdmf_reader(kind)
    reader.SetFileName(os.path.abspath(path))
    reader.UpdateInformation()
    info = reader.GetOutputInformation(0)
    key = vtkStreamingDemandDrivenPipeline.TIME_STEPS()
    times = list(info.Get(key)) if info.Has(key) else []
    steps = []
    for t in times:
        reader.UpdateTimeStep(t)
        data = reader.GetOutputDataObject(0)
        while data.IsA("vtkMultiBlockDataSet"):
            data = data.GetBlock(0)
        copy = data.NewInstance()
        copy.DeepCopy(data)
        steps.append((t, copy))
    return steps, name


def array(attributes, name):
    from vtkmodules.util.numpy_support import vtk_to_numpy

    a = attributes.GetArray(name)
    if a is None:
        return None
    values = vtk_to_numpy(a)
    return values.reshape(a.GetNumberOfTuples(), a.GetNumberOfComponents())


def frames_of(h5):
    """The complete frames of the HDF5 file: dicts of what the sidecars show."""
    frames = []
    with h5py.File(h5, "r") as f:
        names = sorted((n for n in f["frames"] if n.isdigit()), key=int)
        for name in names:
            g = f["frames"][name]
            if int(g.attrs.get("complete", 0)) != 1:
                continue
            fields = {}
            for k, ds in g.items():
                if isinstance(ds, h5py.Dataset) and "center" in ds.attrs:
                    center = ds.attrs["center"]
                    center = center.decode() if isinstance(center, bytes) else center
                    # "Rows" (state for resuming, e.g. crack_gaps) is not drawn: no sidecar array.
                    if center in ("Cell", "Node"):
                        fields[k] = (center, ds[()])
            cracks = g.get("cracks")
            frames.append({
                "name": name,
                "time": float(g.attrs["time"]),
                "n": g["positions"].shape[0],
                "tets": g["tets"][()],
                "velocities": g["velocities"][()],
                "stress": g["stress"][()],
                "fields": fields,
                "crack_triangles": None if cracks is None else cracks["triangles"].shape[0],
                "crack": None if cracks is None else cracks["crack"][()],
            })
    return frames


def von_mises(v):
    xx, yy, zz, yz, xz, xy = v.T
    return np.sqrt(0.5 * ((xx - yy) ** 2 + (yy - zz) ** 2 + (zz - xx) ** 2)
                   + 3.0 * (yz**2 + xz**2 + xy**2))


def check_tensor(where, name, got, voigt):
    """`got` (VTK's array) is the Voigt tensor `voigt` in VTK's 3 × 3 layout, exactly: in the
    precision the file stores the matrices (single for what is only drawn, the default)."""
    if not check(got is not None, f"{where}: no array {name!r}"):
        return
    if not check(got.shape == (len(voigt), 9),
                 f"{where}: {name} is {got.shape[0]} x {got.shape[1]}, expected {len(voigt)} x 9"):
        return
    voigt = voigt.astype(got.dtype)
    for k, label in enumerate(["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"]):
        check(np.array_equal(got[:, k], voigt[:, VOIGT_OF[k]]),
              f"{where}: {name} component {label} differs from the HDF5 Voigt column {VOIGT_OF[k]}")


def check_main(kind, xdmf, frames):
    steps, reader = read_series(kind, xdmf)
    print(f"{reader}: {os.path.basename(xdmf)}: {len(steps)} time steps")
    check(len(steps) == len(frames), f"{reader}: {len(steps)} time steps, expected {len(frames)}")
    for (t, data), fr in zip(steps, frames):
        where = f"{reader} {os.path.basename(xdmf)} t={t:g} ({fr['name']})"
        m = len(fr["tets"])
        check(t == fr["time"], f"{where}: time {t!r}, HDF5 {fr['time']!r}")
        check(data.GetNumberOfCells() == m, f"{where}: {data.GetNumberOfCells()} cells, {m} tets")
        check(data.GetNumberOfPoints() == fr["n"],
              f"{where}: {data.GetNumberOfPoints()} points, {fr['n']} nodes")
        types = {data.GetCellType(i) for i in range(data.GetNumberOfCells())}
        check(types <= {VTK_TETRA}, f"{where}: cell types {types}")
        cd, pd = data.GetCellData(), data.GetPointData()
        check(np.array_equal(array(pd, "velocity"), fr["velocities"]), f"{where}: velocity differs")
        check_tensor(where, "stress", array(cd, "stress"), fr["stress"])
        summary = [f"stress {array(cd, 'stress').shape}" if cd.GetArray("stress") else "no stress"]
        stress = fr["stress"]
        fields = fr["fields"]
        for name, (center, values) in sorted(fields.items()):
            got = array(cd if center == "Cell" else pd, name)
            if values.ndim == 2 and values.shape[1] == 6:
                check_tensor(where, name, got, values)
                continue
            expect = values.reshape(len(values), -1)
            if check(got is not None, f"{where}: no array {name!r}"):
                check(got.shape == expect.shape,
                      f"{where}: {name} is {got.shape}, HDF5 {expect.shape}")
                check(got.shape == expect.shape and np.array_equal(got, expect),
                      f"{where}: {name} differs from the HDF5 values")
        for name, value in [("von_mises", von_mises(stress)),
                            ("max_principal_stress", np.linalg.eigvalsh(
                                stress[:, VOIGT_OF].reshape(-1, 3, 3))[:, -1])]:
            got = array(cd, name)
            if check(got is not None and got.shape == (m, 1), f"{where}: {name} is not m x 1"):
                # Stored in single precision (what is only drawn) from the double stress, and
                # recomputed here from the stress as stored: each within a few f32 ulps (6e-8).
                scale = max(1.0, float(np.abs(stress).max(initial=0.0)))
                check(np.allclose(got[:, 0], value, rtol=0, atol=1e-6 * scale),
                      f"{where}: {name} differs from the Voigt stress's")
                summary.append(f"{name} {got.shape}")
        if "plastic_strain" in fields:
            e = fields["plastic_strain"][1]
            norm = np.sqrt((e[:, :3] ** 2).sum(1) + 2 * (e[:, 3:] ** 2).sum(1))
            got = array(cd, "plastic_strain_norm")
            if check(got is not None, f"{where}: no plastic_strain_norm"):
                # Single precision, from the double ε_p: the norm rounded (6e-8).
                check(np.allclose(got[:, 0], norm, rtol=1e-7, atol=0),
                      f"{where}: plastic_strain_norm differs from ‖ε_p‖ of the Voigt values")
                summary.append(f"plastic_strain {array(cd, 'plastic_strain').shape}")
        print(f"  t={t:<10g} {m:5d} tets {data.GetNumberOfCells():5d} cells  " + ", ".join(summary))


def check_cracks(kind, xdmf, frames):
    steps, reader = read_series(kind, xdmf)
    print(f"{reader}: {os.path.basename(xdmf)}: {len(steps)} time steps")
    check(len(steps) == len(frames), f"{reader}: {len(steps)} crack time steps, expected {len(frames)}")
    check(bool(steps) and steps[0][0] == frames[0]["time"],
          f"{reader}: the crack series starts at {steps[0][0] if steps else None}, "
          f"not at the first frame's time {frames[0]['time']}")
    line = []
    for (t, data), fr in zip(steps, frames):
        where = f"{reader} {os.path.basename(xdmf)} t={t:g} ({fr['name']})"
        count = fr["crack_triangles"] or 0
        check(t == fr["time"], f"{where}: time {t!r}, HDF5 {fr['time']!r}")
        check(data.GetNumberOfCells() == count,
              f"{where}: {data.GetNumberOfCells()} cells, {count} crack triangles")
        types = {data.GetCellType(i) for i in range(data.GetNumberOfCells())}
        check(types <= {VTK_TRIANGLE}, f"{where}: cell types {types}")
        if count:
            got = array(data.GetCellData(), "crack")
            check(got is not None and np.array_equal(got[:, 0], fr["crack"]),
                  f"{where}: crack ids differ")
        line.append(f"t={t:g}: {data.GetNumberOfCells()}")
    if steps:
        check(steps[0][1].GetNumberOfCells() == 0,
              f"{reader}: the crack grid at t = {steps[0][0]} has "
              f"{steps[0][1].GetNumberOfCells()} cells, expected none")
    print("  crack triangles per time: " + ", ".join(line))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("h5", help="icefem output file (RUN.h5)")
    ap.add_argument("--reader", choices=["auto", "xdmf3", "xdmf2"], default="auto",
                    help="VTK reader (auto: vtkXdmf3Reader where VTK has it)")
    ap.add_argument("--no-paraview", action="store_true",
                    help="do not run the check again under pvpython")
    args = ap.parse_args()
    import vtkmodules

    print(f"VTK {getattr(vtkmodules, '__version__', '?')}, Python {sys.version.split()[0]}")
    if args.reader == "auto" and not has_xdmf3():
        print("this VTK has no vtkXdmf3Reader (ParaView's XDMF reader): using vtkXdmfReader")
    frames = frames_of(args.h5)
    stem = os.path.splitext(args.h5)[0]
    check_main(args.reader, stem + ".xdmf", frames)
    if any(fr["crack_triangles"] is not None for fr in frames):
        check(os.path.exists(stem + ".cracks.xdmf"), f"{stem}.cracks.xdmf missing")
        check_cracks(args.reader, stem + ".cracks.xdmf", frames)
    status = 0
    if FAILURES:
        print(f"{len(FAILURES)} check(s) failed")
        status = 1
    else:
        print("all checks passed")
    pvpython = shutil.which("pvpython")
    if not (args.no_paraview or has_xdmf3() or args.reader == "xdmf2"):
        if pvpython is None:
            print("pvpython not found: vtkXdmf3Reader (ParaView's reader) not checked")
        else:
            print(f"--- again with ParaView's VTK ({pvpython}) ---", flush=True)
            again = subprocess.run([pvpython, os.path.abspath(__file__), "--reader", "xdmf3",
                                    "--no-paraview", os.path.abspath(args.h5)])
            status = status or again.returncode
    return status


if __name__ == "__main__":
    sys.exit(main())
