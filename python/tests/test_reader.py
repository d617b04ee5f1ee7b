"""Tests of icefem_reader against files written by the real icefem binary.

The binary is $ICEFEM_BIN (default target/release/icefem of this repository); the tests that need it
are skipped when it is missing. Every run is a few steps on a small mesh (well under 2 s).
"""

import os
import shutil
import subprocess
from pathlib import Path

import h5py
import numpy as np
import pytest

from icefem_reader import Run, open_run, voigt

REPO = Path(__file__).resolve().parents[2]
ICEFEM_BIN = os.environ.get("ICEFEM_BIN", str(REPO / "target" / "release" / "icefem"))
PULLED_BAR = Path(os.environ.get("ICEFEM_SCENES", str(REPO / "scenes"))) / "pulled_bar.toml"

DT = 2.0**-10  # s, exact in binary so that end_time = 6 dt is exactly 6 steps

# A 10 × 2 × 2 cm ice beam clamped at x = 0 under gravity: 6 steps, a frame every 2.
BEAM = f"""
[mesh]
box = {{ size = [0.1, 0.02, 0.02], cells = [5, 1, 1] }}

[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10

[physics]
gravity = [0.0, 0.0, -9.81]

[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]

[time]
dt = {DT!r}
end_time = {6 * DT!r}
output_every = 2
"""

UNIAXIAL_STRESS = 2.5e6  # Pa
# A 10 × 2 × 2 cm bar on rollers at x = 0 (rigid motions removed at two corners) pulled by a
# traction on x = 0.1: small strain, static, so every linear tet has exactly σ = diag(s, 0, 0).
UNIAXIAL = f"""
[mesh]
box = {{ size = [0.1, 0.02, 0.02], cells = [4, 1, 1] }}

[material]
density = 916.0
youngs_modulus = 1e11
poisson_ratio = 0.35
model = "linear"

[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1.0, 1.0]
axes = "x"

[[dirichlet]]
min = [-1.0, -1.0, -1.0]
max = [1e-9, 1e-9, 1e-9]
axes = "yz"

[[dirichlet]]
min = [-1.0, 0.01, -1.0]
max = [1e-9, 1.0, 1e-9]
axes = "z"

[[traction]]
min = [0.0999999, -1.0, -1.0]
max = [1.0, 1.0, 1.0]
traction = [{UNIAXIAL_STRESS!r}, 0.0, 0.0]

[time]
analysis = "static"
dt = 1.0
end_time = 1.0
"""


# --- running icefem --------------------------------------------------------------------------
@pytest.fixture(scope="session")
def icefem():
    if not (os.path.isfile(ICEFEM_BIN) and os.access(ICEFEM_BIN, os.X_OK)):
        pytest.skip(f"icefem binary not found at {ICEFEM_BIN} (set ICEFEM_BIN to run these tests)")
    return ICEFEM_BIN


def run_scene(icefem, directory, name, text):
    """Write scene `text` to directory/name.toml, run it, return the HDF5 file's path."""
    scene, out = directory / f"{name}.toml", directory / f"{name}.h5"
    scene.write_text(text)
    p = subprocess.run(
        [icefem, "run", str(scene), "--output", str(out)], capture_output=True, text=True, timeout=120
    )
    assert p.returncode == 0, f"icefem run {scene} failed:\n{p.stdout}\n{p.stderr}"
    return out


@pytest.fixture(scope="session")
def beam(icefem, tmp_path_factory):
    return run_scene(icefem, tmp_path_factory.mktemp("beam"), "beam", BEAM)


@pytest.fixture(scope="session")
def bar(icefem, tmp_path_factory):
    if not PULLED_BAR.is_file():
        pytest.skip(f"scene {PULLED_BAR} not found")
    return run_scene(icefem, tmp_path_factory.mktemp("bar"), "bar", PULLED_BAR.read_text())


