#!/usr/bin/env python3
"""icefem's limited conduction correction on Gmsh meshes: a cooling ice ball.

Problem. Ice ball R = 0.03 m (gmsh OCC sphere, Mesh.MeshSizeMax = --sizes mm, algorithms 6
and 1, one thread), k = 2.22 W/(m K), rho = 916 kg/m^3, c = 2050 J/(kg K), latent heat 0,
h = 100 W/(m^2 K) to -21 degC air on the whole surface (Bi = hR/k = 1.35); static
mechanics. Backward Euler, 120 steps. Cases: "uniform" -1 degC, dt = 5 s; "warm core"
-0.5 degC at |x| < R/3, -5 degC elsewhere, dt = 5 s; "warm node" -0.5 degC at the node
nearest the centre, -5 degC elsewhere, dt = 5 s (not radial: no series); "early uniform"
-1 degC, dt = 0.5 s.

Discrete schemes, all on icefem's own mesh (nodes and tets read from its HDF5 output):
P1 stiffness K = k*laplace (scikit-fem), lumped capacity rho c V_i (V_i = sum V_e / 4),
lumped convection H_i = sum h A / 3 over the node's boundary triangles, backward Euler:
(rho c V / dt + K + H) T^{n+1} = rho c V / dt T^n + H T_air.
  plain    K as assembled.
  full     every edge whose assembled K_ab > 0 cancelled in every step: K + sum K_ab (e_a -
           e_b)(e_a - e_b)^T (an M-matrix; the rejected alternative, not what icefem does).
  limited  icefem's scheme (src/thermal/monotone.rs, Heat::step), reimplemented: each step
           is solved with plain P1 first; every node that ends it as a new local extremum
           (below) marks all of its edges that are positive in some element (V grad
           lambda_a . grad lambda_b > 0), and the step is solved again from T^n with the
           marked edges whose assembled K_ab > 0 cancelled; passes repeat until a pass marks
           no new edge. Marks accumulate within a step and start empty in every step.
  icefem   the run of --binary, which must equal "limited" to <= 1e-8 K at every node and
           frame.
New local extremum: node i ends a step above max(T_i^n, T_j^{n+1} for its edge neighbours
j, T_air if it convects) + 1e-9 K, or below the min - 1e-9 K (icefem's EXTREMUM_TOLERANCE).
Counted per scheme as node-steps and steps; "largest" is the largest excess (K).

Compared against the radial series at each node's radius r: exact, T - T_air = sum a_n
exp(-lam_n^2 Fo) sin(lam_n r/R)/(lam_n r/R), 1 - lam cot lam = Bi, a_n the projection of the
initial profile; and "BE", exp(-lam^2 Fo) -> (1 + lam^2 dFo)^(-n) after n steps: backward
Euler exact in space, so the error against it is the spatial error alone. Errors are the max
over the 120 steps of |T_c - series| (T_c: the node nearest the centre), of any node's, and of
T_mean = sum V_i T_i / sum V_i against the series' mean ("limited": the reimplementation's
run). Orders log(e0/e1)/log(h0/h1), h the mean edge length. Slowest decay: the smallest
generalised eigenvalue of K + H against the lumped capacity, over the exact lam_1^2 k/(rho c
R^2).

icefem's passes and cancelled edges per step (/stats/heat_passes, heat_cancelled_edges: the
edges cancelled in the step's last pass) are compared with the reimplementation's. Exit code 1
if icefem differs from "limited" by more than 1e-8 K at any node and frame, if its passes or
cancelled edges differ in any step, or if the limited or icefem run has a new local extremum.
Needs gmsh, h5py, numpy, scipy, scikit-fem; writes meshes, scenes and runs under --workdir.
"""

import argparse
import functools
import shlex
import subprocess
import sys
import time
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
STEPS, N_TERMS = 120, 4000
AGREEMENT = 1e-8  # K: icefem against the limited reimplementation
EXTREMUM_TOLERANCE = 1e-9  # K: icefem's (src/thermal/monotone.rs)
SIZES = (6.0, 4.0, 3.0)  # mm
SCHEMES = ("plain", "limited", "full")
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


