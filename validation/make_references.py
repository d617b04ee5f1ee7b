#!/usr/bin/env python3
"""Build scikit-fem reference solutions for validating icefem.

Every case is small-strain isotropic linear elasticity on P1 tetrahedra
(scikit-fem ``MeshTet`` + ``ElementVectorH1(ElementTetP1())``), solved with a
sparse direct solver.  Each case is written to ``validation/reference/<case>.h5``
with the layout documented in ``validation/README.md``.

Run:  validation/setup_venv.sh && validation/.venv/bin/python validation/make_references.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import h5py
import numpy as np
import scipy
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import skfem
from skfem import (
    Basis,
    BilinearForm,
    ElementTetP0,
    ElementTetP1,
    ElementVectorH1,
    FacetBasis,
    LinearForm,
    MeshTet,
    asm,
)
from skfem.helpers import div
from skfem.models.elasticity import linear_elasticity

# ----------------------------------------------------------------------------
# Constants (SI)
# ----------------------------------------------------------------------------
LAMBDA = 8.64e10  # Pa
MU = 3.70e10  # Pa
RHO = 916.0  # kg/m^3
G = np.array([0.0, 0.0, -9.81])  # m/s^2
NO_G = np.zeros(3)

YOUNG = MU * (3 * LAMBDA + 2 * MU) / (LAMBDA + MU)
POISSON = LAMBDA / (2 * (LAMBDA + MU))
BULK = LAMBDA + 2 * MU / 3

BEAM_L, BEAM_W, BEAM_H = 0.4, 0.04, 0.04  # m (x, y, z)
BEAM_LEVELS = [(8, 1, 1), (16, 2, 2), (32, 4, 4)]  # cells (x, y, z); 6 tets per cell
CUBE_SIDE = 0.1  # m
CUBE_LEVELS = [2, 4, 8]  # cells per side
EIG_BOX = np.array([[0.025, 0.025, 0.025], [0.075, 0.075, 0.075]])  # m, [lo; hi]
EIG_E = 0.0291  # isotropic eigenstrain magnitude (dimensionless)
TRACTION = np.array([0.0, 0.0, -1.0e6])  # Pa
DYN_LEVEL = (16, 2, 2)
DYN_RUNS = [  # (label, dt [s], steps)
    ("dt_1e-5", 1e-5, 200),
    ("dt_1e-4", 1e-4, 200),
    ("dt_1e-3", 1e-3, 100),
    ("dt_1_30", 1.0 / 30.0, 30),
]
CLAMP_TOL = 1e-9
RESID_TOL = 1e-12

HERE = Path(__file__).resolve().parent
OUT = HERE / "reference"

ELEM = ElementVectorH1(ElementTetP1())

CHECKS: list[tuple[str, bool, str]] = []
STATS: dict[str, float] = {}


def check(name: str, ok: bool, detail: str) -> None:
    CHECKS.append((name, bool(ok), detail))


# ----------------------------------------------------------------------------
# Helpers
# ----------------------------------------------------------------------------
def beam_mesh(nx: int, ny: int, nz: int) -> MeshTet:
    return MeshTet.init_tensor(
        np.linspace(0.0, BEAM_L, nx + 1),
        np.linspace(0.0, BEAM_W, ny + 1),
        np.linspace(0.0, BEAM_H, nz + 1),
    )


def cube_mesh(n: int) -> MeshTet:
    x = np.linspace(0.0, CUBE_SIDE, n + 1)
    return MeshTet.init_tensor(x, x, x)


def oriented_tets(mesh: MeshTet) -> np.ndarray:
    """(m,4) int64 connectivity, each tet with det[x1-x0,x2-x0,x3-x0] > 0.

    scikit-fem sorts vertex indices inside each tet, so orientation is
    arbitrary; swap vertices 1 and 2 where the signed volume is negative.
    The element order is unchanged (same as mesh.t columns)."""
    t = mesh.t.T.astype(np.int64).copy()
    p = mesh.p.T
    det = signed_det(p, t)
    neg = det < 0
    t[neg, 1], t[neg, 2] = t[neg, 2].copy(), t[neg, 1].copy()
    det2 = signed_det(p, t)
    assert np.all(det2 > 0), "failed to orient tets"
    return t


def signed_det(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    x0 = p[t[:, 0]]
    return np.linalg.det(
        np.stack([p[t[:, 1]] - x0, p[t[:, 2]] - x0, p[t[:, 3]] - x0], axis=-1)
    )


def tet_volumes(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    return np.abs(signed_det(p, t)) / 6.0


def lumped_nodal(p: np.ndarray, t: np.ndarray, per_elem: np.ndarray) -> np.ndarray:
    """sum over elements of per_elem*vol/4 onto each vertex -> (n,)"""
    vol = tet_volumes(p, t)
    out = np.zeros(p.shape[0])
    np.add.at(out, t.ravel(), np.repeat(per_elem * vol / 4.0, 4))
    return out


def stiffness(basis: Basis) -> sp.csr_matrix:
    return asm(linear_elasticity(LAMBDA, MU), basis).tocsr()


def body_force(basis: Basis, g: np.ndarray) -> np.ndarray:
    @LinearForm
    def bf(v, w):
        return RHO * (g[0] * v[0] + g[1] * v[1] + g[2] * v[2])

    return asm(bf, basis)


def clamped_x0_dofs(basis: Basis) -> np.ndarray:
    nodes = np.nonzero(basis.mesh.p[0] < CLAMP_TOL)[0]
    return basis.nodal_dofs[:, nodes].ravel()


def nodal_to_vec(basis: Basis, x: np.ndarray) -> np.ndarray:
    """global dof vector -> (n,3) nodal array"""
    return x[basis.nodal_dofs].T.copy()


def _matvec_ld(A: sp.csr_matrix, x: np.ndarray) -> np.ndarray:
    """A @ x accumulated in extended precision (np.longdouble)."""
    prod = A.data.astype(np.longdouble) * np.asarray(x, dtype=np.longdouble)[A.indices]
    return np.add.reduceat(prod, A.indptr[:-1])


def direct_solve(A: sp.spmatrix, b: np.ndarray, lu=None) -> tuple[np.ndarray, float]:
    """Sparse direct solve (SuperLU) + mixed-precision iterative refinement.

    Residuals are accumulated in np.longdouble, so the returned float64 x is
    (up to rounding) the exact solution of the float64 system.  Returns x and
    the relative residual ||b - A x||_2 / ||b||_2 of the returned float64 x
    (evaluated in extended precision).  Asserted:
      * normwise backward error ||r||_inf / (||A||_inf ||x||_inf + ||b||_inf) < RESID_TOL;
      * relative residual < RESID_TOL, or, when rounding x to float64 alone
        already makes that impossible (slender beams: ||A|| ||x|| / ||b|| ~ 1e6),
        that the refinement has converged to the rounding floor
        (last correction ||dx|| <= 1e-14 ||x||).
    """
    A = A.tocsr()
    if lu is None:
        lu = spla.splu(A.tocsc())
    b = np.asarray(b, dtype=np.float64)
    nb = np.linalg.norm(b)
    if nb == 0.0:
        return np.zeros_like(b), 0.0
    x = lu.solve(b)
    bl = b.astype(np.longdouble)
    dx_rel = np.inf
    for _ in range(6):
        r = np.asarray(bl - _matvec_ld(A, x), dtype=np.float64)
        if np.linalg.norm(r) / nb < RESID_TOL * 1e-2:
            break
        dx = lu.solve(r)
        x = x + dx
        dx_rel = np.linalg.norm(dx) / max(np.linalg.norm(x), 1e-300)
        if dx_rel <= 1e-15:
            break
    r = np.asarray(bl - _matvec_ld(A, x), dtype=np.float64)
    res = float(np.linalg.norm(r) / nb)
    a_inf = float(np.abs(A).sum(axis=1).max())
    bwd = float(np.abs(r).max() / (a_inf * np.abs(x).max() + np.abs(b).max()))
    assert bwd < RESID_TOL, f"backward error {bwd:.3e} >= {RESID_TOL}"
    assert res < RESID_TOL or dx_rel <= 1e-14, (
        f"relative residual {res:.3e} >= {RESID_TOL} and refinement not converged ({dx_rel:.1e})")
    STATS["last_backward_error"] = bwd
    return x, res


def solve_static(K: sp.csr_matrix, f: np.ndarray, fixed: np.ndarray) -> tuple[np.ndarray, float]:
    ndof = K.shape[0]
    free = np.setdiff1d(np.arange(ndof), fixed)
    Kff = K[free][:, free]
    xf, res = direct_solve(Kff, f[free])
    x = np.zeros(ndof)
    x[free] = xf
    return x, res


def write_common(h5: h5py.File, case: str, mesh: MeshTet, tets: np.ndarray, g: np.ndarray,
                 ndof_total: int, ndof_free: int, description: str) -> None:
    h5.attrs["case"] = case
    h5.attrs["description"] = description
    h5.attrs["lambda"] = LAMBDA
    h5.attrs["mu"] = MU
    h5.attrs["rho"] = RHO
    h5.attrs["gravity"] = np.asarray(g, dtype=np.float64)
    h5.attrs["n_nodes"] = np.int64(mesh.p.shape[1])
    h5.attrs["n_tets"] = np.int64(tets.shape[0])
    h5.attrs["n_dofs"] = np.int64(ndof_total)
    h5.attrs["n_free_dofs"] = np.int64(ndof_free)
    h5.attrs["generator"] = (
        f"make_references.py, scikit-fem {skfem.__version__}, numpy {np.__version__}, "
        f"scipy {scipy.__version__}, h5py {h5py.__version__}"
    )
    gm = h5.create_group("mesh")
    gm.create_dataset("nodes", data=np.ascontiguousarray(mesh.p.T, dtype=np.float64))
    gm.create_dataset("tets", data=np.ascontiguousarray(tets, dtype=np.int64))


def tip_node(p: np.ndarray, target=(BEAM_L, BEAM_W, BEAM_H)) -> int:
    return int(np.argmin(np.linalg.norm(p - np.asarray(target), axis=1)))


def write_beam_attrs(h5: h5py.File, cells) -> None:
    h5.attrs["length"] = BEAM_L
    h5.attrs["width"] = BEAM_W
    h5.attrs["height"] = BEAM_H
    h5.attrs["cells"] = np.asarray(cells, dtype=np.int64)
    h5.attrs["clamp_rule"] = "all dofs of nodes with x < 1e-9 fixed to zero"
    h5.attrs["clamp_tol"] = CLAMP_TOL


# ----------------------------------------------------------------------------
# (a) gravity beam
# ----------------------------------------------------------------------------
def case_gravity_beam(r: int, cells) -> dict:
    name = f"gravity_beam_r{r}"
    t0 = time.perf_counter()
    mesh = beam_mesh(*cells)
    basis = Basis(mesh, ELEM)
    K = stiffness(basis)
    f = body_force(basis, G)
    fixed = clamped_x0_dofs(basis)
    t_asm = time.perf_counter() - t0
    t0 = time.perf_counter()
    x, res = solve_static(K, f, fixed)
    t_sol = time.perf_counter() - t0
    bwd = STATS["last_backward_error"]

    tets = oriented_tets(mesh)
    p = mesh.p.T
    # cross-check P1 load against rho*g*vol/4 per node per element
    lump = lumped_nodal(p, tets, np.full(tets.shape[0], RHO))
    f_nodal = nodal_to_vec(basis, f)
    assert np.allclose(f_nodal, lump[:, None] * G[None, :], rtol=1e-12, atol=1e-12 * np.abs(f).max())

    u = nodal_to_vec(basis, x)
    tip = tip_node(p)
    face = p[:, 0] > BEAM_L - CLAMP_TOL
    w_fe_tip = u[tip, 2]
    w_fe_face = u[face, 2].mean()
    q = RHO * abs(G[2]) * BEAM_W * BEAM_H  # N/m
    I = BEAM_W * BEAM_H**3 / 12.0
    w_eb = -q * BEAM_L**4 / (8 * YOUNG * I)

    with h5py.File(OUT / f"{name}.h5", "w") as h5:
        write_common(h5, name, mesh, tets, G, K.shape[0], K.shape[0] - fixed.size,
                     "cantilever beam clamped at x=0 under self-weight")
        write_beam_attrs(h5, cells)
        h5.attrs["tip_node"] = np.int64(tip)
        h5.attrs["t_assembly"] = t_asm
        h5.attrs["t_solve"] = t_sol
        h5.attrs["residual"] = res
        h5.attrs["backward_error"] = bwd
        h5.attrs["euler_bernoulli_tip_w"] = w_eb
        h5.create_group("solution").create_dataset("u", data=u)
    return dict(name=name, ndof=K.shape[0], nfree=K.shape[0] - fixed.size, res=res, bwd=bwd,
                t_asm=t_asm, t_sol=t_sol, w_tip=w_fe_tip, w_face=w_fe_face, w_eb=w_eb,
                ratio=w_fe_tip / w_eb, ratio_face=w_fe_face / w_eb)


# ----------------------------------------------------------------------------
# (b) traction beam
# ----------------------------------------------------------------------------
def case_traction_beam(r: int, cells) -> dict:
    name = f"traction_beam_r{r}"
    t0 = time.perf_counter()
    mesh = beam_mesh(*cells)
    basis = Basis(mesh, ELEM)
    K = stiffness(basis)
    facets = mesh.facets_satisfying(lambda x: x[0] > BEAM_L - CLAMP_TOL, boundaries_only=True)
    fbasis = FacetBasis(mesh, ELEM, facets=facets)

    @LinearForm
    def trac(v, w):
        return TRACTION[0] * v[0] + TRACTION[1] * v[1] + TRACTION[2] * v[2]

    f = asm(trac, fbasis)
    fixed = clamped_x0_dofs(basis)
    t_asm = time.perf_counter() - t0
    t0 = time.perf_counter()
    x, res = solve_static(K, f, fixed)
    t_sol = time.perf_counter() - t0
    bwd = STATS["last_backward_error"]

    # total load check: sum f = t * area
    ftot = nodal_to_vec(basis, f).sum(axis=0)
    assert np.allclose(ftot, TRACTION * BEAM_W * BEAM_H, rtol=1e-12, atol=1e-6)

    tets = oriented_tets(mesh)
    p = mesh.p.T
    u = nodal_to_vec(basis, x)
    tip = tip_node(p)
    P = abs(TRACTION[2]) * BEAM_W * BEAM_H
    I = BEAM_W * BEAM_H**3 / 12.0
    w_eb = -P * BEAM_L**3 / (3 * YOUNG * I)
    with h5py.File(OUT / f"{name}.h5", "w") as h5:
        write_common(h5, name, mesh, tets, NO_G, K.shape[0], K.shape[0] - fixed.size,
                     "cantilever beam clamped at x=0, uniform traction on face x=L")
        write_beam_attrs(h5, cells)
        h5.attrs["traction"] = TRACTION
        h5.attrs["traction_face_rule"] = (
            "boundary facets whose midpoint x > 0.4 - 1e-9 (the end face x = length)")
        h5.attrs["traction_face_x_min"] = BEAM_L - CLAMP_TOL
        h5.attrs["n_traction_facets"] = np.int64(len(facets))
        h5.attrs["tip_node"] = np.int64(tip)
        h5.attrs["t_assembly"] = t_asm
        h5.attrs["t_solve"] = t_sol
        h5.attrs["residual"] = res
        h5.attrs["backward_error"] = bwd
        h5.attrs["euler_bernoulli_tip_w"] = w_eb
        h5.create_group("solution").create_dataset("u", data=u)
    return dict(name=name, ndof=K.shape[0], nfree=K.shape[0] - fixed.size, res=res, bwd=bwd,
                t_asm=t_asm, t_sol=t_sol, w_tip=u[tip, 2], w_eb=w_eb, ratio=u[tip, 2] / w_eb,
                nfacets=len(facets))


# ----------------------------------------------------------------------------
# (c) eigenstrain cube
# ----------------------------------------------------------------------------
def case_eigenstrain_cube(r: int, n: int) -> dict:
    name = f"eigenstrain_cube_r{r}"
    t0 = time.perf_counter()
    mesh = cube_mesh(n)
    basis = Basis(mesh, ELEM)
    K = stiffness(basis)
    centroids = mesh.p[:, mesh.t].mean(axis=1).T  # (m,3)
    # Widened by 1e-9 m: centroids on the box faces (0.025, 0.075) must count on both sides
    # alike, whatever the float rounding of the centroid.
    inside = np.all((centroids >= EIG_BOX[0] - 1e-9) & (centroids <= EIG_BOX[1] + 1e-9), axis=1)
    e_elem = np.where(inside, EIG_E, 0.0)
    basis0 = basis.with_element(ElementTetP0())
    e_field = basis0.interpolate(e_elem)

    # sigma0 = C:(e I) = (3 lambda + 2 mu) e I ;  f = int sigma0 : eps(v) = int (3l+2m) e div v
    @LinearForm
    def eig_load(v, w):
        return (3 * LAMBDA + 2 * MU) * w["e0"] * div(v)

    f = asm(eig_load, basis, e0=e_field)
    fixed = basis.get_dofs(lambda x: x[2] < CLAMP_TOL).all()
    fixed_nodes = np.nonzero(mesh.p[2] < CLAMP_TOL)[0]
    assert np.array_equal(np.sort(fixed), np.sort(basis.nodal_dofs[:, fixed_nodes].ravel()))
    t_asm = time.perf_counter() - t0
    t0 = time.perf_counter()
    x, res = solve_static(K, f, fixed)
    t_sol = time.perf_counter() - t0
    bwd = STATS["last_backward_error"]

    # per-element stress -> pressure p = -tr(sigma)/3
    tets = oriented_tets(mesh)
    p = mesh.p.T
    u = nodal_to_vec(basis, x)
    # P1 strain is constant per element: compute gradients explicitly
    X = p[tets]  # (m,4,3)
    D = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=1)  # rows = edges
    Dinv = np.linalg.inv(D)  # (m,3,3); grad of barycentric 1..3 are columns of Dinv
    dN = np.concatenate([-Dinv.sum(axis=2, keepdims=True), Dinv], axis=2)  # (m,3,4)
    Ue = u[tets]  # (m,4,3)
    gradu = np.einsum("mia,maj->mji", dN, Ue)  # du_j/dx_i -> gradu[m, j, i]
    eps = 0.5 * (gradu + np.transpose(gradu, (0, 2, 1)))
    treps = np.trace(eps, axis1=1, axis2=2)
    tr_sig = (3 * LAMBDA + 2 * MU) * (treps - 3 * e_elem)
    pressure = -tr_sig / 3.0
    pmax_in = pressure[inside].max() if inside.any() else np.nan
    p_ref = 3 * BULK * EIG_E
    # Eshelby spherical inclusion in an infinite matrix (rough reference)
    p_esh = p_ref * (1 - (1 + POISSON) / (3 * (1 - POISSON)))

    with h5py.File(OUT / f"{name}.h5", "w") as h5:
        write_common(h5, name, mesh, tets, NO_G, K.shape[0], K.shape[0] - fixed.size,
                     "cube, face z=0 clamped, isotropic eigenstrain e*I in elements whose "
                     "centroid lies in the inner box")
        h5.attrs["side"] = CUBE_SIDE
        h5.attrs["cells_per_side"] = np.int64(n)
        h5.attrs["clamp_rule"] = "all dofs of nodes with z < 1e-9 fixed to zero"
        h5.attrs["clamp_tol"] = CLAMP_TOL
        h5.attrs["eigenstrain"] = EIG_E
        h5.attrs["eigenstrain_box_min"] = EIG_BOX[0]
        h5.attrs["eigenstrain_box_max"] = EIG_BOX[1]
        h5.attrs["eigenstrain_rule"] = "element centroid c with box_min - 1e-9 <= c <= box_max + 1e-9 (all 3 axes)"
        h5.attrs["n_eigenstrain_tets"] = np.int64(inside.sum())
        h5.attrs["t_assembly"] = t_asm
        h5.attrs["t_solve"] = t_sol
        h5.attrs["residual"] = res
        h5.attrs["backward_error"] = bwd
        h5["mesh"].create_dataset("eigenstrain", data=e_elem.astype(np.float64))
        g = h5.create_group("solution")
        g.create_dataset("u", data=u)
        g.create_dataset("pressure", data=pressure)
    return dict(name=name, ndof=K.shape[0], nfree=K.shape[0] - fixed.size, res=res, bwd=bwd,
                t_asm=t_asm, t_sol=t_sol, n_in=int(inside.sum()), pmax=pmax_in,
                pmean=pressure[inside].mean() if inside.any() else np.nan, p_ref=p_ref, p_esh=p_esh)


# ----------------------------------------------------------------------------
# (d) dynamics: backward Euler, lumped mass, gravity step load
# ----------------------------------------------------------------------------
def case_dynamics() -> dict:
    name = "dynamics_beam"
    cells = DYN_LEVEL
    t0 = time.perf_counter()
    mesh = beam_mesh(*cells)
    basis = Basis(mesh, ELEM)
    K = stiffness(basis)
    f = body_force(basis, G)
    tets = oriented_tets(mesh)
    p = mesh.p.T
    m_node = lumped_nodal(p, tets, np.full(tets.shape[0], RHO))  # (n,)
    mdiag = np.zeros(K.shape[0])
    for c in range(3):
        mdiag[basis.nodal_dofs[c]] = m_node
    # cross-check: row-sum lumping of the consistent P1 mass equals rho*vol/4
    @BilinearForm
    def mass(u, v, w):
        return RHO * (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
    Mc = asm(mass, basis)
    assert np.allclose(np.asarray(Mc.sum(axis=1)).ravel(), mdiag, rtol=1e-12)
    fixed = clamped_x0_dofs(basis)
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    Kff = K[free][:, free].tocsc()
    t_asm = time.perf_counter() - t0

    tip = tip_node(p)
    # static solution (t -> infinity limit) for reference
    xs, _ = solve_static(K, f, fixed)
    u_static = nodal_to_vec(basis, xs)

    out = dict(name=name, ndof=K.shape[0], nfree=free.size, tip=tip, runs={},
               w_static=u_static[tip, 2], t_asm=t_asm)
    with h5py.File(OUT / f"{name}.h5", "w") as h5:
        write_common(h5, name, mesh, tets, G, K.shape[0], free.size,
                     "cantilever beam clamped at x=0, at rest, gravity switched on at t=0; "
                     "backward Euler, row-sum lumped mass, no damping")
        write_beam_attrs(h5, cells)
        h5.attrs["tip_node"] = np.int64(tip)
        h5.attrs["t_assembly"] = t_asm
        h5.attrs["scheme"] = ("(M/h^2 + K) u_{n+1} = M/h^2 (u_n + h v_n) + f ; "
                              "v_{n+1} = (u_{n+1} - u_n)/h ; u_0 = v_0 = 0")
        h5.attrs["mass"] = "lumped: rho*vol/4 per node per element (row-sum of consistent P1 mass)"
        h5.create_group("solution").create_dataset("u_static", data=u_static)
        gd = h5.create_group("dynamics")
        t_sol_total = 0.0
        for label, dt, steps in DYN_RUNS:
            t0 = time.perf_counter()
            mf = mdiag[free]
            A = (sp.diags(mf / dt**2) + Kff).tocsc()
            lu = spla.splu(A)
            uf = np.zeros(free.size)
            vf = np.zeros(free.size)
            ff = f[free]
            times = np.zeros(steps + 1)
            tip_hist = np.zeros((steps + 1, 3))
            max_res = 0.0
            max_bwd = 0.0
            xfull = np.zeros(K.shape[0])
            for k in range(1, steps + 1):
                rhs = mf / dt**2 * (uf + dt * vf) + ff
                unew, res = direct_solve(A, rhs, lu)
                max_res = max(max_res, res)
                max_bwd = max(max_bwd, STATS["last_backward_error"])
                vf = (unew - uf) / dt
                uf = unew
                times[k] = k * dt
                xfull[free] = uf
                tip_hist[k] = xfull[basis.nodal_dofs[:, tip]]
            t_sol = time.perf_counter() - t0
            t_sol_total += t_sol
            xfull[:] = 0.0
            xfull[free] = uf
            u_fin = nodal_to_vec(basis, xfull)
            xfull[:] = 0.0
            xfull[free] = vf
            v_fin = nodal_to_vec(basis, xfull)
            g = gd.create_group(label)
            g.attrs["dt"] = dt
            g.attrs["steps"] = np.int64(steps)
            g.attrs["t_solve"] = t_sol
            g.attrs["max_residual"] = max_res
            g.attrs["max_backward_error"] = max_bwd
            g.create_dataset("time", data=times)
            g.create_dataset("tip_u", data=tip_hist)
            g.create_dataset("u", data=u_fin)
            g.create_dataset("v", data=v_fin)
            out["runs"][label] = dict(dt=dt, steps=steps, tip_z=tip_hist[:, 2].copy(),
                                      t_sol=t_sol, max_res=max_res, max_bwd=max_bwd)
        h5.attrs["t_solve"] = t_sol_total
        out["t_sol"] = t_sol_total
    return out


# ----------------------------------------------------------------------------
# Independent re-check of the written files (plain numpy, no scikit-fem):
# re-assemble K and f from /mesh and the root attributes exactly as the layout
# documents them, and check K u = f on the free dofs.
# ----------------------------------------------------------------------------
def p1_geometry(p: np.ndarray, t: np.ndarray, name: str = "mesh"):
    """P1 tet data for nodes p and positively oriented tets t: volumes (m,), strain matrices
    B (m,6,12) (Voigt xx,yy,zz,yz,xz,xy, engineering shear; dof = 3*node + comp) and the
    divergence rows bdiv (m,12)."""
    X = p[t]
    D = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=1)
    det = np.linalg.det(D)
    assert np.all(det > 0), f"{name}: non-positive tet orientation"
    vol = det / 6.0
    Dinv = np.linalg.inv(D)
    dN = np.concatenate([-Dinv.sum(axis=2, keepdims=True), Dinv], axis=2)  # (m,3,4) dN_a/dx_i
    B = np.zeros((len(t), 6, 12))
    for a in range(4):
        gx, gy, gz = dN[:, 0, a], dN[:, 1, a], dN[:, 2, a]
        B[:, 0, 3 * a] = gx
        B[:, 1, 3 * a + 1] = gy
        B[:, 2, 3 * a + 2] = gz
        B[:, 3, 3 * a + 1], B[:, 3, 3 * a + 2] = gz, gy
        B[:, 4, 3 * a], B[:, 4, 3 * a + 2] = gz, gx
        B[:, 5, 3 * a], B[:, 5, 3 * a + 1] = gy, gx
    return vol, B, B[:, 0] + B[:, 1] + B[:, 2]


def numpy_check_file(path: Path) -> float:
    with h5py.File(path, "r") as h5:
        p = h5["mesh/nodes"][...]
        t = h5["mesh/tets"][...]
        lam, mu, rho = (float(h5.attrs[k]) for k in ("lambda", "mu", "rho"))
        g = h5.attrs["gravity"][...]
        case = h5.attrs["case"]
        u = h5["solution/u"][...]
        eig = h5["mesh/eigenstrain"][...] if "eigenstrain" in h5["mesh"] else np.zeros(len(t))
        trac = h5.attrs["traction"][...] if "traction" in h5.attrs else None
        xmin = float(h5.attrs["traction_face_x_min"]) if trac is not None else None
    n = len(p)
    m = len(t)
    vol, B, _ = p1_geometry(p, t, path.name)
    C = np.zeros((6, 6))
    C[:3, :3] = lam
    C[np.arange(3), np.arange(3)] += 2 * mu
    C[np.arange(3, 6), np.arange(3, 6)] = mu
    Ke = np.einsum("mia,ij,mjb,m->mab", B, C, B, vol)
    dofs = (3 * t[:, :, None] + np.arange(3)[None, None, :]).reshape(m, 12)
    K = sp.coo_matrix((Ke.ravel(), (np.repeat(dofs, 12, axis=1).ravel(), np.tile(dofs, (1, 12)).ravel())),
                      shape=(3 * n, 3 * n)).tocsr()
    f = np.zeros(3 * n)
    # body force, P1 load: rho*g*vol/4 per node per element
    np.add.at(f, dofs.ravel(), (np.repeat(rho * vol / 4, 4)[:, None] * g[None, :]).ravel())
    # eigenstrain: int B^T C eps0, eps0 = e I -> Voigt (e,e,e,0,0,0)
    s0 = C @ np.array([1, 1, 1, 0, 0, 0.0])
    np.add.at(f, dofs.ravel(), np.einsum("mia,i,m->ma", B, s0, eig * vol).ravel())
    # traction on boundary faces with midpoint x > xmin: t * area / 3 per node
    if trac is not None:
        faces = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
        key = np.sort(faces, axis=1)
        _, idx, cnt = np.unique(key, axis=0, return_index=True, return_counts=True)
        bfaces = faces[idx[cnt == 1]]
        bfaces = bfaces[p[bfaces].mean(axis=1)[:, 0] > xmin]
        P = p[bfaces]
        area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
        np.add.at(f, (3 * bfaces[:, :, None] + np.arange(3)).ravel(),
                  (area[:, None, None] / 3 * np.broadcast_to(trac, (len(area), 3, 3))).ravel())
    ax = 2 if case.startswith("eigenstrain") else 0
    fixed_nodes = np.nonzero(p[:, ax] < CLAMP_TOL)[0]
    free = np.setdiff1d(np.arange(3 * n), (3 * fixed_nodes[:, None] + np.arange(3)).ravel())
    assert np.all(u[fixed_nodes] == 0.0)
    r = (K @ u.ravel() - f)[free]
    return float(np.linalg.norm(r) / np.linalg.norm(f[free]))


# ----------------------------------------------------------------------------
def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    print(f"scikit-fem {skfem.__version__}  E = {YOUNG:.4e} Pa  nu = {POISSON:.4f}  K = {BULK:.4e} Pa")

    print("\n(a) gravity beam: tip deflection vs Euler-Bernoulli w = q L^4 / (8 E I)")
    ga = []
    for r, cells in enumerate(BEAM_LEVELS):
        d = case_gravity_beam(r, cells)
        ga.append(d)
        print(f"  {d['name']:<22} cells={cells} ndof={d['ndof']:5d} free={d['nfree']:5d} "
              f"res={d['res']:.1e} bwd={d['bwd']:.1e} t_asm={d['t_asm']:.3f}s t_sol={d['t_sol']:.3f}s  "
              f"w_tip={d['w_tip']:.4e} w_EB={d['w_eb']:.4e} ratio={d['ratio']:.4f} "
              f"(face-mean ratio {d['ratio_face']:.4f})")
    ratios = [d["ratio"] for d in ga]
    check("gravity beam ratio increases with refinement", all(np.diff(ratios) > 0),
          " -> ".join(f"{x:.4f}" for x in ratios))
    check("gravity beam finest ratio in [0.5, 1.05]", 0.5 <= ratios[-1] <= 1.05, f"{ratios[-1]:.4f}")

    print("\n(b) traction beam: tip deflection vs Euler-Bernoulli w = P L^3 / (3 E I)")
    tb = []
    for r, cells in enumerate(BEAM_LEVELS):
        d = case_traction_beam(r, cells)
        tb.append(d)
        print(f"  {d['name']:<22} cells={cells} ndof={d['ndof']:5d} free={d['nfree']:5d} "
              f"facets={d['nfacets']:3d} res={d['res']:.1e} bwd={d['bwd']:.1e} t_asm={d['t_asm']:.3f}s "
              f"t_sol={d['t_sol']:.3f}s  w_tip={d['w_tip']:.4e} w_EB={d['w_eb']:.4e} "
              f"ratio={d['ratio']:.4f}")
    ratios = [d["ratio"] for d in tb]
    check("traction beam ratio increases with refinement", all(np.diff(ratios) > 0),
          " -> ".join(f"{x:.4f}" for x in ratios))

    print("\n(c) eigenstrain cube: pressure p = -tr(sigma)/3 in the eigenstrain region")
    cc = []
    for r, n in enumerate(CUBE_LEVELS):
        d = case_eigenstrain_cube(r, n)
        cc.append(d)
        print(f"  {d['name']:<22} n={n} ndof={d['ndof']:5d} free={d['nfree']:5d} "
              f"tets_in={d['n_in']:4d} res={d['res']:.1e} bwd={d['bwd']:.1e} t_asm={d['t_asm']:.3f}s "
              f"t_sol={d['t_sol']:.3f}s  p_max={d['pmax']:.4e} p_mean={d['pmean']:.4e} "
              f"3Ke={d['p_ref']:.4e} (p_max/3Ke={d['pmax'] / d['p_ref']:.3f}; "
              f"Eshelby sphere {d['p_esh']:.4e})")
    for d in cc:
        check(f"{d['name']} 0 < p_max < 3Ke", 0 < d["pmax"] < d["p_ref"],
              f"p_max/3Ke = {d['pmax'] / d['p_ref']:.3f}")

    print("\n(d) dynamics beam (backward Euler, lumped mass, gravity step at t=0)")
    dd = case_dynamics()
    print(f"  {dd['name']} cells={DYN_LEVEL} ndof={dd['ndof']} free={dd['nfree']} tip_node={dd['tip']} "
          f"w_static={dd['w_static']:.4e} t_asm={dd['t_asm']:.3f}s t_sol(total)={dd['t_sol']:.3f}s")
    for label, run in dd["runs"].items():
        z = run["tip_z"]
        vz = np.diff(z)
        sig = vz[np.abs(vz) > 1e-6 * np.abs(vz).max()]  # ignore round-off-level increments
        sign_changes = int(np.sum(np.diff(np.sign(sig)) != 0))
        print(f"    {label:<8} dt={run['dt']:.3e} steps={run['steps']:3d} t_end={run['dt'] * run['steps']:.4e}s "
              f"tip_z: min={z.min():.4e} final={z[-1]:.4e} min/w_static={z.min() / dd['w_static']:.3f} "
              f"velocity sign changes={sign_changes} max_res={run['max_res']:.1e} max_bwd={run['max_bwd']:.1e} t_sol={run['t_sol']:.3f}s")
        if label == "dt_1e-5":
            check("dynamics dt=1e-5 tip oscillates (velocity changes sign)", sign_changes >= 1,
                  f"{sign_changes} sign changes")
            check("dynamics dt=1e-5 overshoots static deflection", z.min() < dd["w_static"],
                  f"min/w_static = {z.min() / dd['w_static']:.3f}")
            check("dynamics dt=1e-5 tip rebounds (final above min)", z[-1] > z.min(),
                  f"final {z[-1]:.4e} vs min {z.min():.4e}")
        if label == "dt_1_30":
            check("dynamics dt=1/30 settles near static", abs(z[-1] / dd["w_static"] - 1) < 1e-3,
                  f"final/w_static = {z[-1] / dd['w_static']:.6f}")

    print("\nindependent numpy re-assembly from the files (||K u - f|| / ||f|| on free dofs):")
    # Only this script's static elasticity files: the others have their own layout and checks.
    static_cases = ("gravity_beam_", "traction_beam_", "eigenstrain_cube_")
    for fpath in sorted(OUT.glob("*.h5")):
        if not fpath.name.startswith(static_cases):
            continue
        rr = numpy_check_file(fpath)
        print(f"  {fpath.name:<26} {rr:.2e}")
        check(f"{fpath.name} numpy re-check", rr < 1e-9, f"{rr:.2e}")

    print("\nfiles:")
    total = 0
    for fpath in sorted(OUT.glob("*.h5")):
        sz = fpath.stat().st_size
        total += sz
        print(f"  {fpath.name:<26} {sz / 1024:8.1f} KiB")
        check(f"{fpath.name} < 400 KB", sz < 400_000, f"{sz} B")
    print(f"  total {total / 1024:.1f} KiB")
    check("total < 3 MB", total < 3_000_000, f"{total} B")

    print("\nsanity checks:")
    for name, ok, detail in CHECKS:
        print(f"  [{'PASS' if ok else 'FAIL'}] {name}: {detail}")
    nfail = sum(not ok for _, ok, _ in CHECKS)
    print(f"\n{len(CHECKS) - nfail} passed, {nfail} failed")
    return 1 if nfail else 0


if __name__ == "__main__":
    sys.exit(main())
