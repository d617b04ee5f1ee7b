"""Generate the Gmsh meshes of the scene gallery, then read them back and check them.

Writes, next to this script, Gmsh 4.1 ASCII files (metres, z up, linear elements only):

  water_sphere.msh        ball r = 0.04 at the origin, tets; physical volume "water",
                          physical surface "shell" (its boundary triangles)
  cup.msh                 obstacle sheet (triangles only): hemispherical bowl r = 0.042
                          (z <= 0) plus a vertical wall up to z = 0.05, open top; normals
                          point into the cavity; physical surface "cup"
  paddle.msh              obstacle: closed boundary of the box [-0.005,0.005] x [-0.06,0.06]
                          x [0,0.08], normals outward; physical surface "paddle"
  two_material_block.msh  block [0,0.1]^2 x [0,0.06], conformal at z = 0.02; physical
                          volumes "base" (z < 0.02) and "ice" (z > 0.02), physical
                          surfaces "bottom" (z = 0) and "top" (z = 0.06)
  water_column.msh        water cylinder r = 0.03, h = 0.08 standing on z = 0 (axis = z),
                          tets; physical volume "water", physical surfaces "bottom" (z = 0),
                          "side", "top" (z = 0.08) and "shell" (all three)
  glass.msh               obstacle sheet (triangles only): a glass of inner radius 0.0315,
                          1.5 mm around the column: flat floor at z = -0.0003 (0.3 mm below
                          the column) plus a vertical wall up to z = 0.10, open top; normals
                          point into the cavity; physical surface "glass"
  bottle.msh              water in a bottle shape, tets: body cylinder r = 0.03 from z = 0 to
                          0.10, conical shoulder to r = 0.011 at z = 0.125, neck r = 0.011 up
                          to z = 0.15; physical volume "water", physical surfaces "bottom"
                          (z = 0) and "shell" (the whole boundary)

Run (from the repository root):

  python3 -m venv scenes/gallery/.venv
  scenes/gallery/.venv/bin/pip install -r scenes/gallery/requirements.txt
  scenes/gallery/.venv/bin/python scenes/gallery/make_meshes.py

The pip wheel of gmsh 4.15.2 imported and meshed here without any extra Debian package
(it needs libGLU/libXcursor/libXft/libXinerama only on machines lacking them; then:
apt-get install -y libglu1-mesa libxcursor1 libxft2 libxinerama1).
The run is deterministic: one thread, fixed algorithms and sizes, a fresh gmsh session per file.
"""
import math
import os
import sys

import gmsh
import meshio
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def begin(name, size):
    """Fresh gmsh session (so no state leaks between files) with the fixed options."""
    gmsh.initialize(interruptible=False)
    gmsh.model.add(name)
    for key, value in {
        "General.Verbosity": 2,        # errors and warnings only
        "General.NumThreads": 1,       # multithreaded meshing is not reproducible
        "Mesh.Algorithm": 6,           # Frontal-Delaunay for surfaces (the default, pinned)
        "Mesh.Algorithm3D": 1,         # Delaunay for volumes
        "Mesh.ElementOrder": 1,        # linear elements: the solver reads types 2 and 4 only
        "Mesh.MshFileVersion": 4.1,
        "Mesh.Binary": 0,
        "Mesh.MeshSizeMin": size,      # uniform target size: min = max
        "Mesh.MeshSizeMax": size,
        "Mesh.MeshSizeFromCurvature": 0,
        "Mesh.SaveAll": 0,             # only elements of physical groups are saved
    }.items():
        gmsh.option.setNumber(key, value)


def finish(name):
    gmsh.write(os.path.join(HERE, name))
    gmsh.finalize()


def triangles_of(surface):
    """(n, 3, 3) corner coordinates of the triangles of one surface entity, as ordered."""
    _, elem_tags, elem_nodes = gmsh.model.mesh.getElements(2, surface)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    lookup = np.zeros(int(tags.max()) + 1, dtype=int)
    lookup[tags.astype(int)] = np.arange(len(tags))
    xyz = coords.reshape(-1, 3)
    return xyz[lookup[np.asarray(elem_nodes[0], dtype=int)]].reshape(-1, 3, 3)


