#!/usr/bin/env python3
"""Peer side of `validation/bench`: scikit-fem + scipy / CHOLMOD (scikit-sparse) / pyamg on
exactly the mesh and problem of `icefem bench`.

One size per process (so the peak memory is per size):

    bench_peer.py --single N [--spsolve-max-dofs 20000] [--no-cholmod] [--no-amg]
        prints one JSON object (timings in s, memory in bytes)
    bench_peer.py --verify-mesh FILE.h5 --cells NX,NY,NZ --size SX,SY,SZ
        compares box_mesh() with /mesh/rest_positions and /mesh/tets of an icefem output file

Problem (same as src/bench/problems.rs): 10 cm ice cube, `cells_for(N)` = round(cbrt(N/6)) cells per
axis, 6 Kuhn tets per cell, lambda = 8.64e10 Pa, mu = 3.70e10 Pa, rho = 916 kg/m^3, nodes with
z <= 1e-9 clamped (all axes), gravity (3, 0, -9.81) m/s^2, backward Euler h = 1/30 s. The
system timed is the first Newton system of icefem's first step, A = K + M/h^2 on the free
dofs, b = f (the corotated tangent at rest is the linear-elastic K).
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np
import scipy.sparse as sp

# The problem's data (bench.py writes its `icefem run` scenes of the same cube from these too).
LAMBDA, MU, RHO = 8.64e10, 3.70e10, 916.0
GRAVITY = np.array([3.0, 0.0, -9.81])
DT = 1.0 / 30.0
SIDE = 0.1
CLAMP_Z = 1e-9
RTOL = 1e-10

# src/mesh/generate.rs: cell corners numbered by bits, c = (c & 1, (c >> 1) & 1, (c >> 2) & 1).
KUHN = np.array(
    [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]]
)


def cells_for(tets: int) -> int:
    """src/bench/problems.rs cells_for: round(cbrt(N / 6)), at least 1 (Rust rounds half away from 0)."""
    return max(1, int(np.floor(np.cbrt(tets / 6.0) + 0.5)))


def box_mesh(cells, size=(SIDE, SIDE, SIDE), origin=(0.0, 0.0, 0.0)):
    """icefem's box_mesh(origin, size, cells, 6): (n,3) positions, (m,4) int64 tets."""
    nx, ny, nz = cells
    i = np.arange(nx + 1, dtype=np.float64)
    j = np.arange(ny + 1, dtype=np.float64)
    k = np.arange(nz + 1, dtype=np.float64)
    # origin + size * i / n, evaluated in the same order as the Rust code (bit-identical).
    x = origin[0] + size[0] * i / nx
    y = origin[1] + size[1] * j / ny
    z = origin[2] + size[2] * k / nz
    Z, Y, X = np.meshgrid(z, y, x, indexing="ij")  # x fastest: node i + (nx+1)(j + (ny+1)k)
    p = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    ck, cj, ci = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    ci, cj, ck = ci.ravel(), cj.ravel(), ck.ravel()  # cells with i fastest, then j, then k
    corners = np.arange(8)
    node = (ci[:, None] + (corners & 1)) + (nx + 1) * (
        (cj[:, None] + ((corners >> 1) & 1)) + (ny + 1) * (ck[:, None] + ((corners >> 2) & 1))
    )  # (cells, 8)
    t = node[:, KUHN].reshape(-1, 4).astype(np.int64)  # 6 tets per cell, KUHN order
    # orientation fix: det[x1-x0, x2-x0, x3-x0] < 0 -> swap local vertices 2 and 3
    x0 = p[t[:, 0]]
    det = np.linalg.det(np.stack([p[t[:, 1]] - x0, p[t[:, 2]] - x0, p[t[:, 3]] - x0], axis=-1))
    neg = det < 0
    t[neg, 2], t[neg, 3] = t[neg, 3].copy(), t[neg, 2].copy()
    return p, t


