"""Small Gmsh meshes made "as a new user would make them", for command-line tests of icefem.

Units: metres, except water_glass_mm.msh (millimetres; read it with scale 1e-3).
All .msh files are Gmsh 4.1 ASCII written by the gmsh Python API (OCC kernel), one fresh
gmsh.initialize()/finalize() per file, General.NumThreads = 1, Mesh.Algorithm = 6
(Frontal-Delaunay), Mesh.Algorithm3D = 1 (Delaunay), so reruns give identical files.
Orientations are NOT fixed: the files hold what Gmsh writes.

Files written next to this script (whatever the cwd):
  cup_occ.msh         obstacle surface, triangles only (physical surface "cup", no tets):
                      OCC cylinder r 0.04, h 0.06 (base z = 0) cut by a cylinder r 0.035 from
                      z = 0.005 to 0.07: a cup with a 5 mm floor and 5 mm wall, open top.
                      All boundary faces of the solid, Mesh.MeshSizeMax 0.006, generate(2).
  glass_occ.msh       the same for a glass (physical surface "glass"): cylinder r 0.034,
                      h 0.10 minus cylinder r 0.0315 from z = 0.003 to 0.11 (3 mm floor,
                      2.5 mm wall), MeshSizeMax 0.006.
  water_in_cup.msh    tets of a water ball r 0.025, centre (0, 0, 0.031): its lowest point is
                      1 mm above the cup floor. Physical volume "water", physical surface
                      "shell" (its boundary: the file also holds those triangles).
                      MeshSizeMax 0.008.
  water_glass_mm.msh  tets of a water cylinder r 30, h 60, base z = 3.5, IN MILLIMETRES
                      (0.5 mm above the glass floor when read with scale 1e-3). Physical
                      volume "water" only (so only tets are saved). MeshSizeMax 8.
  water_glass.msh     the same cylinder in metres (r 0.030, h 0.060, base z 0.0035),
                      MeshSizeMax 0.008.
  named_faces.msh     tets of the box [0, 0.04] x [0, 0.04] x [0, 0.03]: physical volume
                      "water", physical surfaces "bottom" (z = 0), "top" (z = 0.03) and
                      "side" (the four others). MeshSizeMax 0.01.
  blob.stl            ASCII STL, surface only: an ellipsoid with semi-axes 0.02 x 0.015 x
                      0.012 centred at the origin (a level-2 subdivided icosahedron mapped
                      onto it with numpy: 320 triangles, 162 vertices), closed and
                      consistently outward (normals written as computed from the vertices).
  blob_to_tets.geo    the Gmsh .geo script turning blob.stl into tets with Gmsh's command
                      line (see its header; not run by this script).

Measured (see the printed report): cup_occ.msh and glass_occ.msh are closed and orientable
but NOT consistently oriented: every face is outward except the cavity floor (the face the
inner cylinder's bottom cap leaves), which Gmsh writes facing down into the material
(273 of 2578 triangles for the cup, 223 of 3284 for the glass). glass_occ.msh is ~165 kB at
the requested size 0.006 (0.0065 would give ~140 kB). All tets are positively oriented.

After writing, the script reads the files back with its own small 4.1 reader and prints
facts about them: for the obstacle surfaces the triangle count, closedness, directed edges
used twice, signed volume and inward-facing triangles; for the tet meshes node/tet counts,
bounding box, negatively oriented tets and the clearance to the cup/glass material.

Run (needs the gmsh and numpy pip packages; generated with gmsh 4.15.2, numpy 2.4.6):
  /work/user_scenes/venv/bin/python solver_tests/data/user_meshes/make_user_meshes.py
"""

import math
import os
import sys

import gmsh
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

# Meridian (r, z) polygons of the cup and glass solids (counter-clockwise), metres.
CUP_RZ = [(0.0, 0.0), (0.04, 0.0), (0.04, 0.06), (0.035, 0.06), (0.035, 0.005), (0.0, 0.005)]
GLASS_RZ = [(0.0, 0.0), (0.034, 0.0), (0.034, 0.10), (0.0315, 0.10), (0.0315, 0.003),
            (0.0, 0.003)]


# ----------------------------------------------------------------------------- writing
def start(name, size_max):
    gmsh.initialize()
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.Algorithm", 6)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 0)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size_max)
    gmsh.model.add(name)


def finish(filename, dim):
    gmsh.model.mesh.generate(dim)
    gmsh.write(os.path.join(HERE, filename))
    gmsh.finalize()


