#!/usr/bin/env python3
"""Accuracy and work-precision report: icefem (through its CLI) against scikit-fem.

Both codes solve the same cases on the same meshes: every mesh is built with
scikit-fem (``MeshTet.init_tensor``, 6 tets per hexahedral cell), written to a
binary Gmsh 2.2 file with meshio (tets positively oriented) and referenced from
a generated scene TOML (``[mesh] file = ...``), which ``icefem run`` solves with
the linear (small-strain) model; the heat-conduction case adds ``[thermal]`` with no
latent heat.  Outputs:

  validation/report.md          table of errors and timings
  validation/work_precision.png error against run time (static and dynamic panels)

Exit status 1 if icefem and scikit-fem differ by more than 1e-8 (relative) on
the same discrete problem, or if an icefem run fails.

Run through ``validation/report`` (sets up the venv and builds icefem).
"""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import h5py
import matplotlib
import meshio
import numpy as np
import scipy
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from skfem import (Basis, BilinearForm, ElementTetP0, ElementTetP1, ElementVectorH1, FacetBasis,
                   Functional, LinearForm, MeshTet, asm, condense, solve)
from skfem.helpers import div
from skfem.models.elasticity import linear_elasticity
from skfem.models.poisson import laplace
from skfem.models.poisson import mass as p1_mass

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

# ---------------------------------------------------------------------------
# Problem data (SI)
# ---------------------------------------------------------------------------
LAMBDA, MU, RHO = 8.64e10, 3.70e10, 916.0  # ice
YOUNG = MU * (3 * LAMBDA + 2 * MU) / (LAMBDA + MU)
GRAV = np.array([0.0, 0.0, -9.81])
CLAMP_TOL = 1e-9
REGRESSION_TOL = 1e-8  # relative icefem-vs-scikit-fem difference on the same discrete problem
SLOW_RUN = 2.0  # s; runs slower than this are timed once instead of best-of-repeats

# 1. bar under self-weight (nu = 0, analytic)
BAR_A, BAR_L = 0.02, 0.2
BAR_E, BAR_NU = 1e11, 0.0
BAR_LAMBDA = BAR_E * BAR_NU / ((1 + BAR_NU) * (1 - 2 * BAR_NU))
BAR_MU = BAR_E / (2 * (1 + BAR_NU))
BAR_LEVELS = [(1, 1, 4), (2, 2, 8), (4, 4, 16), (8, 8, 32), (16, 16, 64)]
BAR_ROLLER_LEVELS = BAR_LEVELS[:4]

# 2. beams (as make_references.py)
BEAM_L, BEAM_W, BEAM_H = 0.4, 0.04, 0.04
BEAM_LEVELS = [(8, 1, 1), (16, 2, 2), (32, 4, 4), (64, 8, 8)]
TRACTION = np.array([0.0, 0.0, -1.0e6])

# 3. eigenstrain cube (as make_references.py)
CUBE_SIDE = 0.1
CUBE_LEVELS = [2, 4, 8, 16]
EIG_BOX = np.array([[0.025] * 3, [0.075] * 3])
EIG_E = 0.0291

# 4. dynamics: beam 16x2x2 released under gravity, lumped mass
DYN_CELLS = (16, 2, 2)
DYN_DTS = [1e-6, 3e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3]
DYN_T = 3e-3  # smallest common multiple of the dts: 3000 / 1000 / 300 / 100 / 30 / 10 / 3 steps

# 5. heat conduction: ice bar, no phase change (as make_heat_reference.py)
HEAT_SIZE = (0.1, 0.02, 0.02)  # m
HEAT_CELLS = (20, 4, 4)
HEAT_K, HEAT_C = 2.22, 2050.0  # W/(m K), J/(kg K); density RHO
HEAT_H, HEAT_T_AIR = 25.0, 5.0  # W/(m^2 K), degC: convection on x = 0.1
HEAT_T_WALL, HEAT_T0 = -10.0, 0.0  # degC: held at x = 0, initial
HEAT_DT, HEAT_STEPS = 10.0, 60  # s
HEAT_REFERENCE = HERE / "reference" / "heat_bar.h5"

ELEM = ElementVectorH1(ElementTetP1())
HEAT: dict = {}  # details of the heat case for the notes

FAILURES: list[str] = []
LOAD: list[float] = []
CUBE_RULE_DIFF: dict[int, tuple[int, int]] = {}  # n -> (tets selected, by the exact-float rule)


def fail(msg: str) -> None:
    print(f"FAIL: {msg}", flush=True)
    FAILURES.append(msg)


# ---------------------------------------------------------------------------
# Meshes and files
# ---------------------------------------------------------------------------
def box_mesh(size, cells) -> MeshTet:
    return MeshTet.init_tensor(*[np.linspace(0.0, s, n + 1) for s, n in zip(size, cells)])


def signed_det(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    x0 = p[t[:, 0]]
    return np.linalg.det(np.stack([p[t[:, 1]] - x0, p[t[:, 2]] - x0, p[t[:, 3]] - x0], axis=-1))


def oriented_tets(mesh: MeshTet) -> np.ndarray:
    """(m,4) connectivity in scikit-fem's element order, vertices 1 and 2 swapped where needed
    so that det[x1-x0, x2-x0, x3-x0] > 0."""
    t = mesh.t.T.astype(np.int64).copy()
    p = mesh.p.T
    neg = signed_det(p, t) < 0
    t[neg, 1], t[neg, 2] = t[neg, 2].copy(), t[neg, 1].copy()
    assert np.all(signed_det(p, t) > 0), "failed to orient tets"
    return t


def write_msh(path: Path, mesh: MeshTet) -> np.ndarray:
    """Binary Gmsh 2.2 (exact float64 coordinates). Returns the oriented tets."""
    tets = oriented_tets(mesh)
    ones = np.ones(len(tets), dtype=np.int32)
    meshio.write_points_cells(
        str(path), np.ascontiguousarray(mesh.p.T), [("tetra", tets)],
        cell_data={"gmsh:physical": [ones], "gmsh:geometrical": [ones]},
        file_format="gmsh22", binary=True)
    return tets


def toml_vec(v) -> str:
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def to_nodal(basis: Basis, x: np.ndarray) -> np.ndarray:
    return x[basis.nodal_dofs].T.copy()


def from_nodal(basis: Basis, u: np.ndarray) -> np.ndarray:
    x = np.zeros(basis.N)
    x[basis.nodal_dofs] = u.T
    return x


def rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))


# ---------------------------------------------------------------------------
# icefem through its CLI
# ---------------------------------------------------------------------------
class Icefem:
    def __init__(self, binary: Path, work: Path, repeats: int):
        self.binary = binary
        self.work = work
        self.repeats = repeats
        self.messages: list[str] = []

    def run(self, name: str, mesh: MeshTet, scene_body: str, analysis: str, dt: float,
            end_time: float, output_every: int = 1000000,
            scheme: str | None = None) -> dict | None:
        """Write NAME.msh + NAME.toml, run icefem `repeats` times, return the last frame's
        displacement (n,3), per-element eigenstrain, min over repeats of sum(/stats/t_step)
        and of the process wall time. Runs with [thermal] also return every frame's nodal
        temperature (frames, n), the frames' times and the min over repeats of
        sum(/stats/t_heat). scheme: written as `[time] scheme` when given (icefem's default,
        backward Euler, otherwise)."""
        msh = self.work / f"{name}.msh"
        tets = write_msh(msh, mesh)
        scene = self.work / f"{name}.toml"
        scene.write_text(
            f"# generated by validation/report.py\n"
            f"[mesh]\nfile = \"{msh.name}\"\n\n{scene_body}\n"
            f"[time]\nanalysis = \"{analysis}\"\ndt = {dt!r}\nend_time = {end_time!r}\n"
            f"output_every = {output_every}\n"
            + (f"scheme = \"{scheme}\"\n" if scheme is not None else ""))
        out = self.work / f"{name}.h5"
        best = None
        for _ in range(self.repeats):
            cmd = [str(self.binary), "run", str(scene), "--output", str(out), "--force"]
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, cwd=self.work)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                msg = (f"icefem failed on {name} (exit {proc.returncode}): "
                       f"{(proc.stderr.strip() or proc.stdout.strip())[-2000:]}")
                fail(msg)
                self.messages.append(msg)
                return None
            with h5py.File(out, "r") as f:
                frames = sorted(f["frames"])
                last = f["frames"][frames[-1]]
                res = dict(
                    u=last["displacement"][...],
                    eigenstrain=last["eigenstrain"][...],
                    time=float(last.attrs["time"]),
                    rest=f["mesh/rest_positions"][...],
                    tets=f["mesh/tets"][...],
                    t_solver=float(np.sum(f["stats/t_step"][...])),
                    steps=int(len(f["stats/t_step"])),
                    newton=int(np.sum(f["stats/newton_iterations"][...])),
                    t_assembly=float(np.sum(f["stats/t_assembly"][...])),
                    t_factorization=float(np.sum(f["stats/t_factorization"][...])),
                    t_lsolve=float(np.sum(f["stats/t_solve"][...])),
                    factorizations=int(np.sum(f["stats/factorizations"][...])),
                    wall=wall,
                )
                if "temperature" in last:
                    res.update(
                        temperature=np.stack([f["frames"][k]["temperature"][...]
                                              for k in frames]),
                        frame_times=np.array([float(f["frames"][k].attrs["time"])
                                              for k in frames]),
                        t_heat=float(np.sum(f["stats/t_heat"][...])),
                        heat_newton=f["stats/heat_newton_iterations"][...].astype(int),
                        heat_imbalance=float(np.abs(f["stats/heat_imbalance"][...]).max()))
            if best is None or res["t_solver"] < best["t_solver"]:
                if best is not None:
                    res["wall"] = min(res["wall"], best["wall"])
                    if "t_heat" in res:
                        res["t_heat"] = min(res["t_heat"], best["t_heat"])
                best = res
            else:
                best["wall"] = min(best["wall"], res["wall"])
                if "t_heat" in best:
                    best["t_heat"] = min(best["t_heat"], res["t_heat"])
            if wall > SLOW_RUN:
                break
        # the mesh icefem read must be the scikit-fem mesh, bit for bit
        if not (np.array_equal(best["rest"], mesh.p.T) and np.array_equal(best["tets"], tets)):
            fail(f"{name}: icefem's /mesh differs from the scikit-fem mesh written to {msh.name}")
        if abs(best["time"] - end_time) > 1e-12 * end_time:
            fail(f"{name}: icefem's last frame is at t = {best['time']}, expected {end_time}")
        return best


