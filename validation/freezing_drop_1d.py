#!/usr/bin/env python3
"""A water drop freezing from the outside in: 1-D spherically symmetric reference model.

    freezing_drop_1d.py [--markdown FILE] [--plot FILE.png] [--f-end F] [--no-creep]

An independent reference (numpy/scipy only, no icefem code) for icefem's 3-D freezing drop:
the frozen fraction, the pressure of the trapped water and the stresses in the ice shell,
and when the shell's largest tensile stress first reaches ice's tensile strength.

THE PROBLEM (SI units, temperatures in degC)
  Drop of radius R = 0.01 m, all water at the melting point T_m = 0 at t = 0 (no sensible
  heat in the water), in air at T_a = -20 with a convection coefficient h = 50 W/(m^2 K).
  Ice: k = 2.22 W/(m K), rho_i = 917 kg/m^3, c = 2050 J/(kg K), L = 334e3 J/kg,
  E = 9e9 Pa, nu = 0.33, alpha = 5e-5 1/K. Water: bulk modulus K_w = 2.2e9 Pa. A water
  volume dV freezes into (1 + beta) dV of ice, beta = 0.09 (volume ratio 1.09).
  The geometry of the heat problem and of the small-strain mechanics is the undeformed one:
  ice shell a(t) < r < R, water in r < a(t), frozen fraction f = 1 - (a/R)^3.

HEAT (transient, finite differences)
  rho_i c dT/dt = k (1/r^2) d/dr (r^2 dT/dr)                in a < r < R
  T(a) = T_m;   -k dT/dr(R) = h (T(R) - T_a)                  (Robin)
  rho_i L da/dt = k dT/dr(a)                                   (Stefan)
  T falls outward, dT/dr(a) < 0, so da/dt < 0: the latent heat rho_i L |da/dt| released at
  the front per unit area is the heat flux -k dT/dr(a) conducted outward into the shell.
  Front-fixing (Landau) coordinate xi = (r - a)/s, s = R - a, on a uniform grid of N_xi
  intervals; Theta(xi, t) = T(r, t) obeys
    dTheta/dt = kappa/s^2 (Theta'' + 2 s/r Theta') + Theta' (da/dt) (1 - xi)/s,
    kappa = k/(rho_i c), ' = d/dxi;
  second-order central differences, a ghost node for the Robin condition, a second-order
  one-sided dTheta/dxi at the front. The shell thickness s is the independent variable
  (ds/dt = -da/dt > 0 throughout), so the ODE system d(Theta_j, t, Q)/ds = (dTheta_j/dt, 1,
  4 pi R^2 h (T(R) - T_a)) / (ds/dt) is integrated by scipy's Radau (implicit Runge-Kutta,
  order 5) and returns the time and the temperature profile exactly at the front positions
  the mechanics steps through. Q is the heat lost through the surface, for the energy balance
    Q = rho_i L (4/3) pi (R^3 - a^3) + int_a^R rho_i c (T_m - T) 4 pi r^2 dr,
  which solve_heat enforces (error if off by more than 1e-3): scipy's BDF on this system
  drifted silently at some resolutions (a 20 % energy error, the freezing 30 % too slow).
  Start: a shell of thickness s_0 (the first mechanical layer, 0.01 um) with the quasi-steady
  profile at the quasi-steady time (its error there is far below anything reported).
  Quasi-steady (QS) comparison: no sensible heat in the shell, T(r) = T_m - (T_m - T_a)
  (1/a - 1/r)/((1/a - 1/R) + k/(h R^2)), whence the closed form
    t_QS(a) = rho_i L/(T_m - T_a) [((R^2 - a^2)/2 - (R^3 - a^3)/(3R))/k + (R^3 - a^3)/(3 h R^2)].

MECHANICS (small strain, incremental, homogeneous isotropic ice)
  Layers. The front positions a_0 = R > a_1 > ... > a_n are the steps; at step k the layer
  a_{k+1} < r < a_k freezes (the radial resolution of the shell is the step size). Its
  thickness is ds = ds_0 + eps min(s, a), s = R - a: ds_0 = 0.01 um at the surface, growing
  geometrically by eps = 0.1 % (and refining again as the cavity closes); about 7000 layers
  to f = 0.99.
  Birth. The new layer is born at the water's pressure: sigma_rr = sigma_tt = -p, no
  eigenstrain, temperature T_m (so it is thermally stress-free at birth).
  Volume balance of the cavity per step. The water in the layer, dV = (4/3) pi (a_k^3 -
  a_{k+1}^3), becomes (1 + beta) dV of ice; the excess beta dV must be made room for by the
  compression of the remaining water V_w = (4/3) pi a_{k+1}^3 and by the outward displacement
  u(a) of the shell's new inner surface:
    beta dV = dp V_w/K_w + 4 pi a^2 (dp u_1(a) + u*(a)),
  u_1 = the inner displacement of the current shell (the new layer included) under a unit
  inner pressure, u* = the one under the step's eigenstrain increments with no pressure.
  Then every layer's stress is incremented by dp x (unit-pressure stresses) + (eigenstrain
  stresses) of the current shell. Stresses are tracked per layer at both of its edges (the
  hoop stress jumps between layers born at different pressures).
  Incremental equilibrium, any shell a < r < R with eigenstrain increments (e_r, e_t)
  [thermal: e_r = e_t = alpha dT; creep: deviatoric], given at each layer's two edges:
    d(sigma_rr)/dr + 2 (sigma_rr - sigma_tt)/r = 0,  sigma_rr(a) = -dp,  sigma_rr(R) = 0,
    Hooke: eps_rr = (sigma_rr - 2 nu sigma_tt)/E + e_r,  eps_tt = ((1-nu) sigma_tt - nu sigma_rr)/E + e_t,
    compatibility eps_rr = d(r eps_tt)/dr.
  Eliminating sigma_tt = sigma_rr + (r/2) sigma_rr' gives (r^4 sigma_rr')' = K r^2 ((e_r - e_t)
  - r e_t'), K = 2E/(1-nu). Integrated twice (by parts, so jumps of e_t between layers are
  exact), with P(r) = int_a^r (e_r + 2 e_t) rho^2 drho, W(r) = int_a^r (e_r - e_t)/rho drho:
    sigma_rr(r) = -dp + K (W(r)/3 - P(r)/(3 r^3)) + (D/3)(1/a^3 - 1/r^3)
    sigma_tt(r) = sigma_rr(r) + (K/2)(P(r)/r^3 - e_t(r)) + D/(2 r^3)
    u(a)        = a (-(1 - 2 nu) dp + (1 - nu) D/(2 a^3))/E
  with D fixed by sigma_rr(R) = 0. P and W are sums of exact layer integrals of each layer's
  mean eigenstrain; the local term -K e_t(r)/2 takes the edge's own value. This is exact for
  layer-wise constant eigenstrains and second order for smooth ones; the pressure part
  reproduces Lame's thick sphere
    sigma_rr = -dp a^3 (R^3/r^3 - 1)/(R^3 - a^3),  sigma_tt = dp a^3 (1 + R^3/(2 r^3))/(R^3 - a^3),
    u(a) = dp a ((1 - 2 nu) a^3 + (1 + nu) R^3/2)/(E (R^3 - a^3))
  to rounding, and isotropic eigenstrain gives Timoshenko & Goodier's thermal stresses in a
  sphere. The only discretisation errors are the step size (births and increments at discrete
  fronts) and the layer-wise linear thermal/creep strains.
  Thermal strain (cases 2, 3): eigenstrain alpha (T - T_m) at the layer edges (the front
  positions), T from the heat solution (linear interpolation in xi); its change over a step
  is the step's isotropic eigenstrain increment. The water stays at T_m (no thermal strain).
  Glen creep (case 3, on top of case 2): eps_dot = A(T) tau_e^(n-1) tau, tau the stress
  deviator, tau_e^2 = tau:tau/2, n = 3. In spherical symmetry, with Delta = sigma_rr - sigma_tt:
  tau_rr = 2 Delta/3, tau_tt = -Delta/3, tau_e = |Delta|/sqrt(3), so at each layer edge
    e_r = (2/3) A tau_e^2 Delta dt,  e_t = -(1/3) A tau_e^2 Delta dt
  with that edge's stress and temperature. A(T) = 3.5e-25 exp(-Q/R_g (1/T - 1/263.15))
  Pa^-3 s^-1, T in K, Q = 115 kJ/mol above -10 degC and 60 kJ/mol below (A(0 degC) = 2.4e-24),
  R_g = 8.314 J/(mol K). Explicit (forward Euler) sub-steps within a step, each no longer than
  c_cfl/lambda_max, lambda = 2 mu n A tau_e^(n-1) (the linearised relaxation rate of Delta),
  c_cfl = 0.05; the step's expansion and thermal increments are split over its sub-steps in
  proportion to their durations.
  Cases: (1) expansion only, (2) expansion + thermal strain, (3) (2) + Glen creep.
  Reported: p, the outer hoop stress sigma_tt(R), and the largest tensile principal stress
  max over the shell of max(sigma_rr, sigma_tt), against f and t; and f, t, s = R - a and p
  where that largest tensile stress first reaches 0.5, 1, 2, 3 MPa (linear interpolation
  between steps; sigma_t = 1 MPa is ice's tensile strength).

CHECKS (all computed here, numbers in the report)
  - Lame: the layered solver under a unit inner pressure against the closed form above.
  - Thin-shell limits: Lame's outer hoop stress against p a/(2 s); the grown shell's outer
    hoop stress against the thin-shell growth law sigma_tt(R) = beta E s/((1 - nu) R)
    (thin shell, water incompressible: dp = 2 beta E s ds/((1 - nu) a^2), d sigma = dp a/(2 s)).
  - Eigenstrain solver: against Timoshenko & Goodier for T = A + B/r, and against scipy's
    solve_bvp of the displacement equation for a smooth anisotropic eigenstrain; errors at
    two layer counts (second order).
  - Expansion only: the layered, incremental solution against an ODE in a (solve_ivp,
    rtol 1e-10) for p(a) and sigma_tt(R)(a): dp/da = -beta 4 pi a^2/(V_w/K_w + 4 pi a^2 u_1(a)),
    d sigma_tt(R)/da = (3/2) a^3/(R^3 - a^3) dp/da (the outermost layer sees every increment).
  - Global equilibrium of a half drop at the end of each case: int_a^R sigma_tt r dr = p a^2/2.
  - Heat: energy balance; the thin-shell start t = rho_i L s/(h (T_m - T_a)); QS against FD on
    three (h, T_a) cases.
  - Convergence: every result again at two coarser resolutions, each doubling the mechanical
    step (= layer: ds_0 and eps doubled) and c_cfl and halving N_xi (Radau rtol x 10). The
    reported results are the finest; the change from the 2x coarser run to it is their
    error estimate (the step is first order in p: a layer's dp uses the compliance of the
    shell with that layer already in it).

Run time about 30 s on 2 cores. Needs numpy and scipy; --plot needs matplotlib.
"""

