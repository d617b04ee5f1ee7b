#!/usr/bin/env python3
"""icefem's limited conduction correction on Gmsh meshes: a cooling ice ball.

Obtuse tets give the P1 conduction matrix positive couplings K_ab, and plain P1 can then make
new local extrema. icefem (src/thermal/monotone.rs, Heat::step) solves each step with plain P1
first; every free node ending it above max(its start value, its neighbours' end values, its
air H_i T_air,i / H_i if it convects) + 1e-9 K, or below the min - 1e-9 K (neighbours: nodes
sharing an element; only nodes on edges positive in some element are checked), gets all those
edges of its marked, and the step is solved again with the marked edges whose assembled
K_ab > 0 cancelled by K_ab (e_a - e_b)(e_a - e_b)^T, until no edge is marked anew (marks
accumulate within a step, reset every step). This implements the scheme ("limited") in
scikit-fem, checks icefem (--binary) against it (max |icefem - limited| over nodes and frames
<= 1e-8 K, else exit code 1; icefem's heat Newton iterations, its passes on this linear
problem, against ours) and compares it with plain P1 ("plain") and the full correction
("upwinded": every K_ab > 0 cancelled). Optional --plain-binary / --upwinded-binary: icefem
builds without the correction / with the full one, checked against those runs and timed.

Ball R = 0.03 m (gmsh OCC sphere, Mesh.MeshSizeMax = --sizes mm, algorithms 6 and 1, one
thread), k = 2.22 W/(m K), rho = 916 kg/m^3, c = 2050 J/(kg K), latent heat 0, h = 100
W/(m^2 K) to -21 degC air (Bi = 1.35); static mechanics. Backward Euler, 120 steps. Cases:
uniform -1 degC, dt = 5 s; warm core -0.5 degC at |x| < R/3, -5 degC elsewhere; warm node
-0.5 degC at the node nearest the centre (no series); early uniform: dt = 0.5 s. Errors (max
over the steps) of T_c (node nearest the centre), any node, T_mean = sum m_i T_i / sum m_i,
against the series at each node's radius: exact, T - T_air = sum a_n exp(-lam_n^2 Fo)
sin(lam_n r/R)/(lam_n r/R), 1 - lam cot lam = Bi, and BE, exp(-lam^2 Fo) -> (1 + lam^2
dFo)^(-n): backward Euler exact in space (the spatial error alone). scikit-fem on icefem's
mesh: k*laplace (P1), lumped capacity and convection (h A/3 per triangle node) as icefem's.
Also: the slowest decay rate of K + H (lumped capacity) over the exact one; new global extrema
(above max(max T^n, T_air), below the min), new local extrema (the limiter's test without
tolerance), the largest one-step warming of a node; orders log(e0/e1)/log(h0/h1), h the mean
edge length; t_heat. Needs gmsh, h5py, numpy, scipy, scikit-fem; writes under --workdir.
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
STEPS, N_TERMS, TARGET, TOL = 120, 4000, 1e-8, 1e-9
SIZES = (6.0, 4.0, 3.0)  # mm
RUNS = ("plain", "limited", "upwinded")
# (initial (r/R, T) pieces, dt); r/R = 0: the node nearest the centre (no series)
CASES = {"uniform": ([(1.0, -1.0)], 5.0), "warm core": ([(1 / 3, -0.5), (1.0, -5.0)], 5.0),
         "warm node": ([(0.0, -0.5), (1.0, -5.0)], 5.0), "early uniform": ([(1.0, -1.0)], 0.5)}
ROOT = Path(__file__).resolve().parents[1]
SCENE = """# heat_obtuse_ball.py: an ice ball cooled in air, no phase change
body = [{{file = "ball.msh"}}]
material = {{density = {RHO}, lambda = 8.64e10, mu = 3.70e10, volumetric = "nodal"}}
dirichlet = [{{min = [-0.05, -0.05, -0.05], max = [0.05, 0.05, -0.027], displacement = [0, 0, 0]}}]
time = {{analysis = "static", dt = {dt}, end_time = {end}, output_every = 1}}
output = {{tensor_matrices = false}}
[thermal]
initial_temperature = {t0}
latent_heat = 0.0
ice_conductivity = {K}
water_conductivity = {K}
ice_heat_capacity = {C}
water_heat_capacity = {C}
convection = [{{faces = ["shell"], h = {H}, ambient_temperature = {T_AIR}}}]
{initial}"""


def make_mesh(size_mm, path):
    """Mesh the ball into `path` (msh 4.1 ASCII); the coordinates of its nodes."""
    gmsh.initialize()
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        ball = gmsh.model.occ.addSphere(0, 0, 0, R)
        gmsh.model.occ.synchronize()
        gmsh.model.addPhysicalGroup(3, [ball], name="ice")
        gmsh.model.addPhysicalGroup(2, [t for _, t in gmsh.model.getBoundary([(3, ball)])],
                                    name="shell")
        for option, value in (("General.NumThreads", 1), ("Mesh.MeshSizeMax", size_mm * 1e-3),
                              ("Mesh.Algorithm", 6), ("Mesh.Algorithm3D", 1), ("Mesh.Binary", 0),
                              ("Mesh.RandomSeed", 1), ("Mesh.MshFileVersion", 4.1)):
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
    """Write the case's scene next to ball.msh, run it; (rest positions, tets, temperatures
    [frames, nodes], t_heat and heat Newton iterations per step)."""
    (pieces, dt), initial, name = CASES[case], "", case.replace(" ", "_")
    if len(pieces) > 1:  # one tiny box per warm node
        for p in nodes[warm(np.linalg.norm(nodes, axis=1), pieces)]:
            box = [", ".join(repr(float(v)) for v in p + d) for d in (-1e-7, 1e-7)]
            initial += (f"[[thermal.initial]]\nmin = [{box[0]}]\nmax = [{box[1]}]\n"
                        f"temperature = {pieces[0][1]}\n")
    (folder / f"{name}.toml").write_text(SCENE.format(**globals(), t0=pieces[-1][1],
                                                      initial=initial, dt=dt, end=STEPS * dt))
    output = folder / f"{name}{tag}.h5"
    done = subprocess.run([str(binary), "-q", "run", str(folder / f"{name}.toml"), "--output",
                           str(output), "--force"], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"icefem failed on {folder.name}/{name}: {done.stderr.strip()}")
    with h5py.File(output, "r") as f:
        T = np.array([f["frames"][n]["temperature"][:] for n in sorted(f["frames"])])
        return (f["mesh/rest_positions"][:], f["mesh/tets"][:], T, f["stats/t_heat"][:],
                f["stats/heat_newton_iterations"][:])


@functools.lru_cache
def eigenvalues(bi, n):
    """The first n roots of lam cos lam - (1 - Bi) sin lam = 0 (one in each (j pi, (j+1) pi))."""
    g = lambda lam: lam * np.cos(lam) - (1 - bi) * np.sin(lam)
    return np.array([brentq(g, max(j * np.pi, 1e-9), (j + 1) * np.pi) for j in range(n)])


def series(pieces, rho, dt, kind):
    """theta [steps, nodes] at r/R = rho and the mean theta [steps], 'exact' or 'BE'."""
    lam = eigenvalues(H * R / K, N_TERMS)
    moment = lambda x: (np.sin(lam * x) - lam * x * np.cos(lam * x)) / lam**3  # int s^2 X ds
    bounds = [0.0] + [p for p, _ in pieces]
    a = 4 * lam**3 / (2 * lam - np.sin(2 * lam)) * sum(  # the initial profile's projection
        (t - T_AIR) * (moment(o) - moment(i)) for (_, t), i, o in zip(pieces, bounds, bounds[1:]))
    dfo, n = K / (RHO * C) * dt / R**2, np.arange(1, STEPS + 1)[:, None]
    decay = a * (np.exp(-lam**2 * dfo * n) if kind == "exact" else (1 + lam**2 * dfo) ** -n)
    return (np.hstack([decay @ np.sinc(np.outer(lam, rho[i:i + 500]) / np.pi)
                       for i in range(0, len(rho), 500)]), decay @ (3 * moment(1.0)))


class Ball:
    """The P1 operators of a mesh, the edges the limiter may cancel and the three schemes."""

    def __init__(self, x, tets):
        mesh = MeshTet(x.T.copy(), tets.T.copy())
        basis = Basis(mesh, ElementTetP1())
        self.stiff = (K * asm(laplace, basis)).tocsr()
        self.volume = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # V_e / 4 per node
        self.edges, self.lu = mesh.edges, {}
        faces = mesh.facets[:, mesh.boundary_facets()]
        area = np.linalg.norm(np.cross(*(x[faces[1:]] - x[faces[0]])), axis=1) / 2
        hA = lambda t: np.bincount(faces.ravel(), np.tile(H * area / 3 * t, 3), len(x))
        self.conv = hA(1.0)  # H_i (W/K); a convecting node's air: H_i T_air,i / H_i
        self.air = np.where(self.conv > 0, hA(T_AIR) / np.maximum(self.conv, 1e-300), np.nan)
        # each element's V grad(lambda_a).grad(lambda_b): the edges positive in some element
        d = np.stack([x[tets[:, j]] - x[tets[:, 0]] for j in (1, 2, 3)], axis=-1)
        inv = np.linalg.inv(d)
        grad = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
        pairs = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)])
        e, p = np.nonzero(np.einsum("epk,epk->ep", grad[:, pairs[:, 0]], grad[:, pairs[:, 1]])
                          * np.abs(np.linalg.det(d))[:, None] > 0)
        ends = np.sort(np.stack([tets[e, pairs[p, 0]], tets[e, pairs[p, 1]]], axis=1), axis=1)
        self.a, self.b = np.unique(ends, axis=0).T
        self.coupling = np.asarray(self.stiff[self.a, self.b]).ravel()  # assembled K_ab

    def system(self, cancel):
        """K + H with the edges `cancel` (a mask) cancelled where K_ab > 0; how many."""
        on = cancel & (self.coupling > 0)
        a, b, v = self.a[on], self.b[on], self.coupling[on]
        fix = sp.csr_matrix((np.r_[v, v, -v, -v], (np.r_[a, b, a, b], np.r_[a, b, b, a])),
                            shape=self.stiff.shape)
        return (self.stiff + fix + sp.diags(self.conv)).tocsc(), int(on.sum())

    def step(self, before, dt, cancel):
        """One backward-Euler step; (temperatures, edges cancelled)."""
        key = (dt, cancel.tobytes())
        if key not in self.lu:
            matrix, count = self.system(cancel)
            self.lu[key] = splu(matrix + sp.diags(self.volume * RHO * C / dt).tocsc()), count
        lu, count = self.lu[key]
        return lu.solve(self.volume * RHO * C / dt * before + self.conv * T_AIR), count

    def excess(self, before, after):
        """How far each node ends above max(its start, its neighbours' ends, its air), and
        below the min (K; <= 0: within)."""
        hi, lo = np.fmax(before, self.air), np.fmin(before, self.air)
        e0, e1 = self.edges
        np.maximum.at(hi, e0, after[e1]), np.maximum.at(hi, e1, after[e0])
        np.minimum.at(lo, e0, after[e1]), np.minimum.at(lo, e1, after[e0])
        return after - hi, lo - after

    def run(self, t0, dt, scheme):
        """[steps + 1, nodes] temperatures; per step the passes and the edges cancelled."""
        T, passes, cancelled = [t0], [], []
        for _ in range(STEPS):
            cancel, n = np.full(len(self.a), scheme == "upwinded"), 1
            while True:
                after, count = self.step(T[-1], dt, cancel)
                if scheme != "limited":
                    break
                up, down = self.excess(T[-1], after)
                flagged = (up > TOL) | (down > TOL)  # a flagged node marks all its edges
                marked = flagged[self.a] | flagged[self.b]
                if not (marked & ~cancel).any():
                    break
                cancel, n = cancel | marked, n + 1
            T.append(after), passes.append(n), cancelled.append(count)
        return np.array(T), np.array(passes), np.array(cancelled)


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
    nodes, rows = make_mesh(size, folder / "ball.msh"), {}
    for case, (pieces, dt) in CASES.items():
        x, tets, T_ice, t_heat, newton = run_icefem(binary, folder, case, nodes)
        radius = np.linalg.norm(x, axis=1)
        assert np.array_equal(T_ice[0], np.where(warm(radius, pieces), pieces[0][1],
                                                 pieces[-1][1])), "icefem's initial temperature"
        ball = Ball(x, tets) if not rows else ball  # one mesh: LUs reused across cases
        runs = {s: ball.run(T_ice[0], dt, s) for s in RUNS}
        T = {s: r[0] for s, r in runs.items()}
        (passes, cancelled), c = runs["limited"][1:], np.argmin(radius)
        row = {"icefem": np.abs(T_ice - T["limited"]).max(), "resolved": (passes > 1).sum(),
               "max passes": passes.max(), "cancelled": cancelled.sum(), "passes": passes.sum(),
               "newton": newton.sum(), "differ": (passes != newton).sum(),
               "limited vs plain": np.abs(T["limited"] - T["plain"]).max(),
               "upwinded vs plain": np.abs(T["upwinded"] - T["plain"]).max(),
               "t_heat limited": np.median(t_heat), "sum limited": t_heat.sum()}
        for scheme, other in others.items():
            T_other, heat = run_icefem(other, folder, case, nodes, "_" + scheme)[2:4]
            row |= {f"{scheme} icefem": np.abs(T_other - T[scheme]).max(),
                    f"t_heat {scheme}": np.median(heat), f"sum {scheme}": heat.sum()}
        T["limited"] = T_ice  # icefem's output in the error and extrema tables
        for kind in ("exact", "BE") if pieces[0][0] > 0 else ():
            ref, ref_m = series(pieces, radius / R, dt, kind)
            for s in RUNS:
                error = np.abs(T[s][1:] - T_AIR - ref)
                row[kind, s] = [error[:, c].max(), error.max(), np.abs(
                    T[s][1:] @ ball.volume / ball.volume.sum() - T_AIR - ref_m).max()]
        rows[case] = row | {("extrema", s): extrema(ball, T[s]) for s in RUNS}
    print(f"h = {size:g} mm: {len(tets)} tets, icefem vs limited "
          + ", ".join(f"{r['icefem']:.1e} K" for r in rows.values()), flush=True)
    edge = np.linalg.norm(x[ball.edges[0]] - x[ball.edges[1]], axis=1)
    slowest = lambda u: eigsh(ball.system(np.full(len(ball.a), u))[0], k=1, sigma=0,
                              M=sp.diags(RHO * C * ball.volume).tocsc())[0][0]
    exact = eigenvalues(H * R / K, 1)[0] ** 2 * K / (RHO * C * R**2)
    return dict(size=size, tets=len(tets), nodes=len(x), edges=ball.edges.shape[1],
                some=len(ball.a), positive=(ball.coupling > 0).sum(), h=edge.mean(),
                r_c=radius[c], volume=ball.volume.sum(),
                rates=[slowest(False) / exact, slowest(True) / exact]), rows


def tables(meshes, results, others):
    """The report's markdown tables."""
    timed, bar = ["limited", *others], lambda n: "|" + "---|" * n
    out = ["| MeshSizeMax (mm) | tets | nodes | mean edge (mm) | edges with K_ab > 0: in some "
           "element, assembled | centre node r (mm) | mesh volume / ball's | slowest decay / "
           "exact: plain, upwinded | t_heat median, uniform (ms/step): " + ", ".join(timed)
           + " |", bar(9)]
    for mr, res in zip(meshes, results):
        share = lambda n: f"{n} ({100 * n / mr['edges']:.1f} %)"
        out.append(f"| {mr['size']:g} | {mr['tets']} | {mr['nodes']} | {mr['h'] * 1e3:.2f} | "
                   f"{share(mr['some'])}, {share(mr['positive'])} of {mr['edges']} | "
                   f"{mr['r_c'] * 1e3:.2f} | {mr['volume'] / (4 / 3 * np.pi * R**3):.4f} | "
                   + ", ".join(f"{r:.4f}" for r in mr["rates"]) + " | " + ", ".join(
                       f"{1e3 * res['uniform']['t_heat ' + s]:.2f}" for s in timed) + " |")
    out += ["", f"**The limiter** ({STEPS} steps a run): steps solved more than once, most "
            "passes in a step, cancelled edges summed over the steps, passes summed (ours / "
            "icefem's heat Newton iterations, steps where they differ), Σ t_heat of the run (ms: "
            + ", ".join(timed) + ")", "", "| MeshSizeMax (mm) | case | steps re-solved | max "
            "passes | cancelled edges | passes: ours / icefem (differ) | Σ t_heat (ms) |", bar(7)]
    for mr, res in zip(meshes, results):
        for case, r in res.items():
            out.append(f"| {mr['size']:g} | {case} | {r['resolved']} | {r['max passes']} | "
                       f"{r['cancelled']} | {r['passes']} / {r['newton']} ({r['differ']}) | "
                       + ", ".join(f"{1e3 * r['sum ' + s]:.0f}" for s in timed) + " |")
    for case, (pieces, dt) in CASES.items():
        span = max(t for _, t in pieces) - T_AIR
        for kind in ("exact", "BE") if pieces[0][0] > 0 else ():
            out += ["", f"**{case}, against the {kind} series**: max over t = {dt:g} … "
                    f"{STEPS * dt:g} s, K (% of {span:g} K), and the observed order from the "
                    "coarser mesh", "", "| MeshSizeMax (mm) | scheme | T_c | order | any node | "
                    "order | T_mean | order |", bar(8)]
            for i, (mr, res) in enumerate(zip(meshes, results)):
                ratio = np.log(meshes[i - 1]["h"] / mr["h"])
                for s in RUNS:
                    cells = [f"{e:.4f} ({100 * e / span:.2f} %) | "
                             + (f"{np.log(p / e) / ratio:.2f}" if i else "—")
                             for e, p in zip(res[case][kind, s], results[i - 1][case][kind, s])]
                    out.append(f"| {mr['size']:g} | {s} | " + " | ".join(cells) + " |")
        out += ["", f"**{case}: extrema and consistency** (K; new global max / global min / "
                "local max / local min / largest one-step warming of a node; ≤ 0: none)", "",
                "| MeshSizeMax (mm) | plain | limited (icefem) | upwinded | max \\|icefem − "
                "limited\\| | max \\|limited − plain\\| | max \\|upwinded − plain\\|"
                + "".join(f" | max \\|{s} icefem − {s}\\|" for s in others) + " |",
                bar(7 + len(others))]
        for mr, res in zip(meshes, results):
            r, fmt = res[case], lambda v: " / ".join(f"{e:.1e}" for e in v)
            out.append(f"| {mr['size']:g} | " + " | ".join(fmt(r["extrema", s]) for s in RUNS)
                       + f" | {r['icefem']:.1e} | {r['limited vs plain']:.1e} | "
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
    meshes, results = zip(*(study(args.binary.resolve(), others, args.workdir.resolve(), size)
                            for size in args.sizes))
    report = tables(meshes, results, others)
    print(report)
    if args.markdown:
        command = "validation/heat_obtuse_ball.py " + shlex.join(sys.argv[1:])
        args.markdown.write_text(f"Command: `{command}`\n\n{report}\n")
    return 0 if all(r["icefem"] <= TARGET for rs in results for r in rs.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
