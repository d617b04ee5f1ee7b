#!/usr/bin/env python3
"""Volumetric-locking reference: clamped cantilever beam, nearly incompressible (nu = 0.4999).

Writes ``validation/reference/locking_beam.h5`` (layout in ``validation/README.md``,
section "Locking beam").

Problem
    Beam [0, 0.4] x [0, 0.04] x [0, 0.04] m, all dofs of nodes with x < 1e-9 fixed,
    uniform traction t = (0, 0, -1e5) Pa on the end face x = 0.4 (P = 160 N), no gravity.
    Small-strain isotropic linear elasticity, sigma = 2 mu eps + lambda tr(eps) I,
    E = 1.0e10 Pa, nu = 0.4999 (locking case) and nu = 0.3 (control).

Quantities (tip deflection, m, negative = down)
    w_mean    (1 / (W H)) * integral of u_z over the end face x = L.  Since the traction
              is uniform, -w_mean * |t_z| W H is the compliance f.u, so for conforming
              displacement elements (P1, P2) |w_mean| is a lower bound of the exact value.
    w_centre  u_z at the end-face centre (L, W/2, H/2).
    w_nodes   P1 meshes only: arithmetic mean of u_z over the nodes with x > L - 1e-9.
              This is the number an icefem test gets most directly from its nodal output.

Reference
    Taylor-Hood P2-P1 mixed displacement-pressure elements (ElementVectorH1(ElementTetP2())
    for u, continuous ElementTetP1() for p = lambda div u), on MeshTet.init_tensor meshes
    with 16x2x2, 32x4x4 and 64x8x8 cells.  The reference value is the 64x8x8 value; its
    error estimate is the difference to the 32x4x4 value.  Pure P2 displacement elements
    still lock at nu = 0.4999 on these meshes (their w_mean changes by 1.14 % from 32x4x4
    to 64x8x8, against 0.30 % for Taylor-Hood); they are computed and stored as a
    cross-check and as a lower bound of |w_mean|.

    Measured (w_mean, m):            nu = 0.4999                 nu = 0.3
      Taylor-Hood 16x2x2 / 32x4x4 / 64x8x8
                                 -1.55706 / -1.57405 / -1.578835e-3  -1.59402 / -1.59927 / -1.600786e-3
      change 32x4x4 -> 64x8x8    0.303 %                      0.095 %
      P2 16x2x2 / 32x4x4 / 64x8x8
                                 -1.49807 / -1.55444 / -1.57240e-3   -1.59238 / -1.59880 / -1.60065e-3
      Euler-Bernoulli / Timoshenko  -1.60000e-3 / -1.61400e-3     -1.60000e-3 / -1.61224e-3

P1 and average nodal pressure (ANP)
    Plain P1 tets and the small-strain form of the Bonet-Burton (1998) average nodal
    pressure tet, on the meshes icefem uses (8x1x1, 16x2x2, 32x4x4 cells, 6 tets per cell:
    the nodes and tets of traction_beam_r{0,1,2}.h5; the same tets as icefem's
    box_mesh(..., 6), numbered differently).  ANP energy:
        sum_e V_e mu |dev eps_e|^2 + sum_a V_a (kappa/2) theta_a^2,
        V_a = sum_{e contains a} V_e/4,  theta_a = sum_{e contains a} (V_e/4) div(u)_e / V_a,
        kappa = lambda + 2 mu / 3.
    The load is the consistent P1 traction load t * area / 3 per node per end-face facet.

    Measured w_nodes (m) and w_nodes / reference w_mean:
                      nu = 0.4999                       nu = 0.3
      P1   8x1x1    -1.82223e-5  0.0115              -3.10578e-4  0.1940
           16x2x2   -1.96264e-5  0.0124              -7.50388e-4  0.4688
           32x4x4   -2.51359e-5  0.0159              -1.22868e-3  0.7675
      ANP  8x1x1    -1.98314e-4  0.1256              -4.63847e-4  0.2898
           16x2x2   -5.65254e-4  0.3580              -9.68925e-4  0.6053
           32x4x4   -1.22646e-3  0.7768              -1.36457e-3  0.8524
    P1 tets also lock in bending (shear locking), so no P1-based element reaches the
    reference on these meshes; ANP at nu = 0.4999 comes close to plain P1 at nu = 0.3.

What the Rust locking-free test should check
    * Exactly this ANP tet, on the 16x2x2 and 32x4x4 meshes, nu = 0.4999 and 0.3:
      w_nodes equals the stored anp w_nodes to the linear solver's tolerance (1e-6
      relative with a direct solve); the fields anp/u_16x2x2 and anp/u_32x4x4 (nu = 0.4999
      and 0.3, node numbering of traction_beam_r1.h5 / traction_beam_r2.h5) allow a
      node-by-node comparison.
    * Any locking-free P1 variant (ANP, F-bar, ...), nu = 0.4999, ratio = w_nodes /
      reference_w_mean: ratio >= 0.30 at 16x2x2 and >= 0.70 at 32x4x4 (ANP: 0.358, 0.777;
      plain P1: 0.012, 0.016), ratio increasing with refinement and <= 1.05; and the
      locking measure ratio(nu = 0.4999) / ratio(nu = 0.3) >= 0.85 at 32x4x4 (ANP 0.911,
      plain P1 0.021).

Run:  validation/setup_venv.sh && validation/.venv/bin/python validation/make_locking_reference.py
      (about 7 minutes on 2 cores, most of it in the two 64x8x8 Taylor-Hood factorizations)
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
    ElementTetP1,
    ElementTetP2,
    ElementVectorH1,
    FacetBasis,
    LinearForm,
    MeshTet,
    asm,
)
from skfem.helpers import div
from skfem.models.elasticity import linear_elasticity

import make_references as mr

try:  # CHOLMOD (scikit-sparse) for the large P2 / Taylor-Hood systems; SuperLU otherwise
    from sksparse.cholmod import cholesky as _cholmod
except ImportError:  # pragma: no cover
    _cholmod = None

# ----------------------------------------------------------------------------
# Constants (SI)
# ----------------------------------------------------------------------------
YOUNG = 1.0e10  # Pa
NUS = (0.4999, 0.3)
TRACTION = np.array([0.0, 0.0, -1.0e5])  # Pa, on the end face x = L
BEAM_L, BEAM_W, BEAM_H = mr.BEAM_L, mr.BEAM_W, mr.BEAM_H  # 0.4, 0.04, 0.04 m
P1_LEVELS = mr.BEAM_LEVELS  # (8,1,1), (16,2,2), (32,4,4): the icefem meshes
REF_LEVELS = [(16, 2, 2), (32, 4, 4), (64, 8, 8)]  # P2 and Taylor-Hood
ANP_FIELD_LEVELS = [(16, 2, 2), (32, 4, 4)]  # ANP displacement fields stored in the file
CLAMP_TOL = mr.CLAMP_TOL
CENTRE = np.array([BEAM_L, BEAM_W / 2, BEAM_H / 2])
BWD_TOL = 1e-12
REF_CONV_TOL = 0.005  # |w(64x8x8) - w(32x4x4)| / |w(64x8x8)|
EB_TOL = 0.10  # |w_ref / w_EB - 1| for nu = 0.3
# Bounds proposed for the Rust locking-free test (nu = 0.4999, ratio = w_nodes / reference w_mean);
# the ANP results here must satisfy them.
RUST_MIN_RATIO = {(16, 2, 2): 0.30, (32, 4, 4): 0.70}
RUST_MAX_RATIO = 1.05
RUST_MIN_LOCKING = 0.85  # ratio(nu = 0.4999) / ratio(nu = 0.3) at 32x4x4

HERE = Path(__file__).resolve().parent
OUT = HERE / "reference" / "locking_beam.h5"

VEC_P1 = ElementVectorH1(ElementTetP1())
VEC_P2 = ElementVectorH1(ElementTetP2())

CHECKS: list[tuple[str, bool, str]] = []


def check(name: str, ok: bool, detail: str) -> None:
    CHECKS.append((name, bool(ok), detail))


def lame(nu: float) -> tuple[float, float]:
    """(lambda, mu) from E = YOUNG and nu."""
    return YOUNG * nu / ((1 + nu) * (1 - 2 * nu)), YOUNG / (2 * (1 + nu))


def cells_label(cells) -> str:
    return "x".join(str(c) for c in cells)


def group_name(nu: float) -> str:
    return f"nu_{nu}"


# ----------------------------------------------------------------------------
# Analytic estimates (sanity numbers only)
# ----------------------------------------------------------------------------
def beam_theory(nu: float) -> tuple[float, float]:
    """Euler-Bernoulli and Timoshenko tip deflection under the end load P = |t_z| W H."""
    P = abs(TRACTION[2]) * BEAM_W * BEAM_H
    I = BEAM_W * BEAM_H**3 / 12.0
    w_eb = -P * BEAM_L**3 / (3 * YOUNG * I)
    k = 10 * (1 + nu) / (12 + 11 * nu)  # Cowper's shear coefficient, rectangle
    G = YOUNG / (2 * (1 + nu))
    w_t = w_eb - P * BEAM_L / (k * G * BEAM_W * BEAM_H)
    return w_eb, w_t


# ----------------------------------------------------------------------------
# Sparse solves
# ----------------------------------------------------------------------------
def refined_solve(A: sp.csr_matrix, b: np.ndarray, quasi_definite: bool) -> tuple[np.ndarray, float, str]:
    """Direct solve + iterative refinement with extended-precision residuals.

    SPD systems: CHOLMOD supernodal Cholesky.  Symmetric quasi-definite systems
    ([A B^T; B -C], A and C SPD): CHOLMOD simplicial LDL^T, which exists for every
    symmetric ordering of such a matrix.  Without scikit-sparse: SuperLU.
    Returns x, the normwise backward error ||r||_inf / (||A||_inf ||x||_inf + ||b||_inf)
    (asserted < 1e-12) and the solver name."""
    A = A.tocsr()
    if _cholmod is not None:
        if quasi_definite:
            fac = _cholmod(A.tocsc(), mode="simplicial", ordering_method="nesdis")
            name = "CHOLMOD simplicial LDL^T (nested dissection)"
        else:
            fac = _cholmod(A.tocsc(), mode="supernodal")
            name = "CHOLMOD supernodal Cholesky"
        solve = fac
    else:
        lu = spla.splu(A.tocsc())
        solve = lu.solve
        name = "SuperLU"
    x = solve(b)
    bl = b.astype(np.longdouble)
    a_inf = float(np.abs(A).sum(axis=1).max())

    def bwd_err(x):
        r = np.asarray(bl - mr._matvec_ld(A, x), dtype=np.float64)
        return r, float(np.abs(r).max() / (a_inf * np.abs(x).max() + np.abs(b).max()))

    r, bwd = bwd_err(x)
    for _ in range(4):
        if bwd < 1e-15:
            break
        x = x + solve(r)
        r, bwd = bwd_err(x)
    assert bwd < BWD_TOL, f"backward error {bwd:.3e} >= {BWD_TOL}"
    return x, bwd, name


# ----------------------------------------------------------------------------
# Reference: P2 displacement and Taylor-Hood P2-P1 on a fine mesh
# ----------------------------------------------------------------------------
@LinearForm
def traction_form(v, w):
    return TRACTION[0] * v[0] + TRACTION[1] * v[1] + TRACTION[2] * v[2]


@LinearForm
def uz_form(v, w):
    return v[2]


def end_facets(mesh: MeshTet) -> np.ndarray:
    return mesh.facets_satisfying(lambda x: x[0] > BEAM_L - CLAMP_TOL, boundaries_only=True)


def solve_quadratic(cells, nu: float, taylor_hood: bool) -> dict:
    """P2 displacement (taylor_hood=False) or Taylor-Hood P2-P1 (taylor_hood=True).

    Taylor-Hood unknowns: u in P2, s = p / mu in continuous P1 with p = lambda div u
    (so sigma = 2 mu eps(u) + p I); the scaling by mu balances the two blocks:
        [ A        mu B^T      ] [u]   [f]      A = int 2 mu eps(u):eps(v),
        [ mu B  -mu^2 M/lambda ] [s] = [0],     B = int q div(u),  M = int p q.
    intorder 2 integrates every form exactly on affine tets."""
    lam, mu = lame(nu)
    t0 = time.perf_counter()
    mesh = mr.beam_mesh(*cells)
    bu = Basis(mesh, VEC_P2, intorder=2)
    fb = FacetBasis(mesh, VEC_P2, facets=end_facets(mesh), intorder=2)
    f = asm(traction_form, fb)
    fixed = bu.get_dofs(lambda x: x[0] < CLAMP_TOL).all()
    if taylor_hood:
        bp = bu.with_element(ElementTetP1())

        @BilinearForm
        def b_form(u, q, w):
            return div(u) * q

        @BilinearForm
        def m_form(p, q, w):
            return p * q

        A = asm(linear_elasticity(0.0, mu), bu)
        B = asm(b_form, bu, bp)
        M = asm(m_form, bp)
        K = sp.bmat([[A, mu * B.T], [mu * B, -(mu * mu / lam) * M]]).tocsr()
        f = np.concatenate([f, np.zeros(bp.N)])
    else:
        K = asm(linear_elasticity(lam, mu), bu).tocsr()
    free = np.setdiff1d(np.arange(K.shape[0]), fixed)
    Kff = K[free][:, free]
    t_asm = time.perf_counter() - t0
    t0 = time.perf_counter()
    xf, bwd, solver = refined_solve(Kff, f[free], quasi_definite=taylor_hood)
    t_sol = time.perf_counter() - t0
    x = np.zeros(K.shape[0])
    x[free] = xf
    u = x[: bu.N]
    w_mean = float(asm(uz_form, fb) @ u / (BEAM_W * BEAM_H))
    w_centre = float((bu.probes(CENTRE[:, None]) @ u)[2])
    return dict(cells=cells, ndof=K.shape[0], nfree=free.size, w_mean=w_mean, w_centre=w_centre,
                t_asm=t_asm, t_sol=t_sol, bwd=bwd, solver=solver)


# ----------------------------------------------------------------------------
# P1 and ANP (numpy assembly on the icefem meshes)
# ----------------------------------------------------------------------------
def elem_dofs(t: np.ndarray) -> np.ndarray:
    return (3 * t[:, :, None] + np.arange(3)[None, None, :]).reshape(len(t), 12)


def scatter_elem(Ke: np.ndarray, dofs: np.ndarray, n: int) -> sp.csr_matrix:
    k = dofs.shape[1]
    rows = np.repeat(dofs, k, axis=1).ravel()
    cols = np.tile(dofs, (1, k)).ravel()
    return sp.coo_matrix((Ke.ravel(), (rows, cols)), shape=(n, n)).tocsr()


def p1_matrices(p: np.ndarray, t: np.ndarray, lam: float, mu: float):
    """(K_p1, K_anp): plain P1 stiffness and the ANP stiffness
    K_dev + kappa S^T diag(1/V_a) S, where (S u)_a = sum_{e contains a} (V_e/4) div(u)_e."""
    n = 3 * len(p)
    vol, B, bdiv = mr.p1_geometry(p, t)
    dofs = elem_dofs(t)
    kappa = lam + 2 * mu / 3
    Cdev = np.zeros((6, 6))
    Cdev[:3, :3] = -2 * mu / 3
    Cdev[np.arange(3), np.arange(3)] += 2 * mu
    Cdev[np.arange(3, 6), np.arange(3, 6)] = mu
    K_dev = scatter_elem(np.einsum("mia,ij,mjb,m->mab", B, Cdev, B, vol), dofs, n)
    K_vol_p1 = scatter_elem(kappa * np.einsum("ma,mb,m->mab", bdiv, bdiv, vol), dofs, n)
    m = len(t)
    rows = np.repeat(t, 12, axis=1).ravel()  # node a of element e, for each of its 12 dofs
    cols = np.repeat(dofs[:, None, :], 4, axis=1).ravel()
    vals = np.repeat((vol[:, None] / 4 * bdiv)[:, None, :], 4, axis=1).ravel()
    S = sp.coo_matrix((vals, (rows, cols)), shape=(len(p), n)).tocsr()
    V_node = np.bincount(t.ravel(), weights=np.repeat(vol / 4, 4), minlength=len(p))
    assert np.isclose(V_node.sum(), BEAM_L * BEAM_W * BEAM_H, rtol=1e-12) and m > 0
    K_vol_anp = (kappa * (S.T @ sp.diags(1.0 / V_node) @ S)).tocsr()
    return (K_dev + K_vol_p1).tocsr(), (K_dev + K_vol_anp).tocsr()


def p1_traction_load(p: np.ndarray, t: np.ndarray, trac: np.ndarray):
    """Consistent P1 traction load on boundary faces with midpoint x > L - 1e-9:
    t * area / 3 per node per face.  Also returns those faces (k,3)."""
    faces = np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]])
    _, idx, cnt = np.unique(np.sort(faces, axis=1), axis=0, return_index=True, return_counts=True)
    bfaces = faces[idx[cnt == 1]]
    bfaces = bfaces[p[bfaces].mean(axis=1)[:, 0] > BEAM_L - CLAMP_TOL]
    P = p[bfaces]
    area = 0.5 * np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1)
    f = np.zeros(3 * len(p))
    np.add.at(f, (3 * bfaces[:, :, None] + np.arange(3)).ravel(),
              (area[:, None, None] / 3 * np.broadcast_to(trac, (len(area), 3, 3))).ravel())
    return f, bfaces, area


def clamp_free(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    fixed_nodes = np.nonzero(p[:, 0] < CLAMP_TOL)[0]
    fixed = (3 * fixed_nodes[:, None] + np.arange(3)).ravel()
    return fixed, np.setdiff1d(np.arange(3 * len(p)), fixed)


def solve_p1_family(cells, lam: float, mu: float, trac: np.ndarray = TRACTION) -> dict:
    """Plain P1 and ANP on the init_tensor mesh with `cells`; returns both solutions and the
    tip quantities."""
    t0 = time.perf_counter()
    mesh = mr.beam_mesh(*cells)
    p = mesh.p.T.copy()
    t = mr.oriented_tets(mesh)
    K_p1, K_anp = p1_matrices(p, t, lam, mu)
    f, bfaces, area = p1_traction_load(p, t, trac)
    fixed, free = clamp_free(p)
    t_asm = time.perf_counter() - t0
    basis = Basis(mesh, VEC_P1)
    probe = basis.probes(CENTRE[:, None]).toarray()[2]  # dof ordering of scikit-fem P1 = 3*node + comp
    face_nodes = np.nonzero(p[:, 0] > BEAM_L - CLAMP_TOL)[0]
    out = dict(cells=cells, mesh=mesh, p=p, t=t, K_p1=K_p1, K_anp=K_anp, f=f, free=free,
               n_facets=len(bfaces), t_asm=t_asm, ndof=3 * len(p), nfree=free.size)
    for key, K in (("p1", K_p1), ("anp", K_anp)):
        t0 = time.perf_counter()
        x = np.zeros(3 * len(p))
        x[free], bwd, solver = refined_solve(K[free][:, free], f[free], quasi_definite=False)
        t_sol = time.perf_counter() - t0
        u = x.reshape(-1, 3)
        w_face = np.einsum("k,kj->k", area / 3, u[bfaces, 2]).sum() / (BEAM_W * BEAM_H)
        out[key] = dict(u=u, x=x, t_sol=t_sol, bwd=bwd, solver=solver,
                        w_nodes=float(u[face_nodes, 2].mean()), w_mean=float(w_face),
                        w_centre=float(probe @ x))
    return out


# ----------------------------------------------------------------------------
# Cross-checks of the P1 / ANP assembly
# ----------------------------------------------------------------------------
def cross_checks_p1(d: dict, lam: float, mu: float, tag: str) -> None:
    mesh, p, t = d["mesh"], d["p"], d["t"]
    basis = Basis(mesh, VEC_P1)
    K_sk = asm(linear_elasticity(lam, mu), basis).tocsr()
    diff = abs(K_sk - d["K_p1"]).max() / abs(K_sk).max()
    check(f"{tag} numpy P1 stiffness == scikit-fem", diff < 1e-12, f"max rel diff {diff:.1e}")
    fb = FacetBasis(mesh, VEC_P1, facets=end_facets(mesh))
    f_sk = asm(traction_form, fb)
    fd = np.abs(f_sk - d["f"]).max() / np.abs(f_sk).max()
    check(f"{tag} numpy traction load == scikit-fem FacetBasis", fd < 1e-12, f"max rel diff {fd:.1e}")
    # ANP consistency: for a linear displacement field theta_a = div u at every node, so the
    # ANP and P1 internal forces agree (patch-test consistency).
    rng = np.random.default_rng(0)
    G = rng.standard_normal((3, 3))
    x_lin = (p @ G.T).ravel()
    r = np.linalg.norm(d["K_anp"] @ x_lin - d["K_p1"] @ x_lin) / np.linalg.norm(d["K_p1"] @ x_lin)
    check(f"{tag} ANP == P1 on linear fields", r < 1e-12, f"rel diff {r:.1e}")
    # ANP energy evaluated directly from its definition, for a random displacement field.
    x = rng.standard_normal(3 * len(p))
    u = x.reshape(-1, 3)
    X = p[t]
    Dm = np.stack([X[:, 1] - X[:, 0], X[:, 2] - X[:, 0], X[:, 3] - X[:, 0]], axis=2)  # columns
    Du = np.stack([u[t[:, 1]] - u[t[:, 0]], u[t[:, 2]] - u[t[:, 0]], u[t[:, 3]] - u[t[:, 0]]], axis=2)
    gradu = Du @ np.linalg.inv(Dm)  # du_i/dx_j
    vol = np.linalg.det(Dm) / 6.0
    eps = 0.5 * (gradu + np.transpose(gradu, (0, 2, 1)))
    tr = np.trace(eps, axis1=1, axis2=2)
    dev = eps - tr[:, None, None] / 3 * np.eye(3)
    V_a = np.zeros(len(p))
    np.add.at(V_a, t.ravel(), np.repeat(vol / 4, 4))
    th = np.zeros(len(p))
    np.add.at(th, t.ravel(), np.repeat(vol / 4 * tr, 4))
    th /= V_a
    kappa = lam + 2 * mu / 3
    energy = np.sum(vol * mu * np.sum(dev**2, axis=(1, 2))) + np.sum(V_a * kappa / 2 * th**2)
    r = abs(0.5 * x @ (d["K_anp"] @ x) - energy) / energy
    check(f"{tag} ANP stiffness == energy definition", r < 1e-12, f"rel diff {r:.1e}")


def check_kuhn_split() -> None:
    """The init_tensor tets are the Kuhn split of every cell along its (0,0,0)-(1,1,1) diagonal,
    the split of icefem's box_mesh(..., tets_per_cell = 6) (node numbering differs)."""
    kuhn = [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]]
    for cells in P1_LEVELS:
        nx, ny, nz = cells
        mesh = mr.beam_mesh(*cells)
        h = np.array([BEAM_L / nx, BEAM_W / ny, BEAM_H / nz])
        ijk = np.rint(mesh.p.T / h).astype(np.int64)
        ours = {tuple(sorted(map(tuple, ijk[tet]))) for tet in mesh.t.T}
        theirs = set()
        for k in range(nz):
            for j in range(ny):
                for i in range(nx):
                    for local in kuhn:
                        theirs.add(tuple(sorted((i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1))
                                                for c in local)))
        check(f"mesh {cells_label(cells)} tets == Kuhn split of icefem box_mesh(6)", ours == theirs,
              f"{len(ours)} tets")