def orient(wanted):
    """Reverse each surface entity whose triangle normals oppose wanted(centroids).

    Gmsh orients a surface mesh by the CAD face's parametrisation, which says nothing about
    where the obstacle's "outside" is, so it is checked and fixed per entity here.
    """
    for _, surface in gmsh.model.getEntities(2):
        for attempt in range(2):
            t = triangles_of(surface)
            normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
            dots = np.einsum("ij,ij->i", normal, wanted(t.mean(axis=1)))
            if np.all(dots > 0):
                break
            if attempt == 0 and np.all(dots < 0):
                print(f"{gmsh.model.getCurrent()}: reversed surface entity {surface}")
                gmsh.model.mesh.reverse([(2, surface)])
            else:
                sys.exit(f"surface {surface}: {np.sum(dots <= 0)} of {len(dots)} triangles misoriented")


def cavity_direction(c):
    """Into the cup: towards the origin in the bowl (z < 0), towards the z axis on the wall."""
    return np.where(c[:, 2:3] < 0, -c, c * [-1.0, -1.0, 0.0])


GLASS_R, GLASS_FLOOR, GLASS_TOP = 0.0315, -0.0003, 0.10


def glass_cavity_direction(c):
    """Into the glass: up on the floor, towards the z axis on the wall."""
    on_floor = np.abs(c[:, 2:3] - GLASS_FLOOR) < 1e-9
    return np.where(on_floor, [0.0, 0.0, 1.0], c * [-1.0, -1.0, 0.0])


def surfaces_at_z(z, eps=1e-6, xy=0.2):
    """Surface entities lying in the plane at height z (within |x|, |y| <= xy)."""
    return [s for _, s in gmsh.model.getEntitiesInBoundingBox(-xy, -xy, z - eps, xy, xy, z + eps, 2)]


def water_sphere():
    begin("water_sphere", 0.012)
    ball = gmsh.model.occ.addSphere(0, 0, 0, 0.04)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [ball], name="water")
    gmsh.model.addPhysicalGroup(2, [s for _, s in gmsh.model.getBoundary([(3, ball)])], name="shell")
    gmsh.model.mesh.generate(3)
    finish("water_sphere.msh")


def sheet_of_revolution(name, profile, cavity, remove=()):
    """The open sheet of triangles swept by the curves `profile` (in the xz half-plane)
    revolved about z, the entities `remove` (construction points) taken out, its pieces
    sharing their seams, physical surface `name`, normals towards cavity(centroids); written
    as name.msh."""
    occ = gmsh.model.occ
    occ.revolve([(1, c) for c in profile], 0, 0, 0, 0, 0, 1, 2 * math.pi)
    if remove:
        occ.remove(list(remove))
    occ.removeAllDuplicates()          # the revolved pieces share their seam circles
    occ.synchronize()
    surfaces = [s for _, s in gmsh.model.getEntities(2)]
    gmsh.model.addPhysicalGroup(2, surfaces, name=name)
    gmsh.model.mesh.generate(2)        # a sheet: triangles only
    orient(cavity)
    finish(name + ".msh")


def cup():
    r, height = 0.042, 0.05
    begin("cup", 0.006)
    occ = gmsh.model.occ
    # Profile in the xz half-plane: quarter arc from the bottom pole to (r, 0, 0), then the
    # wall line up to (r, 0, height); revolving it about z gives one connected open sheet.
    bottom, centre, rim0, rim1 = (occ.addPoint(0, 0, -r), occ.addPoint(0, 0, 0),
                                  occ.addPoint(r, 0, 0), occ.addPoint(r, 0, height))
    arc = occ.addCircleArc(bottom, centre, rim0)
    wall = occ.addLine(rim0, rim1)
    sheet_of_revolution("cup", [arc, wall], cavity_direction, remove=[(0, centre)])