import argparse
import math
import os
import shlex
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from scipy.integrate import solve_bvp, solve_ivp

FOUR_PI = 4.0 * math.pi
THRESHOLDS = (0.5e6, 1.0e6, 2.0e6, 3.0e6)  # Pa; 1 MPa is ice's tensile strength
F_MARKS = (1e-3, 2e-3, 5e-3, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 0.9, 0.99)


@dataclass(frozen=True)
class Params:
    """Physical constants (SI, degC) and numerical resolution."""
    R: float = 0.01          # drop radius (m)
    Tm: float = 0.0          # melting point (degC)
    Ta: float = -20.0        # air (degC)
    h: float = 50.0          # convection coefficient (W/(m^2 K))
    k: float = 2.22          # ice conductivity (W/(m K))
    rho: float = 917.0       # ice density (kg/m^3)
    c: float = 2050.0        # ice heat capacity (J/(kg K))
    L: float = 334e3         # latent heat (J/kg)
    E: float = 9e9           # Young's modulus (Pa)
    nu: float = 0.33         # Poisson's ratio
    Kw: float = 2.2e9        # water bulk modulus (Pa)
    beta: float = 0.09       # ice volume / water volume - 1
    alpha: float = 5e-5      # linear thermal expansion (1/K)
    glen_n: float = 3.0
    # numerics
    ds0: float = 1e-8        # thickness of the first layer (m)
    eps: float = 1e-3        # geometric growth of the layer thickness
    n_xi: int = 160          # finite-difference intervals across the shell (even)
    heat_rtol: float = 1e-11
    c_cfl: float = 0.05      # creep sub-step: dt <= c_cfl / lambda_max
    f_end: float = 0.99

    @property
    def mu(self):
        return self.E / (2.0 * (1.0 + self.nu))

    def coarsened(self):
        """Every resolution parameter doubled (the convergence runs)."""
        return replace(self, ds0=self.ds0 * 2, eps=self.eps * 2, n_xi=self.n_xi // 2,
                       heat_rtol=self.heat_rtol * 10, c_cfl=self.c_cfl * 2)


def diff_cubes(x, y):
    """x^3 - y^3 without cancellation for x close to y."""
    return (x - y) * (x * x + x * y + y * y)


# ----------------------------------------------------------------------------------------
# Heat
# ----------------------------------------------------------------------------------------

def qs_time(a, P):
    """Quasi-steady freezing time to reach front radius a (closed form, see docstring)."""
    R = P.R
    cond = ((R - a) * (R + a) / 2.0 - diff_cubes(R, a) / (3.0 * R)) / P.k
    conv = diff_cubes(R, a) / (3.0 * P.h * R * R)
    return P.rho * P.L / (P.Tm - P.Ta) * (cond + conv)


def qs_profile(a, r, P):
    """Quasi-steady temperature in the shell a < r < R."""
    denom = (1.0 / a - 1.0 / P.R) + P.k / (P.h * P.R ** 2)
    return P.Tm - (P.Tm - P.Ta) * (1.0 / a - 1.0 / r) / denom


def simpson(y, dx):
    """Composite Simpson rule on an even number of uniform intervals."""
    return dx / 3.0 * (y[0] + y[-1] + 4.0 * y[1:-1:2].sum() + 2.0 * y[2:-1:2].sum())


def sensible_heat(a, theta, P):
    """int_a^R rho c (T_m - T) 4 pi r^2 dr for the profile theta on the uniform xi grid."""
    n = len(theta) - 1
    s = P.R - a
    r = a + np.linspace(0.0, 1.0, n + 1) * s
    return P.rho * P.c * simpson((P.Tm - theta) * FOUR_PI * r * r, s / n)


def solve_heat(P, a_eval):
    """Transient Stefan problem in the front-fixing coordinate, integrated in a.

    a_eval: decreasing front positions, a_eval[0] = R - s_0 is the start (QS profile).
    Returns dict with t (len a_eval), theta (len a_eval x (n_xi + 1), xi grid incl. the
    front node), Q (heat lost through the surface) and the energy balance residual."""
    n = P.n_xi
    xi = np.linspace(0.0, 1.0, n + 1)
    dxi = 1.0 / n
    kappa = P.k / (P.rho * P.c)

    def rhs(s, y):
        a = P.R - s
        th = np.empty(n + 2)
        th[0] = P.Tm
        th[1:n + 1] = y[:n]
        th[n + 1] = th[n - 1] - 2.0 * dxi * s * P.h / P.k * (th[n] - P.Ta)   # Robin ghost
        grad0 = (-3.0 * th[0] + 4.0 * th[1] - th[2]) / (2.0 * dxi)            # dTheta/dxi at a
        adot = P.k * grad0 / (P.rho * P.L * s)                                 # < 0
        r = a + xi[1:] * s
        d1 = (th[2:] - th[:-2]) / (2.0 * dxi)
        d2 = (th[2:] - 2.0 * th[1:-1] + th[:-2]) / dxi ** 2
        dth_dt = kappa / s ** 2 * (d2 + 2.0 * s / r * d1) + d1 * adot * (1.0 - xi[1:]) / s
        out = np.empty(n + 2)
        sdot = -adot
        out[:n] = dth_dt / sdot
        out[n] = 1.0 / sdot
        out[n + 1] = FOUR_PI * P.R ** 2 * P.h * (th[n] - P.Ta) / sdot
        return out

    # Jacobian pattern: tridiagonal in Theta, every row also through da/dt (Theta_1, Theta_2)
    m = n + 2
    sparsity = np.zeros((m, m), dtype=bool)
    for j in range(n):
        sparsity[j, max(0, j - 1):min(n, j + 2)] = True
    sparsity[:, 0:2] = True
    sparsity[n, [0, 1]] = True
    sparsity[n + 1, [0, 1, n - 1]] = True

    a0 = a_eval[0]
    r0 = a0 + xi * (P.R - a0)
    th0 = qs_profile(a0, r0, P)
    q0 = P.rho * P.L * FOUR_PI / 3.0 * diff_cubes(P.R, a0) + sensible_heat(a0, th0, P)
    y0 = np.concatenate([th0[1:], [qs_time(a0, P), q0]])
    s_eval = P.R - np.asarray(a_eval)
    sol = solve_ivp(rhs, (s_eval[0], s_eval[-1]), y0, method="Radau", t_eval=s_eval,
                    rtol=P.heat_rtol, atol=np.concatenate([np.full(n, 1e-9), [1e-9, 1e-9]]),
                    jac_sparsity=sparsity, first_step=1e-3 * (P.R - a0))
    if not sol.success:
        raise RuntimeError("heat solve failed: " + sol.message)
    theta = np.hstack([np.full((len(a_eval), 1), P.Tm), sol.y[:n].T])
    t = sol.y[n]
    Q = sol.y[n + 1]
    latent = P.rho * P.L * FOUR_PI / 3.0 * diff_cubes(P.R, a_eval)
    sens = np.array([sensible_heat(a, th, P) for a, th in zip(a_eval, theta)])
    balance = np.abs(Q - latent - sens).max() / Q[-1]
    if balance > 1e-3:
        raise RuntimeError(f"heat solve drifted: energy balance off by {balance:.1e}")
    return {"a": np.asarray(a_eval), "t": t, "theta": theta, "Q": Q,
            "latent": latent, "sensible": sens, "nfev": sol.nfev}


# ----------------------------------------------------------------------------------------
# Mechanics
# ----------------------------------------------------------------------------------------

