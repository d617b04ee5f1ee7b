#!/usr/bin/env python3
"""icefem's limited conduction correction on Gmsh meshes: a cooling ice ball.

    heat_obtuse_ball.py [--binary PATH] [--plain-binary PATH] [--upwinded-binary PATH]
                        [--workdir DIR] [--sizes MM ...] [--markdown FILE]

Obtuse tets give the P1 conduction matrix positive off-diagonal couplings K_ab, and plain P1
can then make new local extrema. icefem (src/thermal/monotone.rs, Heat::step) solves each step
with the plain P1 matrix first; every free node that ends it above max(its own start value, its
edge neighbours' end values, its air H_i T_air,i / H_i if it convects) + 1e-9 K, or below the
min - 1e-9 K, gets all its edges marked (neighbours: nodes sharing an element; only nodes on
edges with a positive coupling in some element are checked, and only such edges marked); the
step is solved again with the marked edges whose assembled K_ab > 0 cancelled by the edge
conductance K_ab (e_a - e_b)(e_a - e_b)^T, until no edge is marked anew (marks reset every
step). This script implements that scheme ("limited") in scikit-fem, checks icefem (--binary)
against it and measures its accuracy, convergence, passes and cost against plain P1 and the
full correction ("upwinded": every K_ab > 0 cancelled, what icefem did before: ~7 % too fast).

Problem. An ice ball, R = 0.03 m (gmsh OCC sphere, Mesh.MeshSizeMax = SIZES mm, 2-D algorithm
6, 3-D algorithm 1, one thread; physical volume "ice", surface "shell"; msh 4.1 ASCII),
k = 2.22 W/(m K), rho = 916 kg/m^3, c = 2050 J/(kg K); latent heat 0 and water's properties
set to ice's: the enthalpy model is linear. Convection h = 100 W/(m^2 K) to air at -21 degC on
"shell" (Bi = hR/k = 1.35). Backward Euler, dt = 5 s to 600 s (Fo = 0.79). Initial
conditions: "uniform" -1 degC; "warm core" -0.5 degC at the nodes with |x| < R/3, -5 degC
elsewhere; "warm node" -0.5 degC at the node nearest the centre, -5 degC elsewhere (extrema
only: no series). Warm nodes: a [[thermal.initial]] box of +-1e-7 m each. Minimal static
mechanics (no load, the bottom 3 mm held).

Per mesh and case, max |error| over t = 5 ... 600 s of T_c (the node nearest the centre,
against the series at its radius) and T_mean = sum m_i T_i / sum m_i (m_i = sum rho V_e / 4):
  exact  theta = T - T_air = sum a_n exp(-lam_n^2 Fo) sin(lam_n r/R)/(lam_n r/R), 1 - lam cot
         lam = Bi, a_n the projection of the initial profile; mean: sin(.)/(.) -> 3 (sin lam -
         lam cos lam)/lam^3;
  BE     the same with (1 + lam^2 dFo)^(-n) after n steps: backward Euler on the PDE exact in
         space, so the error against it is the spatial error alone. N_TERMS terms.
Discrete solutions on icefem's own mesh (nodes and tets from its HDF5), in scikit-fem: k*laplace
(P1), lumped capacity (row sums of the P1 mass), convection lumped as icefem's (h A/3 per
boundary-triangle node), backward Euler, same dt, direct solves; plain, limited, upwinded.
icefem must match the limited run: max |icefem - limited| over nodes and frames <= 1e-8 K,
else exit code 1 (its Newton stops at 1e-10 of the largest diagonal x 1 K; the problem is
linear, so its heat Newton iterations per step are its passes, compared with ours). Optional:
--plain-binary / --upwinded-binary, icefem builds without the correction / with the full one,
compared with the plain / upwinded runs and timed. Also: edges with a positive coupling; the
slowest decay rate (K + H against the lumped capacity) over the exact lam_1^2 k/(rho c R^2);
new global extrema (max T^{n+1} above max(max T^n, T_air), min likewise), new local extrema
(the limiter's test without its tolerance), the largest one-step warming of a node; orders
log(e0/e1)/log(h0/h1), h the mean edge length; the median /stats/t_heat per step.

Needs gmsh, h5py, numpy, scipy, scikit-fem and an icefem binary. Writes meshes, scenes and
runs under --workdir (default target/heat_obtuse_ball/ in the repo); prints markdown tables,
also to --markdown FILE. Gmsh's 2 mm ball has 66k tets: left out.
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
DT, END, N_TERMS, TARGET, TOL = 5.0, 600.0, 4000, 1e-8, 1e-9
SIZES = (6.0, 4.0, 3.0)  # mm
RUNS = ("plain", "limited", "upwinded")
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
    temperatures [frames, nodes], t_heat and heat Newton iterations per step)."""
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
        sys.exit(f"icefem failed on {folder.name}/{name}: {done.stderr.strip()}")
    with h5py.File(output, "r") as f:
        frames = [f["frames"][n] for n in sorted(f["frames"])]
        return (f["mesh/rest_positions"][:], f["mesh/tets"][:],
                np.array([g.attrs["time"] for g in frames]),
                np.array([g["temperature"][:] for g in frames]), f["stats/t_heat"][:],
                f["stats/heat_newton_iterations"][:])


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


