#!/usr/bin/env python3
"""What the monotone conduction correction costs on Gmsh meshes: a cooling ice ball.

    heat_obtuse_ball.py [--binary PATH] [--plain-binary PATH] [--workdir DIR] [--sizes MM ...]
                        [--markdown FILE]

icefem cancels every positive off-diagonal entry K_ab of the P1 conduction matrix (obtuse
tets) with the edge conductance K_ab (e_a - e_b)(e_a - e_b)^T (src/thermal/monotone.rs).
This measures, on Gmsh balls, how far that moves the temperatures from the exact solution,
whether it still converges with the mesh, and checks icefem's implementation of it.

Problem. An ice ball, R = 0.03 m (gmsh OCC sphere, Mesh.MeshSizeMax = SIZES mm, 2-D algorithm
6, 3-D algorithm 1, one thread; physical volume "ice", surface "shell"; msh 4.1 ASCII),
k = 2.22 W/(m K), rho = 916 kg/m^3, c = 2050 J/(kg K); latent heat 0 and water's properties
set to ice's: the enthalpy model is linear. Convection h = 100 W/(m^2 K) to air at -21 degC on
"shell" (Bi = hR/k = 1.35). Backward Euler, dt = 5 s to 600 s (Fo = 0.79: the centre falls
from -1 to -18.7 degC). Initial conditions: "uniform" -1 degC; "warm core" -0.5 degC at the
nodes with |x| < R/3, -5 degC elsewhere; "warm node" -0.5 degC at the node nearest the centre,
-5 degC elsewhere (a test of the extrema only: no series). Warm nodes: a [[thermal.initial]]
box of +-1e-7 m each. Minimal static mechanics (no load, the bottom 3 mm held).

Per mesh and case, max |error| over t = 5 ... 600 s of T_c (the node nearest the centre,
against the series at its radius) and T_mean = sum m_i T_i / sum m_i (m_i = sum rho V_e / 4):
  exact  the series, theta = T - T_air = sum a_n exp(-lam_n^2 Fo) sin(lam_n r/R)/(lam_n r/R),
         1 - lam cot lam = Bi, a_n the projection of the initial profile (uniform: 4 (sin lam
         - lam cos lam)/(2 lam - sin 2 lam)); mean: sin(.)/(.) -> 3 (sin lam - lam cos lam)/lam^3;
  BE     the same with (1 + lam^2 dFo)^(-n) after n steps for exp(-lam^2 Fo): backward Euler
         on the PDE exact in space, so the error against it is the spatial error alone.
         N_TERMS terms (at step 1 they fall only like 1/n^2: the tail is < 1e-4 K).
Discrete solutions on icefem's own mesh (nodes and tets from its HDF5), in scikit-fem:
  uncorrected  k*laplace (P1), lumped capacity rho c (row sums of the P1 mass), convection
               lumped as icefem's (h A/3 per boundary-triangle node), backward Euler, same dt;
  corrected    the same with K_ab > 0 set to 0 and K_aa, K_bb += K_ab. icefem (--binary) must
               match it: max |icefem - corrected| over nodes and frames <= 1e-8 K, else exit
               code 1 (its Newton stops at 1e-10 of the largest diagonal x 1 K);
  --plain-binary  an icefem from before the correction, compared with the uncorrected run.
Also: edges with K_ab > 0; the slowest decay rate (K + H against the lumped capacity) over the
exact lam_1^2 k/(rho c R^2); new extrema, global (max T^{n+1} above max(max T^n, T_air), min
likewise) and local (a node ending a step above its own start and every edge neighbour's end,
or below them and, on the boundary, T_air: what an M-matrix excludes); the largest one-step
warming of a node (uniform: the exact solution cools everywhere, as does an M-matrix scheme);
orders log(e0/e1)/log(h0/h1), h the mean edge length; the median /stats/t_heat per step.

Needs gmsh, h5py, numpy, scipy, scikit-fem and an icefem binary. Writes meshes, scenes and
runs under --workdir (default target/heat_obtuse_ball/ in the repo); prints markdown tables,
also to --markdown FILE. On 2 cores: 3 min for --sizes 6 4 3 2.5 with --plain-binary (12
icefem runs; 2.5 mm: 34k tets, 13 s per run). Gmsh's 2 mm ball has 66k tets: left out.
"""