def lame_closed_form(a, R, p, r, E, nu):
    """Textbook thick sphere a < r < R under inner pressure p (outer surface free)."""
    d = R ** 3 - a ** 3
    srr = -p * a ** 3 * (R ** 3 / r ** 3 - 1.0) / d
    stt = p * a ** 3 * (1.0 + R ** 3 / (2.0 * r ** 3)) / d
    ua = p * a * ((1.0 - 2.0 * nu) * a ** 3 + (1.0 + nu) * R ** 3 / 2.0) / (E * d)
    return srr, stt, ua


def shell_response(rn, dp, E, nu, eig=None):
    """Stress increments of the shell rn[0] = a < r < rn[-1] = R (nodes increasing) under an
    inner pressure increment dp and eigenstrain increments eig = (er_lo, er_hi, et_lo, et_hi),
    each one value per layer rn[i] < r < rn[i+1] at its lower (inner) and upper (outer) edge;
    None for no eigenstrain. The integrals P and W take the layer's mean eigenstrain over the
    exact layer weights; the local term of sigma_tt takes the edge's own e_t. So the stress is
    exact for layer-wise constant eigenstrain and second order for a smooth one.

    Returns sigma_rr at the nodes, sigma_tt at each layer's inner and outer edge, u(a)."""
    a, R = rn[0], rn[-1]
    K = 2.0 * E / (1.0 - nu)
    r3 = rn ** 3
    inv = diff_cubes(rn, a) / (a ** 3 * r3)            # 1/a^3 - 1/r^3
    if eig is None:
        Pn = Wn = np.zeros_like(rn)
        et_lo = et_hi = 0.0
    else:
        er_lo, er_hi, et_lo, et_hi = eig
        er = 0.5 * (er_lo + er_hi)
        et = 0.5 * (et_lo + et_hi)
        Pn = np.concatenate([[0.0], np.cumsum((er + 2.0 * et) * diff_cubes(rn[1:], rn[:-1]) / 3.0)])
        Wn = np.concatenate([[0.0], np.cumsum((er - et) * np.log1p((rn[1:] - rn[:-1]) / rn[:-1]))])
    D3 = (dp - K * (Wn[-1] / 3.0 - Pn[-1] / (3.0 * r3[-1]))) / inv[-1]   # D/3
    srr = -dp + K * (Wn / 3.0 - Pn / (3.0 * r3)) + D3 * inv
    base = srr + 0.5 * K * Pn / r3 + 1.5 * D3 / r3     # sigma_tt without -K e_t(r)/2
    stt_in = base[:-1] - 0.5 * K * et_lo
    stt_out = base[1:] - 0.5 * K * et_hi
    ua = a * (-(1.0 - 2.0 * nu) * dp + (1.0 - nu) * 1.5 * D3 / a ** 3) / E
    return srr, stt_in, stt_out, ua


def rate_factor(T_c):
    """Glen's A(T) (Pa^-3 s^-1), Cuffey & Paterson (2010), T in degC."""
    T = np.asarray(T_c) + 273.15
    Q = np.where(T < 263.15, 60e3, 115e3)
    return 3.5e-25 * np.exp(-Q / 8.314 * (1.0 / T - 1.0 / 263.15))


def front_grid(P):
    """Front positions a_0 = R > a_1 > ... > a_n = R (1 - f_end)^(1/3)."""
    a_end = P.R * (1.0 - P.f_end) ** (1.0 / 3.0)
    s_list = [0.0]
    s = 0.0
    while True:
        ds = P.ds0 + P.eps * min(s, P.R - s)
        if P.R - (s + ds) <= a_end * (1.0 + 0.3 * P.eps):
            s_list.append(P.R - a_end)
            break
        s += ds
        s_list.append(s)
    return P.R - np.array(s_list)


def run_mechanics(P, heat, thermal=False, creep=False):
    """Incremental layered shell; heat = solve_heat on the front positions a[1:] (a[0] = R:
    no shell yet). Layer k (born at step k) is a[k+1] < r < a[k]; its inner edge is node
    k+1, its outer edge node k. Per-layer arrays are kept in birth order (outermost first);
    shell_response works in increasing r, hence the [::-1].

    Returns the history per step (after step k the front is at a[k+1]) and the final state."""
    a = np.concatenate([[P.R], heat["a"]])
    t = np.concatenate([[0.0], heat["t"]])
    n = len(a) - 1
    E, nu, mu, Kw = P.E, P.nu, P.mu, P.Kw
    xi = np.linspace(0.0, 1.0, P.n_xi + 1)
    srr_in = np.zeros(n); srr_out = np.zeros(n)       # stresses at each layer's two edges
    stt_in = np.zeros(n); stt_out = np.zeros(n)
    T_node = np.full(n + 1, P.Tm)                     # temperature of the last thermal update
    hist = {key: np.zeros(n) for key in ("f", "t", "s", "p", "stt_R", "smax", "smax_depth",
                                        "dV_excess", "dV_water", "dV_shell")}
    p = 0.0
    dV_excess = dV_water = dV_shell = 0.0
    n_sub_total = 0
    for k in range(n):
        nl = k + 1                                    # layers 0..k
        an = a[k + 1]
        rn = a[k + 1::-1]                             # nodes k+1 (front) ... 0 (R), increasing r
        # 1. birth of layer k at the water's pressure (node k+1 is born at T_m)
        srr_in[k] = srr_out[k] = stt_in[k] = stt_out[k] = -p
        # unit-pressure response of the current shell (Lame) and the cavity's compliance
        u_srr, u_sin, u_sout, u1 = shell_response(rn, 1.0, E, nu)
        comp = FOUR_PI * an * an * u1 + FOUR_PI / 3.0 * an ** 3 / Kw     # d(volume)/dp
        dV_ex = P.beta * FOUR_PI / 3.0 * diff_cubes(a[k], an)            # beta x frozen water
        # 2. thermal eigenstrain increment over the step, at the nodes
        if thermal:
            T_new = np.interp((a[:k + 2] - an) / (P.R - an), xi, heat["theta"][k])
            de_node = P.alpha * (T_new - T_node[:k + 2])
            T_node[:k + 2] = T_new
        else:
            de_node = np.zeros(k + 2)
        th_lo = de_node[1:k + 2]                      # birth order: inner edge of layer j = node j+1
        th_hi = de_node[0:k + 1]
        dt = t[k + 1] - t[k]
        done = 0.0
        while done < 1.0 - 1e-12:
            # 3. sub-step: its share of the step, creep strain increments (explicit Euler)
            frac = 1.0 - done
            if creep:
                A_lo = rate_factor(T_node[1:k + 2])
                A_hi = rate_factor(T_node[0:k + 1])
                d_lo = srr_in[:nl] - stt_in[:nl]      # Delta = sigma_rr - sigma_tt
                d_hi = srr_out[:nl] - stt_out[:nl]
                g_lo = A_lo * d_lo ** 2 / 3.0         # A tau_e^(n-1), tau_e^2 = Delta^2/3, n = 3
                g_hi = A_hi * d_hi ** 2 / 3.0
                lam = 2.0 * mu * P.glen_n * max(g_lo.max(), g_hi.max())
                if lam * dt * frac > P.c_cfl:
                    frac = min(frac, max(P.c_cfl / (lam * dt), 1e-6))
                c_lo = g_lo * d_lo * dt * frac        # creep: e_r = 2c/3, e_t = -c/3
                c_hi = g_hi * d_hi * dt * frac
                eig = ((frac * th_lo + 2.0 / 3.0 * c_lo)[::-1], (frac * th_hi + 2.0 / 3.0 * c_hi)[::-1],
                       (frac * th_lo - 1.0 / 3.0 * c_lo)[::-1], (frac * th_hi - 1.0 / 3.0 * c_hi)[::-1])
            elif thermal:
                eig = (th_lo[::-1], th_hi[::-1], th_lo[::-1], th_hi[::-1])
            else:
                eig = None
            if eig is None:
                e_srr, e_sin, e_sout, ue = 0.0, 0.0, 0.0, 0.0
            else:
                e_srr, e_sin, e_sout, ue = shell_response(rn, 0.0, E, nu, eig)
            # 4. cavity volume balance gives the pressure increment
            dp = (frac * dV_ex - FOUR_PI * an * an * ue) / comp
            p += dp
            dV_excess += frac * dV_ex
            dV_water += dp * FOUR_PI / 3.0 * an ** 3 / Kw
            dV_shell += FOUR_PI * an * an * (ue + dp * u1)
            # 5. stress increments (increasing r -> birth order)
            d_srr = e_srr + dp * u_srr
            srr_in[:nl] += d_srr[:-1][::-1]
            srr_out[:nl] += d_srr[1:][::-1]
            stt_in[:nl] += (e_sin + dp * u_sin)[::-1]
            stt_out[:nl] += (e_sout + dp * u_sout)[::-1]
            done += frac
            n_sub_total += 1
        # 6. record: largest tensile principal stress over every layer edge, and where
        top_in = np.maximum(stt_in[:nl], srr_in[:nl])
        top_out = np.maximum(stt_out[:nl], srr_out[:nl])
        i_in, i_out = np.argmax(top_in), np.argmax(top_out)
        if top_in[i_in] > top_out[i_out]:
            smax, r_max = top_in[i_in], a[i_in + 1]
        else:
            smax, r_max = top_out[i_out], a[i_out]
        hist["f"][k] = 1.0 - (an / P.R) ** 3
        hist["t"][k] = t[k + 1]
        hist["s"][k] = P.R - an
        hist["p"][k] = p
        hist["stt_R"][k] = stt_out[0]
        hist["smax"][k] = smax
        hist["smax_depth"][k] = P.R - r_max
        hist["dV_excess"][k] = dV_excess
        hist["dV_water"][k] = dV_water
        hist["dV_shell"][k] = dV_shell
    # global equilibrium of a half drop: int_a^R sigma_tt r dr = p a^2 / 2 (trapezoid per layer)
    lo, hi = a[1:], a[:-1]
    integral = np.sum(0.5 * (stt_in * lo + stt_out * hi) * (hi - lo))
    scale = np.sum(0.5 * (np.abs(stt_in) * lo + np.abs(stt_out) * hi) * (hi - lo))
    final = {"a": a, "srr_in": srr_in, "srr_out": srr_out, "stt_in": stt_in,
             "stt_out": stt_out, "equilibrium": (integral - p * a[-1] ** 2 / 2.0) / scale,
             "srr_R": srr_out[0], "srr_a": srr_in[-1], "p": p, "substeps": n_sub_total}
    return hist, final