class Ball:
    """The P1 operators of a mesh, the edges a limiter may cancel and the three schemes."""

    def __init__(self, x, tets):
        mesh = MeshTet(x.T.copy(), tets.T.copy())
        basis = Basis(mesh, ElementTetP1())
        self.stiff = (K * asm(laplace, basis)).tocsr()
        self.volume = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # V_e / 4 per node
        self.cap, self.edges = RHO * C * self.volume, mesh.edges
        faces = mesh.facets[:, mesh.boundary_facets()]
        area = np.linalg.norm(np.cross(x[faces[1]] - x[faces[0]], x[faces[2]] - x[faces[0]]),
                              axis=1) / 2
        hA = lambda t: np.bincount(faces.ravel(), np.tile(H * area / 3 * t, 3), len(x))
        self.conv = hA(1.0)  # H_i (W/K); the air of a convecting node: H_i T_air,i / H_i
        self.air = np.where(self.conv > 0, hA(T_AIR) / np.where(self.conv > 0, self.conv, 1),
                            np.nan)
        # V grad(lambda_a).grad(lambda_b) per element and edge: positive in some element?
        d = np.stack([x[tets[:, j]] - x[tets[:, 0]] for j in (1, 2, 3)], axis=-1)
        inv = np.linalg.inv(d)
        grad = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
        pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
        g = np.einsum("epk,epk->ep", grad[:, pairs[:, 0]], grad[:, pairs[:, 1]])
        g *= np.abs(np.linalg.det(d))[:, None] / 6
        e, p = np.nonzero(g > 0)
        ends = np.sort(np.stack([tets[e, pairs[p, 0]], tets[e, pairs[p, 1]]], axis=1), axis=1)
        self.a, self.b = np.unique(ends, axis=0).T
        self.coupling = np.asarray(self.stiff[self.a, self.b]).ravel()  # assembled K_ab
        n = len(self.a)
        self.incidence = sp.csr_matrix((np.ones(2 * n), (np.r_[self.a, self.b],
                                                         np.r_[0:n, 0:n])), (len(x), n))
        self.lu = {}

    def system(self, cancel):
        """K with the edges `cancel` (mask over self.a) cancelled where K_ab > 0, plus H."""
        on = cancel & (self.coupling > 0)
        a, b, v = self.a[on], self.b[on], self.coupling[on]
        fix = sp.coo_matrix((np.r_[v, v, -v, -v], (np.r_[a, b, a, b], np.r_[a, b, b, a])),
                            shape=self.stiff.shape)
        return (self.stiff + fix + sp.diags(self.conv)).tocsc(), int(on.sum())

    def step(self, before, cancel):
        """One backward-Euler step with `cancel`; (temperatures, edges cancelled)."""
        key = cancel.tobytes()
        if key not in self.lu:
            matrix, count = self.system(cancel)
            self.lu[key] = splu(matrix + sp.diags(self.cap / DT).tocsc()), count
        lu, count = self.lu[key]
        return lu.solve(self.cap / DT * before + self.conv * T_AIR), count

    def excess(self, before, after):
        """How far each node ends above max(its start, its neighbours' ends, its air) and
        below the min (K; <= 0: within)."""
        hi, lo = np.fmax(before, self.air), np.fmin(before, self.air)
        e0, e1 = self.edges
        np.maximum.at(hi, e0, after[e1]), np.maximum.at(hi, e1, after[e0])
        np.minimum.at(lo, e0, after[e1]), np.minimum.at(lo, e1, after[e0])
        return after - hi, lo - after

    def run(self, t0, steps, scheme):
        """[steps + 1, nodes] temperatures, and per step the passes and edges cancelled."""
        T, passes, cancelled = [t0], [], []
        for _ in range(steps):
            cancel = np.full(len(self.a), scheme == "upwinded")
            for n in range(1, len(self.a) + 2):
                after, count = self.step(T[-1], cancel)
                if scheme != "limited":
                    break
                up, down = self.excess(T[-1], after)
                marked = self.incidence.T @ ((up > TOL) | (down > TOL)).astype(float) > 0
                if not (marked & ~cancel).any():
                    break
                cancel = cancel | marked
            T.append(after), passes.append(n), cancelled.append(count)
        return np.array(T), np.array(passes), np.array(cancelled)

    def rate(self, cancel):
        """The slowest decay rate over the exact one."""
        exact = eigenvalues(H * R / K, 1)[0] ** 2 * K / (RHO * C * R**2)
        matrix = self.system(np.full(len(self.a), cancel))[0]
        return eigsh(matrix, k=1, M=sp.diags(self.cap).tocsc(), sigma=0)[0][0] / exact