@pytest.fixture(scope="session")
def uniaxial(icefem, tmp_path_factory):
    return run_scene(icefem, tmp_path_factory.mktemp("uniaxial"), "uniaxial", UNIAXIAL)


# --- (1) an elastic beam -----------------------------------------------------------------------
def test_beam_frames_match_stats(beam):
    with open_run(beam) as run:
        assert run.format_version == 1
        assert run.scene["time"]["output_every"] == 2
        stats = run.stats
        assert list(stats["step"]) == [1, 2, 3, 4, 5, 6]  # one row per step, none for step 0
        assert len(run) == 4 and run.frame_indices == [0, 1, 2, 3]
        assert list(run.steps) == [0, 2, 4, 6]
        assert run.times[0] == 0.0
        for frame, t in zip(run, run.times):
            if frame.step > 0:
                assert frame.time == t == stats["time"][stats["step"] == frame.step][0]
        np.testing.assert_allclose(run.times, DT * run.steps, rtol=1e-12)


def test_beam_positions_are_rest_plus_displacement(beam):
    with Run(beam) as run:
        assert run.tets.shape == (5 * 6, 4) and run.rest_positions.shape == (6 * 2 * 2, 3)
        for frame in run:
            assert np.array_equal(frame.tets, run.tets)
            assert np.array_equal(frame.rest_positions, run.rest_positions)
            # Positions are stored only to be drawn, as 32-bit floats: within half an f32 ulp
            # (2⁻²⁴ relative) of rest + displacement, which are stored exactly.
            exact = frame.rest_positions + frame.displacement
            assert frame.positions.dtype == np.float32
            assert np.array_equal(frame.positions, exact.astype(np.float32))
        last = run.last()
        assert last.displacement[:, 2].min() < 0  # it sags under gravity
        n, m = len(last.positions), len(last.tets)
        assert set(last.node_fields) >= {"velocities", "displacement"}
        assert all(len(a) == n for a in last.node_fields.values())
        assert set(last.element_fields) >= {"stress", "eigenstrain"}
        assert all(len(a) == m for a in last.element_fields.values())
        assert last.stress.shape == (m, 6)
        assert last.freeze_state is None and last.plastic_strain is None
        assert last.temperature is None
        with pytest.raises(KeyError, match="plastic_strain"):
            last.plastic_strain_norm()
        assert len(last.cracks) == 0 and last.cracks.vertices.shape == (0, 3)


@pytest.mark.parametrize("mark", ["zero", "missing"])
def test_incomplete_last_frame_is_skipped(beam, tmp_path, mark):
    cut = tmp_path / "cut.h5"
    shutil.copy(beam, cut)
    with h5py.File(cut, "r+") as f:
        attrs = f["frames/000003"].attrs
        if mark == "zero":
            attrs["complete"] = np.uint8(0)
        else:
            del attrs["complete"]
    with open_run(cut) as run:
        assert run.frame_indices == [0, 1, 2] and len(run) == 3
        assert [f.index for f in run] == [0, 1, 2]
        assert list(run.steps) == [0, 2, 4]
        assert run.last().index == 2 and run[-1].index == 2 and run[-3].index == 0
        with pytest.raises(KeyError, match="0-2"):
            run.frame(3)


# --- (2) a fracturing run ----------------------------------------------------------------------
def test_fracture_cracks_and_topology(bar):
    with open_run(bar) as run:
        first, last = run[0], run.last()
        assert len(first.cracks) == 0
        assert first.cracks.triangles.shape == (0, 3) and first.cracks.crack.shape == (0,)
        assert len(last.cracks) > 0
        c = last.cracks
        assert c.triangles.min() >= 0 and c.triangles.max() < len(c.vertices)
        assert c.crack.shape == (len(c.triangles),) and c.crack.min() >= 0
        assert len(c.triangles) == run.stats["crack_faces"][-1]
        # splitting nodes grows the mesh; the scene mesh stays in /mesh
        assert np.array_equal(first.tets, run.tets)
        assert len(last.tets) > len(first.tets) and len(last.positions) > len(first.positions)
        assert len(last.tets) == run.stats["elements"][-1]
        assert last.tets.max() < len(last.positions)
        assert len(last.node_fields["displacement"]) == len(last.positions)
        assert len(last.element_fields["origin"]) == len(last.tets)


