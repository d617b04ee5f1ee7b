"""Writes the dynamics reference's beam mesh (validation/reference/dynamics_beam.h5) as the
Gmsh file a user of scikit-fem would save: `MeshTet.init_tensor` on the same cells, its tets in
scikit-fem's own vertex order (about half of them negatively oriented), Gmsh 2.2 ASCII.

    validation/.venv/bin/python validation/export_beam_mesh.py

The test `the_dynamics_beam_as_a_plain_scene_matches_scikit_fem` runs a plain scene on it.
"""

from pathlib import Path

import meshio
import numpy as np

from make_references import DYN_LEVEL, OUT, beam_mesh


def main() -> None:
    mesh = beam_mesh(*DYN_LEVEL)
    points = mesh.p.T
    tets = mesh.t.T.astype(np.int64)
    edges = points[tets[:, 1:]] - points[tets[:, :1]]
    negative = int((np.linalg.det(edges) < 0).sum())
    path = Path(OUT) / "dynamics_beam.msh"
    meshio.write(path, meshio.Mesh(points, [("tetra", tets)]), file_format="gmsh22", binary=False)
    print(f"{path}: {len(points)} nodes, {len(tets)} tets, {negative} negatively oriented")


if __name__ == "__main__":
    main()