def ice_material(lam=LAMBDA, mu=MU) -> str:
    return f"[material]\ndensity = {RHO!r}\nlambda = {lam!r}\nmu = {mu!r}\nmodel = \"linear\"\n\n"


def ice_dirichlet(axis: int) -> str:
    lo, hi = [-1.0] * 3, [1.0] * 3
    hi[axis] = CLAMP_TOL
    return f"[[dirichlet]]\nmin = {toml_vec(lo)}\nmax = {toml_vec(hi)}\n\n"


def ice_gravity(g=GRAV) -> str:
    return f"[physics]\ngravity = {toml_vec(g)}\n\n"


# ---------------------------------------------------------------------------
# scikit-fem
# ---------------------------------------------------------------------------
def best_of(repeats: int, fn):
    """Run fn() up to `repeats` times (once if a run takes more than SLOW_RUN seconds);
    return the first run's result with the smallest timings."""
    out = None
    for _ in range(repeats):
        r = fn()
        if out is None:
            out = r
        else:
            out["t_asm"] = min(out["t_asm"], r["t_asm"])
            out["t_sol"] = min(out["t_sol"], r["t_sol"])
        if r["t_asm"] + r["t_sol"] > SLOW_RUN:
            break
    out["t"] = out["t_asm"] + out["t_sol"]
    return out


def body_load(basis: Basis, rho: float, g: np.ndarray) -> np.ndarray:
    @LinearForm
    def bf(v, w):
        return rho * (g[0] * v.value[0] + g[1] * v.value[1] + g[2] * v.value[2])

    return asm(bf, basis)


def clamp_dofs(basis: Basis, axis: int) -> np.ndarray:
    """all dofs of the nodes with x[axis] < CLAMP_TOL"""
    return basis.get_dofs(lambda x: x[axis] < CLAMP_TOL).all()


def roller_dofs(basis: Basis) -> np.ndarray:
    """bar: base clamped, u_x = 0 on the faces x = 0, a and u_y = 0 on y = 0, a"""
    near = lambda x, k: (x[k] < CLAMP_TOL) | (x[k] > BAR_A - CLAMP_TOL)  # noqa: E731
    return np.unique(np.concatenate([
        clamp_dofs(basis, 2),
        basis.get_dofs(lambda x: near(x, 0)).nodal["u^1"],
        basis.get_dofs(lambda x: near(x, 1)).nodal["u^2"]]))


def sk_static(mesh: MeshTet, lam: float, mu: float, load, dirichlet) -> dict:
    """Assemble (basis, K, f, Dirichlet dofs) and solve with scikit-fem's condense + solve
    (scipy spsolve / SuperLU). t_asm includes building the basis; the mesh is given.
    dirichlet: basis -> constrained dofs (zero displacement)."""
    t0 = time.perf_counter()
    basis = Basis(mesh, ELEM)
    K = asm(linear_elasticity(lam, mu), basis)
    f = load(basis)
    D = dirichlet(basis)
    t1 = time.perf_counter()
    x = solve(*condense(K, f, D=D))
    t2 = time.perf_counter()
    return dict(basis=basis, x=x, u=to_nodal(basis, x), t_asm=t1 - t0, t_sol=t2 - t1,
                nfree=basis.N - len(D), ndof=basis.N)


# ---------------------------------------------------------------------------
# Cases
# ---------------------------------------------------------------------------
def case_bar(ice: Icefem, rep: int) -> list[dict]:
    rows = []
    g = abs(GRAV[2])

    def exact_uz(z):
        return -(RHO * g / BAR_E) * (BAR_L * z - z**2 / 2)

    @Functional
    def err2(w):
        return (w["uh"].value[2] - exact_uz(w.x[2])) ** 2

    @Functional
    def ref2(w):
        return exact_uz(w.x[2]) ** 2

    material = (f"[material]\ndensity = {RHO!r}\nyoungs_modulus = {BAR_E!r}\n"
                f"poisson_ratio = {BAR_NU!r}\nmodel = \"linear\"\n\n")
    rollers = "".join(
        f"[[dirichlet]]\nmin = {toml_vec(lo)}\nmax = {toml_vec(hi)}\naxes = \"{ax}\"\n\n"
        for ax, k in (("x", 0), ("y", 1))
        for lo, hi in (([-1.0] * 3, [CLAMP_TOL if i == k else 1.0 for i in range(3)]),
                       ([BAR_A - CLAMP_TOL if i == k else -1.0 for i in range(3)], [1.0] * 3)))
    variants = [("bar, self-weight (nu=0)", "bar", BAR_LEVELS, lambda b: clamp_dofs(b, 2),
                 ice_dirichlet(2)),
                ("bar, self-weight (nu=0), lateral rollers", "bar_roller", BAR_ROLLER_LEVELS,
                 roller_dofs, ice_dirichlet(2) + rollers)]
    for label, group, levels, dirichlet, bcs in variants:
        for cells in levels:
            name = f"{group}_" + "{}x{}x{}".format(*cells)
            mesh = box_mesh((BAR_A, BAR_A, BAR_L), cells)
            sk = best_of(rep, lambda: sk_static(mesh, BAR_LAMBDA, BAR_MU,
                                                lambda b: body_load(b, RHO, GRAV), dirichlet))
            ic = ice.run(name, mesh, material + ice_gravity() + bcs, "static", 1.0, 1.0)
            # relative L2 error of u_z by quadrature (degree-4 rule: exact for the squared
            # error of a P1 field against the quadratic exact solution)
            bq = Basis(mesh, ELEM, intorder=4)
            norm = np.sqrt(ref2.assemble(bq))
            e_sk = np.sqrt(err2.assemble(bq, uh=bq.interpolate(sk["x"]))) / norm
            row = dict(case=label, group=group, mesh="{}x{}x{}".format(*cells),
                       h=BAR_L / cells[2], dofs=sk["nfree"], dt=None, err_sk=e_sk,
                       against="analytic (rel. L2 of u_z, quadrature)", t_sk=sk["t"],
                       lateral_sk=float(np.abs(sk["u"][:, :2]).max()
                                        / np.abs(sk["u"][:, 2]).max()))
            if ic is not None:
                x_ic = from_nodal(sk["basis"], ic["u"])
                row.update(err_ice=np.sqrt(err2.assemble(bq, uh=bq.interpolate(x_ic))) / norm,
                           t_ice=ic["t_solver"], wall_ice=ic["wall"],
                           diff=rel(ic["u"], sk["u"]))
            rows.append(row)
            print_row(row)
    return rows


