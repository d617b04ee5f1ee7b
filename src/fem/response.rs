//! The solid's stress response to an elastic strain: Hooke's law, and with a flow rule the
//! incremental potential of its return mapping: perfect plasticity with a smoothed yield, or
//! Glen's creep over one step.

use super::material::Material;
use nalgebra::Matrix3;

/// How an element's deviatoric strain flows within a step (the element's inelastic strain
/// takes what flows; see [`solid_response`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Flow {
    /// Perfect plasticity with elastic limit γ (dimensionless): ‖ε'‖ of the elastic strain
    /// stays at or below γ.
    Yield(f64),
    /// Power-law creep over one step of length h, integrated by backward Euler: the inelastic
    /// strain grows by x n with x = `compliance` ‖σ'‖ⁿ at the step's end stress, where
    /// `compliance` = h B (Pa⁻ⁿ), B the rate factor in Frobenius norms (‖ε̇_c‖ = B ‖σ'‖ⁿ),
    /// and n = `exponent`.
    Creep {
        /// h B (Pa⁻ⁿ).
        compliance: f64,
        /// Stress exponent n (dimensionless, ≥ 1).
        exponent: f64,
    },
}

/// The solid's response to an elastic strain ε (trial strain, with the plastic strain of the
/// start of the step): energy density, stress, and what the tangent needs.
#[derive(Clone, Copy, Debug)]
pub struct SolidResponse {
    /// Energy density Ψ (J/m³).
    pub psi: f64,
    /// Stress σ (Pa), on or inside the yield surface.
    pub sigma: Matrix3<f64>,
    /// Shear modulus acting on deviatoric strain (Pa): μ, or S/(2‖ε'‖) while flowing
    /// (μ γφ/‖ε'‖ while yielding).
    pub mu: f64,
    /// The matching first Lamé constant K − 2μ_eff/3 (Pa).
    pub lambda: f64,
    /// Stiffness the flow direction n = ε'/‖ε'‖ loses while flowing (Pa): 2μ_eff − dS/dr
    /// (2 (μ_eff − μ φ′) while yielding), 0 while elastic. The tangent is
    /// C_eff − flow_drop n⊗n.
    pub flow_drop: f64,
}

/// Width δ of the yield transition relative to the elastic limit γ: the deviatoric response
/// is elastic up to ‖ε'‖ = (1 − δ) γ, perfectly plastic from (1 + δ) γ, and blends between
/// with a continuous tangent.
///
/// The return mapping's energy (below) is only once differentiable at ‖ε'‖ = γ: its tangent
/// jumps from 2μ to 0 along the flow direction, and Newton then cycles between the two sides
/// for elements near the limit (up to 269 iterations in a step of the paper's scene). The
/// blend keeps the stress at or below the yield stress everywhere (it reaches it at
/// (1 + δ) γ), so flowing elements are on the yield surface exactly. The blend is reversible
/// (a softening of the elastic response); plastic strain is the excess beyond (1 + δ) γ
/// (`physics::plasticity`), so the law at an updated state gives the converged stress again.
pub const YIELD_SMOOTHING: f64 = 0.1;

/// The deviatoric stress, as γ φ(r/γ) = ‖σ'‖/2μ, of a deviatoric elastic strain norm `r`
/// with elastic limit `gamma`, and φ′: r below (1 − δ)γ, γ from (1 + δ)γ, and
/// φ(x) = x − (x − 1 + δ)²/(4δ) between (see [`YIELD_SMOOTHING`]).
#[inline]
pub fn deviatoric_stress_norm(r: f64, gamma: f64) -> (f64, f64) {
    let d = YIELD_SMOOTHING;
    let x = r / gamma;
    if x <= 1.0 - d {
        (r, 1.0)
    } else if x >= 1.0 + d {
        (gamma, 0.0)
    } else {
        let y = x - (1.0 - d);
        (gamma * (x - y * y / (4.0 * d)), 1.0 - y / (2.0 * d))
    }
}

/// The deviatoric stress norm S = ‖σ'‖ (Pa) after a creep step of an element whose trial
/// deviatoric elastic strain norm is `r`, for shear modulus `mu`, and dS/dr: the root of
/// S/(2μ) + c Sⁿ = r (the elastic strain left is S/2μ, the rest, c Sⁿ, crept), with
/// c = `compliance` and n = `exponent`.
///
/// The left side is convex and increasing in S, and both 2μr and (r/c)^{1/n} bound the root
/// from above, so Newton from the smaller of them decreases monotonically to it.
#[inline]
pub fn creep_stress_norm(r: f64, mu: f64, compliance: f64, exponent: f64) -> (f64, f64) {
    let two_mu = 2.0 * mu;
    let mut s = (two_mu * r).min((r / compliance).powf(1.0 / exponent));
    for _ in 0..100 {
        let crept = compliance * s.powf(exponent);
        let f = s / two_mu + crept - r;
        if f <= 0.0 {
            break;
        }
        let slope = 1.0 / two_mu + exponent * crept / s;
        let next = s - f / slope;
        // Monotone from above: a step that no longer decreases S is round-off (NaN included).
        if next.is_nan() || next >= s || s - next <= 1e-15 * s {
            s = next.min(s);
            break;
        }
        s = next;
    }
    let crept_slope = exponent * compliance * s.powf(exponent - 1.0);
    (s, two_mu / (1.0 + two_mu * crept_slope))
}