def check_against_traction_beams() -> None:
    """The P1 meshes are those of traction_beam_r{0,1,2}.h5, and the numpy P1 solver reproduces
    those files' solution (ice lambda, mu; t = (0,0,-1e6) Pa)."""
    for r, cells in enumerate(P1_LEVELS):
        path = HERE / "reference" / f"traction_beam_r{r}.h5"
        if not path.exists():
            check(f"{path.name} present", False, "missing")
            continue
        with h5py.File(path, "r") as h5:
            nodes = h5["mesh/nodes"][...]
            tets = h5["mesh/tets"][...]
            u_ref = h5["solution/u"][...]
            trac = h5.attrs["traction"][...]
        d = solve_p1_family(cells, mr.LAMBDA, mr.MU, trac)
        same = np.array_equal(nodes, d["p"]) and np.array_equal(tets, d["t"])
        check(f"mesh {cells_label(cells)} == {path.name} /mesh", same, "nodes and tets identical" if same else "differ")
        e = np.linalg.norm(d["p1"]["u"] - u_ref) / np.linalg.norm(u_ref)
        check(f"P1 solver reproduces {path.name}", e < 1e-9, f"rel l2 {e:.1e}")


# ----------------------------------------------------------------------------
def main() -> int:
    t_start = time.perf_counter()
    OUT.parent.mkdir(parents=True, exist_ok=True)
    print(f"scikit-fem {skfem.__version__}  E = {YOUNG:.3e} Pa  t = {TRACTION} Pa  "
          f"solver: {'CHOLMOD' if _cholmod is not None else 'SuperLU'}")
    check_kuhn_split()
    check_against_traction_beams()

    results = {}
    for nu in NUS:
        lam, mu = lame(nu)
        w_eb, w_t = beam_theory(nu)
        res = dict(nu=nu, lam=lam, mu=mu, kappa=lam + 2 * mu / 3, w_eb=w_eb, w_t=w_t,
                   p1=[], anp=[], p2=[], th=[], anp_u={})
        print(f"\nnu = {nu}: lambda = {lam:.4e} Pa, mu = {mu:.4e} Pa, lambda/mu = {lam / mu:.1f}")
        for cells in P1_LEVELS:
            d = solve_p1_family(cells, lam, mu)
            cross_checks_p1(d, lam, mu, f"nu={nu} {cells_label(cells)}")
            for key in ("p1", "anp"):
                e = d[key]
                res[key].append(dict(cells=cells, ndof=d["ndof"], nfree=d["nfree"], t_asm=d["t_asm"],
                                     t_sol=e["t_sol"], bwd=e["bwd"], solver=e["solver"], w_nodes=e["w_nodes"],
                                     w_mean=e["w_mean"], w_centre=e["w_centre"]))
                print(f"  {key.upper():<4} {cells_label(cells):<7} ndof={d['ndof']:6d} "
                      f"w_nodes={e['w_nodes']:.6e} w_mean={e['w_mean']:.6e} "
                      f"w_centre={e['w_centre']:.6e} bwd={e['bwd']:.1e} t_sol={e['t_sol']:.3f}s")
            if cells in ANP_FIELD_LEVELS:
                res["anp_u"][cells] = d["anp"]["u"]
        for key, th in (("p2", False), ("th", True)):
            for cells in REF_LEVELS:
                e = solve_quadratic(cells, nu, th)
                res[key].append(e)
                print(f"  {key.upper():<4} {cells_label(cells):<7} ndof={e['ndof']:6d} "
                      f"w_mean={e['w_mean']:.7e} w_centre={e['w_centre']:.7e} bwd={e['bwd']:.1e} "
                      f"t_asm={e['t_asm']:.2f}s t_sol={e['t_sol']:.2f}s", flush=True)
        th_last, th_prev = res["th"][-1], res["th"][-2]
        # Richardson extrapolation from the last three levels (h halves each time); an
        # estimate only, the stored reference is the finest computed value.
        w3 = [e["w_mean"] for e in res["th"][-3:]]
        order = float(np.log2((w3[1] - w3[0]) / (w3[2] - w3[1])))
        res["richardson_order"] = order
        res["richardson_w_mean"] = w3[2] + (w3[2] - w3[1]) / (2.0**order - 1.0)
        res["ref_w_mean"] = th_last["w_mean"]
        res["ref_w_centre"] = th_last["w_centre"]
        res["ref_w_mean_err"] = abs(th_last["w_mean"] - th_prev["w_mean"])
        res["ref_w_centre_err"] = abs(th_last["w_centre"] - th_prev["w_centre"])
        results[nu] = res

        # --- sanity checks per nu
        ref = res["ref_w_mean"]
        fine, prev = cells_label(REF_LEVELS[-1]), cells_label(REF_LEVELS[-2])
        for key in ("th", "p2"):
            res[f"{key}_change"] = abs(res[key][-1]["w_mean"] - res[key][-2]["w_mean"]) / abs(res[key][-1]["w_mean"])
        check(f"nu={nu} Taylor-Hood converged: |w({fine}) - w({prev})| / |w| < {REF_CONV_TOL:.1%}",
              res["th_change"] < REF_CONV_TOL, f"{res['th_change']:.3%}")
        wc = res["ref_w_centre_err"] / abs(res["ref_w_centre"])
        check(f"nu={nu} Taylor-Hood centre value converged < {REF_CONV_TOL:.1%}", wc < REF_CONV_TOL, f"{wc:.3%}")
        p2 = [e["w_mean"] for e in res["p2"]]
        check(f"nu={nu} P2 |w_mean| increases with refinement", all(np.diff(p2) < 0),
              " -> ".join(f"{x:.5e}" for x in p2))
        check(f"nu={nu} P2 |w_mean| (a lower bound) <= reference + error estimate",
              abs(p2[-1]) <= abs(ref) + res["ref_w_mean_err"], f"{p2[-1]:.5e} vs {ref:.5e}")
        eb_ratio = ref / w_eb
        if nu == 0.3:
            check(f"nu={nu} reference within {EB_TOL:.0%} of Euler-Bernoulli", abs(eb_ratio - 1) < EB_TOL,
                  f"w_ref/w_EB = {eb_ratio:.4f}")
        else:
            check(f"nu={nu} reference within 2*{EB_TOL:.0%} of Euler-Bernoulli", abs(eb_ratio - 1) < 2 * EB_TOL,
                  f"w_ref/w_EB = {eb_ratio:.4f}")
        p1r = [e["w_nodes"] / ref for e in res["p1"]]
        anpr = [e["w_nodes"] / ref for e in res["anp"]]
        check(f"nu={nu} P1 ratio increases with refinement", all(np.diff(p1r) > 0),
              " -> ".join(f"{x:.4f}" for x in p1r))
        check(f"nu={nu} ANP ratio increases with refinement", all(np.diff(anpr) > 0),
              " -> ".join(f"{x:.4f}" for x in anpr))
        check(f"nu={nu} ANP softer than P1 on every mesh",
              all(a > b for a, b in zip(anpr, p1r)), " / ".join(f"{a:.4f} > {b:.4f}" for a, b in zip(anpr, p1r)))
        dn = max(abs(e["w_nodes"] / e["w_mean"] - 1) for e in res["p1"] + res["anp"])
        check(f"nu={nu} P1/ANP w_nodes within 1e-4 of w_mean", dn < 1e-4, f"max rel diff {dn:.1e}")
        if nu > 0.49:
            check(f"nu={nu} P1 locks: w / w_ref < 0.05 on every mesh", max(p1r) < 0.05,
                  f"max {max(p1r):.4f}")

    # --- the proposed Rust test bounds hold for ANP and fail for plain P1
    lo, hi = results[NUS[0]], results[NUS[1]]
    for key, want in (("anp", True), ("p1", False)):
        r_lo = {e["cells"]: e["w_nodes"] / lo["ref_w_mean"] for e in lo[key]}
        r_hi = {e["cells"]: e["w_nodes"] / hi["ref_w_mean"] for e in hi[key]}
        ok = all(RUST_MIN_RATIO[c] <= r_lo[c] <= RUST_MAX_RATIO for c in RUST_MIN_RATIO)
        lock = r_lo[(32, 4, 4)] / r_hi[(32, 4, 4)]
        ok = ok and lock >= RUST_MIN_LOCKING and r_lo[(32, 4, 4)] > r_lo[(16, 2, 2)]
        check(f"{key.upper()} {'meets' if want else 'fails'} the proposed Rust test bounds", ok == want,
              " ".join(f"ratio {cells_label(c)} = {r_lo[c]:.4f} (>= {RUST_MIN_RATIO[c]})" for c in RUST_MIN_RATIO)
              + f", locking measure 32x4x4 = {lock:.4f} (>= {RUST_MIN_LOCKING})")

    # ------------------------------------------------------------------------
    t_total = time.perf_counter() - t_start
    write_file(results, t_total)
    size = OUT.stat().st_size
    check("locking_beam.h5 < 100 KB", size < 100_000, f"{size} B")
    print_table(results, t_total, size)
    print("\nsanity checks:")
    for name, ok, detail in CHECKS:
        print(f"  [{'PASS' if ok else 'FAIL'}] {name}{': ' + detail if detail else ''}")
    nfail = sum(not ok for _, ok, _ in CHECKS)
    print(f"\n{len(CHECKS) - nfail} passed, {nfail} failed")
    return 1 if nfail else 0