def case_beams(ice: Icefem, rep: int) -> list[dict]:
    rows = []
    I = BEAM_W * BEAM_H**3 / 12.0
    q = RHO * abs(GRAV[2]) * BEAM_W * BEAM_H
    P = abs(TRACTION[2]) * BEAM_W * BEAM_H
    for kind in ("gravity", "traction"):
        for cells in BEAM_LEVELS:
            name = f"{kind}_beam_" + "{}x{}x{}".format(*cells)
            mesh = box_mesh((BEAM_L, BEAM_W, BEAM_H), cells)
            if kind == "gravity":
                w_eb = -q * BEAM_L**4 / (8 * YOUNG * I)
                load = lambda b: body_load(b, RHO, GRAV)  # noqa: E731
                body = ice_material() + ice_gravity() + ice_dirichlet(0)
            else:
                w_eb = -P * BEAM_L**3 / (3 * YOUNG * I)

                def load(b):
                    facets = b.mesh.facets_satisfying(lambda x: x[0] > BEAM_L - CLAMP_TOL,
                                                      boundaries_only=True)
                    fb = FacetBasis(b.mesh, ELEM, facets=facets)

                    @LinearForm
                    def trac(v, w):
                        return (TRACTION[0] * v.value[0] + TRACTION[1] * v.value[1]
                                + TRACTION[2] * v.value[2])

                    return asm(trac, fb)

                body = (ice_material() + ice_dirichlet(0)
                        + f"[[traction]]\nmin = {toml_vec([BEAM_L - CLAMP_TOL, -1, -1])}\n"
                          f"max = {toml_vec([1, 1, 1])}\ntraction = {toml_vec(TRACTION)}\n\n")
            sk = best_of(rep, lambda: sk_static(mesh, LAMBDA, MU, load, lambda b: clamp_dofs(b, 0)))
            ic = ice.run(name, mesh, body, "static", 1.0, 1.0)
            tip = int(np.argmin(np.linalg.norm(mesh.p.T - [BEAM_L, BEAM_W, BEAM_H], axis=1)))
            row = dict(case=f"{kind} beam, tip w vs Euler-Bernoulli", group=f"{kind}_beam",
                       mesh="{}x{}x{}".format(*cells), h=BEAM_L / cells[0], dofs=sk["nfree"],
                       dt=None, err_sk=abs(sk["u"][tip, 2] / w_eb - 1), t_sk=sk["t"],
                       against="analytic (Euler-Bernoulli tip deflection, rel.)",
                       ratio_sk=sk["u"][tip, 2] / w_eb)
            if ic is not None:
                row.update(err_ice=abs(ic["u"][tip, 2] / w_eb - 1), t_ice=ic["t_solver"],
                           wall_ice=ic["wall"], diff=rel(ic["u"], sk["u"]),
                           ratio_ice=ic["u"][tip, 2] / w_eb)
            rows.append(row)
            print_row(row)
    return rows


def case_cube(ice: Icefem, rep: int) -> list[dict]:
    rows = []
    for n in CUBE_LEVELS:
        name = f"eigenstrain_cube_{n}"
        mesh = box_mesh((CUBE_SIDE,) * 3, (n, n, n))
        centroids = mesh.p[:, mesh.t].mean(axis=1).T
        # Elements whose centroid lies in the box, faces included. Centroids on the box faces
        # (e.g. 0.025 and 0.075 for n = 2) must not be decided by rounding (make_references.py
        # compares the float centroid with the box exactly, which keeps 0.025 but drops
        # 0.07500000000000001); both codes use the box widened by 1e-9 m.
        lo, hi = EIG_BOX[0] - CLAMP_TOL, EIG_BOX[1] + CLAMP_TOL
        inside = np.all((centroids >= lo) & (centroids <= hi), axis=1)
        exact_rule = np.all((centroids >= EIG_BOX[0]) & (centroids <= EIG_BOX[1]), axis=1)
        CUBE_RULE_DIFF[n] = (int(inside.sum()), int(exact_rule.sum()))
        e_elem = np.where(inside, EIG_E, 0.0)

        def load(b):
            e0 = b.with_element(ElementTetP0()).interpolate(e_elem)

            @LinearForm
            def eig(v, w):
                return (3 * LAMBDA + 2 * MU) * w["e0"] * div(v)

            return asm(eig, b, e0=e0)

        sk = best_of(rep, lambda: sk_static(mesh, LAMBDA, MU, load, lambda b: clamp_dofs(b, 2)))
        body = (ice_material() + ice_dirichlet(2)
                + f"[[eigenstrain]]\nmin = {toml_vec(lo)}\nmax = {toml_vec(hi)}\n"
                  f"value = {EIG_E!r}\n\n")
        ic = ice.run(name, mesh, body, "static", 1.0, 1.0)
        row = dict(case="eigenstrain cube", group="cube", mesh=f"{n}x{n}x{n}",
                   h=CUBE_SIDE / n, dofs=sk["nfree"], dt=None, err_sk=None, t_sk=sk["t"],
                   against="scikit-fem reference (rel. l2 of nodal u)")
        if ic is not None:
            if not np.array_equal(ic["eigenstrain"], e_elem):
                fail(f"{name}: icefem's per-element eigenstrain differs from scikit-fem's "
                     f"({int(np.sum(ic['eigenstrain'] != e_elem))} elements)")
            d = rel(ic["u"], sk["u"])
            row.update(err_ice=d, diff=d, t_ice=ic["t_solver"], wall_ice=ic["wall"])
        rows.append(row)
        print_row(row)
    return rows


def dynamics_system(mesh: MeshTet):
    """The cantilever's discrete dynamics on `mesh`: basis, K on the free dofs (CSC), the
    row-sum lumped mass, gravity load and the free dofs (clamped at x = 0)."""
    basis = Basis(mesh, ELEM)
    K = asm(linear_elasticity(LAMBDA, MU), basis).tocsr()
    f = body_load(basis, RHO, GRAV)

    @BilinearForm
    def mass(u, v, w):
        return RHO * (u.value[0] * v.value[0] + u.value[1] * v.value[1]
                      + u.value[2] * v.value[2])

    m = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # row-sum lumping = rho vol / 4
    D = clamp_dofs(basis, 0)
    free = np.setdiff1d(np.arange(basis.N), D)
    return basis, K[free][:, free].tocsc(), m[free], f[free], free


def sk_dynamics(mesh: MeshTet, dt: float, t_end: float, scheme: str) -> dict:
    """scikit-fem's run of the cantilever released under gravity on `mesh` to `t_end` with
    `scheme` ("BE", "TR" or "BDF2") at `dt`: the displacement (nodal) and the times of the
    assembly and of the factorisations + steps."""
    t0 = time.perf_counter()
    basis, Kff, mf, ff, free = dynamics_system(mesh)
    t1 = time.perf_counter()
    steps = int(round(t_end / dt))
    u = np.zeros(len(free))
    v = np.zeros(len(free))
    if scheme == "BE":
        # (M/h^2 + K) u_{n+1} = M/h^2 (u_n + h v_n) + f
        lu = spla.splu((sp.diags(mf / dt**2) + Kff).tocsc())
        for _ in range(steps):
            un = lu.solve(mf / dt**2 * (u + dt * v) + ff)
            v = (un - u) / dt
            u = un
    elif scheme == "BDF2":
        # first step backward Euler, as icefem's scheme = "bdf2" (no state one step back)
        lu = spla.splu((sp.diags(mf / dt**2) + Kff).tocsc())
        un = lu.solve(mf / dt**2 * (u + dt * v) + ff)
        up, vp, u, v = u, v, un, (un - u) / dt
        # then M a_(n+1) = f - K u_(n+1), a_(n+1) = 9/(4h^2) (u_(n+1) - ut),
        # ut = (4u_n - u_(n-1))/3 + 2h (4v_n - v_(n-1))/9:
        # (9M/(4h^2) + K) u_(n+1) = f + 9M/(4h^2) ut, v_(n+1) = (3u_(n+1) - 4u_n + u_(n-1))/(2h)
        c = 9 / (4 * dt**2)
        lu = spla.splu((sp.diags(c * mf) + Kff).tocsc())
        for _ in range(steps - 1):
            ut = (4 * u - up) / 3 + 2 * dt * (4 * v - vp) / 9
            un = lu.solve(ff + c * mf * ut)
            vn = (3 * un - 4 * u + up) / (2 * dt)
            up, vp, u, v = u, v, un, vn
    else:
        # trapezoidal rule = Newmark average acceleration (beta = 1/4, gamma = 1/2)
        # (K + 4/h^2 M) u_{n+1} = f + M (4/h^2 u_n + 4/h v_n + a_n), started from the
        # consistent acceleration a0 = M^-1 (f - K u0) on the free dofs (= M^-1 f here), as
        # icefem's scheme = "newmark" is
        a = (ff - Kff @ u) / mf
        lu = spla.splu((sp.diags(4 * mf / dt**2) + Kff).tocsc())
        for _ in range(steps):
            un = lu.solve(ff + mf * (4 / dt**2 * u + 4 / dt * v + a))
            an = 4 / dt**2 * (un - u) - 4 / dt * v - a
            v = v + dt / 2 * (a + an)
            u, a = un, an
    t2 = time.perf_counter()
    x = np.zeros(basis.N)
    x[free] = u
    return dict(u=to_nodal(basis, x), t_asm=t1 - t0, t_sol=t2 - t1, steps=steps)