import argparse
import functools
import shlex
import subprocess
import sys
from pathlib import Path

import gmsh
import h5py
import numpy as np
import scipy.sparse as sp
from scipy.optimize import brentq
from scipy.sparse.linalg import eigsh, splu
from skfem import Basis, ElementTetP1, MeshTet, asm
from skfem.models.poisson import laplace, mass

R, K, RHO, C, H, T_AIR = 0.03, 2.22, 916.0, 2050.0, 100.0, -21.0
DT, END, N_TERMS, TARGET = 5.0, 600.0, 4000, 1e-8
SIZES = (6.0, 4.0, 3.0)  # mm
# initial (r/R, T) pieces; r/R = 0: the node nearest the centre (no series: extrema only)
CASES = {"uniform": [(1.0, -1.0)], "warm core": [(1 / 3, -0.5), (1.0, -5.0)],
         "warm node": [(0.0, -0.5), (1.0, -5.0)]}
SERIES = [case for case, pieces in CASES.items() if pieces[0][0] > 0]
ROOT = Path(__file__).resolve().parents[1]
SCENE = f"""# heat_obtuse_ball.py: an ice ball cooled in air, no phase change
[[body]]
file = "ball.msh"
[material]
density = {RHO}
lambda = 8.64e10
mu = 3.70e10
volumetric = "nodal"
[[dirichlet]]
min = [-0.05, -0.05, -0.05]
max = [0.05, 0.05, -0.027]
displacement = [0.0, 0.0, 0.0]
[thermal]
initial_temperature = {{t0}}
latent_heat = 0.0
ice_conductivity = {K}
water_conductivity = {K}
ice_heat_capacity = {C}
water_heat_capacity = {C}
[[thermal.convection]]
faces = ["shell"]
h = {H}
ambient_temperature = {T_AIR}
{{initial}}[time]
analysis = "static"
dt = {DT}
end_time = {END}
output_every = 1
[output]
tensor_matrices = false
"""


def make_mesh(size_mm, path):
    """Mesh the ball into `path`; the coordinates of its nodes."""
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        ball = gmsh.model.occ.addSphere(0, 0, 0, R)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [ball], name="ice")
        gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getBoundary([(3, ball)])],
                                    name="shell")
        for option, value in (("General.NumThreads", 1), ("Mesh.MeshSizeMax", size_mm * 1e-3),
                              ("Mesh.Algorithm", 6), ("Mesh.Algorithm3D", 1),
                              ("Mesh.RandomSeed", 1), ("Mesh.MshFileVersion", 4.1),
                              ("Mesh.Binary", 0)):
            gmsh.option.setNumber(option, value)
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
        return gmsh.model.mesh.getNodes()[1].reshape(-1, 3)
    finally:
        gmsh.finalize()


def warm(radius, pieces):
    """Which nodes start at the first piece's temperature."""
    return radius <= radius.min() if pieces[0][0] == 0 else radius < pieces[0][0] * R