def run_icefem(binary, folder, case, nodes):
    """Write the case's scene next to ball.msh and run it; (rest positions, tets,
    temperatures [frames, nodes], heat passes and cancelled edges per step)."""
    (pieces, dt), initial, name = CASES[case], "", case.replace(" ", "_")
    if len(pieces) > 1:  # one tiny box per warm node
        for p in nodes[warm(np.linalg.norm(nodes, axis=1), pieces)]:
            box = [", ".join(repr(float(v)) for v in p + d) for d in (-1e-7, 1e-7)]
            initial += (f"[[thermal.initial]]\nmin = [{box[0]}]\nmax = [{box[1]}]\n"
                        f"temperature = {pieces[0][1]}\n")
    scene, output = folder / f"{name}.toml", folder / f"{name}.h5"
    scene.write_text(SCENE.format(**globals(), t0=pieces[-1][1], initial=initial, dt=dt,
                                  end=STEPS * dt))
    done = subprocess.run([str(binary), "-q", "run", str(scene), "--output", str(output),
                           "--force"], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"icefem failed on {folder.name}/{name}: {done.stderr.strip()}")
    with h5py.File(output, "r") as f:
        T = np.array([f["frames"][n]["temperature"][:] for n in sorted(f["frames"])])
        return (f["mesh/rest_positions"][:], f["mesh/tets"][:], T, f["stats/heat_passes"][:],
                f["stats/heat_cancelled_edges"][:])


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
        """One backward-Euler step from `before`; (temperatures, edges cancelled). The plain
        and full systems' factors are kept, the limiter's are not."""
        key = (dt, cancel.any(), cancel.all())
        if key in self.lu:
            lu, count = self.lu[key]
        else:
            matrix, count = self.system(cancel)
            lu = splu(matrix + sp.diags(self.volume * RHO * C / dt).tocsc())
            if cancel.all() or not cancel.any():
                self.lu[key] = lu, count
        return lu.solve(self.volume * RHO * C / dt * before + self.conv * T_AIR), count

    def excess(self, before, after):
        """How far each node ends beyond its bounds: above max(its start, its neighbours'
        ends, its air), or below the min (K; <= 0: within)."""
        hi, lo = np.fmax(before, self.air), np.fmin(before, self.air)
        e0, e1 = self.edges
        np.maximum.at(hi, e0, after[e1]), np.maximum.at(hi, e1, after[e0])
        np.minimum.at(lo, e0, after[e1]), np.minimum.at(lo, e1, after[e0])
        return np.maximum(after - hi, lo - after)

    def run(self, t0, dt, scheme):
        """[steps + 1, nodes] temperatures; per step the passes and the edges cancelled."""
        T, passes, cancelled = [t0], [], []
        for _ in range(STEPS):
            cancel, n = np.full(len(self.a), scheme == "full"), 0
            while True:
                after, count = self.step(T[-1], dt, cancel)
                n += 1
                if scheme != "limited":
                    break
                flagged = self.excess(T[-1], after) > EXTREMUM_TOLERANCE
                marked = (flagged[self.a] | flagged[self.b]) & ~cancel  # all a node's edges
                if not marked.any():
                    break
                cancel = cancel | marked
            T.append(after), passes.append(n), cancelled.append(count)
        return np.array(T), np.array(passes), np.array(cancelled)


def extrema(ball, T):
    """New local extrema of a run: (node-steps, steps, largest excess in K)."""
    excess = np.array([ball.excess(b, a) for b, a in zip(T[:-1], T[1:])])
    new = excess > EXTREMUM_TOLERANCE
    return int(new.sum()), int(new.any(axis=1).sum()), excess.max()