def case_dynamics(ice: Icefem, rep: int) -> tuple[list[dict], dict]:
    mesh = box_mesh((BEAM_L, BEAM_W, BEAM_H), DYN_CELLS)
    tip = int(np.argmin(np.linalg.norm(mesh.p.T - [BEAM_L, BEAM_W, BEAM_H], axis=1)))

    # exact solution of the semi-discrete system M u'' + K u = f, u(0) = u'(0) = 0
    basis, Kff, mf, ff, free = dynamics_system(mesh)
    Kd = Kff.toarray()
    omega2, phi = sla.eigh(Kd, np.diag(mf))  # phi^T M phi = I
    us = np.linalg.solve(Kd, ff)
    u_exact = us - phi @ ((phi.T @ (mf * us)) * np.cos(np.sqrt(omega2) * DYN_T))
    x = np.zeros(basis.N)
    x[free] = u_exact
    U_exact = to_nodal(basis, x)
    x[free] = us
    w_static = to_nodal(basis, x)[tip, 2]
    scale = abs(w_static)
    info = dict(tip=tip, w_static=w_static, w_exact=U_exact[tip, 2], nfree=len(free),
                omega1=float(np.sqrt(omega2[0])), omega_max=float(np.sqrt(omega2[-1])))

    def tip_err(U):
        return float(np.linalg.norm(U[tip] - U_exact[tip]) / scale)

    def sk_run(dt, scheme):
        return sk_dynamics(mesh, dt, DYN_T, scheme)

    rows = []
    body = ice_material() + ice_gravity() + ice_dirichlet(0)
    mesh_name = "{}x{}x{}".format(*DYN_CELLS)
    against = "exact discrete (semi-discrete modal solution, tip)"

    def ice_row(row, dt, scheme, sk=None):
        """run icefem with [time] scheme = SCHEME at dt; add its error, timings and (with a
        scikit-fem run of the same discrete problem) the relative difference to row"""
        tag = "" if scheme is None else f"{scheme}_"
        ic = ice.run(f"dynamics_{tag}dt{dt:.0e}", mesh, body, "dynamic", dt, DYN_T,
                     scheme=scheme)
        if ic is None:
            return
        steps = int(round(DYN_T / dt))
        if ic["steps"] != steps:
            fail(f"dynamics {scheme or 'backward_euler'} dt={dt}: icefem took {ic['steps']} "
                 f"steps, expected {steps}")
        row.update(err_ice=tip_err(ic["u"]), t_ice=ic["t_solver"], wall_ice=ic["wall"],
                   ice_stats=ic)
        if sk is not None:
            row.update(diff=rel(ic["u"], sk["u"]),
                       diff_tip=float(np.linalg.norm(ic["u"][tip] - sk["u"][tip])
                                      / np.linalg.norm(sk["u"][tip])))

    # backward Euler: icefem's default scheme against scikit-fem's BE
    for dt in DYN_DTS:
        sk = best_of(rep, lambda: sk_run(dt, "BE"))
        row = dict(case="beam dynamics, backward Euler", group="dyn_be", mesh=mesh_name,
                   h=None, dofs=len(free), dt=dt, steps=sk["steps"], err_sk=tip_err(sk["u"]),
                   t_sk=sk["t"], t_sk_asm=sk["t_asm"], t_sk_sol=sk["t_sol"], against=against)
        ice_row(row, dt, None, sk)
        rows.append(row)
        print_row(row)
    # trapezoidal rule: icefem scheme = "newmark" against scikit-fem's TR (both start from
    # a0 = M^-1 (f - K u0) on the free dofs)
    for dt in DYN_DTS:
        sk = best_of(rep, lambda: sk_run(dt, "TR"))
        row = dict(case="beam dynamics, trapezoidal (icefem newmark)", group="dyn_tr",
                   mesh=mesh_name, h=None, dofs=len(free), dt=dt, steps=sk["steps"],
                   err_sk=tip_err(sk["u"]), t_sk=sk["t"], t_sk_asm=sk["t_asm"],
                   t_sk_sol=sk["t_sol"], against=against)
        ice_row(row, dt, "newmark", sk)
        rows.append(row)
        print_row(row)
    # BDF2: icefem scheme = "bdf2" against scikit-fem's BDF2 (both start with one
    # backward-Euler step)
    for dt in DYN_DTS:
        sk = best_of(rep, lambda: sk_run(dt, "BDF2"))
        row = dict(case="beam dynamics, BDF2", group="dyn_bdf2", mesh=mesh_name,
                   h=None, dofs=len(free), dt=dt, steps=sk["steps"], err_sk=tip_err(sk["u"]),
                   t_sk=sk["t"], t_sk_asm=sk["t_asm"], t_sk_sol=sk["t_sol"], against=against)
        ice_row(row, dt, "bdf2", sk)
        rows.append(row)
        print_row(row)
    return rows, info


def case_heat(ice: Icefem, rep: int) -> list[dict]:
    """P1 heat conduction in an ice bar, latent heat 0 and equal phases (the linear heat
    equation), the discrete problem of make_heat_reference.py: consistent k-stiffness, lumped
    capacity and convection, -x end held at HEAT_T_WALL, backward Euler. icefem also solves
    the (here irrelevant) mechanics: ice, no gravity, clamped at x = 0, static."""
    L = HEAT_SIZE[0]
    mesh = box_mesh(HEAT_SIZE, HEAT_CELLS)
    n = mesh.p.shape[1]

    def sk_run():
        t0 = time.perf_counter()
        basis = Basis(mesh, ElementTetP1())  # P1: dof i is node i
        K = (HEAT_K * asm(laplace, basis)).tocsr()
        c = RHO * HEAT_C * np.asarray(asm(p1_mass, basis).sum(axis=1)).ravel()
        facets = mesh.facets_satisfying(lambda x: x[0] > L - CLAMP_TOL, boundaries_only=True)
        face_w = np.asarray(asm(p1_mass, FacetBasis(mesh, ElementTetP1(), facets=facets))
                            .sum(axis=1)).ravel()  # int_face phi_i = area/3 per triangle
        h_diag, g = HEAT_H * face_w, HEAT_H * HEAT_T_AIR * face_w
        fixed = basis.get_dofs(lambda x: x[0] < CLAMP_TOL).all()
        free = np.setdiff1d(np.arange(n), fixed)
        A = (sp.diags(c / HEAT_DT + h_diag) + K).tocsr()
        t1 = time.perf_counter()
        # (C/dt + K + H) T_{n+1} = C/dt T_n + g on the free nodes, fixed nodes condensed
        T = np.full((HEAT_STEPS + 1, n), HEAT_T0)
        T[:, fixed] = HEAT_T_WALL
        lu = spla.splu(A[free][:, free].tocsc())
        rhs_fixed = g[free] - A[free][:, fixed] @ T[0, fixed]
        for k in range(HEAT_STEPS):
            T[k + 1, free] = lu.solve(c[free] / HEAT_DT * T[k, free] + rhs_fixed)
        t2 = time.perf_counter()
        return dict(T=T, t_asm=t1 - t0, t_sol=t2 - t1, nfree=len(free), nfixed=len(fixed),
                    nrobin=len(facets))

    sk = best_of(rep, sk_run)
    body = (ice_material() + ice_dirichlet(0)
            # melting point far above the bar's temperatures: the mechanics stays plain ice (with
            # no latent heat and equal phases the heat does not depend on it)
            + f"[thermal]\ninitial_temperature = {HEAT_T0!r}\nlatent_heat = 0.0\n"
              f"melting_point = 100.0\n"
              f"ice_conductivity = {HEAT_K!r}\nwater_conductivity = {HEAT_K!r}\n"
              f"ice_heat_capacity = {HEAT_C!r}\nwater_heat_capacity = {HEAT_C!r}\n\n"
              f"[[thermal.fixed]]\nfaces = [\"-x\"]\ntemperature = {HEAT_T_WALL!r}\n\n"
              f"[[thermal.convection]]\nfaces = [\"+x\"]\nh = {HEAT_H!r}\n"
              f"ambient_temperature = {HEAT_T_AIR!r}\n\n")
    ic = ice.run("heat_bar", mesh, body, "static", HEAT_DT, HEAT_STEPS * HEAT_DT,
                 output_every=1)
    HEAT.update(nodes=n, tets=mesh.t.shape[1], nfixed=sk["nfixed"], nrobin=sk["nrobin"],
                t_asm=sk["t_asm"], t_sol=sk["t_sol"],
                t_min=float(sk["T"].min()), t_max=float(sk["T"].max()))
    if HEAT_REFERENCE.is_file():
        # the stored reference (make_heat_reference.py: SuperLU + iterative refinement)
        with h5py.File(HEAT_REFERENCE, "r") as f:
            T_ref = f["solution/temperature"][...]
        if T_ref.shape == sk["T"].shape:
            HEAT["vs_reference"] = float(np.abs(sk["T"] - T_ref).max() / np.abs(T_ref).max())
            if not HEAT["vs_reference"] <= REGRESSION_TOL:
                fail(f"heat bar: this report's scikit-fem solution differs from "
                     f"{HEAT_REFERENCE.name} by {HEAT['vs_reference']:.3e}")
    row = dict(case="heat bar, conduction (latent heat 0)", group="heat",
               mesh="{}x{}x{}".format(*HEAT_CELLS), h=L / HEAT_CELLS[0], dofs=sk["nfree"],
               dt=HEAT_DT, steps=HEAT_STEPS, err_sk=None, t_sk=sk["t"],
               against="scikit-fem reference (rel. max-norm of nodal T, all steps)")
    if ic is not None:
        Ti = ic["temperature"]
        times = HEAT_DT * np.arange(HEAT_STEPS + 1)
        if Ti.shape != sk["T"].shape or not np.allclose(ic["frame_times"], times,
                                                         rtol=0, atol=1e-9):
            fail(f"heat bar: icefem wrote temperatures of shape {Ti.shape} at "
                 f"{len(ic['frame_times'])} frames, expected {sk['T'].shape} at t = 0, "
                 f"{HEAT_DT:g}, ..., {HEAT_STEPS * HEAT_DT:g} s")
        else:
            # per frame (initial state and every step): max_i |dT_i| / max_i |T_sk,i|
            per_step = np.abs(Ti - sk["T"]).max(axis=1) / np.abs(sk["T"]).max(axis=1)
            d = float(per_step.max())
            HEAT.update(worst_step=int(np.argmax(per_step)), diff_last=float(per_step[-1]))
            row.update(err_ice=d, diff=d)
        row.update(t_ice=ic["t_heat"], wall_ice=ic["wall"])
        HEAT.update(t_step_ice=ic["t_solver"], heat_newton=ic["heat_newton"],
                    heat_imbalance=ic["heat_imbalance"])
    print_row(row)
    return [row]