def run_icefem(binary, folder, case, nodes, tag=""):
    """Write the case's scene next to ball.msh, run it; (rest positions, tets, frame times,
    temperatures [frames, nodes], t_heat per step)."""
    pieces, initial, name = CASES[case], "", case.replace(" ", "_")
    if len(pieces) > 1:  # one tiny box per warm node
        for p in nodes[warm(np.linalg.norm(nodes, axis=1), pieces)]:
            box = [", ".join(repr(float(v)) for v in p + d) for d in (-1e-7, 1e-7)]
            initial += (f"[[thermal.initial]]\nmin = [{box[0]}]\nmax = [{box[1]}]\n"
                        f"temperature = {pieces[0][1]}\n")
    (folder / f"{name}.toml").write_text(SCENE.format(t0=pieces[-1][1], initial=initial))
    output = folder / f"{name}{tag}.h5"
    done = subprocess.run([str(binary), "-q", "run", str(folder / f"{name}.toml"), "--output",
                           str(output), "--force"], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"icefem failed on {folder}/{name}: {done.stderr.strip()}")
    with h5py.File(output, "r") as f:
        frames = [f["frames"][n] for n in sorted(f["frames"])]
        return (f["mesh/rest_positions"][:], f["mesh/tets"][:],
                np.array([g.attrs["time"] for g in frames]),
                np.array([g["temperature"][:] for g in frames]), f["stats/t_heat"][:])


@functools.lru_cache
def eigenvalues(bi, n):
    """The first n roots of lam cos lam - (1 - Bi) sin lam = 0 (one in each (j pi, (j+1) pi))."""
    g = lambda lam: lam * np.cos(lam) - (1 - bi) * np.sin(lam)
    return np.array([brentq(g, max(j * np.pi, 1e-9), (j + 1) * np.pi) for j in range(n)])


def series(pieces, rho_c, times, kind):
    """theta at r/R = rho_c and the mean theta at `times`, of the 'exact' or 'BE' series."""
    lam = eigenvalues(H * R / K, N_TERMS)
    moment = lambda x: (np.sin(lam * x) - lam * x * np.cos(lam * x)) / lam**3  # int s^2 X ds
    bounds = [0.0] + [p for p, _ in pieces]
    a = sum((t - T_AIR) * (moment(o) - moment(i))
            for (_, t), i, o in zip(pieces, bounds, bounds[1:]))
    a = a / ((2 * lam - np.sin(2 * lam)) / (4 * lam**3))
    dfo = K / (RHO * C) * DT / R**2
    steps = np.asarray(times)[:, None] / DT
    decay = np.exp(-lam**2 * dfo * steps) if kind == "exact" else (1 + lam**2 * dfo) ** -steps
    return decay @ (a * np.sinc(lam * rho_c / np.pi)), decay @ (3 * a * moment(1.0))


def skfem_runs(x, tets, t0, steps):
    """Uncorrected and corrected runs [steps + 1, nodes], the lumped masses (m^3), the mesh
    edges, the number with K_ab > 0, the convection per node, and each operator's slowest
    decay rate over the exact one."""
    mesh = MeshTet(x.T.copy(), tets.T.copy())
    basis = Basis(mesh, ElementTetP1())
    stiff = (K * asm(laplace, basis)).tocsr()
    volume = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # V_e / 4 per node
    upper = sp.triu(stiff, 1).tocoo()
    pos = upper.data > 0
    a, b, v = upper.row[pos], upper.col[pos], upper.data[pos]
    fixed = (stiff + sp.coo_matrix((np.r_[v, v, -v, -v], (np.r_[a, b, a, b], np.r_[a, b, b, a])),
                                   shape=stiff.shape)).tocsr()
    assert sp.triu(fixed, 1).data.max() <= 1e-15 * stiff.diagonal().max()
    faces = mesh.facets[:, mesh.boundary_facets()]
    area = np.linalg.norm(np.cross(x[faces[1]] - x[faces[0]], x[faces[2]] - x[faces[0]]),
                          axis=1) / 2
    conv = np.bincount(faces.ravel(), weights=np.tile(H * area / 3, 3), minlength=len(x))
    cap = RHO * C * volume
    exact_rate = eigenvalues(H * R / K, 1)[0] ** 2 * K / (RHO * C * R**2)
    runs, rates = [], []
    for matrix in (stiff, fixed):
        system = (matrix + sp.diags(conv)).tocsc()
        rates.append(eigsh(system, k=1, M=sp.diags(cap).tocsc(), sigma=0)[0][0] / exact_rate)
        lu = splu(system + sp.diags(cap / DT).tocsc())
        T = [t0]
        for _ in range(steps):
            T.append(lu.solve(cap / DT * T[-1] + conv * T_AIR))
        runs.append(np.array(T))
    return runs, volume, mesh.edges, pos.sum(), conv, rates