def hollow(filename, group, r_out, h_out, r_in, z_in, z_in_top):
    start(group, 0.006)
    outer = gmsh.model.occ.addCylinder(0, 0, 0, 0, 0, h_out, r_out)
    inner = gmsh.model.occ.addCylinder(0, 0, z_in, 0, 0, z_in_top - z_in, r_in)
    out, _ = gmsh.model.occ.cut([(3, outer)], [(3, inner)])
    gmsh.model.occ.synchronize()
    faces = gmsh.model.getBoundary(out, oriented=False)
    gmsh.model.addPhysicalGroup(2, [t for _, t in faces], name=group)
    finish(filename, 2)


def water_ball():
    start("water_in_cup", 0.008)
    ball = gmsh.model.occ.addSphere(0, 0, 0.005 + 0.001 + 0.025, 0.025)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [ball], name="water")
    faces = gmsh.model.getBoundary([(3, ball)], oriented=False)
    gmsh.model.addPhysicalGroup(2, [t for _, t in faces], name="shell")
    finish("water_in_cup.msh", 3)


def water_cylinder(filename, z0, h, r, size_max):
    start(filename[:-4], size_max)
    cyl = gmsh.model.occ.addCylinder(0, 0, z0, 0, 0, h, r)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [cyl], name="water")
    finish(filename, 3)


def named_faces():
    start("named_faces", 0.01)
    box = gmsh.model.occ.addBox(0, 0, 0, 0.04, 0.04, 0.03)
    gmsh.model.occ.synchronize()
    gmsh.model.addPhysicalGroup(3, [box], name="water")
    groups = {"bottom": [], "top": [], "side": []}
    for _, tag in gmsh.model.getBoundary([(3, box)], oriented=False):
        _, _, zmin, _, _, zmax = gmsh.model.getBoundingBox(2, tag)
        if zmax < 1e-6:
            groups["bottom"].append(tag)
        elif zmin > 0.03 - 1e-6:
            groups["top"].append(tag)
        else:
            groups["side"].append(tag)
    for name, tags in groups.items():
        gmsh.model.addPhysicalGroup(2, sorted(tags), name=name)
    finish("named_faces.msh", 3)