def crossing(hist, level):
    """f, t, s, p, depth where the largest tensile stress first reaches level (interpolated)."""
    sm = hist["smax"]
    idx = np.nonzero(sm >= level)[0]
    if len(idx) == 0:
        return None
    k = idx[0]
    if k == 0:
        w = 1.0
        prev = {key: 0.0 for key in hist}
        prev["smax"] = 0.0
    else:
        w = (level - sm[k - 1]) / (sm[k] - sm[k - 1])
        prev = {key: hist[key][k - 1] for key in hist}
    out = {key: prev[key] + w * (hist[key][k] - prev[key]) for key in ("f", "t", "s", "p", "stt_R")}
    out["depth"] = hist["smax_depth"][k]
    return out


def at_f(hist, f):
    """History values interpolated at frozen fraction f (None beyond the run)."""
    if f > hist["f"][-1]:
        return None
    return {key: float(np.interp(f, hist["f"], hist[key])) for key in hist}


# ----------------------------------------------------------------------------------------
# Checks
# ----------------------------------------------------------------------------------------

def check_lame(P):
    """Layered solver (no eigenstrain) against the Lame closed form, several thicknesses."""
    worst = 0.0
    rows = []
    rng = np.random.default_rng(1)
    for ratio in (0.5, 0.9, 0.999, 0.99999):
        a = ratio * P.R
        inner = np.sort(rng.uniform(a, P.R, 200))
        rn = np.concatenate([[a], inner, [P.R]])
        srr, sin_, sout, ua = shell_response(rn, 1.0, P.E, P.nu)
        c_rr, c_tt, c_ua = lame_closed_form(a, P.R, 1.0, rn, P.E, P.nu)
        scale = np.abs(c_tt).max()
        err = max(np.abs(srr - c_rr).max() / scale, np.abs(sin_ - c_tt[:-1]).max() / scale,
                  np.abs(sout - c_tt[1:]).max() / scale, abs(ua - c_ua) / c_ua)
        worst = max(worst, err)
        rows.append((ratio, err))
    return worst, rows


def check_thin_lame(P):
    """Lame's outer hoop stress against the thin-shell p a/(2 s)."""
    rows = []
    for s_rel in (1e-2, 1e-3, 1e-4):
        a = P.R * (1.0 - s_rel)
        _, c_tt, _ = lame_closed_form(a, P.R, 1.0, np.array([P.R]), P.E, P.nu)
        rows.append((s_rel, c_tt[0] / (a / (2.0 * (P.R - a))) - 1.0))
    return rows


def check_thermal_timoshenko(P, n_layers):
    """Isotropic eigenstrain alpha (T - T_ref), T = A + B/r, against Timoshenko & Goodier."""
    a, R = 0.5 * P.R, P.R
    A_, B_ = -30.0, 0.15                    # degC, degC m: T(a) = 0, T(R) = -15
    rn = np.linspace(a, R, n_layers + 1)
    e_node = P.alpha * (A_ + B_ / rn)       # eigenstrain at the layer edges
    lo, hi = e_node[:-1], e_node[1:]
    srr, sin_, sout, _ = shell_response(rn, 0.0, P.E, P.nu, (lo, hi, lo, hi))

    def integral(r):                        # int_a^r alpha T rho^2 drho
        return P.alpha * (A_ * (r ** 3 - a ** 3) / 3.0 + B_ * (r ** 2 - a ** 2) / 2.0)

    Ib = integral(R)
    c = P.E / (1.0 - P.nu)
    c_rr = 2.0 * c * ((rn ** 3 - a ** 3) / ((R ** 3 - a ** 3) * rn ** 3) * Ib - integral(rn) / rn ** 3)
    c_tt = c * ((2.0 * rn ** 3 + a ** 3) / ((R ** 3 - a ** 3) * rn ** 3) * Ib + integral(rn) / rn ** 3
                - P.alpha * (A_ + B_ / rn))
    scale = np.abs(c_tt).max()
    err = max(np.abs(srr - c_rr).max(), np.abs(sin_ - c_tt[:-1]).max(),
              np.abs(sout - c_tt[1:]).max()) / scale
    return err, scale


def check_eigen_bvp(P, n_layers):
    """Smooth anisotropic eigenstrain + inner pressure: layered solver against solve_bvp."""
    a, R, p = 0.6 * P.R, P.R, 2e6
    lam = P.E * P.nu / ((1 + P.nu) * (1 - 2 * P.nu))
    mu = P.mu

    def e_r(r): return 1e-4 * (r / R) ** 2
    def e_t(r): return -3e-5 * (R / r) + 2e-5 * np.sin(8.0 * r / R)
    def de_r(r): return 2e-4 * r / R ** 2
    def de_t(r): return 3e-5 * R / r ** 2 + 1.6e-4 / R * np.cos(8.0 * r / R)

    def s_r(r): return lam * (e_r(r) + 2 * e_t(r)) + 2 * mu * e_r(r)
    def s_t(r): return lam * (e_r(r) + 2 * e_t(r)) + 2 * mu * e_t(r)
    def ds_r(r): return lam * (de_r(r) + 2 * de_t(r)) + 2 * mu * de_r(r)

    def ode(r, y):
        u, up = y
        upp = -2 * up / r + 2 * u / r ** 2 + (ds_r(r) + 2 * (s_r(r) - s_t(r)) / r) / (lam + 2 * mu)
        return np.vstack([up, upp])

    def sig_rr(r, u, up): return (lam + 2 * mu) * up + 2 * lam * u / r - s_r(r)
    def sig_tt(r, u, up): return lam * up + 2 * (lam + mu) * u / r - s_t(r)

    def bc(ya, yb):
        return np.array([sig_rr(a, ya[0], ya[1]) + p, sig_rr(R, yb[0], yb[1])])

    x = np.linspace(a, R, 200)
    sol = solve_bvp(ode, bc, x, np.zeros((2, x.size)), tol=1e-10, max_nodes=200000)
    rn = np.linspace(a, R, n_layers + 1)
    eig = (e_r(rn[:-1]), e_r(rn[1:]), e_t(rn[:-1]), e_t(rn[1:]))
    srr, sin_, sout, ua = shell_response(rn, p, P.E, P.nu, eig)
    y = sol.sol(rn)
    c_rr = sig_rr(rn, y[0], y[1])
    c_tt = sig_tt(rn, y[0], y[1])
    scale = np.abs(c_tt).max()
    err = max(np.abs(srr - c_rr).max(), np.abs(sin_ - c_tt[:-1]).max(),
              np.abs(sout - c_tt[1:]).max()) / scale
    err_u = abs(ua - y[0][0]) / abs(y[0][0])
    return max(err, err_u), sol.status


def expansion_ode(P, s_eval):
    """Expansion only, continuous in a: p and sigma_tt(R) at shell thicknesses s_eval."""
    E, nu, R = P.E, P.nu, P.R

    def rhs(s, y):
        a = R - s
        _, _, u1 = lame_closed_form(a, R, 1.0, np.array([R]), E, nu)
        comp = FOUR_PI * a * a * u1 + FOUR_PI / 3.0 * a ** 3 / P.Kw
        dpds = P.beta * FOUR_PI * a * a / comp
        return [dpds, 1.5 * a ** 3 / diff_cubes(R, a) * dpds]

    s0 = 1e-12                              # thin-shell start: p = beta E s^2/((1-nu) R^2)
    y0 = [P.beta * E * s0 ** 2 / ((1 - nu) * R ** 2), P.beta * E * s0 / ((1 - nu) * R)]
    sol = solve_ivp(rhs, (s0, s_eval[-1]), y0, t_eval=s_eval, rtol=1e-10, atol=1e-6,
                    method="DOP853")
    return sol.y[0], sol.y[1]


# ----------------------------------------------------------------------------------------
# Driver and report
# ----------------------------------------------------------------------------------------

CASES = (("expansion", False, False), ("expansion + thermal", True, False),
         ("expansion + thermal + creep", True, True))