def extrema(ball, T):
    """New global max and min, local max and min, and the largest one-step warming (K)."""
    local = np.array([[e.max() for e in ball.excess(b, a)] for b, a in zip(T[:-1], T[1:])])
    return [(T[1:].max(axis=1) - np.maximum(T[:-1].max(axis=1), T_AIR)).max(),
            (np.minimum(T[:-1].min(axis=1), T_AIR) - T[1:].min(axis=1)).max(),
            *local.max(axis=0), (T[1:] - T[:-1]).max()]


def study(binary, others, workdir, size):
    """Mesh, run the cases, compare: (mesh row, {case: row})."""
    folder = workdir / f"h_{size:g}mm"
    folder.mkdir(parents=True, exist_ok=True)
    nodes = make_mesh(size, folder / "ball.msh")
    rows = {}
    for case, pieces in CASES.items():
        x, tets, times, T_ice, t_heat, newton = run_icefem(binary, folder, case, nodes)
        radius = np.linalg.norm(x, axis=1)
        assert np.array_equal(T_ice[0], np.where(warm(radius, pieces), pieces[0][1],
                                                 pieces[-1][1])), "icefem's initial temperature"
        ball = Ball(x, tets)
        runs = {s: ball.run(T_ice[0], len(times) - 1, s) for s in RUNS}
        T = {s: r[0] for s, r in runs.items()}
        passes, cancelled = runs["limited"][1:]
        c = np.argmin(radius)
        row = {"icefem vs limited": np.abs(T_ice - T["limited"]).max(),
               "t_heat limited": np.median(t_heat), "sum t_heat limited": t_heat.sum(),
               "resolved": (passes > 1).sum(), "max passes": passes.max(),
               "cancelled": cancelled.sum(), "passes": passes.sum(), "newton": newton.sum(),
               "passes differ": (passes != newton).sum(),
               "limited vs plain": np.abs(T["limited"] - T["plain"]).max(),
               "upwinded vs plain": np.abs(T["upwinded"] - T["plain"]).max()}
        for scheme, other in others.items():
            T_other, heat = run_icefem(other, folder, case, nodes, "_" + scheme)[3:5]
            row |= {f"{scheme} icefem": np.abs(T_other - T[scheme]).max(),
                    f"t_heat {scheme}": np.median(heat), f"sum t_heat {scheme}": heat.sum()}
        T["limited"] = T_ice  # icefem's output in the error and extrema tables
        for kind in ("exact", "BE") if case in SERIES else ():
            ref_c, ref_m = series(pieces, radius[c] / R, times[1:], kind)
            for s in RUNS:
                row[kind, s, "c"] = np.abs(T[s][1:, c] - T_AIR - ref_c).max()
                row[kind, s, "m"] = np.abs(T[s][1:] @ ball.volume / ball.volume.sum()
                                           - T_AIR - ref_m).max()
        for s in RUNS:
            row["extrema", s] = extrema(ball, T[s])
        rows[case] = row
    edge = np.linalg.norm(x[ball.edges[0]] - x[ball.edges[1]], axis=1)
    return dict(size=size, tets=len(tets), nodes=len(x), edges=ball.edges.shape[1],
                some=len(ball.a), positive=(ball.coupling > 0).sum(), h=edge.mean(),
                r_c=radius[c], volume=ball.volume.sum(),
                rates=[ball.rate(False), ball.rate(True)]), rows