# ---------------------------------------------------------------------------
# Output
# ---------------------------------------------------------------------------
def fmt(x, spec=".2e", none="—"):
    return none if x is None or (isinstance(x, float) and np.isnan(x)) else format(x, spec)


def print_row(r: dict) -> None:
    print(f"  {r['case']:<46} {r['mesh']:>8} dofs={r['dofs']:6d} dt={fmt(r['dt'], '.0e', '-'):>5} "
          f"err ice={fmt(r.get('err_ice'))} sk={fmt(r.get('err_sk'))} "
          f"diff={fmt(r.get('diff'))} t ice={fmt(r.get('t_ice'), '.4f')}s "
          f"(wall {fmt(r.get('wall_ice'), '.3f')}s) sk={fmt(r['t_sk'], '.4f')}s", flush=True)


def rates(errs, hs):
    return [float(np.log(errs[i] / errs[i + 1]) / np.log(hs[i] / hs[i + 1]))
            for i in range(len(errs) - 1)]


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f", {kb / 2**20:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    return f"{os.cpu_count()} cores ({cpu}){mem}, {platform.system()} {platform.release()}"


def git_state() -> str:
    try:
        rev = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
                             capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(ROOT), "status", "--porcelain", "--", "src",
                                "Cargo.toml", "Cargo.lock"],
                               capture_output=True, text=True).stdout.strip()
        return rev + (" + uncommitted changes in src/ or Cargo.*" if dirty else "")
    except OSError:
        return "unknown"