def run_all(P, with_creep=True):
    """Heat once, then the mechanical cases, on the grid of P."""
    t0 = time.perf_counter()
    a = front_grid(P)
    heat = solve_heat(P, a[1:])
    t_heat = time.perf_counter() - t0
    energy = (heat["Q"] - heat["latent"] - heat["sensible"]) / heat["Q"]
    results = {"P": P, "heat": heat, "n_steps": len(a) - 1, "t_heat": t_heat, "cases": {},
               "energy": float(np.abs(energy).max())}
    for name, thermal, creep in CASES:
        if creep and not with_creep:
            continue
        t1 = time.perf_counter()
        hist, final = run_mechanics(P, heat, thermal=thermal, creep=creep)
        results["cases"][name] = {"hist": hist, "final": final,
                                  "wall": time.perf_counter() - t1,
                                  "cross": {lvl: crossing(hist, lvl) for lvl in THRESHOLDS}}
    return results


def heat_checks(P, heat):
    """Energy balance of the FD heat run, its thin-shell start, and QS against FD."""
    res = (heat["Q"] - heat["latent"] - heat["sensible"]) / heat["Q"]
    s = P.R - heat["a"]
    t_thin = P.rho * P.L * s / (P.h * (P.Tm - P.Ta))
    thin = [(s_, float(np.interp(s_, s, heat["t"] / t_thin))) for s_ in (1e-6, 1e-5, 1e-4)]
    qs_rows = []
    for h, Ta in ((50.0, -20.0), (200.0, -20.0), (50.0, -40.0)):
        Pc = replace(P, h=h, Ta=Ta)
        fs = (0.0025, 0.1, 0.5, 0.9, 0.99)
        a_eval = np.concatenate([[P.R - P.ds0], P.R * (1.0 - np.array(fs)) ** (1.0 / 3.0)])
        hc = solve_heat(Pc, a_eval)
        t_qs = qs_time(a_eval[1:], Pc)
        qs_rows.append((h, Ta, fs, hc["t"][1:], t_qs, hc["sensible"][-1] / hc["Q"][-1]))
    return {"energy_max": float(np.abs(res).max()), "energy_end": float(res[-1]),
            "sensible_end": float(heat["sensible"][-1] / heat["Q"][-1]), "thin": thin,
            "qs": qs_rows}


def mech_checks(P, levels):
    """Thin-shell growth law and the expansion ODE against the layered expansion-only runs
    (the reported resolution and the 2x coarser one), at a few shell thicknesses."""
    hist = levels[-1]["cases"]["expansion"]["hist"]
    s = hist["s"]
    law = P.beta * P.E * s / ((1.0 - P.nu) * P.R)
    growth = [(s_, float(np.interp(s_, s, hist["stt_R"] / law))) for s_ in (1e-7, 1e-6, 8e-6, 1e-4)]
    k1 = min(int(np.searchsorted(hist["smax"], 1e6)), len(s) - 1)
    s_pts = sorted({x for x in (1e-6, s[k1], 1e-4, 1e-3) if x < s[-1]} | {s[-1]})
    ode = []
    for lv in (levels[-2], levels[-1]):
        h = lv["cases"]["expansion"]["hist"]
        idx = [min(int(np.searchsorted(h["s"], x)), len(h["s"]) - 1) for x in s_pts]
        s_at = h["s"][idx]
        p_ode, stt_ode = expansion_ode(P, s_at)
        ode.append([(float(s_at[j]), float(h["p"][i] / p_ode[j] - 1.0),
                     float(h["stt_R"][i] / stt_ode[j] - 1.0)) for j, i in enumerate(idx)])
    return {"growth": growth, "ode": ode}


def fmt(x, d=4):
    """Significant-digit format; an em dash for None."""
    if x is None:
        return "—"
    return f"{x:.{d}g}"


def mpa(x, d=4):
    return fmt(None if x is None else x / 1e6, d)


def um(x, d=4):
    return fmt(None if x is None else x * 1e6, d)


def rel(x, y):
    """Relative change of y against x, formatted."""
    if x is None or y is None:
        return "—"
    return f"{(y - x) / abs(x):+.1e}"


def order(x1, x2, x4):
    """Observed order from three resolutions, each twice finer than the one before."""
    d1, d2 = x1 - x2, x2 - x4
    if d2 == 0 or d1 == 0 or d1 / d2 <= 0:
        return "—"
    return f"{math.log2(d1 / d2):.2f}"


def threshold_table(res):
    lines = ["| case | σ_max reaches | f | t (s) | shell R − a (µm) | p (kPa) | σ_θθ(R) (MPa) | depth of σ_max (µm) |",
             "|---|---|---|---|---|---|---|---|"]
    for name, case in res["cases"].items():
        for lvl in THRESHOLDS:
            c = case["cross"][lvl]
            if c is None:
                lines.append(f"| {name} | {lvl / 1e6:g} MPa | not reached | | | | | |")
                continue
            lines.append(f"| {name} | {lvl / 1e6:g} MPa | {c['f']:.5f} | {c['t']:.4g} | {um(c['s'])} | "
                         f"{c['p'] / 1e3:.4g} | {mpa(c['stt_R'])} | {um(c['depth'], 2)} |")
    return "\n".join(lines)


def history_table(case):
    lines = ["| f | t (s) | R − a (mm) | p (MPa) | σ_θθ(R) (MPa) | largest tensile (MPa) | its depth (mm) |",
             "|---|---|---|---|---|---|---|"]
    for f in F_MARKS:
        v = at_f(case["hist"], f)
        if v is None:
            continue
        lines.append(f"| {f:g} | {v['t']:.4g} | {v['s'] * 1e3:.4g} | {mpa(v['p'])} | {mpa(v['stt_R'])} | "
                     f"{mpa(v['smax'])} | {v['smax_depth'] * 1e3:.3g} |")
    return "\n".join(lines)


def heat_table(res):
    P, heat = res["P"], res["heat"]
    s = P.R - heat["a"]
    f = 1.0 - (heat["a"] / P.R) ** 3
    lines = ["| f | R − a (mm) | t FD (s) | t QS (s) | t_QS/t_FD − 1 | surface T, FD (°C) |", "|---|---|---|---|---|---|"]
    for fm in F_MARKS:
        if fm > f[-1]:
            continue
        t = float(np.interp(fm, f, heat["t"]))
        sm = float(np.interp(fm, f, s))
        tq = float(qs_time(P.R - sm, P))
        Ts = float(np.interp(fm, f, heat["theta"][:, -1]))
        lines.append(f"| {fm:g} | {sm * 1e3:.4g} | {t:.5g} | {tq:.5g} | {(tq - t) / t:+.2%} | {Ts:.3f} |")
    return "\n".join(lines)


def convergence_tables(levels):
    """Thresholds and late values at three resolutions (each halving every step and grid)."""
    names = list(levels[0]["cases"])
    lines = ["| case | quantity | 4× coarser | 2× coarser | reported | 4× → 2× | 2× → reported | order |",
             "|---|---|---|---|---|---|---|---|"]
    for name in names:
        for lvl in THRESHOLDS:
            cs = [lv["cases"][name]["cross"][lvl] for lv in levels]
            if any(c is None for c in cs):
                continue
            for key, label, scale, d in (("s", "R − a (µm)", 1e6, 6), ("t", "t (s)", 1.0, 6),
                                         ("p", "p (kPa)", 1e-3, 6)):
                x = [c[key] * scale for c in cs]
                lines.append(f"| {name} | {label} at {lvl / 1e6:g} MPa | {x[0]:.{d}g} | {x[1]:.{d}g} | "
                             f"{x[2]:.{d}g} | {rel(x[0], x[1])} | {rel(x[1], x[2])} | {order(*x)} |")
        for fm in (0.1, 0.5, 0.99):
            vs = [at_f(lv["cases"][name]["hist"], fm) for lv in levels]
            if any(v is None for v in vs):
                continue
            for key, label in (("p", "p"), ("smax", "largest tensile")):
                x = [v[key] / 1e6 for v in vs]
                lines.append(f"| {name} | {label} (MPa) at f = {fm:g} | {x[0]:.6g} | {x[1]:.6g} | {x[2]:.6g} | "
                             f"{rel(x[0], x[1])} | {rel(x[1], x[2])} | {order(*x)} |")
    return "\n".join(lines)


def heat_convergence(levels):
    lines = ["| f | t, 4× coarser (s) | t, 2× coarser | t, reported | 4× → 2× | 2× → reported | order |",
             "|---|---|---|---|---|---|---|"]
    for fm in (0.0025, 0.1, 0.5, 0.99):
        x = []
        for lv in levels:
            P, heat = lv["P"], lv["heat"]
            f = 1.0 - (heat["a"] / P.R) ** 3
            if fm > f[-1]:
                break
            x.append(float(np.interp(fm, f, heat["t"])))
        if len(x) < 3:
            continue
        lines.append(f"| {fm:g} | {x[0]:.8g} | {x[1]:.8g} | {x[2]:.8g} | {rel(x[0], x[1])} | "
                     f"{rel(x[1], x[2])} | {order(*x)} |")
    return "\n".join(lines)


