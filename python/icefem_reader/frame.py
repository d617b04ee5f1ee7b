"""One output frame of an icefem run: the group ``/frames/NNNNNN`` of the HDF5 file."""

import importlib
from dataclasses import dataclass
from functools import cached_property

import h5py
import numpy as np

from . import voigt

# Datasets every frame has that are geometry, not fields: read through their own properties.
_GEOMETRY = ("positions", "rest_positions", "tets")
# Fields every frame has that the writer stores without a `center` attribute.
_BUILTIN_CENTER = {"velocities": "Node", "stress": "Cell"}

# The four faces of a tet (a, b, c, d): face i is the one opposite vertex i.
_FACES = np.array([[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]])


@dataclass(frozen=True)
class Cracks:
    """A frame's crack surface as separate triangles (both sides of every crack).

    vertices:  float [3t, 3], m (current configuration, with the rendering gap where closed)
    triangles: int [t, 3], indices into ``vertices``
    crack:     int [t], which crack (connected crack surface) each triangle belongs to
    All three are empty (t = 0) in a frame without cracks or a run without fracture.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    crack: np.ndarray

    def __len__(self):
        """Number of crack triangles t."""
        return len(self.triangles)


def _optional_import(module, method):
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(
            f"Frame.{method}() needs the '{module}' package: "
            f"pip install {module}  (or: pip install 'icefem-reader[{module}]')"
        ) from e


class Frame:
    """A complete output frame. Obtain it from a `Run`; arrays are read from the file lazily,
    on first access, so use the frame while its run is open.

    Units are SI: m, s, Pa, N. Node arrays have n rows, element arrays m rows (this frame's
    mesh, which grows when fracture splits nodes).
    """

    def __init__(self, group: h5py.Group, index: int, filename: str):
        self._group = group
        self.index = index
        """Frame index as in the file (``/frames/NNNNNN``)."""
        self.step = int(group.attrs["step"])
        """Time step after which the frame was written (0: the initial state)."""
        self.time = float(group.attrs["time"])
        """Simulated time of the frame, s."""
        self._filename = filename

    def __repr__(self):
        return f"<icefem Frame {self.index} step {self.step} t={self.time:g} s of {self._filename}>"

    def _open_group(self):
        if not self._group.id.valid:
            raise ValueError(f"{self!r}: its run's file is closed (read frames inside `with`)")
        return self._group

    def _read(self, name):
        return self._open_group()[name][()]

    # --- geometry -------------------------------------------------------------------------
    @cached_property
    def positions(self):
        """Current node positions, float [n, 3], m."""
        return self._read("positions")

    @cached_property
    def rest_positions(self):
        """Rest (reference) node positions of this frame's mesh, float [n, 3], m."""
        return self._read("rest_positions")

    @cached_property
    def tets(self):
        """Node indices of each linear tetrahedron of this frame's mesh, int [m, 4], 0-based."""
        return self._read("tets")

    @cached_property
    def velocities(self):
        """Node velocities, float [n, 3], m/s."""
        return self._read("velocities")

    @cached_property
    def displacement(self):
        """Node displacement u = positions − rest_positions, float [n, 3], m (stored exactly)."""
        return self._read("displacement")

    # --- fields ---------------------------------------------------------------------------
    @cached_property
    def _fields(self):
        n, m = len(self.rest_positions), len(self.tets)
        fields = {"Node": {}, "Cell": {}}
        for name, obj in self._open_group().items():
            if name in _GEOMETRY or not isinstance(obj, h5py.Dataset):
                continue
            center = obj.attrs.get("center", _BUILTIN_CENTER.get(name))
            if isinstance(center, bytes):
                center = center.decode()
            if center == "Rows":  # state for resuming (crack_gaps): neither nodes nor elements
                continue
            if center not in fields:  # no attribute: judge by the row count, elements first
                center = "Cell" if obj.shape[0] == m else "Node" if obj.shape[0] == n else None
            if center is not None:
                fields[center][name] = obj[()]
        return fields

    @property
    def node_fields(self):
        """Per-node fields, dict name → float [n] or [n, k]: ``velocities`` (m/s),
        ``displacement`` (m), and when present ``contact_normal_force``,
        ``contact_friction_force`` (N), ``contact_active`` (0/1), ``refused_split``,
        ``temperature`` (°C, [thermal]), ``acceleration`` (m/s², scheme "newmark"),
        ``back_displacement``, ``back_velocity`` (scheme "bdf2")."""
        return self._fields["Node"]

    @property
    def element_fields(self):
        """Per-element fields, dict name → float [m] or [m, 6]: ``stress`` (Pa, Voigt),
        ``eigenstrain`` (1), and when present ``freeze_state`` (0 water … 1 ice),
        ``plastic_strain`` (1, Voigt), ``origin`` (scene element index)."""
        return self._fields["Cell"]

    @property
    def stress(self):
        """Cauchy stress per element, float [m, 6], Pa, Voigt order xx yy zz yz xz xy."""
        return self.element_fields["stress"]

    @property
    def freeze_state(self):
        """Frozen share per element, float [m], 0 (water) … 1 (ice); None without [freezing]."""
        return self.element_fields.get("freeze_state")

    @property
    def temperature(self):
        """Temperature per node, float [n], °C; None without [thermal]."""
        return self.node_fields.get("temperature")

    @property
    def plastic_strain(self):
        """Plastic strain per element, float [m, 6], Voigt; None without [plasticity]."""
        return self.element_fields.get("plastic_strain")

    def von_mises(self):
        """Von Mises stress per element, float [m], Pa."""
        return voigt.von_mises(self.stress)

    def principal_max(self):
        """Largest principal stress per element, float [m], Pa (positive = tension)."""
        return voigt.principal_max(self.stress)

    def plastic_strain_norm(self):
        """Frobenius norm of the plastic strain per element, float [m] (dimensionless).

        Raises KeyError when the run has no plastic strain (the scene has no [plasticity]).
        """
        if self.plastic_strain is None:
            raise KeyError(f"{self!r} has no plastic_strain (the scene has no [plasticity])")
        return voigt.frobenius_norm(self.plastic_strain)

    @cached_property
    def cracks(self):
        """The crack triangles of this frame (`Cracks`; empty arrays when there are none)."""
        g = self._open_group().get("cracks")
        if g is None:
            return Cracks(np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros(0, np.int64))
        return Cracks(g["vertices"][()], g["triangles"][()], g["crack"][()])

    # --- derived geometry -----------------------------------------------------------------
    def surface(self):
        """Boundary triangles of this frame's tets, int [k, 3] (node indices).

        A boundary face is a face used by exactly one tet — after fracture this includes both
        sides of every crack. Each triangle is oriented outward: its right-hand normal
        points away from the tet it bounds, judged in the rest configuration (where no tet is
        inverted). Use with ``positions`` (deformed) or ``rest_positions``.
        """
        tets = self.tets
        faces = tets[:, _FACES].reshape(-1, 3)
        opposite = tets.reshape(-1)  # the vertex opposite each face
        _, inverse, counts = np.unique(
            np.sort(faces, axis=1), axis=0, return_inverse=True, return_counts=True
        )
        boundary = counts[inverse.reshape(-1)] == 1
        faces, opposite = faces[boundary], opposite[boundary]
        x = self.rest_positions
        normal = np.cross(x[faces[:, 1]] - x[faces[:, 0]], x[faces[:, 2]] - x[faces[:, 0]])
        inward = np.einsum("ij,ij->i", normal, x[opposite] - x[faces[:, 0]]) > 0
        faces[inward] = faces[inward][:, [0, 2, 1]]
        return faces

    # --- export ---------------------------------------------------------------------------
    def to_meshio(self):
        """A ``meshio.Mesh``: current positions, "tetra" cells, every node and element field
        as point and cell data. Needs meshio."""
        meshio = _optional_import("meshio", "to_meshio")
        return meshio.Mesh(
            self.positions,
            [("tetra", self.tets)],
            point_data=dict(self.node_fields),
            cell_data={name: [a] for name, a in self.element_fields.items()},
        )

    def to_pyvista(self):
        """A ``pyvista.UnstructuredGrid``: current positions, tetrahedra, every node and
        element field as point and cell data. Needs pyvista."""
        pv = _optional_import("pyvista", "to_pyvista")
        grid = pv.UnstructuredGrid({pv.CellType.TETRA: self.tets}, self.positions)
        for name, a in self.node_fields.items():
            grid.point_data[name] = a
        for name, a in self.element_fields.items():
            grid.cell_data[name] = a
        return grid
