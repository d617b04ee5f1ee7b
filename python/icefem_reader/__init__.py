"""Read icefem's HDF5 output (format_version 1; layout: docs/output.md).

    from icefem_reader import open_run
    with open_run("bar.h5") as run:
        last = run.last()
        print(last.time, last.von_mises().max(), len(last.cracks))

`Run` is the file (scene, mesh, complete frames, stats), `Frame` one output frame, `Cracks`
a frame's crack triangles; `voigt` has the tensor helpers. Units are SI: m, s, Pa, N, J.
"""

from . import voigt
from .frame import Cracks, Frame
from .run import SUPPORTED_FORMAT_VERSIONS, Run, open_run

__version__ = "0.1.0"
__all__ = ["Run", "open_run", "Frame", "Cracks", "voigt", "SUPPORTED_FORMAT_VERSIONS"]