def study(binary, workdir, size):
    """Mesh, run the cases, compare: (mesh row, {case: row})."""
    folder = workdir / f"h_{size:g}mm"
    folder.mkdir(parents=True, exist_ok=True)
    nodes, rows, ball = make_mesh(size, folder / "ball.msh"), {}, None
    for case, (pieces, dt) in CASES.items():
        x, tets, T_ice, ice_passes, ice_cancelled = run_icefem(binary, folder, case, nodes)
        radius = np.linalg.norm(x, axis=1)
        assert np.array_equal(T_ice[0], np.where(warm(radius, pieces), pieces[0][1],
                                                 pieces[-1][1])), "icefem's initial temperature"
        ball = ball or Ball(x, tets)  # one mesh for all cases
        runs = {s: ball.run(T_ice[0], dt, s) for s in SCHEMES}
        T = {s: r[0] for s, r in runs.items()} | {"icefem": T_ice}
        (passes, cancelled), c = runs["limited"][1:], np.argmin(radius)
        row = {"icefem vs limited": np.abs(T_ice - T["limited"]).max(),
               "resolved": (passes > 1).sum(), "passes": passes.sum(), "max passes": passes.max(),
               "cancelled": cancelled.sum(), "most cancelled": cancelled.max(),
               "icefem resolved": (ice_passes > 1).sum(), "icefem cancelled": ice_cancelled.sum(),
               "differ": ((passes != ice_passes) | (cancelled != ice_cancelled)).sum(),
               "limited vs plain": np.abs(T["limited"] - T["plain"]).max()}
        for kind in ("exact", "BE") if pieces[0][0] > 0 else ():
            ref, ref_mean = series(pieces, radius / R, dt, kind)
            for s in SCHEMES:
                error = np.abs(T[s][1:] - T_AIR - ref)
                mean = T[s][1:] @ ball.volume / ball.volume.sum() - T_AIR
                row[kind, s] = [error[:, c].max(), error.max(), np.abs(mean - ref_mean).max()]
        rows[case] = row | {("extrema", s): extrema(ball, T[s]) for s in (*SCHEMES, "icefem")}
    edge = np.linalg.norm(x[ball.edges[0]] - x[ball.edges[1]], axis=1)
    slowest = lambda full: eigsh(ball.system(np.full(len(ball.a), full))[0], k=1, sigma=0,
                                 M=sp.diags(RHO * C * ball.volume).tocsc())[0][0]
    exact = eigenvalues(H * R / K, 1)[0] ** 2 * K / (RHO * C * R**2)
    return dict(size=size, tets=len(tets), nodes=len(x), edges=ball.edges.shape[1],
                some=len(ball.a), positive=(ball.coupling > 0).sum(), h=edge.mean(),
                r_c=radius[c], volume=ball.volume.sum(),
                rates=[slowest(False) / exact, slowest(True) / exact]), rows