def extrema(T, edges, conv):
    """New global max and min, local max and min, and the largest one-step warming (K)."""
    out = [(T[1:].max(axis=1) - np.maximum(T[:-1].max(axis=1), T_AIR)).max(),
           (np.minimum(T[:-1].min(axis=1), T_AIR) - T[1:].min(axis=1)).max()]
    e0, e1 = edges
    hi, lo = -np.inf, -np.inf
    for before, after in zip(T[:-1], T[1:]):
        top, bottom = before.copy(), np.where(conv > 0, np.minimum(before, T_AIR), before)
        np.maximum.at(top, e0, after[e1]), np.maximum.at(top, e1, after[e0])
        np.minimum.at(bottom, e0, after[e1]), np.minimum.at(bottom, e1, after[e0])
        hi, lo = max(hi, (after - top).max()), max(lo, (bottom - after).max())
    return out + [hi, lo, (T[1:] - T[:-1]).max()]


def study(binary, plain_binary, workdir, size):
    """Mesh, run both cases, compare: (mesh row, {case: row})."""
    folder = workdir / f"h_{size:g}mm"
    folder.mkdir(parents=True, exist_ok=True)
    nodes = make_mesh(size, folder / "ball.msh")
    rows = {}
    for case, pieces in CASES.items():
        x, tets, times, T_ice, t_heat = run_icefem(binary, folder, case, nodes)
        radius = np.linalg.norm(x, axis=1)
        assert np.array_equal(T_ice[0], np.where(warm(radius, pieces), pieces[0][1],
                                                 pieces[-1][1])), "icefem's initial temperature"
        (plain, fixed), volume, edges, positive, conv, rates = skfem_runs(
            x, tets, T_ice[0], len(times) - 1)
        c = np.argmin(radius)
        row = {"icefem vs fixed": np.abs(T_ice - fixed).max(), "t_heat": np.median(t_heat),
               "fixed vs plain": np.abs(fixed - plain).max()}
        if plain_binary:
            T_old, old_heat = run_icefem(plain_binary, folder, case, nodes, "_plain")[3:]
            row |= {"old vs plain": np.abs(T_old - plain).max(), "t_heat old": np.median(old_heat)}
        for kind in ("exact", "BE") if case in SERIES else ():
            ref_c, ref_m = series(pieces, radius[c] / R, times[1:], kind)
            for run, T in (("plain", plain), ("icefem", T_ice)):
                row[kind, run, "c"] = np.abs(T[1:, c] - T_AIR - ref_c).max()
                row[kind, run, "m"] = np.abs(T[1:] @ volume / volume.sum() - T_AIR - ref_m).max()
        for run, T in (("plain", plain), ("icefem", T_ice)):
            row["extrema", run] = extrema(T, edges, conv)
        rows[case] = row
    edge = np.linalg.norm(x[edges[0]] - x[edges[1]], axis=1)
    return dict(size=size, tets=len(tets), nodes=len(x), edges=edges.shape[1], positive=positive,
                h=edge.mean(), r_c=radius[c], volume=volume.sum(), rates=rates), rows


