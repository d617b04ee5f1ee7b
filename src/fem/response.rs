//! The solid's stress response to an elastic strain: Hooke's law, and with an elastic limit
//! the incremental potential of the return mapping with a smoothed yield.

use super::material::Material;
use nalgebra::Matrix3;

/// The solid's response to an elastic strain ε (trial strain, with the plastic strain of the
/// start of the step): energy density, stress, and what the tangent needs.
#[derive(Clone, Copy, Debug)]
pub struct SolidResponse {
    /// Energy density Ψ (J/m³).
    pub psi: f64,
    /// Stress σ (Pa), on or inside the yield surface.
    pub sigma: Matrix3<f64>,
    /// Shear modulus acting on deviatoric strain (Pa): μ, or μ γφ/‖ε'‖ while yielding.
    pub mu: f64,
    /// The matching first Lamé constant K − 2μ_eff/3 (Pa).
    pub lambda: f64,
    /// Stiffness the flow direction n = ε'/‖ε'‖ loses while yielding (Pa):
    /// 2 (μ_eff − μ φ′), 0 while elastic. The tangent is C_eff − flow_drop n⊗n.
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

/// The solid's response to the elastic strain `eps` (the return mapping of O'Brien et al.
/// 2002, the paper's eqs. (3)–(5), as an incremental potential; see
/// docs/numerics.md#plasticity). Elastic: σ = C:ε, Ψ = ½ σ:ε. With an elastic limit γ and a
/// deviator ε' whose norm r = ‖ε'‖ exceeds it, the return mapping Δε_p = (r − γ)/r ε' leaves
/// the deviator at γ ε'/r; that is the minimiser over Δε_p of the elastic energy plus the
/// plastic dissipation 2μγ ‖Δε_p‖, and the minimum is the convex
///
/// ```text
/// Ψ = K/2 tr(ε)² + μ γ (2r − γ),   σ = K tr(ε) I + 2μγ ε'/r,
/// ```
///
/// so Newton minimises it like an elastic energy, its converged stress is the returned one
/// (‖σ'‖ = 2μγ: von Mises = √(3/2)·2μγ), and its Hessian is the consistent tangent
/// K 1⊗1 + 2μγ/r (I_dev − n⊗n), n = ε'/r. Within δγ of the limit the deviatoric stress is
/// 2μγφ(r/γ) n ([`deviatoric_stress_norm`]), whose energy is μr² − μγ²y³/(6δ) with y = r/γ − 1 + δ.
#[inline]
pub fn solid_response(
    mat: &Material,
    yield_limit: Option<f64>,
    eps: &Matrix3<f64>,
) -> SolidResponse {
    if let Some(gamma) = yield_limit {
        let tr = eps.trace();
        let dev = eps - Matrix3::identity() * (tr / 3.0);
        let r = dev.norm();
        let d = YIELD_SMOOTHING;
        if r > (1.0 - d) * gamma {
            let k = mat.bulk();
            let (kept, slope) = deviatoric_stress_norm(r, gamma);
            let mu = mat.mu * kept / r;
            let x = r / gamma;
            let deviatoric = if x >= 1.0 + d {
                let at_end = (1.0 + d) * (1.0 + d) - 4.0 * d * d / 3.0;
                mat.mu * gamma * gamma * at_end + 2.0 * mat.mu * gamma * (r - gamma * (1.0 + d))
            } else {
                let y = x - (1.0 - d);
                mat.mu * r * r - mat.mu * gamma * gamma * y * y * y / (6.0 * d)
            };
            return SolidResponse {
                psi: 0.5 * k * tr * tr + deviatoric,
                sigma: Matrix3::identity() * (k * tr) + 2.0 * mu * dev,
                mu,
                lambda: k - 2.0 * mu / 3.0,
                flow_drop: 2.0 * (mu - mat.mu * slope),
            };
        }
    }
    let sigma = mat.hooke(eps);
    SolidResponse {
        psi: 0.5 * sigma.dot(eps),
        sigma,
        mu: mat.mu,
        lambda: mat.lambda,
        flow_drop: 0.0,
    }
}