def paddle():
    begin("paddle", 0.01)
    box = gmsh.model.occ.addBox(-0.005, -0.06, 0, 0.01, 0.12, 0.08)
    gmsh.model.occ.synchronize()
    faces = [s for _, s in gmsh.model.getBoundary([(3, box)])]
    gmsh.model.addPhysicalGroup(2, faces, name="paddle")
    gmsh.model.mesh.generate(2)        # the obstacle is the boundary surface only
    orient(lambda c: c - [0.0, 0.0, 0.04])   # away from the box centre = outward
    finish("paddle.msh")


def two_material_block():
    begin("two_material_block", 0.012)
    occ = gmsh.model.occ
    lower = occ.addBox(0, 0, 0, 0.1, 0.1, 0.02)
    upper = occ.addBox(0, 0, 0.02, 0.1, 0.1, 0.04)
    occ.fragment([(3, lower)], [(3, upper)])   # one shared face at z = 0.02: conformal mesh
    occ.synchronize()
    volumes = {occ.getCenterOfMass(3, v)[2] < 0.02: v for _, v in gmsh.model.getEntities(3)}
    gmsh.model.addPhysicalGroup(3, [volumes[True]], name="base")
    gmsh.model.addPhysicalGroup(3, [volumes[False]], name="ice")
    eps = 1e-6
    for name, z in (("bottom", 0.0), ("top", 0.06)):
        faces = gmsh.model.getEntitiesInBoundingBox(-eps, -eps, z - eps, 0.1 + eps, 0.1 + eps, z + eps, 2)
        gmsh.model.addPhysicalGroup(2, [s for _, s in faces], name=name)
    gmsh.model.mesh.generate(3)
    finish("two_material_block.msh")


def water_column():
    r, height = 0.03, 0.08
    begin("water_column", 0.0105)
    column = gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, height, r)
    gmsh.model.occ.synchronize()
    shell = [s for _, s in gmsh.model.getBoundary([(3, column)])]
    bottom, top = surfaces_at_z(0.0), surfaces_at_z(height)
    gmsh.model.addPhysicalGroup(3, [column], name="water")
    gmsh.model.addPhysicalGroup(2, bottom, name="bottom")
    gmsh.model.addPhysicalGroup(2, [s for s in shell if s not in bottom + top], name="side")
    gmsh.model.addPhysicalGroup(2, top, name="top")
    gmsh.model.addPhysicalGroup(2, shell, name="shell")
    gmsh.model.mesh.generate(3)
    finish("water_column.msh")


def glass():
    begin("glass", 0.005)
    occ = gmsh.model.occ
    # Profile in the xz half-plane: the floor line from the axis out to the wall, then the
    # wall line up to the rim; revolving it about z gives one connected open sheet.
    axis, corner, rim = (occ.addPoint(0, 0, GLASS_FLOOR), occ.addPoint(GLASS_R, 0, GLASS_FLOOR),
                         occ.addPoint(GLASS_R, 0, GLASS_TOP))
    floor = occ.addLine(axis, corner)
    wall = occ.addLine(corner, rim)
    sheet_of_revolution("glass", [floor, wall], glass_cavity_direction)


def bottle():
    body_r, body_top, shoulder_top, neck_r, neck_top = 0.03, 0.10, 0.125, 0.011, 0.15
    begin("bottle", 0.0108)
    occ = gmsh.model.occ
    body = occ.addCylinder(0, 0, 0, 0, 0, body_top, body_r)
    shoulder = occ.addCone(0, 0, body_top, 0, 0, shoulder_top - body_top, body_r, neck_r)
    neck = occ.addCylinder(0, 0, shoulder_top, 0, 0, neck_top - shoulder_top, neck_r)
    # one volume: the discs where the parts met are gone, their circles stay as the edges
    # between the body's side, the shoulder's cone and the neck's side
    out, _ = occ.fuse([(3, body)], [(3, shoulder), (3, neck)])
    occ.synchronize()
    volumes = [v for d, v in out if d == 3]
    assert len(volumes) == 1, out
    shell = [s for _, s in gmsh.model.getBoundary([(3, volumes[0])])]
    gmsh.model.addPhysicalGroup(3, volumes, name="water")
    gmsh.model.addPhysicalGroup(2, surfaces_at_z(0.0), name="bottom")
    gmsh.model.addPhysicalGroup(2, shell, name="shell")
    gmsh.model.mesh.generate(3)
    finish("bottle.msh")