def icosphere(level):
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(level):
        mid = {}

        def midpoint(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mid[key] = len(verts) - 1
            return mid[key]

        nf = []
        for a, b, c in f:
            ab, bc, ca = midpoint(a, b), midpoint(b, c), midpoint(c, a)
            nf += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = nf
    return np.array(verts), np.array(f)


def blob_stl():
    verts, faces = icosphere(2)
    x = verts * np.array([0.02, 0.015, 0.012])
    lines = ["solid blob"]
    for a, b, c in faces:
        n = np.cross(x[b] - x[a], x[c] - x[a])
        if np.dot(n, x[a] + x[b] + x[c]) < 0:  # star-shaped about 0: make it outward
            b, c = c, b
            n = -n
        n /= np.linalg.norm(n)
        lines.append("  facet normal %.9e %.9e %.9e" % tuple(n))
        lines.append("    outer loop")
        for p in (a, b, c):
            lines.append("      vertex %.9e %.9e %.9e" % tuple(x[p]))
        lines.append("    endloop")
        lines.append("  endfacet")
    lines.append("endsolid blob")
    with open(os.path.join(HERE, "blob.stl"), "w") as fh:
        fh.write("\n".join(lines) + "\n")


GEO = """\
// Turn blob.stl (a closed triangle surface, metres) into tets with Gmsh's command line:
//   /work/user_scenes/venv/bin/python /work/user_scenes/venv/bin/gmsh blob_to_tets.geo \\
//       -3 -nt 1 -format msh41 -o blob_tets.msh
// (the wheel's `gmsh` is a Python script with `#!/usr/bin/env python`: run it with the
// venv's python, not by its shebang). Relative paths in Merge are relative to this file.
// The STL triangles are kept as the boundary (no reparametrisation): only the volume is
// meshed, at most H (in the STL's units: H = 0.006 for a mm STL runs away, give 6).
// Works whatever the STL's triangle orientation (checked with flipped triangles). An open
// STL still exits 0 ("Warning : No tetrahedra in region 1"): the .msh then holds no tets
// (no $Nodes/$Elements at all), so count the tets of the output; exit codes prove nothing.
// Gmsh's t13 route (ClassifySurfaces{40*Pi/180, 1, 1, Pi}; CreateGeometry; before the
// Surface Loop) remeshes the surface instead, and fails on mixed orientations.
H = 0.006;
Mesh.MeshSizeMax = H;
Mesh.Algorithm3D = 1;
General.NumThreads = 1;
Merge "blob.stl";
Surface Loop(1) = Surface{:};
Volume(1) = {1};
Physical Volume("water") = {1};
"""


def write_geo():
    with open(os.path.join(HERE, "blob_to_tets.geo"), "w") as fh:
        fh.write(GEO)


# ----------------------------------------------------------------------------- reading
def read_msh41(path, entities=False):
    """Minimal Gmsh 4.1 ASCII reader: node coordinates, elements by type (node indices into
    the coordinate array), physical names; with entities=True also each element's entity tag."""
    with open(path) as fh:
        lines = [ln.strip() for ln in fh]
    i, nodes, elems, names, ents = 0, {}, {}, {}, {}
    while i < len(lines):
        sec = lines[i]
        i += 1
        if sec == "$PhysicalNames":
            for _ in range(int(lines[i])):
                i += 1
                d, t, nm = lines[i].split(maxsplit=2)
                names[(int(d), int(t))] = nm.strip('"')
            i += 1
        elif sec == "$Nodes":
            nblocks = int(lines[i].split()[0])
            i += 1
            for _ in range(nblocks):
                _, _, param, n = map(int, lines[i].split())
                i += 1
                tags = [int(lines[i + k]) for k in range(n)]
                i += n
                for k in range(n):
                    nodes[tags[k]] = [float(s) for s in lines[i + k].split()[:3]]
                i += n
                assert param == 0
        elif sec == "$Elements":
            nblocks = int(lines[i].split()[0])
            i += 1
            for _ in range(nblocks):
                _, etag, etype, n = map(int, lines[i].split())
                i += 1
                rows = [list(map(int, lines[i + k].split()))[1:] for k in range(n)]
                elems.setdefault(etype, []).extend(rows)
                ents.setdefault(etype, []).extend([etag] * n)
                i += n
    tag = np.array(sorted(nodes))
    xyz = np.array([nodes[t] for t in tag])
    index = {t: k for k, t in enumerate(tag)}
    out = {et: np.array([[index[t] for t in row] for row in rows]) for et, rows in elems.items()}
    if entities:
        return xyz, out, names, {et: np.array(v) for et, v in ents.items()}
    return xyz, out, names


def read_stl(path):
    pts = []
    with open(path) as fh:
        for ln in fh:
            s = ln.split()
            if s and s[0] == "vertex":
                pts.append(tuple(float(v) for v in s[1:4]))
    uniq, tri = {}, []
    for p in pts:
        tri.append(uniq.setdefault(p, len(uniq)))
    return np.array(list(uniq)), np.array(tri).reshape(-1, 3)


# ----------------------------------------------------------------------------- measuring
def signed_volume(x, tri):
    a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


def consistent_flips(tri):
    """BFS over edge-neighbours: flip[k] = True if triangle k must be reversed to agree
    with its component's seed; then each component is made to enclose positive volume."""
    edges = {}
    for k, t in enumerate(tri):
        for j in range(3):
            a, b = int(t[j]), int(t[(j + 1) % 3])
            edges.setdefault((min(a, b), max(a, b)), []).append((k, a < b))
    flip = np.full(len(tri), -1)
    comps, conflicts = [], 0
    for seed in range(len(tri)):
        if flip[seed] >= 0:
            continue
        flip[seed], queue, comp = 0, [seed], []
        while queue:
            k = queue.pop()
            comp.append(k)
            t = tri[k]
            for j in range(3):
                a, b = int(t[j]), int(t[(j + 1) % 3])
                fwd = (a < b) != bool(flip[k])  # direction as reoriented
                for m, mfwd in edges[(min(a, b), max(a, b))]:
                    if m == k:
                        continue
                    want = int(mfwd == fwd)  # neighbour must run the edge the other way
                    if flip[m] < 0:
                        flip[m] = want
                        queue.append(m)
                    elif flip[m] != want:
                        conflicts += 1
        comps.append(comp)
    return flip.astype(bool), comps, conflicts


def surface_facts(x, tri, rz=None):
    und, dirs = {}, {}
    for t in tri:
        for j in range(3):
            a, b = int(t[j]), int(t[(j + 1) % 3])
            und[(min(a, b), max(a, b))] = und.get((min(a, b), max(a, b)), 0) + 1
            dirs[(a, b)] = dirs.get((a, b), 0) + 1
    counts = np.array(list(und.values()))
    flip, comps, conflicts = consistent_flips(tri)
    fixed = tri.copy()
    fixed[flip] = fixed[flip][:, ::-1]
    for comp in comps:  # orient each component outward (positive enclosed volume)
        if signed_volume(x, fixed[comp]) < 0:
            fixed[comp] = fixed[comp][:, ::-1]
            flip[comp] = ~flip[comp]
    f = {
        "triangles": len(tri),
        "nodes used": len(np.unique(tri)),
        "edges": len(und),
        "edges used once": int((counts == 1).sum()),
        "edges used >2": int((counts > 2).sum()),
        "closed (every edge in 2 tris)": bool((counts == 2).all()),
        "directed edges used twice": sum(1 for v in dirs.values() if v >= 2),
        "components": len(comps),
        "BFS orientation conflicts": conflicts,
        "signed volume (as written)": signed_volume(x, tri),
        "signed volume (reoriented)": signed_volume(x, fixed),
        "inward triangles (BFS vs outward)": int(flip.sum()),
    }
    if rz is not None:  # probe 1 mm either side of each centroid against the true solid
        a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
        n = np.cross(b - a, c - a)
        n /= np.linalg.norm(n, axis=1)[:, None]
        cen = (a + b + c) / 3
        ahead = signed_distance_rz(cen + 1e-3 * n, rz) > 0
        behind = signed_distance_rz(cen - 1e-3 * n, rz) > 0
        f["inward triangles (1 mm probe)"] = int((~ahead & behind).sum())
        f["outward triangles (1 mm probe)"] = int((ahead & ~behind).sum())
        f["ambiguous (1 mm probe)"] = int(len(tri) - (ahead ^ behind).sum())
        f["area"] = float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum() / 2)
    return f, fixed