MODEL_TEXT = """\
## Model

SI units, temperatures in °C. Drop R = 0.01 m, all water at T_m = 0 °C at t = 0, air at
T_a = −20 °C, convection h = 50 W/(m² K). Ice: k = 2.22 W/(m K), ρ_i = 917 kg/m³,
c = 2050 J/(kg K), L = 334e3 J/kg, E = 9e9 Pa, ν = 0.33, α = 5e-5 1/K. Water: K_w = 2.2e9 Pa;
a water volume dV freezes into (1 + β) dV of ice, β = 0.09. Undeformed geometry (small
strain): ice shell a(t) < r < R, water r < a, frozen fraction f = 1 − (a/R)³.

**Heat** (transient, finite differences):

```
ρ_i c ∂T/∂t = k r⁻² ∂/∂r (r² ∂T/∂r)      a < r < R
T(a) = T_m,   −k ∂T/∂r(R) = h (T(R) − T_a)
ρ_i L da/dt = k ∂T/∂r(a)                  (∂T/∂r(a) < 0, so da/dt < 0)
```

The latent heat ρ_i L |da/dt| released per unit front area is the flux −k ∂T/∂r(a)
conducted into the shell. Front-fixing coordinate ξ = (r − a)/s, s = R − a, uniform grid of N_ξ intervals,
Θ(ξ, t) = T:

```
∂Θ/∂t = κ/s² (Θ'' + (2s/r) Θ') + Θ' (da/dt)(1 − ξ)/s,   κ = k/(ρ_i c),  ' = ∂/∂ξ
```

(central differences, a ghost node for the Robin condition, second-order one-sided Θ'(0) in
the Stefan condition), integrated by scipy's Radau (implicit Runge–Kutta, order 5) with the
shell thickness s as the independent variable, so that t and Θ come out exactly at the front
positions the mechanics steps through. A state Q integrates the heat lost at the surface,
4πR² h (T(R) − T_a), for the energy balance Q = ρ_i L (4/3)π(R³ − a³) + ∫ ρ_i c (T_m − T) 4πr² dr,
which the script enforces (it stops if the balance is off by more than 1e-3: scipy's BDF on
the same system drifted silently at some resolutions, by 20 % in energy). Start: the first mechanical layer
(s₀ = ds₀) with the quasi-steady profile. Quasi-steady (QS) comparison, no sensible heat:

```
T(r) = T_m − (T_m − T_a) (1/a − 1/r) / ((1/a − 1/R) + k/(h R²))
t_QS(a) = ρ_i L/(T_m − T_a) · [((R² − a²)/2 − (R³ − a³)/(3R))/k + (R³ − a³)/(3 h R²)]
```

**Mechanics** (small strain, incremental, layered). The front positions a₀ = R > a₁ > … are
the steps; at step k the layer a_{k+1} < r < a_k freezes, so the layers are the shell's radial
discretisation. Layer thickness ds = ds₀ + ε·min(s, a): ds₀ at the surface, growing by ε per
layer, refining again as the cavity closes. Per step:

1. *Birth*: the new layer gets σ_rr = σ_θθ = −p (the water's pressure), no eigenstrain, T = T_m.
2. *Eigenstrain increments* of every layer over the step: thermal α ΔT (cases 2, 3; T at the
   layer edges from the heat solution, linear in ξ), Glen creep (case 3).
3. *Cavity volume balance*: the water frozen in the step, dV = (4/3)π(a_k³ − a_{k+1}³), wants
   (1 + β) dV as ice; the excess β dV is taken by compressing the remaining water
   V_w = (4/3)π a_{k+1}³ and by the outward displacement of the shell's (new) inner surface:

   ```
   β dV = dp V_w/K_w + 4π a² (dp u₁(a) + u*(a))
   ```

   u₁: inner displacement of the current shell (new layer included) under unit inner pressure;
   u*: under the step's eigenstrain increments at zero pressure.
4. Every layer's stresses (kept at both edges of each layer: σ_θθ jumps between layers born at
   different pressures) are incremented by dp × (unit-pressure stresses) + (eigenstrain
   stresses) of the current shell.

Incremental equilibrium of a shell a < r < R with eigenstrain increments (e_r, e_θ):

```
dσ_rr/dr + 2(σ_rr − σ_θθ)/r = 0,   σ_rr(a) = −dp,   σ_rr(R) = 0
ε_rr = (σ_rr − 2ν σ_θθ)/E + e_r,   ε_θθ = ((1 − ν) σ_θθ − ν σ_rr)/E + e_θ,   ε_rr = d(r ε_θθ)/dr
```

With σ_θθ = σ_rr + (r/2) σ_rr' (equilibrium), compatibility becomes
(r⁴ σ_rr')' = K r² ((e_r − e_θ) − r e_θ'), K = 2E/(1 − ν). Integrated twice (by parts, so a jump
of e_θ between layers is exact), with P(r) = ∫_a^r (e_r + 2e_θ) ρ² dρ and
W(r) = ∫_a^r (e_r − e_θ)/ρ dρ:

```
σ_rr(r) = −dp + K (W/3 − P/(3r³)) + (D/3)(1/a³ − 1/r³)
σ_θθ(r) = σ_rr(r) + (K/2)(P/r³ − e_θ(r)) + D/(2r³)
u(a)    = a (−(1 − 2ν) dp + (1 − ν) D/(2a³)) / E,     D from σ_rr(R) = 0
```

P and W are sums of exact layer integrals of each layer's mean eigenstrain; the local
term −K e_θ(r)/2 takes the edge's own value. Without eigenstrain this is Lamé's thick sphere,

```
σ_rr = −dp a³ (R³/r³ − 1)/(R³ − a³),   σ_θθ = dp a³ (1 + R³/(2r³))/(R³ − a³),
u(a) = dp a ((1 − 2ν) a³ + (1 + ν) R³/2) / (E (R³ − a³)),
```

and with isotropic eigenstrain it is Timoshenko & Goodier's thermal stress in a sphere.

**Glen creep** (case 3 = case 2 + creep): ε̇ = A(T) τₑⁿ⁻¹ τ, τ the stress deviator,
τₑ² = τ:τ/2, n = 3. With Δ = σ_rr − σ_θθ: τ_rr = 2Δ/3, τ_θθ = −Δ/3, τₑ = |Δ|/√3, so at each
layer edge e_r = (2/3) A τₑ² Δ dt and e_θ = −(1/3) A τₑ² Δ dt.
A(T) = 3.5e-25 exp(−Q/R_g (1/T − 1/263.15)) Pa⁻³ s⁻¹ (T in K, Q = 115 kJ/mol above −10 °C,
60 kJ/mol below; A(0 °C) = 2.4e-24). Forward Euler sub-steps no longer than c_cfl/λ_max,
λ = 2μ n A τₑⁿ⁻¹ (the linearised relaxation rate of Δ), c_cfl = 0.05; the step's expansion and
thermal increments are split over the sub-steps in proportion to their durations.

**Reported**: p; the hoop stress σ_θθ(R) at the outer surface; the largest tensile principal
stress σ_max = max over every layer edge of max(σ_rr, σ_θθ), and its depth R − r; against f and
t. Thresholds: the first f, t, shell thickness R − a and p at which σ_max reaches 0.5, 1, 2 and
3 MPa (linear interpolation between steps).
"""