def write_file(results: dict, t_total: float) -> None:
    with h5py.File(OUT, "w") as h5:
        h5.attrs["case"] = "locking_beam"
        h5.attrs["description"] = (
            "clamped cantilever beam, uniform end-face traction, nearly incompressible "
            "(nu = 0.4999) and control (nu = 0.3): tip deflections of a Taylor-Hood P2-P1 "
            "reference, P2, plain P1 and ANP P1 tets")
        h5.attrs["youngs_modulus"] = YOUNG
        h5.attrs["poisson_ratios"] = np.asarray(NUS, dtype=np.float64)
        h5.attrs["traction"] = TRACTION
        h5.attrs["traction_face_rule"] = "boundary facets whose midpoint x > 0.4 - 1e-9 (the end face x = length)"
        h5.attrs["length"] = BEAM_L
        h5.attrs["width"] = BEAM_W
        h5.attrs["height"] = BEAM_H
        h5.attrs["clamp_rule"] = "all dofs of nodes with x < 1e-9 fixed to zero"
        h5.attrs["clamp_tol"] = CLAMP_TOL
        h5.attrs["gravity"] = np.zeros(3)
        h5.attrs["w_mean_rule"] = "(1/(width*height)) * integral of u_z over the end face x = length (m)"
        h5.attrs["w_centre_rule"] = "u_z at (length, width/2, height/2) (m)"
        h5.attrs["w_nodes_rule"] = "mean of u_z over the mesh nodes with x > length - 1e-9 (m; P1 meshes)"
        h5.attrs["reference_method"] = (
            "Taylor-Hood P2-P1 (ElementVectorH1(ElementTetP2()) displacement, continuous "
            "ElementTetP1() pressure p = lambda div u), MeshTet.init_tensor, finest level")
        h5.attrs["t_total"] = t_total
        h5.attrs["generator"] = (
            f"make_locking_reference.py, scikit-fem {skfem.__version__}, numpy {np.__version__}, "
            f"scipy {scipy.__version__}, h5py {h5py.__version__}")
        for nu, res in results.items():
            g = h5.create_group(group_name(nu))
            g.attrs["nu"] = nu
            g.attrs["lambda"] = res["lam"]
            g.attrs["mu"] = res["mu"]
            g.attrs["kappa"] = res["kappa"]
            g.attrs["reference_w_mean"] = res["ref_w_mean"]
            g.attrs["reference_w_mean_error"] = res["ref_w_mean_err"]
            g.attrs["reference_w_centre"] = res["ref_w_centre"]
            g.attrs["reference_w_centre_error"] = res["ref_w_centre_err"]
            g.attrs["reference_cells"] = np.asarray(REF_LEVELS[-1], dtype=np.int64)
            g.attrs["richardson_w_mean"] = res["richardson_w_mean"]
            g.attrs["richardson_order"] = res["richardson_order"]
            g.attrs["euler_bernoulli_w"] = res["w_eb"]
            g.attrs["timoshenko_w"] = res["w_t"]
            for key, elem in (("th", "Taylor-Hood P2-P1"), ("p2", "P2 displacement"),
                              ("p1", "P1"), ("anp", "P1 average nodal pressure (Bonet-Burton)")):
                runs = res[key]
                s = g.create_group({"th": "taylor_hood"}.get(key, key))
                s.attrs["element"] = elem
                s.attrs["cells"] = np.asarray([e["cells"] for e in runs], dtype=np.int64).ravel()
                s.attrs["n_dofs"] = np.asarray([e["ndof"] for e in runs], dtype=np.int64)
                s.attrs["n_free_dofs"] = np.asarray([e["nfree"] for e in runs], dtype=np.int64)
                s.attrs["w_mean"] = np.asarray([e["w_mean"] for e in runs])
                s.attrs["w_centre"] = np.asarray([e["w_centre"] for e in runs])
                if key in ("p1", "anp"):
                    s.attrs["w_nodes"] = np.asarray([e["w_nodes"] for e in runs])
                s.attrs["t_assembly"] = np.asarray([e["t_asm"] for e in runs])
                s.attrs["t_solve"] = np.asarray([e["t_sol"] for e in runs])
                s.attrs["backward_error"] = np.asarray([e["bwd"] for e in runs])
                s.attrs["solver"] = runs[0]["solver"] + ", extended-precision iterative refinement"
                if key == "anp":
                    for cells, u in res["anp_u"].items():
                        s.create_dataset(f"u_{cells_label(cells)}", data=np.ascontiguousarray(u))