def signed_distance_rz(p, rz):
    """Distance from points p (n, 3) to the axisymmetric solid whose meridian polygon is rz
    (exact in 3D: the nearest solid point lies in the point's meridian half-plane);
    negative inside the material."""
    r, z = np.hypot(p[:, 0], p[:, 1]), p[:, 2]
    poly = np.array(rz)
    d = np.full(len(p), np.inf)
    inside = np.zeros(len(p), bool)
    for k in range(len(poly)):
        (r0, z0), (r1, z1) = poly[k], poly[(k + 1) % len(poly)]
        er, ez = r1 - r0, z1 - z0
        s = np.clip(((r - r0) * er + (z - z0) * ez) / (er * er + ez * ez), 0, 1)
        d = np.minimum(d, np.hypot(r - r0 - s * er, z - z0 - s * ez))
        cross = (z0 > z) != (z1 > z)
        with np.errstate(divide="ignore", invalid="ignore"):
            rx = r0 + (z - z0) * er / np.where(ez == 0, 1, ez)
        inside ^= cross & (r < rx)
    return np.where(inside, -d, d)


def point_triangle_distance(p, x, tri):
    """Distance from each point p to the triangle set (brute force, vectorised)."""
    a, b, c = x[tri[:, 0]], x[tri[:, 1]], x[tri[:, 2]]
    out = np.empty(len(p))

    def seg(q, u, v):
        e = v - u
        s = np.clip(np.einsum("ij,ij->i", q - u, e) / np.einsum("ij,ij->i", e, e), 0, 1)
        return np.linalg.norm(q - u - s[:, None] * e, axis=1)

    n = np.cross(b - a, c - a)
    n2 = np.einsum("ij,ij->i", n, n)
    for k, q in enumerate(p):
        qq = np.broadcast_to(q, a.shape)
        dist = np.einsum("ij,ij->i", qq - a, n) / np.sqrt(n2)
        proj = qq - (dist / np.sqrt(n2))[:, None] * n
        w_a = np.einsum("ij,ij->i", np.cross(b - proj, c - proj), n) / n2
        w_b = np.einsum("ij,ij->i", np.cross(c - proj, a - proj), n) / n2
        ok = (w_a >= 0) & (w_b >= 0) & (1 - w_a - w_b >= 0)
        edge = np.minimum(np.minimum(seg(qq, a, b), seg(qq, b, c)), seg(qq, c, a))
        out[k] = np.where(ok, np.abs(dist), edge).min()
    return out


