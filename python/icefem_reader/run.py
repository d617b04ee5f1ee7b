"""An icefem run file (HDF5, format_version 1): its scene, mesh, complete frames and stats."""

import operator
import os
from functools import cached_property

import h5py
import numpy as np

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

from .frame import Frame

SUPPORTED_FORMAT_VERSIONS = (1,)


def _open_h5(path):
    """Open read-only with HDF5 file locking off, so a file icefem is still writing opens."""
    try:
        return h5py.File(path, "r", locking=False)
    except TypeError:  # h5py < 3.5 (no `locking`): the HDF5_USE_FILE_LOCKING variable applies
        return h5py.File(path, "r")


def _text(value):
    return value.decode() if isinstance(value, bytes) else str(value)


def _is_complete(group):
    """A frame is complete only if its attribute `complete` is the integer 1 (as icefem's)."""
    flag = group.attrs.get("complete")
    if flag is None or np.ndim(flag) != 0:
        return False
    return np.issubdtype(np.asarray(flag).dtype, np.integer) and flag == 1


def _ranges(indices):
    """[0, 1, 2, 5, 7, 8] → '0-2, 5, 7-8'."""
    parts, start = [], None
    for i, k in enumerate(indices):
        if start is None:
            start = k
        if i + 1 == len(indices) or indices[i + 1] != k + 1:
            parts.append(f"{start}" if start == k else f"{start}-{k}")
            start = None
    return ", ".join(parts) or "none"


class Run:
    """An icefem output file, opened read-only. Use as a context manager::

        with Run("bar.h5") as run:
            for frame in run: ...

    Only complete frames (attribute ``complete`` = 1) are listed; a run still being written
    or killed mid-frame reads up to its last complete frame. Units are SI (m, s, Pa, N, J).
    """

    def __init__(self, path):
        self.path = os.fspath(path)
        if os.path.exists(self.path) and not h5py.is_hdf5(self.path):
            raise ValueError(f"{self.path}: not an HDF5 file, so not icefem output")
        self._file = _open_h5(self.path)
        try:
            self._check_and_list()
        except BaseException:
            self._file.close()
            raise

    def _check_and_list(self):
        version = self._file.attrs.get("format_version")
        if version is None:
            raise ValueError(f"{self.path}: not icefem output (no root attribute format_version)")
        self.format_version = int(version)
        """Layout version of the file (this reader supports 1)."""
        if self.format_version not in SUPPORTED_FORMAT_VERSIONS:
            raise ValueError(
                f"{self.path}: unsupported icefem format_version {self.format_version} "
                f"(this reader supports {', '.join(map(str, SUPPORTED_FORMAT_VERSIONS))})"
            )
        frames = self._file.get("frames", {})
        names = sorted((int(n), n) for n in frames if n.isascii() and n.isdigit())
        self._frames = {k: frames[n] for k, n in names if _is_complete(frames[n])}
        self.frame_indices = list(self._frames)
        """Indices (as in the file) of the complete frames, ascending."""
        self.steps = np.array([int(g.attrs["step"]) for g in self._frames.values()], dtype=np.int64)
        """Step of each complete frame, int [len(run)]."""
        self.times = np.array([float(g.attrs["time"]) for g in self._frames.values()])
        """Time of each complete frame, float [len(run)], s."""

    # --- file ------------------------------------------------------------------------------
    def close(self):
        """Close the file (frames read from it can no longer load arrays)."""
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"<icefem Run {self.path}: {len(self)} complete frames>"

    # --- metadata --------------------------------------------------------------------------
    @property
    def scene_text(self):
        """The scene's TOML text, as the run read it."""
        return _text(self._file.attrs["scene"])

    @cached_property
    def scene(self):
        """The scene, parsed: a dict of the TOML tables."""
        return tomllib.loads(self.scene_text)

    @property
    def scene_path(self):
        """The scene file's absolute path (as given to ``icefem run`` in older files)."""
        return _text(self._file.attrs.get("scene_path", ""))

    @cached_property
    def obstacle_meshes(self):
        """The triangle surfaces of the scene's mesh obstacles at t = 0, as the run placed them:
        dict ``[[obstacle]]`` index → (vertices float [v, 3] m, triangles int [t, 3]); empty
        without mesh obstacles (and in files written before they were stored)."""
        group = self._file.get("obstacles", {})
        return {
            int(k): (g["vertices"][()], g["triangles"][()])
            for k, g in sorted(group.items(), key=lambda item: int(item[0]))
        }

    @property
    def icefem_version(self):
        """Version of the icefem that wrote the file."""
        return _text(self._file.attrs.get("icefem_version", ""))

    @cached_property
    def rest_positions(self):
        """Rest positions of the scene's mesh, float [n, 3], m (before any fracture)."""
        return self._file["mesh/rest_positions"][()]

    @cached_property
    def tets(self):
        """Tetrahedra of the scene's mesh, int [m, 4], 0-based (before any fracture)."""
        return self._file["mesh/tets"][()]

    @cached_property
    def stats(self):
        """Per-step statistics: dict column → 1-D array, one row per step (no row for the
        initial frame, step 0). Columns and units: docs/output.md (e.g. ``time`` s,
        ``energy`` J, ``residual`` N, ``newton_iterations``)."""
        stats = self._file.get("stats")
        return {} if stats is None else {name: ds[()] for name, ds in stats.items()}

    # --- frames ----------------------------------------------------------------------------
    def __len__(self):
        """Number of complete frames."""
        return len(self._frames)

    def __iter__(self):
        """The complete frames, in order."""
        return (self.frame(k) for k in self.frame_indices)

    def frame(self, k):
        """The complete frame with index ``k`` as in the file (``/frames/NNNNNN``). A negative
        ``k`` counts from the end of the complete frames (-1: the last).

        Raises KeyError, listing the complete frames, when there is no such complete frame.
        """
        if not self._file:
            raise ValueError(f"{self.path}: the file is closed")
        k = operator.index(k)
        if k < 0 and -k <= len(self.frame_indices):
            k = self.frame_indices[k]
        if k not in self._frames:
            raise KeyError(
                f"{self.path}: no complete frame {k}; complete frames: {_ranges(self.frame_indices)}"
            )
        return Frame(self._frames[k], k, self.path)

    __getitem__ = frame

    def last(self):
        """The last complete frame."""
        return self.frame(-1)


def open_run(path):
    """Open an icefem output file: the same as ``Run(path)``."""
    return Run(path)