def build_report(args, P, levels, lame_err, lame_rows, thin_rows, timo, bvp, hc, mc, wall):
    base = levels[-1]
    cases = base["cases"]
    exp_ = cases["expansion"]
    c1 = exp_["cross"][1e6]
    s_law = 1e6 * (1.0 - P.nu) * P.R / (P.beta * P.E)
    command = "python3 validation/freezing_drop_1d.py " + shlex.join(sys.argv[1:])
    out = []
    out.append("# A water drop freezing from the outside in: 1-D spherically symmetric reference\n")
    out.append(
        "An independent reference for icefem's 3-D freezing drop: a 1 cm water drop at 0 °C in "
        "−20 °C air freezes inward; the 9 % expansion of each new ice layer compresses the "
        "trapped water and stretches the shell. Transient Stefan problem by finite differences, "
        "shell stresses by an incremental layered thick-sphere solution (exact for layer-wise "
        "constant eigenstrains), three cases: (1) expansion only, (2) expansion + thermal "
        "strain, (3) expansion + thermal strain + Glen creep. Every number below comes from "
        "the script; the formulas are repeated in its docstring.\n")
    out.append(f"Command: `{command}` (a Python with numpy and scipy) — {wall:.0f} s on "
               f"{os.cpu_count()} cores (all three "
               f"resolutions and the checks; the reported, finest resolution alone takes "
               f"{base['wall']:.1f} s).\n")
    out.append(MODEL_TEXT)
    out.append(f"Reported resolution: ds₀ = {P.ds0 * 1e6:g} µm, ε = {P.eps:g} ({base['n_steps']} "
               f"steps/layers to f = {P.f_end:g}), N_ξ = {P.n_xi}, Radau rtol = {P.heat_rtol:g}, "
               f"c_cfl = {P.c_cfl:g}.\n")

    # ---------------- results
    out.append("## When the shell first reaches the tensile strength\n")
    out.append(threshold_table(base) + "\n")
    ex, th = cases["expansion"]["cross"][1e6], cases["expansion + thermal"]["cross"][1e6]
    txt = (f"In case (1) the largest tensile stress reaches σ_t = 1 MPa at f = {ex['f']:.5f}, "
           f"t = {ex['t']:.3g} s, when the shell is {ex['s'] * 1e6:.3g} µm thick and the water "
           f"is at only {ex['p'] / 1e3:.3g} kPa. The largest tensile stress is the hoop stress at "
           f"the outer surface (its depth in the table is at most one layer, the outermost layer's "
           f"inner edge). It follows the thin-shell growth law σ_θθ(R) ≈ β E s/((1 − ν) R): the "
           f"thin outer layers, born at almost zero pressure, are stretched by every later "
           f"pressure increment, each amplified by a/(2s); that law puts 1 MPa at "
           f"s = {s_law * 1e6:.3g} µm. The heat transfer only sets the time: at this thickness "
           f"the shell is nearly isothermal and t ≈ ρ_i L s/(h (T_m − T_a)). Thermal strain "
           f"changes the 1 MPa thickness by {(th['s'] - ex['s']) / ex['s']:+.2%}")
    if "expansion + thermal + creep" in cases:
        cr = cases["expansion + thermal + creep"]["cross"]
        parts = ", ".join(f"{(cr[l]['s'] - cases['expansion + thermal']['cross'][l]['s']) / cases['expansion + thermal']['cross'][l]['s']:+.2%} at {l / 1e6:g} MPa"
                          for l in THRESHOLDS if cr[l] is not None)
        txt += (f"; creep (against case 2) changes it by {parts}: the shell is at ≈ 0 °C, where "
                f"A is largest, but the load is only seconds old")
    out.append(txt + ".\n")
    # where the excess volume goes at 1 MPa
    k = int(np.searchsorted(exp_["hist"]["s"], c1["s"]))
    h_ = exp_["hist"]
    out.append(f"At that moment {h_['dV_shell'][k] / h_['dV_excess'][k]:.2%} of the accumulated "
               f"excess volume β·(frozen water) has gone into the shell's expansion and "
               f"{h_['dV_water'][k] / h_['dV_excess'][k]:.2%} into compressing the water; the "
               f"water's share grows as the shell stiffens (at f = {h_['f'][-1]:.3g}: "
               f"{h_['dV_water'][-1] / h_['dV_excess'][-1]:.1%}).\n")

    out.append("## Pressure and stresses against f and t\n")
    out.append("Beyond σ_max = 1 MPa the shell would have cracked; the curves go on as if it "
               "had not (linear elastic ice without fracture), to show the model's trends.\n")
    for name, case in cases.items():
        out.append(f"### {name}\n")
        out.append(history_table(case) + "\n")

    out.append("## Heat: frozen fraction against time\n")
    out.append(heat_table(base) + "\n")
    out.append(f"Sensible heat of the shell at f = {P.f_end:g}: {hc['sensible_end']:.2%} of the "
               f"heat lost (the Stefan number c (T_m − T_a)/L = "
               f"{P.c * (P.Tm - P.Ta) / P.L:.3f} bounds it); QS neglects it and is "
               f"correspondingly faster late in the freezing.\n")

    # ---------------- checks
    out.append("## Checks\n")
    out.append("| check | result |\n|---|---|")
    out.append(f"| layered solver, unit inner pressure, against Lamé's closed form (σ_rr, σ_θθ at "
               f"every layer edge / max σ_θθ, and u(a)), 200 random layers, a/R = "
               f"{', '.join(f'{r:g}' for r, _ in lame_rows)} | "
               f"{', '.join(f'{e:.1e}' for _, e in lame_rows)} (largest {lame_err:.1e}; the thin "
               f"shells lose digits to the 1/(R³ − a³) conditioning) |")
    out.append(f"| thin-shell limit of Lamé: σ_θθ(R) / (p a/(2s)) − 1 at s/R = "
               f"{', '.join(f'{s:g}' for s, _ in thin_rows)} | "
               f"{', '.join(f'{d:+.2e}' for _, d in thin_rows)} (→ 0 as −s/R) |")
    out.append(f"| thin-shell growth law: grown shell's σ_θθ(R) / (β E s/((1 − ν) R)) at s = "
               f"{', '.join(f'{s * 1e6:g}' for s, _ in mc['growth'])} µm (case 1) | "
               f"{', '.join(f'{r:.5f}' for _, r in mc['growth'])} (→ 1 as s → 0; "
               f"the first value sits on the first {P.ds0 * 1e6:g} µm layers) |")
    out.append(f"| isotropic eigenstrain α(A + B/r) (T from 0 to −15 °C, a = R/2) against "
               f"Timoshenko & Goodier, {timo[0][0]} / {timo[1][0]} layers (max error / max σ_θθ) | "
               f"{timo[0][1]:.2e} / {timo[1][1]:.2e} (order {math.log2(timo[0][1] / timo[1][1]):.2f}) |")
    out.append(f"| smooth anisotropic eigenstrain + 2 MPa inner pressure (a = 0.6 R) against "
               f"scipy solve_bvp of the displacement equation, {bvp[0][0]} / {bvp[1][0]} layers | "
               f"{bvp[0][1]:.2e} / {bvp[1][1]:.2e} (order {math.log2(bvp[0][1] / bvp[1][1]):.2f}) |")
    for label, rows in (("2× coarser", mc["ode"][0]), ("reported", mc["ode"][1])):
        out.append(f"| expansion only, {label} resolution: layered incremental run / continuous "
                   f"ODE in s (solve_ivp, rtol 1e-10) − 1 for p; σ_θθ(R), at s = "
                   f"{', '.join(f'{r[0] * 1e6:.4g}' for r in rows)} µm | p: "
                   f"{', '.join(f'{r[1]:+.1e}' for r in rows)}; σ_θθ(R): "
                   f"{', '.join(f'{r[2]:+.1e}' for r in rows)} |")
    eqs = ", ".join(f"{name}: {case['final']['equilibrium']:.1e}" for name, case in cases.items())
    out.append(f"| global equilibrium of a half drop at f = {P.f_end:g}, "
               f"(∫_a^R σ_θθ r dr − p a²/2) / ∫ |σ_θθ| r dr (trapezoid per layer) | {eqs} |")
    out.append(f"| σ_rr(R) and σ_rr(a) + p at f = {P.f_end:g} / p | "
               + ", ".join(f"{name}: {abs(case['final']['srr_R']) / case['final']['p']:.0e}, "
                           f"{abs(case['final']['srr_a'] + case['final']['p']) / case['final']['p']:.0e}"
                           for name, case in cases.items()) + " |")
    out.append(f"| heat energy balance (Q − latent − sensible)/Q: largest over the run, at the end | "
               f"{hc['energy_max']:.1e}, {hc['energy_end']:.1e}; at the 4×, 2× coarser and "
               f"reported resolutions: "
               + ", ".join(f"{lv['energy']:.1e}" for lv in levels) + " |")
    out.append(f"| heat thin-shell start: t / (ρ_i L s/(h (T_m − T_a))) at s = "
               f"{', '.join(f'{s * 1e6:g}' for s, _ in hc['thin'])} µm | "
               f"{', '.join(f'{r:.5f}' for _, r in hc['thin'])} |")
    out.append("")
    out.append("Quasi-steady against finite differences, t_QS/t_FD − 1 (the FD run at the "
               "reported resolution for each case):\n")
    fs = hc["qs"][0][2]
    out.append("| h (W/(m² K)) | T_a (°C) | " + " | ".join(f"f = {f:g}" for f in fs)
               + " | t_FD at f = 0.99 (s) | sensible / Q at 0.99 |")
    out.append("|---|---|" + "---|" * (len(fs) + 2))
    for h, Ta, fs_, t_fd, t_qs, sens in hc["qs"]:
        out.append(f"| {h:g} | {Ta:g} | " + " | ".join(f"{q / t - 1:+.2%}" for q, t in zip(t_qs, t_fd))
                   + f" | {t_fd[-1]:.5g} | {sens:.2%} |")
    worst_end = max(abs(q[-1] / t[-1] - 1.0) for _, _, _, t, q, _ in hc["qs"])
    worst_first = max(abs(q[0] / t[0] - 1.0) for _, _, _, t, q, _ in hc["qs"])
    out.append(f"\nQuasi-steady is fast by at most {worst_end:.1%} at f = 0.99 in these cases and "
               f"by at most {worst_first:.0e} (relative) at f = 0.0025, about the first crack: the "
               "shell's sensible heat, which QS neglects, matters only late. The results above "
               "use the transient FD.\n")

    # ---------------- convergence
    out.append("## Convergence\n")
    out.append("Three resolutions, each halving everything of the one before: the mechanical "
               "step (= layer thickness: ds₀ and ε), the heat grid (N_ξ doubled), the Radau "
               "tolerance (÷10) and the creep sub-step (c_cfl). The finest is the one reported "
               "above; the column '2× → reported' is the change when step size and radial "
               "resolution are both halved, and with first-order convergence (order ≈ 1) it is "
               "also the size of the reported value's remaining error. Steps: "
               + ", ".join(f"{lv['n_steps']}" for lv in levels) + "; wall times: "
               + ", ".join(f"{lv['wall']:.1f} s" for lv in levels) + "; creep sub-steps: "
               + ", ".join(f"{lv['cases']['expansion + thermal + creep']['final']['substeps']}"
                           for lv in levels if "expansion + thermal + creep" in lv["cases"])
               + ".\n")
    out.append(convergence_tables(levels) + "\n")
    out.append("Heat alone (time to reach f):\n")
    out.append(heat_convergence(levels) + "\n")

    # ---------------- caveats
    out.append("## What to keep in mind\n")
    hist1 = exp_["hist"]
    V0 = FOUR_PI / 3.0 * P.R ** 3
    notes = []
    notes.append(
        f"**The first crack is a thin-shell effect, at a shell of {c1['s'] * 1e6:.3g} µm.** "
        f"A 3-D mesh must resolve that thickness to reproduce it; an element layer of thickness "
        f"h at the surface that freezes at once carries ≈ β E h/((1 − ν) R) of hoop stress "
        f"({P.beta * P.E * 1e-4 / ((1 - P.nu) * P.R) / 1e6:.0f} MPa for h = 0.1 mm, "
        f"{P.beta * P.E * 1e-3 / ((1 - P.nu) * P.R) / 1e6:.0f} MPa for 1 mm), so a coarser 3-D "
        f"run cracks as soon as its first surface layer is ice, and its first crack measures "
        f"the mesh, not this reference. Compare the 3-D stresses with these curves at equal "
        f"shell thickness rather than only the first crack.")
    notes.append(
        "**Small strain, fixed geometry.** The heat problem and f use the undeformed radii; the "
        "9 % excess is pushed into the cavity's volume budget, not into the geometry. The "
        f"excess taken up by the shell's deformation reaches {h_['dV_shell'][-1] / V0:.2%} of the "
        f"drop's volume at f = {hist1['f'][-1]:.3g} in case 1, and the hoop stress "
        f"{hist1['stt_R'][-1] / 1e6:.0f} MPa (elastic strain ≈ {hist1['stt_R'][-1] * (1 - P.nu) / P.E:.1%}): "
        "late values of case 1 are far outside linear elasticity and ice's strength.")
    k10 = np.searchsorted(hist1["p"], 13.5e6)
    k210 = np.searchsorted(hist1["p"], 210e6)
    if k10 < len(hist1["p"]):
        msg = (f"**Pressure melting is ignored.** The melting point drops by 0.074 K/MPa; case 1 "
               f"reaches 13.5 MPa (1 K) at f = {hist1['f'][k10]:.3g}")
        if k210 < len(hist1["p"]):
            msg += (f" and 210 MPa (the ice Ih/III/liquid triple point, −22 °C) at "
                    f"f = {hist1['f'][k210]:.3g}")
        msg += (f"; beyond 210 MPa ice Ih is not the phase that would form, and the model's "
                f"p = {hist1['p'][-1] / 1e6:.0f} MPa at f = {hist1['f'][-1]:.3g}, with its front "
                "at 0 °C, is not physical. With creep the end pressure is "
                + (f"{cases['expansion + thermal + creep']['final']['p'] / 1e6:.0f} MPa"
                   if "expansion + thermal + creep" in cases else "not computed (--no-creep)")
                + ". None of this matters before the first crack (kPa).")
        notes.append(msg)
    notes.append(
        "**Birth rule.** New ice is born at −p I, and the 1.09 ratio is applied at that "
        "pressure (ice's and water's different compressibilities are neglected: a relative "
        f"volume error of order p/K_w, {c1['p'] / P.Kw:.0e} at the first crack, "
        f"{hist1['p'][-1] / P.Kw:.2f} at f = {hist1['f'][-1]:.3g} in case 1). A different birth "
        "rule (ice born stress-free, or expanding tangentially against the existing shell) "
        "would change the result qualitatively: the first crack here comes from the outermost "
        "layers being born at p ≈ 0 and the excess volume going only into the cavity. The 3-D "
        "code's `expansion = \"displaces_water\"` is meant to follow the same rule; a 3-D run "
        "with another expansion model should not be expected to match these curves.")
    notes.append(
        "**Latent heat and the water.** Latent heat per unit ice volume is ρ_i L; the "
        "water stays exactly at T_m (no supercooling, no recalescence stage, which real drops "
        "have and which would form the first shell dendritically in milliseconds).")
    notes.append(
        "**Creep**: steady Glen creep only (no primary creep, no pressure correction of T in A); "
        "explicit sub-steps, first order in time (see the convergence table). Thermal strain "
        "refers to T_m at birth; α is constant.")
    out.append("\n".join(f"- {n}" for n in notes) + "\n")
    return "\n".join(out)