def winding(p, x, tri):
    """Generalised winding number of the (consistently outward) triangle set at points p."""
    w = np.empty(len(p))
    for k, q in enumerate(p):
        a, b, c = x[tri[:, 0]] - q, x[tri[:, 1]] - q, x[tri[:, 2]] - q
        la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc
               + np.einsum("ij,ij->i", b, c) * la + np.einsum("ij,ij->i", c, a) * lb)
        w[k] = 2 * np.arctan2(num, den).sum() / (4 * math.pi)
    return w


def tet_facts(x, tets):
    a, b, c, d = (x[tets[:, k]] for k in range(4))
    det = np.einsum("ij,ij->i", b - a, np.cross(c - a, d - a))
    used = np.unique(tets)
    return {
        "nodes in file": len(x),
        "nodes used by tets": len(used),
        "tets": len(tets),
        "bbox min": x[used].min(axis=0).round(6).tolist(),
        "bbox max": x[used].max(axis=0).round(6).tolist(),
        "volume": float(np.abs(det).sum() / 6),
        "tets with det < 0": int((det < 0).sum()),
        "min |det|/6": float(np.abs(det).min() / 6),
    }


def report():
    def show(title, facts):
        print("\n== " + title)
        for k, v in facts.items():
            print("  %-36s %s" % (k, v))

    obstacles = {}
    for fname, rz in (("cup_occ.msh", CUP_RZ), ("glass_occ.msh", GLASS_RZ)):
        path = os.path.join(HERE, fname)
        x, el, names, ent = read_msh41(path, entities=True)
        f, fixed = surface_facts(x, el[2], rz)
        f = {"file size (bytes)": os.path.getsize(path), "physical names": names,
             "element types": sorted(el), **f}
        inward = np.any(fixed != el[2], axis=1)
        for e in np.unique(ent[2]):
            sel = ent[2] == e
            p = x[np.unique(el[2][sel])]
            r = np.hypot(p[:, 0], p[:, 1])
            f["  face %d (r %.4f..%.4f, z %.4f..%.4f)" % (
                e, r.min(), r.max(), p[:, 2].min(), p[:, 2].max())] = "%d tris, %d inward" % (
                sel.sum(), inward[sel].sum())
        show(fname, f)
        obstacles[fname] = (x, fixed, rz)

    x, tri = read_stl(os.path.join(HERE, "blob.stl"))
    f, _ = surface_facts(x, tri)
    f["analytic volume 4/3 pi abc"] = 4 / 3 * math.pi * 0.02 * 0.015 * 0.012
    show("blob.stl (%d bytes)" % os.path.getsize(os.path.join(HERE, "blob.stl")), f)

    for fname, obst, scale in (("water_in_cup.msh", "cup_occ.msh", 1.0),
                               ("water_glass_mm.msh", "glass_occ.msh", 1e-3),
                               ("water_glass.msh", "glass_occ.msh", 1.0),
                               ("named_faces.msh", None, 1.0)):
        path = os.path.join(HERE, fname)
        x, el, names = read_msh41(path)
        f = {"file size (bytes)": os.path.getsize(path), "physical names": names,
             "element types": {k: len(v) for k, v in sorted(el.items())}, **tet_facts(x, el[4])}
        if obst:
            ox, otri, rz = obstacles[obst]
            p = x[np.unique(el[4])] * scale
            sd = signed_distance_rz(p, rz)
            f["scale applied for distances"] = scale
            f["min distance to true solid"] = float(sd.min())
            f["nodes inside true solid"] = int((sd < 0).sum())
            f["min distance to meshed surface"] = float(point_triangle_distance(p, ox, otri).min())
            f["nodes inside meshed solid (winding)"] = int((winding(p, ox, otri) > 0.5).sum())
        show(fname, f)


if __name__ == "__main__":
    hollow("cup_occ.msh", "cup", 0.04, 0.06, 0.035, 0.005, 0.07)
    hollow("glass_occ.msh", "glass", 0.034, 0.10, 0.0315, 0.003, 0.11)
    water_ball()
    water_cylinder("water_glass_mm.msh", 3.5, 60.0, 30.0, 8.0)
    water_cylinder("water_glass.msh", 0.0035, 0.060, 0.030, 0.008)
    named_faces()
    blob_stl()
    write_geo()
    if "--no-report" not in sys.argv:
        report()