def test_stored_stress_measures_match_the_voigt_stress(bar):
    with open_run(bar) as run:
        assert os.path.isabs(run.scene_path)
        assert run.obstacle_meshes == {}  # the bar has no mesh obstacle
        for frame in (run[0], run.last()):
            fields = frame.element_fields
            # Stored (from the double stress) and recomputed (from the stress as stored, in
            # single precision): both within a few f32 ulps (6e-8 each) of the exact values.
            scale = np.abs(frame.stress).max()
            np.testing.assert_allclose(fields["von_mises"], frame.von_mises(), rtol=0, atol=1e-6 * scale)
            np.testing.assert_allclose(
                fields["max_principal_stress"], frame.principal_max(), rtol=0, atol=1e-6 * scale
            )


def test_surface_of_a_box(bar):
    with open_run(bar) as run:
        size = np.array(run.scene["mesh"]["box"]["size"])  # m, the box of pulled_bar.toml
        frame = run[0]
        tri = frame.surface()
        # Frame 0 is at rest: its positions are the rest positions, stored exactly (the
        # positions, only drawn, are single precision).
        x = frame.rest_positions
        a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
        normals = 0.5 * np.cross(b - a, c - a)  # area-weighted
        area = np.linalg.norm(normals, axis=1).sum()
        box_area = 2 * (size[0] * size[1] + size[1] * size[2] + size[0] * size[2])
        assert area == pytest.approx(box_area, rel=1e-12)
        # outward: the divergence theorem gives the box's volume (inward would give minus it)
        volume = np.einsum("ij,ij->", (a + b + c) / 3, normals) / 3
        assert volume == pytest.approx(np.prod(size), rel=1e-12)
        # each boundary face once
        assert len(np.unique(np.sort(tri, axis=1), axis=0)) == len(tri)
        # after fracture the crack sides are boundary too
        assert len(run.last().surface()) > len(tri)


def test_von_mises_of_uniaxial_run(uniaxial):
    with open_run(uniaxial) as run:
        frame = run.last()
        s = UNIAXIAL_STRESS
        np.testing.assert_allclose(frame.stress, np.tile([s, 0, 0, 0, 0, 0], (len(frame.tets), 1)), atol=1e-6 * s)
        # From the stress as stored (32-bit floats: 6e-8 relative).
        np.testing.assert_allclose(frame.von_mises(), s, rtol=1e-6)
        np.testing.assert_allclose(frame.principal_max(), s, rtol=1e-6)


