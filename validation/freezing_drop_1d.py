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
  (The brief writes rho_i L da/dt = -k dT/dr|_a "with the sign so that the front moves
  inward"; with T decreasing outward that sign needs da/dt read as the front's inward speed,
  which is what the line above does.)
  Front-fixing (Landau) coordinate xi = (r - a)/s, s = R - a, on a uniform grid of N_xi
  intervals; Theta(xi, t) = T(r, t) obeys
    dTheta/dt = kappa/s^2 (Theta'' + 2 s/r Theta') + Theta' (da/dt) (1 - xi)/s,
    kappa = k/(rho_i c), ' = d/dxi;
  second-order central differences, a ghost node for the Robin condition, a second-order
  one-sided dTheta/dxi at the front. The front position a is the independent variable
  (da/dt < 0 throughout), so the ODE system d(Theta_j, t, Q)/da = (dTheta_j/dt, 1,
  4 pi R^2 h (T(R) - T_a)) / (da/dt) is integrated by scipy's BDF and returns the time and the
  temperature profile exactly at the front positions the mechanics steps through. Q is the
  heat lost through the surface, for the energy balance
    Q = rho_i L (4/3) pi (R^3 - a^3) + int_a^R rho_i c (T_m - T) 4 pi r^2 dr.
  Start: a shell of thickness s_0 (the first mechanical layer, 0.04 um) with the quasi-steady
  profile at the quasi-steady time (its error there is far below anything reported).
  Quasi-steady (QS) comparison: no sensible heat in the shell, T(r) = T_m - (T_m - T_a)
  (1/a - 1/r)/((1/a - 1/R) + k/(h R^2)), whence the closed form
    t_QS(a) = rho_i L/(T_m - T_a) [((R^2 - a^2)/2 - (R^3 - a^3)/(3R))/k + (R^3 - a^3)/(3 h R^2)].

MECHANICS (small strain, incremental, homogeneous isotropic ice)
  Layers. The front positions a_0 = R > a_1 > ... > a_n are the steps; at step k the layer
  a_{k+1} < r < a_k freezes (the radial resolution of the shell is the step size). Its
  thickness is ds = ds_0 + eps min(s, a), s = R - a: 0.04 um at the surface, growing
  geometrically by eps = 0.4 % (and refining again as the cavity closes).
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
  Incremental equilibrium, any shell a < r < R with layer-wise constant eigenstrain
  increments (e_r, e_t) [thermal: e_r = e_t = alpha dT; creep: deviatoric]:
    d(sigma_rr)/dr + 2 (sigma_rr - sigma_tt)/r = 0,  sigma_rr(a) = -dp,  sigma_rr(R) = 0,
    Hooke: eps_rr = (sigma_rr - 2 nu sigma_tt)/E + e_r,  eps_tt = ((1-nu) sigma_tt - nu sigma_rr)/E + e_t,
    compatibility eps_rr = d(r eps_tt)/dr.
  Eliminating sigma_tt = sigma_rr + (r/2) sigma_rr' gives (r^4 sigma_rr')' = K r^2 ((e_r - e_t)
  - r e_t'), K = 2E/(1-nu). Integrated twice (by parts, so jumps of e_t between layers are
  exact), with P(r) = int_a^r (e_r + 2 e_t) rho^2 drho, W(r) = int_a^r (e_r - e_t)/rho drho:
    sigma_rr(r) = -dp + K (W(r)/3 - P(r)/(3 r^3)) + (D/3)(1/a^3 - 1/r^3)
    sigma_tt(r) = sigma_rr(r) + (K/2)(P(r)/r^3 - e_t(r)) + D/(2 r^3)
    u(a)        = a (-(1 - 2 nu) dp + (1 - nu) D/(2 a^3))/E
  with D fixed by sigma_rr(R) = 0. This is exact for layer-wise constant eigenstrains (P and W
  are sums of exact layer integrals), so the pressure part reproduces Lame's thick sphere
    sigma_rr = -dp a^3 (R^3/r^3 - 1)/(R^3 - a^3),  sigma_tt = dp a^3 (1 + R^3/(2 r^3))/(R^3 - a^3),
    u(a) = dp a ((1 - 2 nu) a^3 + (1 + nu) R^3/2)/(E (R^3 - a^3))
  to rounding, and isotropic eigenstrain gives Timoshenko & Goodier's thermal stresses in a
  sphere. The only discretisation errors are the step size (births and increments at discrete
  fronts) and the layer-wise constant thermal/creep strains.
  Thermal strain (cases 2, 3): eigenstrain alpha (T - T_m) per layer, T at the layer's middle
  from the heat solution (linear interpolation in xi); its change over a step is the step's
  isotropic eigenstrain increment. The water stays at T_m (no thermal strain).
  Glen creep (case 3, on top of case 2): eps_dot = A(T) tau_e^(n-1) tau, tau the stress
  deviator, tau_e^2 = tau:tau/2, n = 3. In spherical symmetry, with Delta = sigma_rr - sigma_tt:
  tau_rr = 2 Delta/3, tau_tt = -Delta/3, tau_e = |Delta|/sqrt(3), so per layer
    e_r = (2/3) A tau_e^2 Delta dt,  e_t = -(1/3) A tau_e^2 Delta dt
  (rates averaged over the layer's two edges). A(T) = 3.5e-25 exp(-Q/R_g (1/T - 1/263.15))
  Pa^-3 s^-1, T in K, Q = 115 kJ/mol above -10 degC and 60 kJ/mol below (A(0 degC) = 2.4e-24),
  R_g = 8.314 J/(mol K). Explicit (forward Euler) sub-steps within a step, each no longer than
  c_cfl/lambda_max, lambda = 2 mu n A tau_e^(n-1) (the linearised relaxation rate of Delta),
  c_cfl = 0.2; the step's expansion and thermal increments are split over its sub-steps in
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
  - Convergence: every result again with the mechanical step (= layer) halved (ds_0 and eps
    halved), N_xi doubled, the ODE tolerance divided by 10 and c_cfl halved.

Run time about a minute on 2 cores. Needs numpy and scipy; --plot needs matplotlib.
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
    ds0: float = 4e-8        # thickness of the first layer (m)
    eps: float = 4e-3        # geometric growth of the layer thickness
    n_xi: int = 40           # finite-difference intervals across the shell (even)
    heat_rtol: float = 1e-8
    c_cfl: float = 0.2       # creep sub-step: dt <= c_cfl / lambda_max
    f_end: float = 0.99

    @property
    def mu(self):
        return self.E / (2.0 * (1.0 + self.nu))

    def halved(self):
        """Every resolution parameter halved (the convergence run)."""
        return replace(self, ds0=self.ds0 / 2, eps=self.eps / 2, n_xi=2 * self.n_xi,
                       heat_rtol=self.heat_rtol / 10, c_cfl=self.c_cfl / 2)


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

    def rhs(a, y):
        s = P.R - a
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
        out[:n] = dth_dt / adot
        out[n] = 1.0 / adot
        out[n + 1] = FOUR_PI * P.R ** 2 * P.h * (th[n] - P.Ta) / adot
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
    sol = solve_ivp(rhs, (a0, a_eval[-1]), y0, method="BDF", t_eval=a_eval,
                    rtol=P.heat_rtol, atol=np.concatenate([np.full(n, 1e-9), [1e-9, 1e-9]]),
                    jac_sparsity=sparsity, first_step=1e-3 * (P.R - a0))
    if not sol.success:
        raise RuntimeError("heat solve failed: " + sol.message)
    theta = np.hstack([np.full((len(a_eval), 1), P.Tm), sol.y[:n].T])
    t = sol.y[n]
    Q = sol.y[n + 1]
    latent = P.rho * P.L * FOUR_PI / 3.0 * diff_cubes(P.R, a_eval)
    sens = np.array([sensible_heat(a, th, P) for a, th in zip(a_eval, theta)])
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


def shell_response(rn, er, et, dp, E, nu):
    """Stresses of the shell rn[0] = a < r < rn[-1] = R (nodes increasing) under an inner
    pressure increment dp and layer-wise constant eigenstrain increments er, et (one per
    layer rn[i] < r < rn[i+1]; None for none). Exact for that data (see the docstring).

    Returns sigma_rr at the nodes, sigma_tt at each layer's inner and outer edge, u(a)."""
    a, R = rn[0], rn[-1]
    K = 2.0 * E / (1.0 - nu)
    r3 = rn ** 3
    inv = diff_cubes(rn, a) / (a ** 3 * r3)            # 1/a^3 - 1/r^3
    if er is None:
        Pn = np.zeros_like(rn)
        Wn = np.zeros_like(rn)
        et = 0.0
    else:
        Pn = np.concatenate([[0.0], np.cumsum((er + 2.0 * et) * diff_cubes(rn[1:], rn[:-1]) / 3.0)])
        Wn = np.concatenate([[0.0], np.cumsum((er - et) * np.log1p((rn[1:] - rn[:-1]) / rn[:-1]))])
    D3 = (dp - K * (Wn[-1] / 3.0 - Pn[-1] / (3.0 * r3[-1]))) / inv[-1]   # D/3
    srr = -dp + K * (Wn / 3.0 - Pn / (3.0 * r3)) + D3 * inv
    base = srr + 0.5 * K * Pn / r3 + 1.5 * D3 / r3
    stt_in = base[:-1] - 0.5 * K * et
    stt_out = base[1:] - 0.5 * K * et
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
    """Incremental layered shell; heat = solve_heat on a[1:] (a[0] = R: no shell yet).

    Returns the history per step (after step k: front a[k+1]) and the final state."""
    a = np.concatenate([[P.R], heat["a"]])
    t = np.concatenate([[0.0], heat["t"]])
    n = len(a) - 1
    E, nu, mu, Kw = P.E, P.nu, P.mu, P.Kw
    xi = np.linspace(0.0, 1.0, P.n_xi + 1)
    mid = 0.5 * (a[:-1] + a[1:])          # layer k's middle, layer k = a[k+1] < r < a[k]
    # per layer (birth order = outermost first): stress at inner/outer edge
    srr_in = np.zeros(n); srr_out = np.zeros(n)
    stt_in = np.zeros(n); stt_out = np.zeros(n)
    T_lay = np.zeros(n)                   # temperature the layer's eigenstrain refers to
    hist = {k: np.zeros(n) for k in ("f", "t", "s", "p", "stt_R", "smax", "smax_depth",
                                      "dV_water", "dV_shell")}
    p = 0.0
    n_sub_total = 0
    for k in range(n):
        # 1. birth of layer k at the water's pressure, at T_m
        srr_in[k] = srr_out[k] = stt_in[k] = stt_out[k] = -p
        T_lay[k] = P.Tm
        nl = k + 1
        rn = a[k + 1::-1]                 # nodes, increasing r: a_{k+1}, a_k, ..., a_0 = R
        an = a[k + 1]
        # unit-pressure response of the current shell (Lame)
        u_srr, u_sin, u_sout, u1 = shell_response(rn, None, None, 1.0, E, nu)
        comp = FOUR_PI * an * an * u1 + FOUR_PI / 3.0 * an ** 3 / Kw     # d(volume)/dp
        dV_ex = P.beta * FOUR_PI / 3.0 * diff_cubes(a[k], an)
        # 2. thermal eigenstrain increment over the step (layer order: increasing r)
        if thermal:
            T_new = np.interp((mid[:nl] - an) / (P.R - an), xi, heat["theta"][k])
            de_th = P.alpha * (T_new - T_lay[:nl])
            T_lay[:nl] = T_new
        else:
            de_th = np.zeros(nl)
        de_th_r = de_th[::-1]
        dt = t[k + 1] - t[k]
        done = 0.0
        dVw = dVs = 0.0
        while done < 1.0:
            # 3. sub-step: creep strain increment (explicit) and its share of the step
            if creep:
                T_r = T_lay[:nl]
                A = rate_factor(T_r)
                d_in = srr_in[:nl] - stt_in[:nl]
                d_out = srr_out[:nl] - stt_out[:nl]
                g_in = A * d_in ** 2 / 3.0          # A tau_e^2, tau_e^2 = Delta^2/3 (n = 3)
                g_out = A * d_out ** 2 / 3.0
                lam = 2.0 * mu * P.glen_n * max(g_in.max(), g_out.max())
                frac = 1.0 - done
                if lam * dt * frac > P.c_cfl:
                    frac = P.c_cfl / (lam * dt)
                    if done + frac > 1.0 - 1e-12:
                        frac = 1.0 - done
                rate = 0.5 * (g_in * d_in + g_out * d_out)   # A tau_e^2 Delta, layer average
                dcr = rate[::-1] * dt * frac
                er = frac * de_th_r + (2.0 / 3.0) * dcr
                et = frac * de_th_r - (1.0 / 3.0) * dcr
                eig = True
            else:
                frac = 1.0
                er = et = de_th_r
                eig = thermal
            if eig:
                e_srr, e_sin, e_sout, ue = shell_response(rn, er, et, 0.0, E, nu)
            else:
                e_srr = np.zeros(nl + 1); e_sin = e_sout = np.zeros(nl); ue = 0.0
            # 4. cavity volume balance gives the pressure increment
            dp = (frac * dV_ex - FOUR_PI * an * an * ue) / comp
            p += dp
            dVw += dp * FOUR_PI / 3.0 * an ** 3 / Kw
            dVs += FOUR_PI * an * an * (ue + dp * u1)
            # 5. stress increments (arrays in increasing r -> birth order by reversing)
            srr_in[:nl] += (e_srr[:-1] + dp * u_srr[:-1])[::-1]
            srr_out[:nl] += (e_srr[1:] + dp * u_srr[1:])[::-1]
            stt_in[:nl] += (e_sin + dp * u_sin)[::-1]
            stt_out[:nl] += (e_sout + dp * u_sout)[::-1]
            done += frac
            n_sub_total += 1
        # 6. record
        tens = np.maximum(np.maximum(stt_in[:nl], stt_out[:nl]),
                          np.maximum(srr_in[:nl], srr_out[:nl]))
        i_in = np.argmax(np.maximum(stt_in[:nl], srr_in[:nl]))
        i_out = np.argmax(np.maximum(stt_out[:nl], srr_out[:nl]))
        if max(stt_in[i_in], srr_in[i_in]) > max(stt_out[i_out], srr_out[i_out]):
            r_max = a[i_in + 1]
        else:
            r_max = a[i_out]
        hist["f"][k] = 1.0 - (an / P.R) ** 3
        hist["t"][k] = t[k + 1]
        hist["s"][k] = P.R - an
        hist["p"][k] = p
        hist["stt_R"][k] = stt_out[0]
        hist["smax"][k] = tens.max()
        hist["smax_depth"][k] = P.R - r_max
        hist["dV_water"][k] = dVw
        hist["dV_shell"][k] = dVs
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
        srr, sin_, sout, ua = shell_response(rn, None, None, 1.0, P.E, P.nu)
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
    rm = 0.5 * (rn[1:] + rn[:-1])
    e_layer = P.alpha * (A_ + B_ / rm)      # layer-wise constant (midpoint)
    srr, sin_, sout, _ = shell_response(rn, e_layer, e_layer, 0.0, P.E, P.nu)

    def integral(r):                        # int_a^r alpha T rho^2 drho
        return P.alpha * (A_ * (r ** 3 - a ** 3) / 3.0 + B_ * (r ** 2 - a ** 2) / 2.0)

    Ib = integral(R)
    c = P.E / (1.0 - P.nu)
    c_rr = 2.0 * c * ((rn ** 3 - a ** 3) / ((R ** 3 - a ** 3) * rn ** 3) * Ib - integral(rn) / rn ** 3)
    c_tt = c * ((2.0 * rn ** 3 + a ** 3) / ((R ** 3 - a ** 3) * rn ** 3) * Ib + integral(rn) / rn ** 3
                - P.alpha * (A_ + B_ / rn))
    scale = np.abs(c_tt).max()
    err_rr = np.abs(srr - c_rr).max() / scale
    # sigma_tt: compare at nodes using the mean of the two adjacent layer edges
    stt_nodes = np.concatenate([[sin_[0]], 0.5 * (sout[:-1] + sin_[1:]), [sout[-1]]])
    err_tt = np.abs(stt_nodes - c_tt).max() / scale
    return max(err_rr, err_tt), scale


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
    rm = 0.5 * (rn[1:] + rn[:-1])
    srr, sin_, sout, ua = shell_response(rn, e_r(rm), e_t(rm), p, P.E, P.nu)
    y = sol.sol(rn)
    c_rr = sig_rr(rn, y[0], y[1])
    c_tt = sig_tt(rn, y[0], y[1])
    stt_nodes = np.concatenate([[sin_[0]], 0.5 * (sout[:-1] + sin_[1:]), [sout[-1]]])
    scale = np.abs(c_tt).max()
    err = max(np.abs(srr - c_rr).max(), np.abs(stt_nodes - c_tt).max()) / scale
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
    results = {"P": P, "heat": heat, "n_steps": len(a) - 1, "t_heat": t_heat, "cases": {}}
    for name, thermal, creep in CASES:
        if creep and not with_creep:
            continue
        t1 = time.perf_counter()
        hist, final = run_mechanics(P, heat, thermal=thermal, creep=creep)
        results["cases"][name] = {"hist": hist, "final": final,
                                  "wall": time.perf_counter() - t1,
                                  "cross": {lvl: crossing(hist, lvl) for lvl in THRESHOLDS}}
    return results


def fmt(x, d=3):
    if x is None:
        return "—"
    return f"{x:.{d}g}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--markdown", type=Path, help="write the report here")
    parser.add_argument("--plot", type=Path, help="write a figure (png, needs matplotlib)")
    parser.add_argument("--f-end", type=float, default=Params.f_end,
                        help="frozen fraction at which the run stops (default %(default)s)")
    parser.add_argument("--no-creep", action="store_true", help="skip case 3 (Glen creep)")
    args = parser.parse_args()
    wall0 = time.perf_counter()
    P = Params(f_end=args.f_end)
    with_creep = not args.no_creep

    base = run_all(P, with_creep)
    fine = run_all(P.halved(), with_creep)
    # ... (report assembled below)
    print("done", time.perf_counter() - wall0)


if __name__ == "__main__":
    sys.exit(main())