def tables(meshes, results, others):
    """The report's markdown tables."""
    timed = ["limited", *others]
    out = ["| MeshSizeMax (mm) | tets | nodes | mean edge (mm) | edges with K_ab > 0: in some "
           "element, assembled | centre node r (mm) | mesh volume / ball's | slowest decay / "
           "exact: plain, upwinded | t_heat median, uniform (ms/step): " + ", ".join(timed)
           + " |", "|" + "---|" * 9]
    for mr, res in zip(meshes, results):
        share = lambda n: f"{n} ({100 * n / mr['edges']:.1f} %)"
        out.append(f"| {mr['size']:g} | {mr['tets']} | {mr['nodes']} | {mr['h'] * 1e3:.2f} | "
                   f"{share(mr['some'])}, {share(mr['positive'])} of {mr['edges']} | "
                   f"{mr['r_c'] * 1e3:.2f} | {mr['volume'] / (4 / 3 * np.pi * R**3):.4f} | "
                   + ", ".join(f"{r:.4f}" for r in mr["rates"]) + " | " + ", ".join(
                       f"{1e3 * res['uniform']['t_heat ' + s]:.2f}" for s in timed) + " |")
    out += ["", "**The limiter** (120 steps per run): steps solved again, most passes in a step, "
            "edges cancelled summed over the steps, passes summed (scikit-fem / icefem's heat "
            "Newton iterations, steps where they differ), t_heat summed over the run (ms: "
            + ", ".join(timed) + ")", "", "| h (mm) | case | steps re-solved | max passes | "
            "edges cancelled | passes: ours / icefem (differ) | Σ t_heat (ms) |",
            "|" + "---|" * 7]
    for mr, res in zip(meshes, results):
        for case, r in res.items():
            out.append(f"| {mr['size']:g} | {case} | {r['resolved']} | {r['max passes']} | "
                       f"{r['cancelled']} | {r['passes']} / {r['newton']} "
                       f"({r['passes differ']}) | "
                       + ", ".join(f"{1e3 * r['sum t_heat ' + s]:.0f}" for s in timed) + " |")
    keys = [(s, q) for q in "cm" for s in RUNS]
    for case, pieces in CASES.items():
        span = max(t for _, t in pieces) - T_AIR
        for kind in ("exact", "BE") if case in SERIES else ():
            out += ["", f"**{case}, against the {kind} series**: max over t = 5 … 600 s, K (% of "
                    f"{span:g} K), and the observed order from the coarser mesh", "", "| h (mm) | "
                    + " | ".join(f"T_{'c' if q == 'c' else 'mean'} {s} | order"
                                 for s, q in keys) + " |", "|" + "---|" * 13]
            for i, (mr, res) in enumerate(zip(meshes, results)):
                cells = []
                for s, q in keys:
                    e, prev = res[case][kind, s, q], results[i - 1][case][kind, s, q]
                    order = np.log(prev / e) / np.log(meshes[i - 1]["h"] / mr["h"]) if i else 0
                    cells.append(f"{e:.4f} ({100 * e / span:.2f} %) | "
                                 + (f"{order:.2f}" if i else "—"))
                out.append(f"| {mr['size']:g} | " + " | ".join(cells) + " |")
        out += ["", f"**{case}: extrema and consistency** (K; new global max / global min / "
                "local max / local min / largest one-step warming of a node; ≤ 0: none)", "",
                "| h (mm) | plain | limited (icefem) | upwinded | max \\|icefem − limited\\| | "
                "max \\|limited − plain\\| | max \\|upwinded − plain\\|"
                + "".join(f" | max \\|{s} icefem − {s}\\|" for s in others) + " |",
                "|" + "---|" * (7 + len(others))]
        for mr, res in zip(meshes, results):
            r = res[case]
            fmt = lambda v: " / ".join(f"{e:.1e}" for e in v)
            out.append(f"| {mr['size']:g} | " + " | ".join(fmt(r["extrema", s]) for s in RUNS)
                       + f" | {r['icefem vs limited']:.1e} | {r['limited vs plain']:.1e} | "
                       f"{r['upwinded vs plain']:.3f}"
                       + "".join(f" | {r[s + ' icefem']:.1e}" for s in others) + " |")
    return "\n".join(out)


def main():
    """Run the study, print the tables; the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--binary", type=Path, default=ROOT / "target" / "release" / "icefem")
    parser.add_argument("--plain-binary", type=Path, help="an icefem without the correction")
    parser.add_argument("--upwinded-binary", type=Path, help="an icefem with the full one")
    parser.add_argument("--workdir", type=Path, default=ROOT / "target" / "heat_obtuse_ball")
    parser.add_argument("--sizes", type=float, nargs="+", default=SIZES)
    parser.add_argument("--markdown", type=Path)
    args = parser.parse_args()
    others = {s: b.resolve() for s, b in (("plain", args.plain_binary),
                                          ("upwinded", args.upwinded_binary)) if b}
    meshes, results = [], []
    for size in args.sizes:
        mesh_row, rows = study(args.binary.resolve(), others, args.workdir.resolve(), size)
        meshes.append(mesh_row)
        results.append(rows)
        print(f"h = {size:g} mm: {mesh_row['tets']} tets, icefem vs limited "
              + ", ".join(f"{r['icefem vs limited']:.1e} K" for r in rows.values()), flush=True)
    report = tables(meshes, results, others)
    print(report)
    if args.markdown:
        command = "validation/heat_obtuse_ball.py " + shlex.join(sys.argv[1:])
        args.markdown.write_text(f"Command: `{command}`\n\n{report}\n")
    return 0 if all(r["icefem vs limited"] <= TARGET for rs in results for r in rs.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