def tables(meshes, results):
    """The report's markdown tables."""
    old = "t_heat old" in results[0]["uniform"]
    out = ["| MeshSizeMax (mm) | tets | nodes | mean edge (mm) | edges with K_ab > 0 | centre node "
           "r (mm) | mesh volume / ball's | slowest decay / exact: uncorrected, corrected | "
           "t_heat median, uniform (ms/step)" + (": corrected, before" if old else "") + " |",
           "|" + "---|" * 9]
    for mr, res in zip(meshes, results):
        share = f"{mr['positive']} of {mr['edges']} ({100 * mr['positive'] / mr['edges']:.1f} %)"
        out.append(f"| {mr['size']:g} | {mr['tets']} | {mr['nodes']} | {mr['h'] * 1e3:.2f} | "
                   f"{share} | {mr['r_c'] * 1e3:.2f} | {mr['volume'] / (4 / 3 * np.pi * R**3):.4f}"
                   " | " + ", ".join(f"{r:.4f}" for r in mr["rates"]) + " | " + ", ".join(
                       f"{1e3 * res['uniform'][k]:.2f}" for k in ("t_heat", "t_heat old")[:1 + old])
                   + " |")
    label = {"plain": "uncorrected", "icefem": "corrected"}
    keys = [(r, q) for q in "cm" for r in label]
    for case, pieces in CASES.items():
        span = max(t for _, t in pieces) - T_AIR
        for kind in ("exact", "BE") if case in SERIES else ():
            out += ["", f"**{case}, against the {kind} series**: max over t = 5 … 600 s, K (% of "
                    f"{span:g} K), and the observed order from the coarser mesh", "", "| h (mm) | "
                    + " | ".join(f"T_{'c' if q == 'c' else 'mean'} {label[r]} | order"
                                 for r, q in keys) + " |", "|" + "---|" * 9]
            for i, (mr, res) in enumerate(zip(meshes, results)):
                cells = []
                for r, q in keys:
                    e, prev = res[case][kind, r, q], results[i - 1][case][kind, r, q]
                    order = np.log(prev / e) / np.log(meshes[i - 1]["h"] / mr["h"]) if i else 0
                    cells.append(f"{e:.4f} ({100 * e / span:.2f} %) | "
                                 + (f"{order:.2f}" if i else "—"))
                out.append(f"| {mr['size']:g} | " + " | ".join(cells) + " |")
        out += ["", f"**{case}: extrema and consistency** (K; new global max / global min / "
                "local max / local min / largest one-step warming of a node; ≤ 0: none)", "",
                "| h (mm) | uncorrected | corrected (icefem) "
                "| max \\|icefem − corrected skfem\\| "
                "| max \\|corrected − uncorrected\\|"
                + (" | max \\|icefem before − uncorrected\\|" if old else "") + " |",
                "|" + "---|" * (5 + old)]
        for mr, res in zip(meshes, results):
            row = res[case]
            fmt = lambda v: " / ".join(f"{e:.1e}" for e in v)
            out.append(f"| {mr['size']:g} | {fmt(row['extrema', 'plain'])} | "
                       f"{fmt(row['extrema', 'icefem'])} | {row['icefem vs fixed']:.1e} | "
                       f"{row['fixed vs plain']:.3f}"
                       + (f" | {row['old vs plain']:.1e}" if old else "") + " |")
    return "\n".join(out)


def main():
    """Run the study, print the tables; the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--binary", type=Path, default=ROOT / "target" / "release" / "icefem")
    parser.add_argument("--plain-binary", type=Path, help="an icefem without the correction")
    parser.add_argument("--workdir", type=Path, default=ROOT / "target" / "heat_obtuse_ball")
    parser.add_argument("--sizes", type=float, nargs="+", default=SIZES)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args()
    meshes, results = [], []
    plain = args.plain_binary.resolve() if args.plain_binary else None
    for size in args.sizes:
        mesh_row, rows = study(args.binary.resolve(), plain, args.workdir.resolve(), size)
        meshes.append(mesh_row)
        results.append(rows)
        print(f"h = {size:g} mm: {mesh_row['tets']} tets, icefem vs corrected skfem "
              + ", ".join(f"{r['icefem vs fixed']:.1e} K" for r in rows.values()), flush=True)
    report = tables(meshes, results)
    print(report)
    if args.markdown:
        command = "validation/heat_obtuse_ball.py " + shlex.join(sys.argv[1:])
        args.markdown.write_text(f"Command: `{command}`\n\n{report}\n")
    return 0 if all(r["icefem vs fixed"] <= TARGET for rs in results for r in rs.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