def test_voigt_formulas():
    rows = np.array(
        [
            [-3.0, 0, 0, 0, 0, 0],  # uniaxial compression: von Mises |s|
            [0, 0, 0, 0, 0, 2.0],  # pure shear τ = 2 (xy): √3 τ, principal +τ
            [5.0, 5.0, 5.0, 0, 0, 0],  # hydrostatic: 0
            [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        ]
    )
    vm = voigt.von_mises(rows)
    np.testing.assert_allclose(vm[:3], [3.0, np.sqrt(3) * 2.0, 0.0], atol=1e-14)
    # against the matrix definitions: √(3/2 s:s) and the eigenvalues
    t = voigt.to_tensor(rows)
    assert np.array_equal(t[3], [[1, 6, 5], [6, 2, 4], [5, 4, 3]])
    dev = t - np.trace(t, axis1=1, axis2=2)[:, None, None] * np.eye(3) / 3
    np.testing.assert_allclose(vm, np.sqrt(1.5 * np.sum(dev**2, axis=(1, 2))), rtol=1e-14)
    np.testing.assert_allclose(voigt.principal_max(rows), np.linalg.eigvalsh(t)[:, -1], rtol=1e-14)
    np.testing.assert_allclose(voigt.principal_max(rows[:2]), [0.0, 2.0], atol=1e-14)
    np.testing.assert_allclose(voigt.frobenius_norm(rows), np.linalg.norm(t, axis=(1, 2)), rtol=1e-14)


# --- (3) export -------------------------------------------------------------------------------
def test_meshio_round_trip(bar, tmp_path):
    meshio = pytest.importorskip("meshio", reason="meshio is not installed")
    with open_run(bar) as run:
        frame, unread = run.last(), run[0]
        vtu = tmp_path / "last.vtu"
        meshio.write(vtu, frame.to_meshio())
        back = meshio.read(vtu)
        assert len(back.points) == len(frame.positions)
        assert [(c.type, len(c.data)) for c in back.cells] == [("tetra", len(frame.tets))]
        np.testing.assert_array_equal(back.points, frame.positions)
        np.testing.assert_array_equal(back.point_data["displacement"], frame.displacement)
        np.testing.assert_array_equal(back.cell_data["stress"][0], frame.stress)
    # arrays load lazily: after the file is closed, that is a clear error
    with pytest.raises(ValueError, match="closed"):
        unread.velocities
    with pytest.raises(ValueError, match="closed"):
        run.last()


def test_pyvista_grid(bar):
    pytest.importorskip("pyvista", reason="pyvista is not installed")
    with open_run(bar) as run:
        frame = run.last()
        grid = frame.to_pyvista()
        assert grid.n_points == len(frame.positions) and grid.n_cells == len(frame.tets)
        np.testing.assert_array_equal(grid.cell_data["stress"], frame.stress)


# --- (4) errors -------------------------------------------------------------------------------
def test_not_icefem_output(tmp_path):
    plain = tmp_path / "plain.h5"
    with h5py.File(plain, "w") as f:
        f["data"] = np.arange(3.0)
    with pytest.raises(ValueError, match="plain.h5.*format_version"):
        Run(plain)
    text = tmp_path / "notes.h5"
    text.write_text("not HDF5 at all\n")
    with pytest.raises(ValueError, match="notes.h5.*not an HDF5 file"):
        Run(text)
    with pytest.raises(FileNotFoundError):
        Run(tmp_path / "missing.h5")


def test_unsupported_format_version(beam, tmp_path):
    future = tmp_path / "future.h5"
    shutil.copy(beam, future)
    with h5py.File(future, "r+") as f:
        f.attrs["format_version"] = np.uint32(2)
    with pytest.raises(ValueError, match="future.h5.*unsupported.*format_version 2"):
        Run(future)


def test_missing_frame(beam):
    with open_run(beam) as run:
        for k in (4, 99, -5):
            with pytest.raises(KeyError, match=r"complete frames: 0-3"):
                run.frame(k)
        with pytest.raises(KeyError):
            run[10]


# --- a run frozen by heat conduction ------------------------------------------------------------
THERMAL_CUBE = """
[mesh]
box = { size = [0.04, 0.04, 0.04], cells = [2, 2, 2] }
[material]
density = 916.0
lambda = 8.64e10
mu = 3.70e10
[[obstacle]]
type = "container"
min = [0.0, 0.0, 0.0]
max = [0.04, 0.04, 0.06]
[thermal]
initial_temperature = 1.0
[[thermal.convection]]
faces = ["walls", "bottom"]
h = 500.0
ambient_temperature = -10.0
[time]
dt = 600.0
end_time = 3600.0
"""


def test_temperature_of_a_thermal_run(icefem, tmp_path):
    with Run(run_scene(icefem, tmp_path, "thermal", THERMAL_CUBE)) as run:
        first, last = run.frame(0), run.last()
        assert np.all(first.temperature == 1.0)  # °C, every node at the start
        assert len(last.temperature) == len(last.positions)
        assert last.temperature.max() < first.temperature.min()  # the walls cooled it
        assert last.freeze_state.mean() > first.freeze_state.mean()