def make_plot(path, res):
    """Four panels: p(f), largest tensile stress (f), f(t) FD and QS, stresses (t)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    P, heat = res["P"], res["heat"]
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for name, case in res["cases"].items():
        h = case["hist"]
        line, = axes[0, 0].loglog(h["f"], h["p"] / 1e6, label=name)
        axes[0, 1].loglog(h["f"], h["smax"] / 1e6, color=line.get_color(), label=name)
        axes[1, 1].loglog(h["t"], h["smax"] / 1e6, color=line.get_color(), label=f"{name}: largest tensile")
        axes[1, 1].loglog(h["t"], h["stt_R"] / 1e6, color=line.get_color(), ls="--", lw=0.8)
    f = 1.0 - (heat["a"] / P.R) ** 3
    axes[1, 0].plot(heat["t"], f, "k", label="transient FD")
    axes[1, 0].plot(qs_time(heat["a"], P), f, "k:", label="quasi-steady")
    for ax_ in (axes[0, 1], axes[1, 1]):
        for lvl in THRESHOLDS:
            ax_.axhline(lvl / 1e6, color="0.8", lw=0.8, zorder=0)
    axes[0, 0].set(xlabel="frozen fraction f", ylabel="p (MPa)", title="water pressure")
    axes[0, 1].set(xlabel="frozen fraction f", ylabel="MPa",
                   title="largest tensile stress (grey: 0.5, 1, 2, 3 MPa)")
    axes[1, 0].set(xlabel="t (s)", ylabel="frozen fraction f", title="heat: f against time")
    axes[1, 1].set(xlabel="t (s)", ylabel="MPa",
                   title="largest tensile stress; dashed: hoop stress at r = R")
    axes[0, 0].legend()
    axes[1, 0].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--markdown", type=Path, help="write the report here")
    parser.add_argument("--plot", type=Path, help="write a figure (png, needs matplotlib)")
    parser.add_argument("--f-end", type=float, default=Params.f_end,
                        help="frozen fraction at which the run stops (default %(default)s)")
    parser.add_argument("--no-creep", action="store_true", help="skip case 3 (Glen creep)")
    args = parser.parse_args()
    if not 0.01 <= args.f_end < 1.0:
        parser.error("--f-end must be in [0.01, 1)")
    if args.plot:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            parser.error("--plot needs matplotlib, which this Python does not have")
    wall0 = time.perf_counter()
    P = Params(f_end=args.f_end)
    with_creep = not args.no_creep

    # three resolutions: 4x coarser, 2x coarser, the reported one
    levels = []
    for Pl in (P.coarsened().coarsened(), P.coarsened(), P):
        t0 = time.perf_counter()
        levels.append(run_all(Pl, with_creep))
        levels[-1]["wall"] = time.perf_counter() - t0
        print(f"resolution ds0 = {Pl.ds0:.2g} m, eps = {Pl.eps:.2g}, N_xi = {Pl.n_xi}: "
              f"{levels[-1]['n_steps']} steps, {levels[-1]['wall']:.1f} s", flush=True)
    base = levels[-1]

    # checks
    lame_err, lame_rows = check_lame(P)
    thin_rows = check_thin_lame(P)
    timo = [(n, check_thermal_timoshenko(P, n)[0]) for n in (100, 200)]
    bvp = [(n, check_eigen_bvp(P, n)[0]) for n in (100, 200)]
    hc = heat_checks(P, base["heat"])
    mc = mech_checks(P, levels)
    wall = time.perf_counter() - wall0
    report = build_report(args, P, levels, lame_err, lame_rows, thin_rows, timo, bvp, hc, mc, wall)

    # stdout: the short table
    print()
    print(f"{'case':30s} {'sigma':>6s} {'f':>9s} {'t (s)':>8s} {'R-a (um)':>9s} {'p (kPa)':>8s}")
    for name, case in base["cases"].items():
        for lvl in THRESHOLDS:
            c = case["cross"][lvl]
            if c is None:
                print(f"{name:30s} {lvl / 1e6:4g} MPa  not reached")
                continue
            print(f"{name:30s} {lvl / 1e6:4g} MPa {c['f']:9.5f} {c['t']:8.4g} {c['s'] * 1e6:9.4g} "
                  f"{c['p'] / 1e3:8.4g}")
    print(f"checks: Lame {lame_err:.1e}; eigenstrain vs Timoshenko {timo[-1][1]:.1e}, vs solve_bvp "
          f"{bvp[-1][1]:.1e} ({bvp[-1][0]} layers); expansion vs ODE at 1 MPa: p "
          f"{mc['ode'][1][1][1]:+.1e}, sigma_tt(R) {mc['ode'][1][1][2]:+.1e}; heat energy "
          f"balance {hc['energy_max']:.1e}")
    print(f"total {wall:.1f} s")
    if args.markdown:
        args.markdown.write_text(report)
        print(f"wrote {args.markdown}")
    if args.plot:
        make_plot(args.plot, base)
        print(f"wrote {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