# ---------------------------------------------------------------- check the written files

def members(m, name, cell_type):
    """Indices, into all cells of cell_type concatenated, of physical group name.

    Computed from m.cell_sets directly: meshio 5.3.5's cell_sets_dict skips the offset of a
    block whose set entry is None, which would misnumber cells of later blocks.
    """
    out, offset = [], 0
    for ids, block in zip(m.cell_sets[name], m.cells):
        if block.type == cell_type:
            if ids is not None:
                out.append(np.asarray(ids, dtype=int) + offset)
            offset += len(block.data)
    return np.concatenate(out) if out else np.zeros(0, int)


def verify(name):
    # file_format given: by extension alone meshio first tries ANSYS .msh and prints its error
    m = meshio.read(os.path.join(HERE, name), file_format="gmsh")
    tets = np.concatenate([c.data for c in m.cells if c.type == "tetra"] or [np.zeros((0, 4), int)])
    tris = np.concatenate([c.data for c in m.cells if c.type == "triangle"] or [np.zeros((0, 3), int)])
    assert {c.type for c in m.cells} <= {"tetra", "triangle"}, "only linear tets and triangles"
    p = m.points
    groups = {n: (int(td[1]), len(members(m, n, "tetra")) + len(members(m, n, "triangle")))
              for n, td in m.field_data.items()}
    row = [name, len(p), len(tets), len(tris),
           ", ".join(f"{n}(dim {d}): {k}" for n, (d, k) in sorted(groups.items()))]
    notes = []
    if len(tets):
        a, b, c, d = (p[tets[:, i]] for i in range(4))
        vol = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)) / 6
        notes.append(f"negative tets {np.sum(vol < 0)}, flat tets {np.sum(np.abs(vol) < 1e-15)}")
    t = p[tris]
    if len(tris):   # open edges (used by one triangle): none for a closed surface
        e = np.sort(tris[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        edges, uses = np.unique(e, axis=0, return_counts=True)
        open_z = p[edges[uses == 1]][:, :, 2]
        notes.append(f"triangle edges used once {np.sum(uses == 1)}, more than twice {np.sum(uses > 2)}"
                     + (f" (their z in [{open_z.min():.4f}, {open_z.max():.4f}])" if open_z.size else ""))
    if name == "water_sphere.msh":
        rad = np.linalg.norm(p, axis=1)
        surf = rad[np.unique(tris)]
        notes.append(f"node radius min {rad.min():.5f} max {rad.max():.5f}; "
                     f"surface nodes {surf.min():.6f}..{surf.max():.6f}")
    if name == "cup.msh":
        normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        bad = np.sum(np.einsum("ij,ij->i", normal, cavity_direction(t.mean(axis=1))) <= 0)
        notes.append(f"triangles not facing the cavity {bad}; z range [{p[:, 2].min():.4f}, {p[:, 2].max():.4f}]")
        assert bad == 0
    if name == "paddle.msh":
        enclosed = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6
        notes.append(f"enclosed volume {enclosed:.12e} (box {0.01 * 0.12 * 0.08:.12e})")
        assert abs(enclosed - 0.01 * 0.12 * 0.08) < 1e-9
    if name == "two_material_block.msh":
        z = p[tets][:, :, 2]
        inside = ((z.max(axis=1) <= 0.02 + 1e-12) | (z.min(axis=1) >= 0.02 - 1e-12))
        cells = {n: members(m, n, "tetra") for n in ("base", "ice")}
        member = np.zeros(len(tets), int)
        for ids in cells.values():
            np.add.at(member, ids, 1)
        notes.append(f"tets straddling z=0.02 {np.sum(~inside)}; base {len(cells['base'])}, "
                     f"ice {len(cells['ice'])}; tets in exactly one group {np.sum(member == 1)}/{len(tets)}")
        assert inside.all() and (member == 1).all()
        for n in ("bottom", "top"):
            zt = p[tris[members(m, n, "triangle")]][:, :, 2]
            notes.append(f"{n} triangles z in [{zt.min():.4f}, {zt.max():.4f}]")
    if name in ("water_column.msh", "bottle.msh"):
        a, b, c, d = (p[tets[:, i]] for i in range(4))
        volume = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a)).sum() / 6
        shell = t[members(m, "shell", "triangle")]
        enclosed = np.einsum("ij,ij->i", shell[:, 0], np.cross(shell[:, 1], shell[:, 2])).sum() / 6
        zb = t[members(m, "bottom", "triangle")][:, :, 2]
        lo, hi = p[np.unique(tets)].min(axis=0), p[np.unique(tets)].max(axis=0)
        notes.append(f"volume {volume:.6e} m^3, shell encloses {enclosed:.6e} m^3 (signed); "
                     f"tets in \"water\" {len(members(m, 'water', 'tetra'))}/{len(tets)}")
        notes.append(f"bounding box {np.round(lo, 5).tolist()} .. {np.round(hi, 5).tolist()}; "
                     f"bottom triangles {len(zb)}, z in [{zb.min():.4f}, {zb.max():.4f}]")
        assert len(members(m, "water", "tetra")) == len(tets)
        assert abs(enclosed - volume) < 1e-12 * len(shell) and np.all(np.abs(zb) < 1e-12)
    if name == "water_column.msh":
        parts = {n: len(members(m, n, "triangle")) for n in ("bottom", "side", "top", "shell")}
        zt = t[members(m, "top", "triangle")][:, :, 2]
        notes.append(f"bottom + side + top = {parts['bottom'] + parts['side'] + parts['top']} "
                     f"(shell {parts['shell']}); top triangles z in [{zt.min():.4f}, {zt.max():.4f}]")
        assert parts["bottom"] + parts["side"] + parts["top"] == parts["shell"] == len(tris)
        assert np.all(np.abs(zt - 0.08) < 1e-12)
    if name == "glass.msh":
        normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        bad = np.sum(np.einsum("ij,ij->i", normal, glass_cavity_direction(t.mean(axis=1))) <= 0)
        wall = np.abs(p[:, 2] - GLASS_FLOOR) > 1e-9
        c = t.mean(axis=1)
        on_wall = np.abs(c[:, 2] - GLASS_FLOOR) > 1e-9
        # the wall's facets sag inward between its nodes: the least centroid radius is its inside
        notes.append(f"triangles not facing the cavity {bad}; z range [{p[:, 2].min():.4f}, "
                     f"{p[:, 2].max():.4f}]; wall node radius {np.hypot(*p[wall, :2].T).min():.5f}.."
                     f"{np.hypot(*p[wall, :2].T).max():.5f}, least wall facet centroid radius "
                     f"{np.hypot(*c[on_wall, :2].T).min():.5f}")
        assert bad == 0
    return row, notes


if __name__ == "__main__":
    water_sphere()
    cup()
    paddle()
    two_material_block()
    water_column()
    glass()
    bottle()
    print(f"{'file':24} {'nodes':>6} {'tets':>6} {'tris':>6}  physical groups (elements)")
    for name in ("water_sphere.msh", "cup.msh", "paddle.msh", "two_material_block.msh",
                 "water_column.msh", "glass.msh", "bottle.msh"):
        row, notes = verify(name)
        print(f"{row[0]:24} {row[1]:6} {row[2]:6} {row[3]:6}  {row[4]}")
        for n in notes:
            print(f"{'':24}   {n}")
        print(f"{'':24}   size {os.path.getsize(os.path.join(HERE, name))} bytes")
