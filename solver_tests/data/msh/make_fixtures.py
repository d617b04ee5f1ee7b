"""Generate the Gmsh .msh test fixtures for `src/mesh/gmsh.rs` (icefem).

All files hold the same small box mesh: [0, 0.2] x [0, 0.1] x [0, 0.05] m
(volume 1e-3 m^3), meshed by Gmsh itself, so the files are genuine Gmsh output.
Without physical groups Gmsh saves every element, so each file also holds
points, lines and triangles that the reader must ignore.

Files written (next to this script):
  box_v41_ascii.msh, box_v41_binary.msh, box_v22_ascii.msh, box_v22_binary.msh
      the same mesh in the four supported encodings (tags 1..N, contiguous).
  box_sparse_v41_binary.msh, box_sparse_v22_ascii.msh
      node tags renumbered to 10*tag + 7 (non-contiguous, spread over entity blocks;
      the 2.2 one is rewritten from box_v22_ascii.msh because Gmsh's 2.2 writer
      always renumbers nodes 1..N).
  box_reversed_v41_ascii.msh
      node tags renumbered to N + 1 - tag: contiguous, but NOT ascending along the
      entity blocks (guards against a reader that assumes tag = position).
  groups_v41_ascii.msh, groups_v41_binary.msh, groups_v22_ascii.msh,
  groups_v22_binary.msh
      the same box split at x = 0.1 into two volumes meshed conformally, with named
      physical groups: volumes "left" and "right", surfaces "end" (x = 0.2) and "floor"
      (z = 0, both halves). With physical groups Gmsh saves only their elements.
  box_meshio_v41_ascii.msh, box_meshio_v22_binary.msh
      the mesh round-tripped through meshio's writers (another writer's dialect).
      In general meshio's 4.1 writer may list contiguous tags out of block order,
      which is the case box_reversed_v41_ascii.msh covers.

How to rerun (the files are written next to this script, whatever the cwd):
  python3 -m venv /tmp/msh-venv
  /tmp/msh-venv/bin/pip install gmsh meshio numpy
  /tmp/msh-venv/bin/python solver_tests/data/msh/make_fixtures.py
  cargo test --release mesh::gmsh
Generated with gmsh 4.15.2, meshio 5.3.5, numpy 2.4.6. The Rust tests check
counts that depend on the mesher, so update BOX_NODES / BOX_TETS in gmsh.rs if a
different Gmsh version meshes the box differently.
"""

import os

import gmsh
import meshio

HERE = os.path.dirname(os.path.abspath(__file__))
BOX = (0.2, 0.1, 0.05)


def out(name):
    return os.path.join(HERE, name)


def build_box():
    gmsh.model.add("box")
    gmsh.model.occ.addBox(0, 0, 0, *BOX)
    gmsh.model.occ.synchronize()
    # Coarse on purpose: a few dozen tets keeps every file well under 50 KB.
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.1)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.1)
    gmsh.model.mesh.generate(3)


def build_groups():
    gmsh.model.add("groups")
    left = gmsh.model.occ.addBox(0, 0, 0, BOX[0] / 2, BOX[1], BOX[2])
    right = gmsh.model.occ.addBox(BOX[0] / 2, 0, 0, BOX[0] / 2, BOX[1], BOX[2])
    gmsh.model.occ.fragment([(3, left)], [(3, right)])
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [left], name="left")
    gmsh.model.addPhysicalGroup(3, [right], name="right")

    def faces(test):
        found = []
        for dim, tag in gmsh.model.getEntities(2):
            lo = gmsh.model.getBoundingBox(dim, tag)
            if test(lo[:3], lo[3:]):
                found.append(tag)
        return found

    eps = 1e-6  # Gmsh pads entity bounding boxes by 1e-7
    gmsh.model.addPhysicalGroup(2, faces(lambda a, b: a[0] > BOX[0] - eps), name="end")
    gmsh.model.addPhysicalGroup(2, faces(lambda a, b: b[2] < eps), name="floor")
    gmsh.option.setNumber("Mesh.MeshSizeMin", 0.05)
    gmsh.option.setNumber("Mesh.MeshSizeMax", 0.05)
    gmsh.model.mesh.generate(3)


def save(name, version, binary):
    gmsh.option.setNumber("Mesh.MshFileVersion", version)
    gmsh.option.setNumber("Mesh.Binary", 1 if binary else 0)
    gmsh.write(out(name))


def renumber(new_tag):
    tags, _, _ = gmsh.model.mesh.getNodes()
    old = [int(t) for t in tags]
    gmsh.model.mesh.renumberNodes(old, [new_tag(t, len(old)) for t in old])


def sparsify_v22_ascii(src, dst):
    """Copy a 2.2 ASCII file, mapping every node tag t to 10*t + 7."""
    lines = open(src).read().splitlines()
    section, result = None, []
    for line in lines:
        words = line.split()
        if line.startswith("$"):
            section = line
        elif section == "$Nodes" and len(words) == 4:
            words[0] = str(10 * int(words[0]) + 7)
        elif section == "$Elements" and len(words) > 1:
            first_node = 3 + int(words[2])  # tag, type, ntags, tags..., nodes...
            words[first_node:] = [str(10 * int(w) + 7) for w in words[first_node:]]
        result.append(" ".join(words))
    open(dst, "w").write("\n".join(result) + "\n")


def main():
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    build_box()
    save("box_v41_ascii.msh", 4.1, False)
    save("box_v41_binary.msh", 4.1, True)
    save("box_v22_ascii.msh", 2.2, False)
    save("box_v22_binary.msh", 2.2, True)

    # Gmsh renumbers nodes contiguously on save unless told not to.
    gmsh.option.setNumber("Mesh.Renumber", 0)
    renumber(lambda t, n: 10 * t + 7)
    save("box_sparse_v41_binary.msh", 4.1, True)
    renumber(lambda t, n: (t - 7) // 10)  # back to 1..N
    renumber(lambda t, n: n + 1 - t)
    save("box_reversed_v41_ascii.msh", 4.1, False)
    gmsh.clear()
    gmsh.option.setNumber("Mesh.Renumber", 1)
    build_groups()
    save("groups_v41_ascii.msh", 4.1, False)
    save("groups_v41_binary.msh", 4.1, True)
    save("groups_v22_ascii.msh", 2.2, False)
    save("groups_v22_binary.msh", 2.2, True)
    gmsh.finalize()

    # Gmsh's 2.2 writer always renumbers nodes 1..N, so sparsify that file by hand.
    sparsify_v22_ascii(out("box_v22_ascii.msh"), out("box_sparse_v22_ascii.msh"))

    mesh = meshio.read(out("box_v41_ascii.msh"))
    # meshio's 4.1 writer needs a physical tag per cell; Gmsh wrote none, so use 0.
    mesh.cell_data["gmsh:physical"] = [0 * g for g in mesh.cell_data["gmsh:geometrical"]]
    meshio.write(out("box_meshio_v41_ascii.msh"), mesh, file_format="gmsh", binary=False)
    meshio.write(out("box_meshio_v22_binary.msh"), mesh, file_format="gmsh22", binary=True)


if __name__ == "__main__":
    main()