def peak_rss() -> int:
    """VmHWM of this process (bytes); falls back to ru_maxrss."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def verify_mesh(path: str, cells, size) -> int:
    import h5py

    p, t = box_mesh(cells, size)
    with h5py.File(path, "r") as f:
        rp = f["/mesh/rest_positions"][:]
        rt = f["/mesh/tets"][:].astype(np.int64)
        frames = sorted(f["frames"]) if "frames" in f else []
        u_ice = f["frames"][frames[-1]]["displacement"][:] if frames else None
    ok_p = rp.shape == p.shape and np.array_equal(rp, p)
    ok_t = rt.shape == t.shape and np.array_equal(rt, t)
    physics = ""
    if ok_p and ok_t and u_ice is not None:
        # same material, clamp and gravity: icefem's static linear solution vs K u = f here
        from skfem import Basis, ElementTetP1, ElementVectorH1, LinearForm, MeshTet, asm, condense, solve
        from skfem.models.elasticity import linear_elasticity

        basis = Basis(MeshTet(p.T.copy(), t.T.copy()), ElementVectorH1(ElementTetP1()))
        K = asm(linear_elasticity(LAMBDA, MU), basis)
        f = asm(LinearForm(lambda v, w: RHO * (GRAVITY[0] * v[0] + GRAVITY[1] * v[1] + GRAVITY[2] * v[2])), basis)
        D = basis.nodal_dofs[:, np.nonzero(p[:, 2] <= CLAMP_Z)[0]].ravel()
        u = solve(*condense(K, f, D=D)).reshape(-1, 3)
        rel = np.linalg.norm(u - u_ice) / np.linalg.norm(u)
        physics = f"; static linear displacement vs scikit-fem K u = f: relative L2 difference {rel:.1e}"
        ok_p = ok_p and rel < 1e-6
    print(
        f"mesh check cells {list(cells)}: {p.shape[0]} nodes, {t.shape[0]} tets; positions "
        f"{'bit-identical' if ok_p else 'DIFFER'}, tets {'identical' if ok_t else 'DIFFER'}{physics}"
    )
    if not ok_p and rp.shape == p.shape:
        print(f"  max |dx| = {np.abs(rp - p).max():.3e}")
    if not ok_t and rt.shape == t.shape:
        bad = np.nonzero((rt != t).any(axis=1))[0]
        print(f"  {bad.size} tets differ, first {bad[:5]}: icefem {rt[bad[:2]]} vs {t[bad[:2]]}")
    return 0 if (ok_p and ok_t) else 1


def rigid_body_modes(x: np.ndarray) -> np.ndarray:
    """(3n, 6) near-null space of 3-D elasticity at positions x (n,3), dof 3i+c."""
    n = x.shape[0]
    B = np.zeros((n, 3, 6))
    B[:, 0, 0] = B[:, 1, 1] = B[:, 2, 2] = 1.0
    c = x - x.mean(axis=0)
    B[:, 0, 3], B[:, 1, 3] = -c[:, 1], c[:, 0]  # rotation about z
    B[:, 1, 4], B[:, 2, 4] = -c[:, 2], c[:, 1]  # about x
    B[:, 0, 5], B[:, 2, 5] = c[:, 2], -c[:, 0]  # about y
    return B.reshape(3 * n, 6)


def problem(cells: int, default_quadrature: bool = True):
    """Assembles the step system; returns timings and the free system."""
    from skfem import Basis, BilinearForm, ElementTetP1, ElementVectorH1, LinearForm, MeshTet, asm
    from skfem.helpers import dot
    from skfem.models.elasticity import linear_elasticity

    out = {}
    t0 = time.perf_counter()
    p, t = box_mesh((cells, cells, cells))
    mesh = MeshTet(np.ascontiguousarray(p.T), np.ascontiguousarray(t.T))
    out["t_mesh"] = time.perf_counter() - t0

    @BilinearForm
    def mass(u, v, w):
        return RHO * dot(u, v)

    @LinearForm
    def gravity(v, w):
        return RHO * (GRAVITY[0] * v[0] + GRAVITY[1] * v[1] + GRAVITY[2] * v[2])

    def assemble(intorder):
        t0 = time.perf_counter()
        basis = Basis(mesh, ElementVectorH1(ElementTetP1()), intorder=intorder)
        t1 = time.perf_counter()
        K = asm(linear_elasticity(LAMBDA, MU), basis)
        t2 = time.perf_counter()
        m = np.asarray(asm(mass, basis).sum(axis=1)).ravel()  # row-sum lumped mass
        f = asm(gravity, basis)
        t3 = time.perf_counter()
        return basis, K, m, f, (t1 - t0, t2 - t1, t3 - t2)

    K_default = f_default = None
    if default_quadrature:
        # scikit-fem's default quadrature for P1 (4 points: intorder 2) ...
        basis, K, m, f, (tb, tk, tm) = assemble(None)
        out["quad_points_default"] = int(basis.X.shape[1])
        out["t_basis"], out["t_K"], out["t_Mf"] = tb, tk, tm
        out["t_assembly"] = tb + tk + tm  # basis + K + lumped M + body force
        K_default, f_default = K, f
        del basis, m
    # ... and the 1-point rule, exact here (constant strains, linear lumped-mass / load integrands)
    basis, K, m, f, (tb, tk, tm) = assemble(1)
    out["t_basis_q1"], out["t_K_q1"], out["t_Mf_q1"] = tb, tk, tm
    out["t_assembly_q1"] = tb + tk + tm
    if K_default is not None:
        out["q1_vs_default"] = float(max(abs(K - K_default).max() / abs(K_default).max(),
                                         np.abs(f - f_default).max() / np.abs(f_default).max()))
    del K_default, f_default

    t0 = time.perf_counter()
    nd = basis.nodal_dofs  # (3, nodes)
    assert np.array_equal(nd, np.arange(3 * mesh.p.shape[1]).reshape(-1, 3).T), "dof order"
    clamped = np.nonzero(mesh.p[2] <= CLAMP_Z)[0]
    fixed = np.zeros(basis.N, dtype=bool)
    fixed[nd[:, clamped].ravel()] = True
    free = np.nonzero(~fixed)[0]
    A = (K + sp.diags(m / DT**2)).tocsr()[free][:, free].tocsc()
    A.sort_indices()
    b = np.asarray(f[free], dtype=np.float64)
    out["t_system"] = time.perf_counter() - t0
    out["tets"] = int(t.shape[0])
    out["dofs"] = int(free.size)
    out["nnz"] = int(A.nnz)
    out["mass"] = float(m[0::3].sum())
    free_nodes = np.nonzero(~fixed[0::3])[0]
    return out, A, b, mesh.p.T[free_nodes]


def relres(A, x, b) -> float:
    return float(np.linalg.norm(A @ x - b) / np.linalg.norm(b))


def run(cells: int, spsolve_max: int, cholmod: bool, amg: bool, warm: bool,
        default_quadrature: bool = True) -> dict:
    out, A, b, xfree = problem(cells, default_quadrature)
    n = out["dofs"]
    if spsolve_max and n <= spsolve_max:
        import scipy.sparse.linalg as spla

        t0 = time.perf_counter()
        x = spla.spsolve(A, b)
        out["t_spsolve"] = time.perf_counter() - t0
        out["res_spsolve"] = relres(A, x, b)
        del x
    factor = None
    if cholmod:
        try:
            from sksparse.cholmod import analyze
        except ImportError as e:  # reported, the rest still runs
            out["cholmod_error"] = str(e)
        else:
            t0 = time.perf_counter()
            factor = analyze(A)
            t1 = time.perf_counter()
            factor.cholesky_inplace(A)
            t2 = time.perf_counter()
            x = factor(b)
            t3 = time.perf_counter()
            out["t_cholmod_analyse"] = t1 - t0
            out["t_cholmod_factor"] = t2 - t1
            out["t_cholmod_solve"] = t3 - t2
            out["res_cholmod"] = relres(A, x, b)
            del x
    if amg:
        import pyamg

        B = rigid_body_modes(xfree)
        t0 = time.perf_counter()
        ml = pyamg.smoothed_aggregation_solver(A.tobsr(blocksize=(3, 3)), B=B)
        t1 = time.perf_counter()
        res: list[float] = []
        x = ml.solve(b, x0=np.zeros_like(b), tol=RTOL, maxiter=2000, accel="cg", residuals=res)
        t2 = time.perf_counter()
        out["t_amg_setup"] = t1 - t0
        out["t_amg_solve"] = t2 - t1
        out["amg_iterations"] = len(res) - 1
        out["amg_levels"] = len(ml.levels)
        out["res_amg"] = relres(A, x, b)
        del x, ml
    out["peak_rss"] = peak_rss()
    if factor is not None and not warm and n <= 120_000:
        out["nnz_L_cholmod"] = int(factor.L().nnz)  # after the peak-memory reading
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--single", type=int, help="approximate tet count (icefem bench --single N)")
    ap.add_argument("--spsolve-max-dofs", type=int, default=20000)
    ap.add_argument("--no-cholmod", action="store_true")
    ap.add_argument("--no-amg", action="store_true")
    ap.add_argument("--cholmod-only", action="store_true",
                    help="1-point assembly + CHOLMOD only (e.g. with OPENBLAS_NUM_THREADS=1)")
    ap.add_argument("--verify-mesh", metavar="FILE.h5")
    ap.add_argument("--cells", default="3,4,5")
    ap.add_argument("--size", default="0.1,0.1,0.1")
    a = ap.parse_args()
    if a.verify_mesh:
        cells = tuple(int(c) for c in a.cells.split(","))
        size = tuple(float(s) for s in a.size.split(","))
        return verify_mesh(a.verify_mesh, cells, size)
    if a.single is None:
        ap.error("--single N or --verify-mesh FILE")
    if a.cholmod_only:
        a.spsolve_max_dofs, a.no_cholmod, a.no_amg = 0, False, True
    dq = not a.cholmod_only
    # Warm-up on a 2x2x2 mesh: imports, first-call overheads, BLAS threads (not timed).
    run(2, a.spsolve_max_dofs, not a.no_cholmod, not a.no_amg, warm=True, default_quadrature=dq)
    out = run(cells_for(a.single), a.spsolve_max_dofs, not a.no_cholmod, not a.no_amg, warm=False,
              default_quadrature=dq)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