def write_report(path: Path, rows: list[dict], dyn: dict, rate_text: list[str], args,
                 wall_total: float, ice: Icefem) -> None:
    L = []
    L.append("# icefem vs scikit-fem: accuracy and work-precision report\n")
    L.append(f"- Date: {datetime.datetime.now().astimezone().strftime('%Y-%m-%d %H:%M %Z')}")
    L.append(f"- Machine: {machine()}; load average (1 min) {LOAD[0]:.2f} at the start, "
             f"{os.getloadavg()[0]:.2f} at the end (other jobs on the machine make the "
             "timings noisy)")
    L.append(f"- Command: `validation/report` (from the repository root; runs "
             f"`validation/report.py`, {wall_total:.0f} s in all)")
    L.append(f"- icefem: `{args.icefem}` (git {git_state()}), scenes run as "
             f"`icefem run NAME.toml --output NAME.h5`; scikit-fem {skfem.__version__}, "
             f"numpy {np.__version__}, scipy {scipy.__version__}, meshio {meshio.__version__}")
    L.append(f"- Timings are the best of {args.repeats} runs (a single run when it takes "
             f"more than {SLOW_RUN:g} s). **icefem time** = sum of "
             "`/stats/t_step` in the output file (assembly + factorisation + solve + Newton "
             "bookkeeping, all steps; icefem uses both cores via rayon). **icefem wall** = "
             "the whole `icefem run` process (start-up, mesh reading, set-up, HDF5/XDMF "
             "output). **scikit-fem time** = assembly (Basis, K, f, Dirichlet dofs; for the "
             "dynamics also the lumped mass) + solve (`condense` + `solve` = SuperLU for the "
             "static cases; for the dynamics one `splu` per matrix — two for BDF2, whose first "
             "step is a backward-Euler step — + all steps), `time.perf_counter`; "
             "mesh construction is excluded from both. ratio = scikit-fem time / icefem time. "
             "Heat bar: **icefem time** = sum of `/stats/t_heat` (the heat solve alone; "
             "icefem solves the mechanics too), **scikit-fem time** = assembly (Basis, K, "
             "lumped capacity and convection, fixed nodes) + one `splu` + all steps.")
    L.append("- Same meshes: every mesh is scikit-fem's `MeshTet.init_tensor` (6 tets per "
             "hexahedral cell), written as binary Gmsh 2.2 by meshio with positively oriented "
             "tets and read by icefem via `[mesh] file`; the report checks that icefem's "
             "`/mesh/rest_positions` and `/mesh/tets` equal the scikit-fem arrays exactly. "
             "icefem scenes use `model = \"linear\"`. `dofs` = free dofs.")
    L.append(f"- Regression check: icefem and scikit-fem solve the same discrete problem in "
             f"every row with a value in the last column; the script fails if that relative "
             f"difference exceeds {REGRESSION_TOL:g}.")
    L.append("")
    if FAILURES:
        L.append("## FAILURES\n")
        L += [f"- {m}" for m in FAILURES]
        L.append("")
    L.append("## Results\n")
    hdr = ["case", "mesh", "dofs", "dt (s)", "error (icefem)", "error (scikit-fem)",
           "error measured against", "icefem time (s)", "icefem wall (s)",
           "scikit-fem time (s)", "ratio (skfem/icefem)", "icefem vs scikit-fem (rel. diff)"]
    L.append("| " + " | ".join(hdr) + " |")
    L.append("|" + "---|" * len(hdr))
    for r in rows:
        ratio = r["t_sk"] / r["t_ice"] if r.get("t_ice") and r["t_sk"] is not None else None
        err_sk = (fmt(r.get("err_sk")) if r["group"] not in ("cube", "heat")
                  else "— (reference)")
        dt = "static" if r["dt"] is None else f"{r['dt']:.0e} ({r['steps']} steps)"
        L.append("| " + " | ".join([
            r["case"], r["mesh"], str(r["dofs"]), dt, fmt(r.get("err_ice")), err_sk,
            r["against"], fmt(r.get("t_ice"), ".4f"), fmt(r.get("wall_ice"), ".3f"),
            fmt(r["t_sk"], ".4f"), fmt(ratio, ".2f"), fmt(r.get("diff"))]) + " |")
    L.append("")
    L.append("## Observed rates\n")
    L += rate_text
    L.append("")
    L.append("## Notes\n")
    bar = [r for r in rows if r["group"] == "bar"]
    L.append(f"- **Bar under self-weight**: column [0,{BAR_A}]²×[0,{BAR_L}] m, E = {BAR_E:g} Pa, "
             f"ν = 0, ρ = {RHO:g}, g = 9.81 m/s² downwards, base z = 0 clamped (all dofs), "
             "everything else free. The exact 3-D solution is u_z = -(ρg/E)(Lz - z²/2), "
             "u_x = u_y = 0. Error = ||u_z,h - u_z||_L2 / ||u_z||_L2 by quadrature (degree-4 "
             "rule per tet, exact for the squared error of a P1 field against a quadratic). "
             "The observed rate only approaches 2 on the finest meshes: the 6-tet (Kuhn) "
             "split is not symmetric, so the consistent nodal loads within a cross-section "
             "are uneven and the discrete column sways sideways, although u_x = u_y = 0 "
             "exactly (max |u_x|,|u_y| / max |u_z| = "
             + ", ".join(f"{r['lateral_sk']:.3f}" for r in bar)
             + " for the meshes above); the slender column (L/a = 10) is very compliant to "
             "that. This is the discretisation (both codes agree to ≈1e-11), not a bug. "
             "The second bar variant adds roller conditions on the side faces (u_x = 0 on "
             "x = 0, a; u_y = 0 on y = 0, a; icefem `[[dirichlet]] axes = \"x\"` / "
             "`\"y\"`), which the exact solution satisfies; it removes the sway and "
             "shows the clean O(h²) rate from the coarsest mesh on.")
    L.append("- **Beams** (0.4×0.04×0.04 m ice, clamped at x = 0, gravity or 1 MPa end "
             "traction): error = |w_tip / w_EB - 1| at the node (0.4, 0.04, 0.04), with "
             "w_EB = qL⁴/(8EI) resp. PL³/(3EI). Linear tetrahedra (P1) **shear-lock** in "
             "bending, so the coarse meshes are far too stiff (w_tip/w_EB = "
             + ", ".join(f"{r['ratio_sk']:.3f}" for r in rows if r['group'] == 'gravity_beam')
             + " for the gravity beam); in addition the 3-D elastic solution differs from "
             "Euler–Bernoulli by shear deformation and the clamp (≈1 % for L/h = 10), so this "
             "error does not go to zero. It measures the discretisation, not a bug; the last "
             "column is the code-to-code check.")
    L.append("- **Eigenstrain cube** (0.1 m ice cube, base z = 0 clamped, e = 0.0291 in the "
             "elements whose centroid lies in [0.025, 0.075]³): no analytic solution; error "
             "(icefem) = relative l2 difference of the nodal displacements from scikit-fem's "
             "on the same mesh. The report checks that icefem's per-element `eigenstrain` "
             "output equals scikit-fem's element selection. Both codes use the box widened "
             "by 1e-9 m, so centroids on its faces count as inside; make_references.py "
             "compares the float centroid with the box exactly, so 0.075 computed as "
             "0.07500000000000001 falls outside there (tets selected here / by that rule: "
             + ", ".join(f"n={n}: {a}/{b}" for n, (a, b) in CUBE_RULE_DIFF.items()) + ").")
    be = [r for r in rows if r["group"] == "dyn_be" and r.get("ice_stats")]
    tr = [r for r in rows if r["group"] == "dyn_tr" and r.get("diff") is not None]
    bd = [r for r in rows if r["group"] == "dyn_bdf2" and r.get("diff") is not None]
    sk_tail = []
    small_dts = sorted(DYN_DTS)[:3]
    for label, group in (("backward Euler", "dyn_be"), ("trapezoidal", "dyn_tr"),
                         ("BDF2", "dyn_bdf2")):
        rs = sorted((r for r in rows if r["group"] == group and r.get("err_sk") is not None
                     and r["dt"] in small_dts), key=lambda r: -r["dt"])
        sk_tail.append((label, rates([r["err_sk"] for r in rs], [r["dt"] for r in rs])
                        if len(rs) > 1 else []))
    L.append(f"- **Dynamics**: beam {'x'.join(map(str, DYN_CELLS))} cells, released from rest "
             f"under gravity at t = 0, no damping, row-sum lumped mass, T = {DYN_T:g} s (the "
             f"smallest common multiple of the {len(DYN_DTS)} time steps, hence "
             f"{round(DYN_T / min(DYN_DTS))} steps at dt = {min(DYN_DTS):.0e}). The "
             "reference is the exact solution of the semi-discrete system M u'' + K u = f, "
             "u(0) = u'(0) = 0 on the free dofs: u(T) = u_s - Σ φ_k (φ_kᵀ M u_s) cos(ω_k T) from "
             "a dense generalised eigendecomposition (K φ = ω² M φ, φᵀMφ = I). Error = "
             "|u_tip,h(T) - u_tip(T)| / |w_static,tip| (Euclidean norm of the tip node's "
             f"displacement vector; w_static,tip = {dyn['w_static']:.4e} m, exact "
             f"w_tip(T) = {dyn['w_exact']:.4e} m, ω_1 = {dyn['omega1']:.4g} rad/s "
             f"(period {2 * np.pi / dyn['omega1'] * 1e3:.3f} ms), ω_max = "
             f"{dyn['omega_max']:.3g} rad/s). Backward Euler: (M/h² + K) u_(n+1) = "
             "M/h² (u_n + h v_n) + f, which is what icefem's incremental-potential "
             "minimisation gives for the linear model (its default `[time] scheme`). "
             "Trapezoidal = Newmark average acceleration (β = 1/4, γ = 1/2), second order "
             "and non-dissipative: (K + 4M/h²) u_(n+1) = f + M (4/h² u_n + 4/h v_n + a_n), "
             "a_(n+1) = 4/h² (u_(n+1) - u_n) - 4/h v_n - a_n, v_(n+1) = v_n + h/2 (a_n + "
             "a_(n+1)). scikit-fem's trapezoidal rule starts from the consistent initial "
             "acceleration a_0 = M⁻¹(f - K u_0) on the free dofs (u_0 = 0 here, so "
             "a_0 = M⁻¹ f), as icefem's `[time] scheme = \"newmark\"` does "
             "([docs/numerics.md](../docs/numerics.md#second-order-schemes-newmark-and-bdf2)); "
             "with the same mesh, lumped mass and linear model the two solve the identical "
             "discrete problem, and the last column of the trapezoidal rows is their relative "
             "difference (l2 norm of the nodal displacements at T over the whole mesh, as "
             "for backward Euler"
             + (f"; largest {max(r['diff'] for r in tr):.2e}, at the tip node "
                f"{max(r['diff_tip'] for r in tr):.2e}" if tr else "")
             + "). BDF2 (icefem `[time] scheme = \"bdf2\"`): the first step is a "
             "backward-Euler step (there is no state one step back), every later step solves "
             "M a_(n+1) = f - K u_(n+1) with a_(n+1) = 9/(4h²) (u_(n+1) - ũ), "
             "ũ = (4u_n - u_(n-1))/3 + 2h (4v_n - v_(n-1))/9, i.e. (9M/(4h²) + K) u_(n+1) = "
             "f + 9M/(4h²) ũ, then v_(n+1) = (3u_(n+1) - 4u_n + u_(n-1))/(2h); scikit-fem "
             "does exactly this with the same lumped mass (one `splu` of M/h² + K for the "
             "first step, one of 9M/(4h²) + K for the rest), so the BDF2 rows are compared "
             "like the others"
             + (f" (largest difference {max(r['diff'] for r in bd):.2e}, at the tip node "
                f"{max(r['diff_tip'] for r in bd):.2e})" if bd else "")
             + ". The gravity step excites every mode and ω_max·dt ≫ 1 for the larger dt, "
             "so the rates there are pre-asymptotic; the smallest steps show where they head "
             "(last two rates, dt = "
             + " → ".join(f"{d:.0e}" for d in sorted(small_dts, reverse=True)) + ": "
             + "; ".join(f"{label} {', '.join(f'{x:.2f}' for x in rr)}"
                         for label, rr in sk_tail if rr)
             + "; the schemes' orders are 1, 2 and 2). At "
             "dt ≥ 3e-4 backward Euler has damped the motion to the static solution, so its "
             "error saturates at |w_static - w(T)| / |w_static|; BDF2 damps the modes with "
             "h ω ≳ 1 as well, but less per step than backward Euler.")
    dyn_rates = []
    for label, group in (("backward Euler", "dyn_be"), ("Newmark", "dyn_tr"),
                         ("BDF2", "dyn_bdf2")):
        rs = sorted((r for r in rows if r["group"] == group and r.get("err_ice") is not None),
                    key=lambda r: -r["dt"])
        if len(rs) > 1:
            dyn_rates.append(f"{label} " + ", ".join(
                f"{x:.2f}" for x in rates([r["err_ice"] for r in rs], [r["dt"] for r in rs])))
            dts_text = " → ".join(f"{r['dt']:.0e}" for r in rs)
    if dyn_rates:
        L.append("- Measured convergence rates of icefem's schemes in the dynamics "
                 f"(log-slope of the tip error between successive dt, {dts_text} s): "
                 + "; ".join(dyn_rates) + ". These are pre-asymptotic (see above): the "
                 "error is that of one instant of the undamped, step-loaded beam.")
    schemes = (("backward Euler", "dyn_be"), ("Newmark / trapezoidal", "dyn_tr"),
               ("BDF2", "dyn_bdf2"))
    n_sk_lu = {"dyn_be": 1, "dyn_tr": 1, "dyn_bdf2": 2}  # scikit-fem's splu calls per run
    per_step = []
    for label, group in schemes:
        r = next((r for r in rows if r["group"] == group and r["dt"] == min(DYN_DTS)), None)
        if r is None:
            continue
        txt = f"{label}: icefem " + (fmt(r["t_ice"] / r["steps"] * 1e3, ".3f")
                                     if r.get("t_ice") else "—") + " ms"
        if r.get("t_sk") is not None:
            n = n_sk_lu[group]
            txt += (f", scikit-fem {r['t_sk'] / r['steps'] * 1e3:.3f} ms (steps alone, with "
                    f"{'its two factorisations' if n == 2 else 'the one factorisation'}: "
                    f"{r['t_sk_sol'] / r['steps'] * 1e3:.3f} ms)")
        per_step.append(txt)
    if per_step:
        L.append(f"- Time per step at dt = {min(DYN_DTS):.0e} "
                 f"({int(round(DYN_T / min(DYN_DTS)))} steps; icefem Σ /stats/t_step / steps, "
                 "scikit-fem (assembly + `splu` + all steps) / steps): " + "; ".join(per_step)
                 + ".")
    cost = []
    for label, group in schemes:
        rs = sorted((r for r in rows if r["group"] == group and r.get("ice_stats")),
                    key=lambda r: r["dt"])
        if not rs:
            continue
        cost.append(f"{label}: " + ", ".join(
            f"dt = {r['dt']:.0e} ({r['steps']} steps, "
            f"{r['ice_stats']['newton'] / r['steps']:.1f} Newton it./step, "
            f"{r['ice_stats']['factorizations']} factorisation"
            f"{'s' if r['ice_stats']['factorizations'] != 1 else ''}): "
            f"assembly {r['ice_stats']['t_assembly'] / r['steps'] * 1e3:.3f} ms, "
            f"factorisation {r['ice_stats']['t_factorization'] / r['steps'] * 1e3:.3f} ms, "
            f"solve {r['ice_stats']['t_lsolve'] / r['steps'] * 1e3:.3f} ms, "
            f"step {r['ice_stats']['t_solver'] / r['steps'] * 1e3:.3f} ms"
            for r in (rs[0], rs[-1])))
    if cost:
        fine = [r for r in rows if r["group"] in ("dyn_be", "dyn_tr", "dyn_bdf2")
                and r["dt"] == min(DYN_DTS) and r.get("ice_stats")]
        same = all(r["ice_stats"]["factorizations"] == n_sk_lu[r["group"]] for r in fine)
        rest = [(r["ice_stats"]["t_solver"] - r["ice_stats"]["t_assembly"]
                 - r["ice_stats"]["t_factorization"] - r["ice_stats"]["t_lsolve"])
                / r["steps"] * 1e3 for r in fine]
        L.append("- icefem per-step cost in the dynamics (linear model; per step, from "
                 "`/stats`): " + "; ".join(cost) + ". With the linear model and no contact "
                 "the step's Hessian depends only on the inertia term's step length (h for "
                 "backward Euler, h/2 for Newmark, 2h/3 for BDF2): icefem assembles it in the "
                 "first step of each length and keeps it; every step is then one solve with "
                 "it (the potential is quadratic). The elastic term is kept as a quadratic "
                 "too (its energy, gradient and Hessian at the supports' prescribed values, "
                 "from one pass over the elements in the whole run), so `assembly` is one "
                 "product with its Hessian for the gradient at the predictor, the gradient "
                 "after the solve is that plus the kept matrix times the update, and the "
                 "linear solver factors only when the matrix differs from the one it last "
                 "factored. At dt = "
                 f"{min(DYN_DTS):.0e} the factorisation counts "
                 + ("equal" if same else "differ from")
                 + " scikit-fem's `splu` calls (one per run; two for BDF2, its "
                 "backward-Euler first step and the BDF2 steps). What a step costs beyond "
                 "assembly, factorisation and solve ("
                 + (f"{min(rest):.3f}–{max(rest):.3f} ms at dt = {min(DYN_DTS):.0e}"
                    if rest else "—")
                 + ") is the rest of icefem's step: the product with the kept matrix for "
                 "the residual, the other terms (inertia, gravity) and the predictor, the "
                 "energies of the new state for `/stats` (from the quadratic: no pass, and "
                 "a quadratic solve needs no energy-balance check), and copying the state; "
                 "scikit-fem's "
                 "steps are a right-hand side and one pair of triangular solves of the fixed "
                 "factor. Over a whole run scikit-fem also pays its assembly (Basis, K, f, "
                 "mass) once, which dominates its time on the few-step rows.")
    if HEAT:
        d = HEAT.get("worst_step")
        L.append(f"- **Heat bar** (the discrete problem of `validation/make_heat_reference.py`, "
                 f"[README](README.md#heat-bar-p1-heat-conduction-heat_barh5)): ice bar "
                 f"[0,{HEAT_SIZE[0]:g}]×[0,{HEAT_SIZE[1]:g}]×[0,{HEAT_SIZE[2]:g}] m, "
                 f"{'x'.join(map(str, HEAT_CELLS))} cells ({HEAT['nodes']} nodes, "
                 f"{HEAT['tets']} tets), ρ = {RHO:g} kg/m³, c = {HEAT_C:g} J/(kg K), "
                 f"k = {HEAT_K:g} W/(m K); the {HEAT['nfixed']} nodes at x = 0 held at "
                 f"{HEAT_T_WALL:g} °C from t = 0 (condensed out), convection "
                 f"h = {HEAT_H:g} W/(m² K) to {HEAT_T_AIR:g} °C air on the "
                 f"{HEAT['nrobin']} triangles of x = {HEAT_SIZE[0]:g}, other faces insulated, "
                 f"T = {HEAT_T0:g} °C at t = 0; backward Euler, dt = {HEAT_DT:g} s, "
                 f"{HEAT_STEPS} steps. P1 stiffness k·`laplace`, capacity lumped (ρc × row "
                 "sums of the P1 mass), convection lumped (h·area/3 on the diagonal, "
                 "h·T_air·area/3 on the right-hand side, per node per triangle); scikit-fem "
                 "factors (C/dt + K + H) on the free nodes once with `splu` and does one "
                 "solve per step. icefem runs the scene with `[thermal]` latent_heat = 0 and "
                 "equal ice and water conductivities and heat capacities (the enthalpy is then "
                 "linear: the linear heat equation), `[[thermal.fixed]] faces = [\"-x\"]`, "
                 "`[[thermal.convection]] faces = [\"+x\"]`, `output_every = 1`, plus the "
                 "mechanics it always solves (the report's ice material, no gravity, x = 0 "
                 "clamped, static), with `melting_point = 100` so that the mechanics sees "
                 "ice throughout (without latent heat and with equal phases the heat does "
                 "not depend on it); the mechanics does not feed back into the heat. "
                 "Compared: the "
                 "`/frames/*/temperature` of every frame (initial state and all "
                 f"{HEAT_STEPS} steps) node by node, max_i |T_icefem − T_skfem| / "
                 "max_i |T_skfem| per frame, the largest over the frames in the table"
                 + (f" (at frame {d}; {HEAT['diff_last']:.2e} at the last)" if d is not None
                    else "")
                 + f". scikit-fem's temperatures stay in [{HEAT['t_min']:.4f}, "
                 f"{HEAT['t_max']:.4f}] °C"
                 + ("" if "vs_reference" not in HEAT else
                    "; they equal the stored reference `reference/heat_bar.h5` (SuperLU with "
                    "iterative refinement) "
                    + ("bit for bit" if HEAT["vs_reference"] == 0 else
                       f"to {HEAT['vs_reference']:.1e} relative"))
                 + f". scikit-fem time split: assembly {HEAT['t_asm']:.4f} s, factorisation + "
                 f"{HEAT_STEPS} solves {HEAT['t_sol']:.4f} s"
                 + (f"; icefem: {HEAT['heat_newton'].sum()} heat Newton iterations in "
                    f"{HEAT_STEPS} steps ("
                    + (f"{HEAT['heat_newton'].min()}" if HEAT['heat_newton'].min()
                       == HEAT['heat_newton'].max() else
                       f"{HEAT['heat_newton'].min()}–{HEAT['heat_newton'].max()}")
                    + " per step; the Jacobian is the same every step, so its Cholesky "
                    "factor is reused as scikit-fem's `splu` is), Σ t_heat "
                    f"(in the table) vs Σ t_step = {HEAT['t_step_ice']:.4f} s for heat + "
                    f"mechanics, largest |/stats/heat_imbalance| {HEAT['heat_imbalance']:.1e} J"
                    if "heat_newton" in HEAT else "")
                 + ".")
    L.append("- **Stefan problem** (latent heat, moving freezing front) is not in this "
             "report: the study is a cargo test (`stefan_convergence_study` in "
             "`solver_tests/thermal.rs`), not something the `icefem` binary runs. Its "
             "convergence table "
             "(front position against Neumann's solution, by cell size and step) is in "
             "[docs/thermal.md](../docs/thermal.md#validation), produced by "
             "`cargo test --release --test thermal -- --ignored --nocapture`.")
    if ice.messages:
        L.append("- icefem messages:")
        L += [f"  - `{m}`" for m in ice.messages]
    L.append("")
    L.append("![work-precision](work_precision.png)")
    path.write_text("\n".join(L) + "\n")