/// The solid's response to the elastic strain `eps` with the flow rule `flow`, if any: Hooke's
/// law σ = C:ε, Ψ = ½ σ:ε, or, with a flow rule, the incremental potential of its return
/// mapping (see docs/numerics.md#plasticity and docs/ice.md#creep), a convex energy whose
/// stress is the returned one and whose Hessian is the consistent tangent. Only the deviator
/// ε' (norm r = ‖ε'‖, direction n = ε'/r) flows; σ' = S n with S a function of r alone, so
/// the tangent is K 1⊗1 + (S/r) (I_dev − n⊗n) + (dS/dr) n⊗n.
///
/// - [`Flow::Yield`] (O'Brien et al. 2002, the paper's eqs. (3)–(5)): with an elastic limit γ
///   and r above it, the return mapping Δε_p = (r − γ)/r ε' leaves the deviator at γ ε'/r;
///   that is the minimiser over Δε_p of the elastic energy plus the plastic dissipation
///   2μγ ‖Δε_p‖, and the minimum is Ψ = K/2 tr(ε)² + μ γ (2r − γ), σ = K tr(ε) I + 2μγ ε'/r
///   (‖σ'‖ = 2μγ: von Mises = √(3/2)·2μγ). Within δγ of the limit the deviatoric stress is
///   2μγφ(r/γ) n ([`deviatoric_stress_norm`]), whose energy is μr² − μγ²y³/(6δ) with
///   y = r/γ − 1 + δ.
/// - [`Flow::Creep`] (Glen's law over one step by backward Euler): the crept strain x along n
///   minimises μ(r − x)² + n/(n+1) x S(x) with S(x) = (x/c)^{1/n}, whose stationarity is
///   2μ(r − x) = S: the stress the creep rate of the step's end belongs to. The minimum is
///   Ψ = K/2 tr(ε)² + S²/(4μ) + n/(n+1) c S^{n+1} with S from [`creep_stress_norm`].
#[inline]
pub fn solid_response(mat: &Material, flow: Option<Flow>, eps: &Matrix3<f64>) -> SolidResponse {
    let tr = eps.trace();
    let dev = eps - Matrix3::identity() * (tr / 3.0);
    let r = dev.norm();
    let deviatoric = match flow {
        Some(Flow::Yield(gamma)) if r > (1.0 - YIELD_SMOOTHING) * gamma => {
            let d = YIELD_SMOOTHING;
            let (kept, slope) = deviatoric_stress_norm(r, gamma);
            let x = r / gamma;
            let psi = if x >= 1.0 + d {
                let at_end = (1.0 + d) * (1.0 + d) - 4.0 * d * d / 3.0;
                mat.mu * gamma * gamma * at_end + 2.0 * mat.mu * gamma * (r - gamma * (1.0 + d))
            } else {
                let y = x - (1.0 - d);
                mat.mu * r * r - mat.mu * gamma * gamma * y * y * y / (6.0 * d)
            };
            let mu = mat.mu * kept / r;
            Some((psi, mu, 2.0 * (mu - mat.mu * slope)))
        }
        Some(Flow::Creep {
            compliance,
            exponent,
        }) if r > 0.0 && compliance > 0.0 && mat.mu > 0.0 => {
            let (s, slope) = creep_stress_norm(r, mat.mu, compliance, exponent);
            let psi = s * s / (4.0 * mat.mu)
                + exponent / (exponent + 1.0) * compliance * s.powf(exponent + 1.0);
            let mu = 0.5 * s / r;
            Some((psi, mu, 2.0 * mu - slope))
        }
        _ => None,
    };
    match deviatoric {
        Some((psi, mu, flow_drop)) => {
            let k = mat.bulk();
            SolidResponse {
                psi: 0.5 * k * tr * tr + psi,
                sigma: Matrix3::identity() * (k * tr) + 2.0 * mu * dev,
                mu,
                lambda: k - 2.0 * mu / 3.0,
                flow_drop,
            }
        }
        None => {
            let sigma = mat.hooke(eps);
            SolidResponse {
                psi: 0.5 * sigma.dot(eps),
                sigma,
                mu: mat.mu,
                lambda: mat.lambda,
                flow_drop: 0.0,
            }
        }
    }
}