def tables(meshes, results):
    """The report's markdown tables."""
    bar = lambda n: "|" + "---|" * n
    out = ["| MeshSizeMax (mm) | tets | nodes | mean edge (mm) | edges with K_ab > 0: in some "
           "element, assembled | centre node r (mm) | mesh volume / ball's | slowest decay / "
           "exact: plain, full |", bar(8)]
    for mr in meshes:
        share = lambda n: f"{n} ({100 * n / mr['edges']:.1f} %)"
        out.append(f"| {mr['size']:g} | {mr['tets']} | {mr['nodes']} | {mr['h'] * 1e3:.2f} | "
                   f"{share(mr['some'])}, {share(mr['positive'])} of {mr['edges']} | "
                   f"{mr['r_c'] * 1e3:.2f} | {mr['volume'] / (4 / 3 * np.pi * R**3):.4f} | "
                   + ", ".join(f"{r:.4f}" for r in mr["rates"]) + " |")
    out += ["", f"**The limiter** ({STEPS} steps a run): steps solved more than once and edges "
            "cancelled summed over the steps (limited reimplementation / icefem's stats), "
            "passes summed over the steps and most in one, most cancelled edges in one step, "
            "steps where icefem's passes or cancelled edges differ from the reimplementation's, "
            "max |icefem − limited| and max |limited − plain| over nodes and frames (K)", "",
            "| MeshSizeMax (mm) | case | steps re-solved | cancelled edges | passes: sum, most | "
            "most cancelled | steps differing | \\|icefem − limited\\| | \\|limited − "
            "plain\\| |", bar(9)]
    for mr, res in zip(meshes, results):
        for case, r in res.items():
            out.append(f"| {mr['size']:g} | {case} | {r['resolved']} / {r['icefem resolved']} | "
                       f"{r['cancelled']} / {r['icefem cancelled']} | {r['passes']}, "
                       f"{r['max passes']} | {r['most cancelled']} | {r['differ']} | "
                       f"{r['icefem vs limited']:.1e} | {r['limited vs plain']:.1e} |")
    out += ["", "**New local extrema** (> 1e-9 K beyond the node's start, its neighbours' ends "
            "and its air): node-steps / steps / largest excess (K; ≤ 0: none)", "",
            "| MeshSizeMax (mm) | case | plain | limited | icefem | full |", bar(6)]
    for mr, res in zip(meshes, results):
        for case, r in res.items():
            out.append(f"| {mr['size']:g} | {case} | " + " | ".join(
                "{} / {} / {:.1e}".format(*r["extrema", s])
                for s in ("plain", "limited", "icefem", "full")) + " |")
    for case, (pieces, dt) in CASES.items():
        span = max(t for _, t in pieces) - T_AIR
        for kind in ("exact", "BE") if pieces[0][0] > 0 else ():
            out += ["", f"**{case}, against the {kind} series**: max over t = {dt:g} … "
                    f"{STEPS * dt:g} s, K (% of {span:g} K), and the observed order from the "
                    "coarser mesh", "", "| MeshSizeMax (mm) | scheme | T_c | order | any node | "
                    "order | T_mean | order |", bar(8)]
            for i, (mr, res) in enumerate(zip(meshes, results)):
                ratio = np.log(meshes[i - 1]["h"] / mr["h"])
                for s in SCHEMES:
                    cells = [f"{e:.4f} ({100 * e / span:.2f} %) | "
                             + (f"{np.log(p / e) / ratio:.2f}" if i else "—")
                             for e, p in zip(res[case][kind, s], results[i - 1][case][kind, s])]
                    out.append(f"| {mr['size']:g} | {s} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def main():
    """Run the study, print the tables; the exit code."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--binary", type=Path, default=ROOT / "target" / "release" / "icefem",
                        help="the icefem to check (default: target/release/icefem)")
    parser.add_argument("--workdir", type=Path, default=ROOT / "target" / "heat_obtuse_ball",
                        help="meshes, scenes and runs (default: target/heat_obtuse_ball)")
    parser.add_argument("--sizes", type=float, nargs="+", default=SIZES,
                        help="Mesh.MeshSizeMax values, mm (default: 6 4 3)")
    parser.add_argument("--markdown", type=Path, help="also write the tables here")
    args = parser.parse_args()
    start, studied = time.perf_counter(), []
    for size in args.sizes:
        studied.append(study(args.binary.resolve(), args.workdir.resolve(), size))
        rows = studied[-1][1].values()
        print(f"h = {size:g} mm ({time.perf_counter() - start:.0f} s): max |icefem − limited| "
              + ", ".join(f"{r['icefem vs limited']:.1e}" for r in rows) + " K", file=sys.stderr,
              flush=True)
    meshes, results = zip(*studied)
    report = tables(meshes, results)
    print(report)
    if args.markdown:
        command = "validation/heat_obtuse_ball.py " + shlex.join(sys.argv[1:])
        args.markdown.write_text(f"Command: `{command}`\n\n{report}\n")
    rows = [(f"{mr['size']:g} mm, {case}", r) for mr, rs in studied for case, r in rs.items()]
    failures = [f"{where}: icefem differs from the limited reimplementation by "
                f"{r['icefem vs limited']:.1e} K" for where, r in rows
                if not r["icefem vs limited"] <= AGREEMENT]
    failures += [f"{where}: icefem's passes or cancelled edges differ from the limited "
                 f"reimplementation's in {r['differ']} steps" for where, r in rows if r["differ"]]
    failures += [f"{where}: {r['extrema', s][0]} new local extrema in the {s} run"
                 for where, r in rows for s in ("limited", "icefem") if r["extrema", s][0]]
    for failure in failures:
        print("FAIL:", failure, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