def print_table(results: dict, t_total: float, size: int) -> None:
    print("\n" + "=" * 100)
    print(f"tip deflection (m), E = {YOUNG:.2e} Pa, t = {TRACTION[2]:.1e} Pa on x = {BEAM_L}; "
          f"ratio = w / reference w_mean")
    for nu, res in results.items():
        ref = res["ref_w_mean"]
        print(f"\nnu = {nu}: reference (Taylor-Hood {cells_label(REF_LEVELS[-1])}) w_mean = {ref:.6e} "
              f"+- {res['ref_w_mean_err']:.2e} ({res['ref_w_mean_err'] / abs(ref):.3%}), "
              f"w_centre = {res['ref_w_centre']:.6e} +- {res['ref_w_centre_err']:.2e}")
        print(f"  Euler-Bernoulli {res['w_eb']:.6e} (ref/EB {ref / res['w_eb']:.4f}), "
              f"Timoshenko {res['w_t']:.6e} (ref/T {ref / res['w_t']:.4f})")
        print(f"  {'method':<12}{'cells':<9}{'ndof':>8}{'w_nodes':>14}{'w_mean':>14}{'w_centre':>14}"
              f"{'ratio':>8}{'t_asm':>8}{'t_sol':>8}")
        for key, label in (("p1", "P1"), ("anp", "ANP"), ("p2", "P2"), ("th", "Taylor-Hood")):
            for e in res[key]:
                wn = f"{e['w_nodes']:14.6e}" if "w_nodes" in e else f"{'':>14}"
                w = e.get("w_nodes", e["w_mean"])
                print(f"  {label:<12}{cells_label(e['cells']):<9}{e['ndof']:8d}{wn}{e['w_mean']:14.6e}"
                      f"{e['w_centre']:14.6e}{w / ref:8.4f}{e['t_asm']:8.2f}{e['t_sol']:8.2f}")
        print(f"  change {cells_label(REF_LEVELS[-2])} -> {cells_label(REF_LEVELS[-1])}: "
              f"Taylor-Hood {res['th_change']:.3%}, P2 {res['p2_change']:.3%}; Taylor-Hood Richardson "
              f"estimate {res['richardson_w_mean']:.6e} (observed order {res['richardson_order']:.2f}, "
              f"{abs(res['richardson_w_mean'] / ref - 1):.3%} from the reference)")
    print(f"\n{OUT.name}: {size / 1024:.1f} KiB, total run time {t_total:.1f} s")


if __name__ == "__main__":
    sys.exit(main())