def plot(path: Path, rows: list[dict]) -> None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(14, 5.6))

    def line(ax, groups, key_err, key_t, label, style, annotate=None, offset=(4, 4), **kw):
        rs = [r for r in rows if r["group"] in groups and r.get(key_err) is not None
              and r.get(key_t) is not None]
        if not rs:
            return
        rs.sort(key=lambda r: -(r["h"] if r["h"] is not None else r["dt"]))  # coarse first
        ax.loglog([r[key_t] for r in rs], [r[key_err] for r in rs], style, label=label, **kw)
        for r in rs if annotate else []:
            ax.annotate(annotate(r), (r[key_t], r[key_err]), textcoords="offset points",
                        xytext=offset, fontsize=7, color=kw.get("color"))

    def mesh_label(r):
        return r["mesh"]

    def dt_label(r):
        return f"{r['dt']:.0e}"

    line(ax1, ["bar"], "err_ice", "t_ice", "icefem, bar vs analytic (solver time)", "o-",
         mesh_label, color="C0")
    line(ax1, ["bar"], "err_ice", "wall_ice", "icefem, bar (process wall time)", "o:",
         color="C0", alpha=0.5, mfc="none")
    line(ax1, ["bar"], "err_sk", "t_sk", "scikit-fem, bar vs analytic", "s-", color="C1")
    line(ax1, ["bar_roller"], "err_ice", "t_ice", "icefem, bar with lateral rollers", "o-.",
         mesh_label, offset=(4, -10), color="C4")
    line(ax1, ["bar_roller"], "err_sk", "t_sk", "scikit-fem, bar with lateral rollers", "s-.",
         color="C5")
    line(ax1, ["gravity_beam"], "err_ice", "t_ice", "icefem, gravity beam tip vs EB", "o--",
         mesh_label, color="C2")
    line(ax1, ["gravity_beam"], "err_sk", "t_sk", "scikit-fem, gravity beam tip vs EB", "s--",
         color="C3")
    ax1.set_title("static: linear elasticity, P1 tets (one solve per mesh)")
    ax1.set_xlabel("run time (s)  [icefem: sum of /stats/t_step; scikit-fem: assembly + solve]")
    ax1.set_ylabel("relative error")
    ax1.grid(True, which="both", alpha=0.3)
    ax1.legend(fontsize=7, loc="lower left")

    line(ax2, ["dyn_be"], "err_ice", "t_ice", "icefem backward Euler (solver time)", "o-",
         dt_label, color="C0")
    line(ax2, ["dyn_be"], "err_ice", "wall_ice", "icefem backward Euler (process wall time)",
         "o:", color="C0", alpha=0.5, mfc="none")
    line(ax2, ["dyn_be"], "err_sk", "t_sk", "scikit-fem backward Euler", "s-",
         dt_label, offset=(4, -10), color="C1")
    line(ax2, ["dyn_tr"], "err_sk", "t_sk",
         "scikit-fem trapezoidal (Newmark avg. acc.)", "^-", dt_label, offset=(4, -10),
         color="C3")
    line(ax2, ["dyn_tr"], "err_ice", "t_ice", "icefem Newmark (solver time)", "D-", dt_label,
         color="C2")
    line(ax2, ["dyn_bdf2"], "err_sk", "t_sk", "scikit-fem BDF2", "<-",
         dt_label, offset=(4, -10), color="C5")
    line(ax2, ["dyn_bdf2"], "err_ice", "t_ice", "icefem BDF2 (solver time)", "v-", dt_label,
         color="C4")
    ax2.set_title(f"dynamics: beam {'x'.join(map(str, DYN_CELLS))}, tip at T = {DYN_T:g} s "
                  "vs exact semi-discrete")
    ax2.set_xlabel("run time (s)  [icefem: sum of /stats/t_step; scikit-fem: assembly + "
                   "factor + steps]")
    ax2.set_ylabel("|tip error| / |static tip deflection|")
    ax2.grid(True, which="both", alpha=0.3)
    ax2.legend(fontsize=7, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--icefem", type=Path, default=ROOT / "target" / "release" / "icefem")
    ap.add_argument("--repeats", type=int, default=3, help="timing repeats (best of)")
    ap.add_argument("--work", type=Path, default=None,
                    help="keep meshes, scenes and icefem output here (default: a temp dir)")
    ap.add_argument("--out", type=Path, default=HERE, help="where report.md and the PNG go")
    args = ap.parse_args()
    if not args.icefem.is_file():
        print(f"icefem binary not found: {args.icefem}", file=sys.stderr)
        return 2
    t_start = time.perf_counter()
    LOAD.append(os.getloadavg()[0])
    tmp = None
    if args.work is None:
        tmp = tempfile.mkdtemp(prefix="icefem-report-")
        work = Path(tmp)
    else:
        work = args.work.resolve()
        work.mkdir(parents=True, exist_ok=True)
    print(f"work dir {work}; icefem {args.icefem}; scikit-fem {skfem.__version__}", flush=True)
    ice = Icefem(args.icefem.resolve(), work, args.repeats)
    try:
        rows = []
        print("1. bar under self-weight", flush=True)
        rows += case_bar(ice, args.repeats)
        print("2. beams (gravity, traction)", flush=True)
        rows += case_beams(ice, args.repeats)
        print("3. eigenstrain cube", flush=True)
        rows += case_cube(ice, args.repeats)
        print("4. dynamics", flush=True)
        drows, dyn = case_dynamics(ice, args.repeats)
        rows += drows
        print("5. heat conduction", flush=True)
        rows += case_heat(ice, args.repeats)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)

    for r in rows:
        if r.get("diff") is not None and not r["diff"] <= REGRESSION_TOL:
            fail(f"{r['case']} {r['mesh']} dt={r['dt']}: icefem vs scikit-fem relative "
                 f"difference {r['diff']:.3e} > {REGRESSION_TOL:g}")

    rate_text = []

    def add_rates(label, groups, key, hkey):
        rs = [r for r in rows if r["group"] in groups and r.get(key) is not None]
        rs.sort(key=lambda r: -r[hkey])
        if len(rs) < 2:
            return
        rr = rates([r[key] for r in rs], [r[hkey] for r in rs])
        steps = " → ".join(r["mesh"] if hkey == "h" else f"{r['dt']:.0e}" for r in rs)
        rate_text.append(f"- {label} ({steps}): " + ", ".join(f"{x:.2f}" for x in rr))

    add_rates("bar, L2(u_z) vs h, icefem", ["bar"], "err_ice", "h")
    add_rates("bar, L2(u_z) vs h, scikit-fem", ["bar"], "err_sk", "h")
    add_rates("bar with lateral rollers, L2(u_z) vs h, icefem", ["bar_roller"], "err_ice", "h")
    add_rates("bar with lateral rollers, L2(u_z) vs h, scikit-fem", ["bar_roller"], "err_sk", "h")
    add_rates("gravity beam, tip vs EB vs h, icefem (locking + model error; not a convergence "
              "rate)", ["gravity_beam"], "err_ice", "h")
    add_rates("traction beam, tip vs EB vs h, icefem (locking + model error; not a convergence "
              "rate)", ["traction_beam"], "err_ice", "h")
    add_rates("dynamics, backward Euler vs dt, icefem", ["dyn_be"], "err_ice", "dt")
    add_rates("dynamics, backward Euler vs dt, scikit-fem",
              ["dyn_be"], "err_sk", "dt")
    add_rates("dynamics, trapezoidal (Newmark) vs dt, icefem", ["dyn_tr"], "err_ice", "dt")
    add_rates("dynamics, trapezoidal vs dt, scikit-fem",
              ["dyn_tr"], "err_sk", "dt")
    add_rates("dynamics, BDF2 vs dt, icefem", ["dyn_bdf2"], "err_ice", "dt")
    add_rates("dynamics, BDF2 vs dt, scikit-fem",
              ["dyn_bdf2"], "err_sk", "dt")
    print("\nobserved rates:\n" + "\n".join(rate_text))

    args.out.mkdir(parents=True, exist_ok=True)
    plot(args.out / "work_precision.png", rows)
    write_report(args.out / "report.md", rows, dyn, rate_text, args,
                 time.perf_counter() - t_start, ice)
    print(f"\nwrote {args.out / 'report.md'} and {args.out / 'work_precision.png'} "
          f"({time.perf_counter() - t_start:.0f} s)")
    if FAILURES:
        print(f"\n{len(FAILURES)} failure(s):\n" + "\n".join(f"  {m}" for m in FAILURES))
        return 1
    print("all icefem/scikit-fem comparisons within "
          f"{REGRESSION_TOL:g} (relative) on the same discrete problems")
    return 0


if __name__ == "__main__":
    sys.exit(main())
