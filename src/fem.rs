//! Linear-tetrahedron kinematics and constitutive laws: rest data, deformation gradient,
//! Hooke's law for the `linear` (small-strain) and `corotated` models, element energy,
//! gradient and stiffness.
//!
//! Conventions: `F = Ds · Dm⁻¹` with `Ds = [x1 − x0, x2 − x0, x3 − x0]`; `vec(F)` is column
//! major (entry `F[a][k]` at `a + 3k`); energies in J, forces in N, stiffness in N/m.
#![allow(non_snake_case)]

use crate::mesh::TetMesh;
use nalgebra::{Matrix3, SMatrix, Vector3};

/// 9 × 9 matrix: derivative of `vec(P)` with respect to `vec(F)`.
pub type Tangent = SMatrix<f64, 9, 9>;

/// Isotropic linear-elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    /// First Lamé constant λ (Pa).
    pub lambda: f64,
    /// Shear modulus μ (Pa).
    pub mu: f64,
    /// Density ρ (kg/m³).
    pub density: f64,
}

impl Material {
    /// Lamé constants from Young's modulus E (Pa) and Poisson's ratio ν (−1 < ν < 0.5).
    pub fn from_young_poisson(e: f64, nu: f64, density: f64) -> Self {
        Material {
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: e / (2.0 * (1.0 + nu)),
            density,
        }
    }
    /// Young's modulus E (Pa).
    pub fn young(&self) -> f64 {
        self.mu * (3.0 * self.lambda + 2.0 * self.mu) / (self.lambda + self.mu)
    }
    /// Poisson's ratio ν.
    pub fn poisson(&self) -> f64 {
        self.lambda / (2.0 * (self.lambda + self.mu))
    }
    /// Bulk modulus K = λ + 2μ/3 (Pa).
    pub fn bulk(&self) -> f64 {
        self.lambda + 2.0 * self.mu / 3.0
    }
    /// P-wave speed √((λ + 2μ)/ρ) (m/s).
    pub fn p_wave_speed(&self) -> f64 {
        ((self.lambda + 2.0 * self.mu) / self.density).sqrt()
    }
    /// Hooke's law σ = 2με + λ tr(ε) I (Pa) for a symmetric strain ε.
    pub fn hooke(&self, eps: &Matrix3<f64>) -> Matrix3<f64> {
        2.0 * self.mu * eps + Matrix3::identity() * (self.lambda * eps.trace())
    }
}

/// Which strain measure the elastic energy uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ElasticModel {
    /// Small strain ε = sym(F) − I: linear, exact for small displacements, but a rigid rotation
    /// produces spurious strain and forces.
    Linear,
    /// Corotated: F = R S (polar decomposition), ε = S − I. Rotation invariant.
    Corotated,
}

/// The constitutive law of one element: its strain measure, the solid's material (scaled ice
/// while it freezes), the bulk modulus of its water part and, if it can yield, its elastic
/// limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Law {
    /// Strain measure.
    pub model: ElasticModel,
    /// The solid's Lamé constants (Pa) and density (kg/m³).
    pub material: Material,
    /// Bulk modulus of the element's water part (Pa; 0 for none).
    pub water_bulk: f64,
    /// Elastic limit γ (dimensionless) if the element yields (see [`solid_response`]).
    pub yield_limit: Option<f64>,
}

impl Law {
    /// An elastic solid of `material` without water.
    pub fn elastic(model: ElasticModel, material: Material) -> Self {
        Law {
            model,
            material,
            water_bulk: 0.0,
            yield_limit: None,
        }
    }
}

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

/// The solid's response to the elastic strain `eps` (SPEC eq. 3–5 as an incremental
/// potential). Elastic: σ = C:ε, Ψ = ½ σ:ε. With an elastic limit γ and a deviator ε' whose
/// norm r = ‖ε'‖ exceeds it, the return mapping Δε_p = (r − γ)/r ε' leaves the deviator at
/// γ ε'/r; that is the minimiser over Δε_p of the elastic energy plus the plastic dissipation
/// 2μγ ‖Δε_p‖, and the minimum is the convex
///
/// ```text
/// Ψ = K/2 tr(ε)² + μ γ (2r − γ),   σ = K tr(ε) I + 2μγ ε'/r,
/// ```
///
/// so Newton minimises it like an elastic energy, its converged stress is the returned one
/// (‖σ'‖ = 2μγ: von Mises = √(3/2)·2μγ), and its Hessian is the consistent tangent
/// K 1⊗1 + 2μγ/r (I_dev − n⊗n), n = ε'/r. Within δγ of the limit the deviatoric stress is
/// 2μγφ(r/γ) n ([`deviatoric_stress_norm`]), whose energy is μr² − μγ²y³/(6δ) with y = r/γ − 1 + δ.
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

/// Rest data of one tet.
#[derive(Clone, Copy, Debug)]
pub struct ElementRest {
    /// Rest volume (m³).
    pub volume: f64,
    /// Gradients of the four shape functions in the rest configuration (1/m).
    pub grads: [Vector3<f64>; 4],
}

impl ElementRest {
    /// Rest data of every tet of `mesh`.
    pub fn of_mesh(mesh: &TetMesh) -> Vec<ElementRest> {
        mesh.tets
            .iter()
            .map(|tet| {
                let Dm = TetMesh::edge_matrix(&mesh.rest, tet);
                // The mesh constructor rejected degenerate tets, so Dm is invertible.
                let inv = Dm.try_inverse().unwrap_or_else(Matrix3::zeros);
                let g1: Vector3<f64> = inv.row(0).transpose();
                let g2: Vector3<f64> = inv.row(1).transpose();
                let g3: Vector3<f64> = inv.row(2).transpose();
                ElementRest {
                    volume: Dm.determinant() / 6.0,
                    grads: [-(g1 + g2 + g3), g1, g2, g3],
                }
            })
            .collect()
    }

    /// Displacement gradient H = ∇u = Σᵢ uᵢ ⊗ ∇Nᵢ = F − I for the element's vertex
    /// displacements (m). Working with H rather than F keeps small strains accurate to round-off
    /// of the strain itself instead of round-off of the positions.
    pub fn displacement_gradient(&self, u: &[Vector3<f64>; 4]) -> Matrix3<f64> {
        u.iter()
            .zip(&self.grads)
            .map(|(ui, gi)| ui * gi.transpose())
            .sum()
    }
}

/// Energy, gradient and (optionally) stiffness of one element.
#[derive(Clone, Debug)]
pub struct ElementEval {
    /// Elastic energy (J).
    pub energy: f64,
    /// dE/dx for the 12 vertex coordinates (N); the elastic force is its negative.
    pub gradient: [f64; 12],
    /// d²E/dx², row-major 12 × 12 (N/m), symmetric positive semi-definite.
    pub hessian: [f64; 144],
}

impl Default for ElementEval {
    fn default() -> Self {
        ElementEval {
            energy: 0.0,
            gradient: [0.0; 12],
            hessian: [0.0; 144],
        }
    }
}

/// Energy density Ψ (J/m³), first Piola–Kirchhoff stress P (Pa) and, if asked, the tangent
/// dP/dF for the elastic displacement gradient `He = Fe − I`.
/// The solid may yield with elastic limit `yield_limit` (see [`solid_response`]).
pub fn constitutive(
    model: ElasticModel,
    mat: &Material,
    yield_limit: Option<f64>,
    He: &Matrix3<f64>,
    tangent: Option<&mut Tangent>,
    project: bool,
) -> (f64, Matrix3<f64>) {
    match model {
        ElasticModel::Linear => {
            let eps = 0.5 * (He + He.transpose());
            let response = solid_response(mat, yield_limit, &eps);
            if let Some(t) = tangent {
                *t = linear_tangent(response.mu, response.lambda);
                if response.flow_drop != 0.0 {
                    // − flow_drop n⊗n with n = ε'/‖ε'‖ (symmetric, so n : dF = n : sym(dF)).
                    let dev = response.sigma - Matrix3::identity() * (response.sigma.trace() / 3.0);
                    let n = SMatrix::<f64, 9, 1>::from_column_slice(dev.normalize().as_slice());
                    *t -= response.flow_drop * n * n.transpose();
                }
            }
            (response.psi, response.sigma)
        }
        ElasticModel::Corotated => corotated(mat, yield_limit, He, tangent, project),
    }
}

/// dP/dF of the small-strain law with Lamé constants `lambda`, `mu` (Pa): C acting on sym(dF).
fn linear_tangent(mu: f64, lambda: f64) -> Tangent {
    let mut t = Tangent::zeros();
    for a in 0..3 {
        for k in 0..3 {
            let row = a + 3 * k;
            // 2μ sym(dF): μ (dF_ak + dF_ka)
            t[(row, a + 3 * k)] += mu;
            t[(row, k + 3 * a)] += mu;
            if a == k {
                for b in 0..3 {
                    t[(row, b + 3 * b)] += lambda;
                }
            }
        }
    }
    t
}

/// Signed SVD F = U diag(s) Vᵀ with det U = det V = +1; an inverted F gets a negative s[2].
pub fn signed_svd(F: &Matrix3<f64>) -> (Matrix3<f64>, Vector3<f64>, Matrix3<f64>) {
    let svd = F.svd(true, true);
    // Both factors were requested, so they are present.
    let mut U = svd.u.unwrap_or_else(Matrix3::identity);
    let mut Vt = svd.v_t.unwrap_or_else(Matrix3::identity);
    let mut s = svd.singular_values;
    // Put the smallest singular value last so that a sign flip lands on it.
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| s[j].total_cmp(&s[i]));
    let (U0, Vt0, s0) = (U, Vt, s);
    for (dst, &src) in order.iter().enumerate() {
        U.set_column(dst, &U0.column(src));
        Vt.set_row(dst, &Vt0.row(src));
        s[dst] = s0[src];
    }
    if U.determinant() < 0.0 {
        U.column_mut(2).neg_mut();
        s[2] = -s[2];
    }
    if Vt.determinant() < 0.0 {
        Vt.row_mut(2).neg_mut();
        s[2] = -s[2];
    }
    (U, s, Vt.transpose())
}

/// Corotated strain S − I = sym(Rᵀ F) − I for F = I + H, computed without cancellation:
/// sym(Rᵀ) − I + sym(Rᵀ H), where sym(R) − I = −(|w|² I − w wᵀ)/(1 + cos θ) with w the axial
/// vector of skew(R) (|w| = sin θ). Forming S from the singular values instead would leave an
/// absolute error of ~1e-16 in the strain, i.e. 1e-9 relative at the 1e-7 strains of ice under
/// gravity, and Newton could not reduce the residual below that.
fn corotated_strain(R: &Matrix3<f64>, H: &Matrix3<f64>) -> Matrix3<f64> {
    let cos_theta = 0.5 * (R.trace() - 1.0);
    let sym_r = if cos_theta > 0.0 {
        let w = Vector3::new(
            R[(2, 1)] - R[(1, 2)],
            R[(0, 2)] - R[(2, 0)],
            R[(1, 0)] - R[(0, 1)],
        ) * 0.5;
        -(Matrix3::identity() * w.norm_squared() - w * w.transpose()) / (1.0 + cos_theta)
    } else {
        0.5 * (R + R.transpose()) - Matrix3::identity()
    };
    let rh = R.transpose() * H;
    sym_r + 0.5 * (rh + rh.transpose())
}

/// Rotation R of the polar decomposition F = R S (the inversion-safe one: det R = +1): by
/// Newton's iteration R ← ½ (R + R⁻ᵀ) where it applies (det F ≥ 0.1), else from the signed
/// SVD.
pub fn polar_rotation(F: &Matrix3<f64>) -> Matrix3<f64> {
    polar_rotation_newton(F).unwrap_or_else(|| svd_rotation(F))
}

/// The rotation U Vᵀ of the signed SVD of F.
fn svd_rotation(F: &Matrix3<f64>) -> Matrix3<f64> {
    let (U, _, V) = signed_svd(F);
    U * V.transpose()
}

/// det F below which [`polar_rotation_newton`] leaves the rotation to the SVD: an inverted
/// element (det F ≤ 0) needs the signed SVD's rotation, and near inversion Newton's iteration
/// converges slowly.
const NEWTON_POLAR_MIN_DET: f64 = 0.1;

/// Newton's iterations after which [`polar_rotation_newton`] gives up: from the deformation
/// gradient of a strained element it converges quadratically (the error squares each time),
/// in 2 iterations at ice's strains of 1e-4, 4 at 1e-2, 5 at 0.2.
const NEWTON_POLAR_MAX_ITERATIONS: usize = 8;

/// The rotation of F = R S by Newton's iteration R ← ½ (R + R⁻ᵀ) from R = F (Higham 1986),
/// which converges to the orthogonal polar factor; `None` if det F < [`NEWTON_POLAR_MIN_DET`]
/// or it has not converged in [`NEWTON_POLAR_MAX_ITERATIONS`]. It stops once an update is
/// below 1e-8: the error of the updated iterate is about half the square of the update, 5e-17.
/// A tenth of the cost of the SVD (measured: 50–85 ns against 520 ns), for the energy and
/// gradient passes, which need R but not the singular vectors.
fn polar_rotation_newton(F: &Matrix3<f64>) -> Option<Matrix3<f64>> {
    let mut r = *F;
    for _ in 0..NEWTON_POLAR_MAX_ITERATIONS {
        // R⁻ᵀ = cof(R) / det R, the cofactor columns being cross products of R's columns.
        let c0 = r.column(1).cross(&r.column(2));
        let det = r.column(0).dot(&c0);
        // A NaN determinant gives up too.
        if det.is_nan() || det < NEWTON_POLAR_MIN_DET {
            return None;
        }
        let c1 = r.column(2).cross(&r.column(0));
        let c2 = r.column(0).cross(&r.column(1));
        let next = 0.5 * (r + Matrix3::from_columns(&[c0, c1, c2]) / det);
        let update = (next - r).amax();
        r = next;
        if update <= 1e-8 {
            return Some(r);
        }
    }
    None
}

/// Corotated energy Ψ = μ Σ(sᵢ − 1)² + λ/2 (Σsᵢ − 3)² in the signed singular values sᵢ of F,
/// i.e. ½ ε:C:ε with ε = S − I. Its tangent is exact; with `project` the rotational (twist)
/// eigenvalues (ψᵢ + ψⱼ)/(sᵢ + sⱼ) that compression makes negative are replaced by their
/// absolute value, which keeps every element stiffness positive semi-definite. Clamping them
/// at zero instead (Teran et al. 2005) leaves the twist modes without curvature: Newton then
/// over-steps along them, and the freezing container with fracture stalled at step 1030 that
/// way; with |·| (the absolute-eigenvalue projection) it runs its 2400 steps.
fn corotated(
    mat: &Material,
    yield_limit: Option<f64>,
    He: &Matrix3<f64>,
    tangent: Option<&mut Tangent>,

    project: bool,
) -> (f64, Matrix3<f64>) {
    let F = Matrix3::identity() + He;
    let newton_rotation = polar_rotation_newton(&F);
    let R = newton_rotation.unwrap_or_else(|| svd_rotation(&F));
    let strain = corotated_strain(&R, He);
    let response = solid_response(mat, yield_limit, &strain);
    // For this energy P = 2μ(F − R) + λ tr(S − I) R = R σ(S − I).
    let P = R * response.sigma;
    if let Some(t) = tangent {
        // Away from inversion (Newton's polar factor applied) the unprojected tangent needs
        // no singular vectors; projecting needs the twist eigenvalues one by one.
        if project || newton_rotation.is_none() || !corotated_tangent(&R, &strain, &response, t) {
            corotated_tangent_svd(&F, &response, project, t);
        }
    }
    (response.psi, P)
}

/// The corotated tangent dP/dF in the singular basis F = U diag(s) Vᵀ, written into `t`:
/// stretch modes 2μδᵢⱼ + λ − flow_drop fᵢfⱼ (f the unit flow direction), shear modes 2μ and
/// twist modes (ψᵢ + ψⱼ)/(sᵢ + sⱼ), made |·| with `project`.
fn corotated_tangent_svd(
    F: &Matrix3<f64>,
    response: &SolidResponse,
    project: bool,
    t: &mut Tangent,
) {
    let (mu, lambda) = (response.mu, response.lambda);
    let (U, s, V) = signed_svd(F);
    let tr = s.sum() - 3.0;
    let psi = s.map(|si| 2.0 * mu * (si - 1.0) + lambda * tr);
    // Yielding: the flow direction (deviator of the strain in singular values) loses
    // stiffness, − flow_drop n nᵀ.
    let flow = if response.flow_drop != 0.0 {
        s.map(|si| si - 1.0 - tr / 3.0).normalize()
    } else {
        Vector3::zeros()
    };
    t.fill(0.0);
    // Basis tensors D_ij = U e_i e_jᵀ Vᵀ, vectorised column-major.
    let basis = |i: usize, j: usize| -> SMatrix<f64, 9, 1> {
        let D = U.column(i) * V.column(j).transpose();
        SMatrix::<f64, 9, 1>::from_column_slice(D.as_slice())
    };
    let d = [basis(0, 0), basis(1, 1), basis(2, 2)];
    for i in 0..3 {
        for j in 0..3 {
            let h = 2.0 * mu * f64::from(i == j) - response.flow_drop * flow[i] * flow[j] + lambda;
            *t += h * d[i] * d[j].transpose();
        }
    }
    for (i, j) in [(0, 1), (0, 2), (1, 2)] {
        let (bij, bji) = (basis(i, j), basis(j, i));
        // Symmetric (shear) mode: (ψᵢ − ψⱼ)/(sᵢ − sⱼ) = 2μ_eff exactly for this energy.
        let flip = (bij + bji) * std::f64::consts::FRAC_1_SQRT_2;
        *t += 2.0 * mu * flip * flip.transpose();
        // Rotational mode; the denominator is guarded for elements inverted to s_i ≈ −s_j.
        let twist = (bij - bji) * std::f64::consts::FRAC_1_SQRT_2;
        let c2 = (psi[i] + psi[j]) / (s[i] + s[j]).max(1e-6);
        let c2 = if project { c2.abs() } else { c2 };
        *t += c2 * twist * twist.transpose();
    }
}

/// The unprojected corotated tangent of [`corotated_tangent_svd`] without the singular
/// vectors, from the polar factor R and the strain E = S − I of F = R S: for Z = Rᵀ dF,
///
/// ```text
/// dP = R (2μ sym Z + λ tr(Z) I − flow_drop N (N:Z) + [M w]ₓ),   w = axial(skew Z),
/// M = (tr(σ) I − σ)(tr(S) I − S)⁻¹,
/// ```
///
/// N = dev E/‖dev E‖. M has the eigenvalues (ψᵢ + ψⱼ)/(sᵢ + sⱼ) on S's eigenvectors, the
/// twist stiffnesses. Column by column (dF = eₐe_bᵀ), a sixth of the SVD's cost. Returns
/// false (and leaves `t`) if tr(S) I − S is too close to singular (an element near inversion).
fn corotated_tangent(
    R: &Matrix3<f64>,
    strain: &Matrix3<f64>,
    response: &SolidResponse,
    t: &mut Tangent,
) -> bool {
    let (mu, lambda) = (response.mu, response.lambda);
    let tr = strain.trace();
    let stretch_sum = Matrix3::identity() * (2.0 + tr) - strain;
    // Its eigenvalues sᵢ + sⱼ are ~2 for the strains ice survives.
    if stretch_sum.determinant() < 1e-6 {
        return false;
    }
    let Some(stretch_inv) = stretch_sum.try_inverse() else {
        return false;
    };
    let sigma = strain * (2.0 * mu) + Matrix3::identity() * (lambda * tr);
    let twist = (Matrix3::identity() * sigma.trace() - sigma) * stretch_inv;
    let twist = 0.5 * (twist + twist.transpose());
    let flow = if response.flow_drop != 0.0 {
        (strain - Matrix3::identity() * (tr / 3.0)).normalize()
    } else {
        Matrix3::zeros()
    };
    for b in 0..3 {
        for a in 0..3 {
            // Z = Rᵀ eₐ e_bᵀ: column b is row a of R.
            let mut Z = Matrix3::zeros();
            Z.set_column(b, &R.row(a).transpose());
            let w = Vector3::new(
                Z[(2, 1)] - Z[(1, 2)],
                Z[(0, 2)] - Z[(2, 0)],
                Z[(1, 0)] - Z[(0, 1)],
            ) * 0.5;
            let Y = (Z + Z.transpose()) * mu + Matrix3::identity() * (lambda * Z.trace())
                - flow * (response.flow_drop * flow.dot(&Z))
                + (twist * w).cross_matrix();
            let dP = R * Y;
            t.set_column(
                a + 3 * b,
                &SMatrix::<f64, 9, 1>::from_column_slice(dP.as_slice()),
            );
        }
    }
    true
}

/// Energy density, stress and (added into `tangent`) the tangent of unfrozen water with bulk
/// modulus `bulk` (Pa) and no shear stiffness, for the elastic displacement gradient `He`.
/// Linear: Ψ = K/2 tr(ε)². Corotated: Ψ = K/2 (J − 1)² with J = det Fe, the exact volume
/// ratio — a shear-free corotated law, K/2 (Σsᵢ − 3)², would let an element collapse to zero
/// volume at zero energy. With `project` the indefinite (J − 1) ∂²J term is left out.
fn water(
    model: ElasticModel,
    bulk: f64,
    He: &Matrix3<f64>,
    tangent: Option<&mut Tangent>,
    project: bool,
) -> (f64, Matrix3<f64>) {
    match model {
        ElasticModel::Linear => {
            let tr = He.trace();
            if let Some(t) = tangent {
                for a in 0..3 {
                    for b in 0..3 {
                        t[(a + 3 * a, b + 3 * b)] += bulk;
                    }
                }
            }
            (0.5 * bulk * tr * tr, Matrix3::identity() * (bulk * tr))
        }
        ElasticModel::Corotated => {
            let F = Matrix3::identity() + He;
            let cof = cofactor(&F);
            let j1 = det_minus_one(He);
            let P = cof * (bulk * j1);
            if let Some(t) = tangent {
                let g = SMatrix::<f64, 9, 1>::from_column_slice(cof.as_slice());
                *t += bulk * g * g.transpose();
                if !project {
                    add_det_hessian(&F, bulk * j1, t);
                }
            }
            (0.5 * bulk * j1 * j1, P)
        }
    }
}

/// The cofactor matrix ∂ det F / ∂F: column k is f_{k+1} × f_{k+2} (columns cyclic).
fn cofactor(F: &Matrix3<f64>) -> Matrix3<f64> {
    let f = [F.column(0), F.column(1), F.column(2)];
    Matrix3::from_columns(&[f[1].cross(&f[2]), f[2].cross(&f[0]), f[0].cross(&f[1])])
}

/// Adds `scale` × ∂² det F / ∂F² to `t`: ∂²J/∂fₖ∂f_{k+1} = −[f_{k+2}]ₓ and its transpose for
/// the reverse pair.
fn add_det_hessian(F: &Matrix3<f64>, scale: f64, t: &mut Tangent) {
    for k in 0..3 {
        let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
        let block = -F.column(k2).into_owned().cross_matrix() * scale;
        for a in 0..3 {
            for b in 0..3 {
                t[(a + 3 * k, b + 3 * k1)] += block[(a, b)];
                t[(b + 3 * k1, a + 3 * k)] += block[(a, b)];
            }
        }
    }
}

/// det(I + H) − 1 = tr H + ½((tr H)² − tr H²) + det H, without the cancellation of forming
/// the determinant first: at the 1e-7 strains of water under gravity, det − 1 would keep only
/// 9 digits, and its force error would stall Newton above the tolerance.
fn det_minus_one(H: &Matrix3<f64>) -> f64 {
    let tr = H.trace();
    tr + 0.5 * (tr * tr - (H * H).trace()) + H.determinant()
}

/// Evaluates one element: energy `V Ψ`, gradient `V P ∇Nᵢ` and, if `with_hessian`, the stiffness
/// `V Bᵀ (dP/dF) B`. The law is the solid's (scaled ice while freezing, yielding if the law
/// has an elastic limit) plus, if its `water_bulk` > 0, the water term of [`water`].
///
/// The strain offset ε* (eigenstrain, plastic strain) enters as σ = C : (ε − ε*) in the linear
/// model, and multiplicatively, `Fe = F F*⁻¹`, in the corotated one (see
/// [`offset_elastic_gradient`]) — the same to first order, but exact for a free body: an
/// isotropic ε* = e I gives a stress-free state scaled by exactly (1 + e).
// The arguments are the element's independent inputs; bundling them would only add a type.
#[allow(clippy::too_many_arguments)]
pub fn element_eval(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
    with_hessian: bool,
    project: bool,
    out: &mut ElementEval,
) {
    let H = rest.displacement_gradient(u);
    // Zeroed only when asked for: an energy or gradient pass skips the 81 entries.
    let mut tangent = with_hessian.then(Tangent::zeros);
    let model = law.model;
    let law = |He: &Matrix3<f64>, mut t: Option<&mut Tangent>| {
        let (psi, P) = constitutive(
            model,
            &law.material,
            law.yield_limit,
            He,
            t.as_deref_mut(),
            project,
        );
        if law.water_bulk > 0.0 {
            let (psi_w, P_w) = water(model, law.water_bulk, He, t, project);
            (psi + psi_w, P + P_w)
        } else {
            (psi, P)
        }
    };
    let t = tangent.as_mut();
    // The offset factor A enters through the shape-function gradients: He = H A + (A − I)
    // varies with the vertex displacements through Aᵀ∇Nᵢ, so the gradient is V Pe Aᵀ∇Nᵢ and
    // the stiffness V B'ᵀ (dPe/dFe) B' with B' built from Aᵀ∇Nᵢ.
    let (psi, P, grads) = match model {
        // σ = C:(sym H − ε*); the tangent does not depend on ε*.
        ElasticModel::Linear => {
            let (psi, P) = law(&(H - offset.strain), t);
            (psi, P, rest.grads)
        }
        ElasticModel::Corotated if offset.is_zero() => {
            let (psi, P) = law(&H, t);
            (psi, P, rest.grads)
        }
        ElasticModel::Corotated => {
            let (A, He) = offset_elastic_gradient(offset, &H);
            let (psi, Pe) = law(&He, t);
            (psi, Pe, offset_grads(&A, rest))
        }
    };
    let v = rest.volume;
    out.energy = v * psi;
    for (i, gi) in grads.iter().enumerate() {
        let g = v * P * gi;
        out.gradient[3 * i..3 * i + 3].copy_from_slice(g.as_slice());
    }
    if let Some(tangent) = &tangent {
        out.hessian = [0.0; 144];
        add_stiffness(&grads, v, tangent, &mut out.hessian);
    }
}

/// The gradients Aᵀ∇Nᵢ through which the vertex displacements move He = H A + (A − I).
fn offset_grads(A: &Matrix3<f64>, rest: &ElementRest) -> [Vector3<f64>; 4] {
    rest.grads.map(|g| A.tr_mul(&g))
}

/// Adds the element stiffness `v Bᵀ T B` (row-major 12 × 12) of the tangent `T` = dP/dF,
/// B mapping the 12 vertex displacements to vec(H) through the shape-function gradients
/// `grads` (B[a+3k, 3j+b] = δ_ab ∇N_j[k]): T B first (9 × 12), then Bᵀ (T B).
fn add_stiffness(grads: &[Vector3<f64>; 4], v: f64, tangent: &Tangent, hessian: &mut [f64; 144]) {
    let mut tb = [[0.0; 12]; 9];
    for (r, row) in tb.iter_mut().enumerate() {
        for (j, gj) in grads.iter().enumerate() {
            for b in 0..3 {
                row[3 * j + b] = tangent[(r, b)] * gj[0]
                    + tangent[(r, b + 3)] * gj[1]
                    + tangent[(r, b + 6)] * gj[2];
            }
        }
    }
    for (i, gi) in grads.iter().enumerate() {
        for a in 0..3 {
            let out = &mut hessian[(3 * i + a) * 12..(3 * i + a + 1) * 12];
            let (t0, t1, t2) = (&tb[a], &tb[a + 3], &tb[a + 6]);
            for c in 0..12 {
                out[c] += v * (gi[0] * t0[c] + gi[1] * t1[c] + gi[2] * t2[c]);
            }
        }
    }
}

/// The volume change θ of an element's elastic deformation and its derivatives, for the
/// averaged-nodal-pressure volumetric energy (`physics::volumetric`).
#[derive(Clone, Copy, Debug)]
pub struct VolumeChange {
    /// θ: tr(ε) − tr(ε*) (linear) or det Fe − 1 (corotated), dimensionless.
    pub theta: f64,
    /// ∂θ/∂F (3 × 3).
    pub gradient: Matrix3<f64>,
    /// The elastic deformation Fe = F A if the second derivative ∂²θ/∂Fe² = ∂² det Fe/∂Fe²
    /// was asked for (formed where it is used, from Fe: a 9 × 9 matrix per element would be
    /// 650 bytes to move); `None` also for the linear model, whose θ is linear.
    pub deformation: Option<Matrix3<f64>>,
    /// The offset factor A of Fe = F A (identity without an offset or in the linear model).
    pub offset_factor: Matrix3<f64>,
}

impl VolumeChange {
    /// ∂θ/∂x for the 12 vertex coordinates of the element (1/m).
    pub fn nodal_gradient(&self, rest: &ElementRest) -> [f64; 12] {
        let mut g = [0.0; 12];
        for i in 0..4 {
            let gi = self.gradient * rest.grads[i];
            g[3 * i..3 * i + 3].copy_from_slice(gi.as_slice());
        }
        g
    }

    /// Adds the forces and stiffness of a pressure `p` (Pa) acting through θ on an element
    /// of rest volume V: gradient V p ∂θ/∂x and, if `out_hessian`, V p ∂²θ/∂x² (an indefinite
    /// matrix, left out by callers that need a positive semi-definite stiffness).
    pub fn add_pressure(&self, rest: &ElementRest, p: f64, out: &mut ElementEval, hessian: bool) {
        let v = rest.volume;
        for (o, g) in out.gradient.iter_mut().zip(self.nodal_gradient(rest)) {
            *o += v * p * g;
        }
        if let (true, Some(fe)) = (hessian, &self.deformation) {
            let mut t = Tangent::zeros();
            add_det_hessian(fe, 1.0, &mut t);
            let grads = offset_grads(&self.offset_factor, rest);
            add_stiffness(&grads, v * p, &t, &mut out.hessian);
        }
    }
}

/// The volume change of an element's elastic deformation (see [`VolumeChange`]), with its
/// second derivative if `with_hessian`. Corotated: θ = J − 1 of Fe = F A (the exact volume
/// ratio, as for water), formed without cancellation.
pub fn volume_change(
    model: ElasticModel,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
    with_hessian: bool,
) -> VolumeChange {
    let H = rest.displacement_gradient(u);
    match model {
        ElasticModel::Linear => VolumeChange {
            theta: H.trace() - offset.strain.trace(),
            gradient: Matrix3::identity(),
            deformation: None,
            offset_factor: Matrix3::identity(),
        },
        ElasticModel::Corotated => {
            let (A, He) = offset_elastic_gradient(offset, &H);
            let Fe = Matrix3::identity() + He;
            VolumeChange {
                theta: det_minus_one(&He),
                gradient: cofactor(&Fe) * A.transpose(),
                deformation: with_hessian.then_some(Fe),
                offset_factor: A,
            }
        }
    }
}

/// Elastic strain of an element and the rotation of its frame: linear, ε = sym(H) − ε* in the
/// world frame (R = I); corotated, S − I of Fe = F (I + ε*)⁻¹ = R S, in the element's frame.
/// Plasticity's return mapping acts on this strain.
pub fn elastic_strain(
    model: ElasticModel,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let H = rest.displacement_gradient(u);
    match model {
        ElasticModel::Linear => (
            0.5 * (H + H.transpose()) - offset.strain,
            Matrix3::identity(),
        ),
        ElasticModel::Corotated => {
            let (_, He) = offset_elastic_gradient(offset, &H);
            let R = polar_rotation(&(Matrix3::identity() + He));
            (corotated_strain(&R, &He), R)
        }
    }
}

/// Cauchy stress of an element in the world frame (Pa), Voigt order xx yy zz yz xz xy.
/// Linear: σ = C:(ε − ε*). Corotated: σ = R (C:(S − I)) Rᵀ for Fe = F (I + ε*)⁻¹ = R S.
/// A yielding solid's stress is the returned one ([`solid_response`]). Water adds its
/// pressure: −K tr(ε) (linear) or −K (J − 1) (corotated) on the diagonal.
pub fn element_stress(
    law: &Law,
    rest: &ElementRest,
    u: &[Vector3<f64>; 4],
    offset: &StrainOffset,
) -> [f64; 6] {
    let (model, water_bulk) = (law.model, law.water_bulk);
    let (strain, R) = elastic_strain(model, rest, u, offset);
    let solid = solid_response(&law.material, law.yield_limit, &strain).sigma;
    let mut sigma = R * solid * R.transpose();
    if water_bulk > 0.0 {
        let volume_change = match model {
            ElasticModel::Linear => strain.trace(),
            ElasticModel::Corotated => {
                let (_, He) = offset_elastic_gradient(offset, &rest.displacement_gradient(u));
                det_minus_one(&He)
            }
        };
        sigma += Matrix3::identity() * (water_bulk * volume_change);
    }
    to_voigt(&sigma)
}

/// A strain offset ε* = e I + d (the expansion e and the plastic strain d, deviatoric) with
/// the corotated model's offset factor A = F*⁻¹ computed once, for F* = (1 + e) exp(d): ε* is
/// fixed during a solve, and A's matrix exponential would otherwise be the costliest part of
/// every element evaluation.
///
/// F* is the natural shape of the element: isotropic growth by 1 + e (the expansion, exact for
/// a free body) and the plastic shape change exp(d), which keeps volume exactly (det = e^tr d
/// = 1). With I + d instead, the natural volume would shrink by ½ tr(d²) at second order —
/// 1 % at ‖ε_p‖ = 0.14, a hydrostatic tension of K · 1 % ≈ 1e9 Pa that was pure artefact (and
/// read as fracture). A − I is formed from exp_m1, without cancellation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainOffset {
    /// ε* (dimensionless): σ = C:(ε − ε*) in the linear model.
    pub strain: Matrix3<f64>,
    /// A − I.
    factor_minus_i: Matrix3<f64>,
}

impl StrainOffset {
    /// The offset ε* = `strain` (symmetric).
    pub fn new(strain: Matrix3<f64>) -> Self {
        let e = strain.trace() / 3.0;
        let d = strain - Matrix3::identity() * e;
        // A − I = (exp(−d) − I − e I) / (1 + e).
        let exp_m1 = if d.iter().all(|v| *v == 0.0) {
            Matrix3::zeros()
        } else {
            expm1_symmetric(&(-d))
        };
        StrainOffset {
            strain,
            factor_minus_i: (exp_m1 - Matrix3::identity() * e) / (1.0 + e),
        }
    }

    /// No offset.
    pub fn zero() -> Self {
        Self::new(Matrix3::zeros())
    }

    /// Whether ε* = 0.
    pub fn is_zero(&self) -> bool {
        self.strain.iter().all(|v| *v == 0.0)
    }
}

/// The corotated model's offset factor A = F*⁻¹ of `offset` and the elastic displacement
/// gradient He = (I + H) A − I for the displacement gradient H, formed as H A + (A − I).
pub(crate) fn offset_elastic_gradient(
    offset: &StrainOffset,
    H: &Matrix3<f64>,
) -> (Matrix3<f64>, Matrix3<f64>) {
    let a = Matrix3::identity() + offset.factor_minus_i;
    (a, H * a + offset.factor_minus_i)
}

/// exp(X) − I of a symmetric 3 × 3 matrix without cancellation, by scaling and squaring: X is
/// halved s times until ‖X/2ˢ‖_F ≤ 1/8, exp − I of that by its Taylor series to the degree m
/// whose truncation ‖Y‖ᵐ/(m + 1)! relative to ‖Y‖ is below 1e-17 (10 at 1/8, 4 at the 1e-4
/// strains of ice), then squared back as E ← 2E + E² (the identity for exp(2Y) − I). A twentieth of the cost of an eigendecomposition, which the corotated
/// model's plastic offset needs for every element at every solve; equal to it to round-off.
fn expm1_symmetric(x: &Matrix3<f64>) -> Matrix3<f64> {
    let norm = x.norm();
    let halvings = if norm > 0.125 {
        (norm / 0.125).log2().ceil() as i32
    } else {
        0
    };
    let y = x * 0.5f64.powi(halvings);
    let y_norm = norm * 0.5f64.powi(halvings);
    let mut degree = 1;
    let mut truncation = y_norm / 2.0;
    while degree < 10 && truncation > 1e-17 {
        degree += 1;
        truncation *= y_norm / (degree + 1) as f64;
    }
    // Horner: Y (I + Y/2 (I + Y/3 (… (I + Y/m)))).
    let mut e = Matrix3::identity();
    for k in (2..=degree).rev() {
        e = Matrix3::identity() + y * e / k as f64;
    }
    e = y * e;
    for _ in 0..halvings {
        e = 2.0 * e + e * e;
    }
    0.5 * (e + e.transpose())
}

/// Symmetric tensor to Voigt order xx yy zz yz xz xy.
pub fn to_voigt(s: &Matrix3<f64>) -> [f64; 6] {
    [
        s[(0, 0)],
        s[(1, 1)],
        s[(2, 2)],
        s[(1, 2)],
        s[(0, 2)],
        s[(0, 1)],
    ]
}

/// Symmetric tensor from Voigt order xx yy zz yz xz xy (the inverse of [`to_voigt`]; the
/// off-diagonal entries are tensor components). `v` has 6 values.
pub fn from_voigt(v: &[f64]) -> Matrix3<f64> {
    Matrix3::new(v[0], v[5], v[4], v[5], v[1], v[3], v[4], v[3], v[2])
}

/// Von Mises equivalent of a symmetric tensor: √(3/2 s:s), s its deviator.
pub fn von_mises(s: &Matrix3<f64>) -> f64 {
    let d = s - Matrix3::identity() * (s.trace() / 3.0);
    (1.5 * d.norm_squared()).sqrt()
}

/// Largest eigenvalue of a symmetric tensor (for stress: the largest principal stress,
/// positive in tension).
pub fn max_principal(s: &Matrix3<f64>) -> f64 {
    s.symmetric_eigenvalues().max()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// The paper's ice, for the unit tests of this crate.
    pub(crate) const ICE: Material = Material {
        lambda: 8.64e10,
        mu: 3.70e10,
        density: 916.0,
    };

    fn tet() -> (ElementRest, [Vector3<f64>; 4]) {
        let mesh = TetMesh::from_arrays(
            &[
                [0.0, 0.0, 0.0],
                [0.02, 0.001, 0.0],
                [0.003, 0.018, 0.002],
                [0.001, 0.002, 0.021],
            ],
            vec![[0, 1, 2, 3]],
        )
        .unwrap();
        let rest = ElementRest::of_mesh(&mesh)[0];
        (
            rest,
            [mesh.rest[0], mesh.rest[1], mesh.rest[2], mesh.rest[3]],
        )
    }

    /// Gradient and Hessian against central finite differences of the energy / gradient.
    fn check_derivatives(model: ElasticModel, offset: Matrix3<f64>, strain: f64) {
        check_law_derivatives(model, &ICE, 0.0, None, offset, strain);
    }

    /// Gradient and Hessian of `mat` plus water of bulk modulus `water` against finite
    /// differences.
    fn check_law_derivatives(
        model: ElasticModel,
        mat: &Material,
        water: f64,
        yield_limit: Option<f64>,
        offset: Matrix3<f64>,
        strain: f64,
    ) {
        let (rest, x0) = tet();
        // A generic deformation: a rotation of a shear plus stretch of relative size `strain`,
        // given as displacements x − X.
        let G = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25) * strain;
        let R = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.9).into_inner();
        let x = x0.map(|p| R * (p + G * p) - p);
        let law = Law {
            model,
            material: *mat,
            water_bulk: water,
            yield_limit,
        };
        let mut e = ElementEval::default();
        element_eval(
            &law,
            &rest,
            &x,
            &StrainOffset::new(offset),
            true,
            false,
            &mut e,
        );
        let h = 1e-9;
        let scale = e.gradient.iter().map(|g| g.abs()).fold(0.0, f64::max);
        let hscale = e.hessian.iter().map(|g| g.abs()).fold(0.0, f64::max);
        for d in 0..12 {
            let mut xp = x;
            let mut xm = x;
            xp[d / 3][d % 3] += h;
            xm[d / 3][d % 3] -= h;
            let (mut ep, mut em) = (ElementEval::default(), ElementEval::default());
            element_eval(
                &law,
                &rest,
                &xp,
                &StrainOffset::new(offset),
                false,
                false,
                &mut ep,
            );
            element_eval(
                &law,
                &rest,
                &xm,
                &StrainOffset::new(offset),
                false,
                false,
                &mut em,
            );
            let fd = (ep.energy - em.energy) / (2.0 * h);
            // Energy differences lose ~8 digits to cancellation at h = 1e-9: 1e-5 relative.
            assert!(
                (fd - e.gradient[d]).abs() <= 1e-5 * scale,
                "{model:?} grad {d}: {fd} vs {}",
                e.gradient[d]
            );
            for c in 0..12 {
                let fdh = (ep.gradient[c] - em.gradient[c]) / (2.0 * h);
                assert!(
                    (fdh - e.hessian[c * 12 + d]).abs() <= 1e-5 * hscale,
                    "{model:?} hess ({c},{d}): {fdh} vs {}",
                    e.hessian[c * 12 + d]
                );
            }
        }
    }

    /// Half-frozen ice: half the ice's Lamé constants.
    fn half_frozen() -> Material {
        Material {
            lambda: 0.5 * ICE.lambda,
            mu: 0.5 * ICE.mu,
            density: ICE.density,
        }
    }

    #[test]
    fn water_derivatives_match_finite_differences() {
        // Half-frozen: half the ice's Lamé constants plus half the water's bulk modulus, with
        // the expansion offset, stretched and compressed.
        let half = half_frozen();
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            check_law_derivatives(
                model,
                &half,
                1.1e9,
                None,
                Matrix3::identity() * 0.0145,
                0.02,
            );
            check_law_derivatives(model, &half, 1.1e9, None, Matrix3::identity() * -0.03, 0.01);
            // Pure water (no shear stiffness at all).
            let none = Material {
                lambda: 0.0,
                mu: 0.0,
                density: ICE.density,
            };
            check_law_derivatives(model, &none, 2.2e9, None, Matrix3::zeros(), 0.02);
        }
    }

    #[test]
    fn linear_derivatives_match_finite_differences() {
        check_derivatives(ElasticModel::Linear, Matrix3::zeros(), 0.0);
        check_derivatives(ElasticModel::Linear, Matrix3::identity() * 0.0291, 0.0);
    }

    #[test]
    fn corotated_derivatives_match_finite_differences_in_tension() {
        // Stretched state: all twist eigenvalues positive, so the tangent is exact.
        let stretch = Matrix3::identity() * -0.05;
        check_derivatives(ElasticModel::Corotated, stretch, 0.01);
        let sym = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, 0.003)
            - Matrix3::identity() * 0.05;
        check_derivatives(ElasticModel::Corotated, sym, 0.02);
    }

    #[test]
    fn corotated_exact_tangent_matches_finite_differences_in_compression() {
        // Compressed: some twist eigenvalues are negative; the unprojected tangent is still
        // the exact Hessian.
        check_derivatives(ElasticModel::Corotated, Matrix3::identity() * 0.05, 0.02);
    }

    #[test]
    fn corotated_tangent_without_singular_vectors_is_the_svd_one() {
        let R = nalgebra::Rotation3::from_euler_angles(0.4, -0.9, 2.2).into_inner();
        let shape = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25);
        // Ice's strains, a large stretch, compression (negative twist stiffness) and an
        // isotropic stretch (repeated singular values: the SVD basis is arbitrary there).
        let cases = [
            R * (Matrix3::identity() + shape * 1e-4),
            R * (Matrix3::identity() + shape * 0.3),
            R * (Matrix3::identity() * 0.9 + shape * 0.05),
            R * 1.02,
        ];
        for F in cases {
            for limit in [None, Some(1e-5)] {
                let strain = corotated_strain(&polar_rotation(&F), &(F - Matrix3::identity()));
                let response = solid_response(&ICE, limit, &strain);
                let (mut closed, mut svd) = (Tangent::zeros(), Tangent::zeros());
                assert!(corotated_tangent(
                    &polar_rotation(&F),
                    &strain,
                    &response,
                    &mut closed
                ));
                corotated_tangent_svd(&F, &response, false, &mut svd);
                // The same tangent to round-off: ~1e-15 relative, except that the SVD's flow
                // direction comes from sᵢ − 1, whose ~1e-16 absolute error is 1e-12 of a 1e-4
                // deviator (measured 2.1e-12 there); the strain here is formed without it.
                let err = (closed - svd).amax() / svd.amax();
                assert!(err < 1e-11, "{err:e} for {F} with limit {limit:?}");
            }
        }
    }

    #[test]
    fn corotated_free_expansion_is_stress_free() {
        let (rest, x0) = tet();
        let e = 0.0291;
        let x = x0.map(|p| p * e);
        let offset = StrainOffset::new(Matrix3::identity() * e);
        let mut out = ElementEval::default();
        let law = Law::elastic(ElasticModel::Corotated, ICE);
        element_eval(&law, &rest, &x, &offset, false, false, &mut out);
        let gmax = out.gradient.iter().map(|g| g.abs()).fold(0.0, f64::max);
        // Forces of a 2 % strain would be ~1e7 N here; round-off leaves ~1e-16 of that.
        assert!(gmax < 1e-6, "{gmax}");
        let s = element_stress(&law, &rest, &x, &offset);
        assert!(s.iter().all(|v| v.abs() < 1e-2), "{s:?}");
    }

    #[test]
    fn yielding_derivatives_match_finite_differences() {
        // The strains below are 10–100 × the elastic limit: every case yields. Half-frozen
        // ice with water and an expansion offset, and ice with a plastic strain offset.
        let half = half_frozen();
        let plastic = Matrix3::new(0.01, 0.002, 0.0, 0.002, -0.004, 0.001, 0.0, 0.001, -0.006);
        for model in [ElasticModel::Linear, ElasticModel::Corotated] {
            check_law_derivatives(model, &ICE, 0.0, Some(1e-3), Matrix3::zeros(), 0.02);
            check_law_derivatives(model, &ICE, 0.0, Some(1e-4), plastic, 0.01);
            let offset = Matrix3::identity() * 0.0145;
            check_law_derivatives(model, &half, 1.1e9, Some(1e-4), offset, 0.02);
        }
    }

    #[test]
    fn yielding_stress_is_on_the_yield_surface_and_keeps_the_volume_response() {
        let gamma = 1e-4;
        let eps = Matrix3::new(3e-3, 1e-3, 0.0, 1e-3, -1e-3, 2e-4, 0.0, 2e-4, 5e-4);
        let r = solid_response(&ICE, Some(gamma), &eps);
        assert!(r.flow_drop > 0.0);
        let dev = r.sigma - Matrix3::identity() * (r.sigma.trace() / 3.0);
        // ‖σ'‖ = 2μγ to round-off; the pressure is the elastic one, K tr ε.
        assert!((dev.norm() - 2.0 * ICE.mu * gamma).abs() < 1e-9 * ICE.mu * gamma);
        assert!((r.sigma.trace() / 3.0 - ICE.bulk() * eps.trace()).abs() < 1e-6);
        // The radial return of the trial stress gives the same stress.
        let trial = ICE.hooke(&eps);
        let tdev = trial - Matrix3::identity() * (trial.trace() / 3.0);
        let returned = trial - tdev * (1.0 - 2.0 * ICE.mu * gamma / tdev.norm());
        assert!((returned - r.sigma).norm() < 1e-9 * trial.norm());
        // Below the limit: Hooke's law, bit for bit.
        let small = eps * 1e-3;
        assert_eq!(
            solid_response(&ICE, Some(gamma), &small).sigma,
            ICE.hooke(&small)
        );
    }

    #[test]
    fn expm1_of_a_symmetric_matrix_is_the_eigendecomposition_s() {
        use nalgebra::SymmetricEigen;
        // Plastic strains from 1e-8 to 2: the series with scaling and squaring against
        // V diag(exp_m1(λ)) Vᵀ, to round-off relative to the result.
        let shape = Matrix3::new(0.7, 0.2, -0.1, 0.2, -0.3, 0.4, -0.1, 0.4, -0.4);
        for scale in [1e-8, 1e-4, 0.05, 0.3, 2.0] {
            let x = shape * scale;
            let eig = SymmetricEigen::new(x);
            let v = eig.eigenvectors;
            let exact =
                v * Matrix3::from_diagonal(&eig.eigenvalues.map(f64::exp_m1)) * v.transpose();
            let e = expm1_symmetric(&x);
            assert!(
                (e - exact).norm() <= 1e-14 * exact.norm(),
                "scale {scale}: {:e}",
                (e - exact).norm() / exact.norm()
            );
        }
    }

    #[test]
    fn signed_svd_flags_inversion() {
        let F = Matrix3::from_diagonal(&Vector3::new(1.0, 0.5, -0.2));
        let (U, s, V) = signed_svd(&F);
        assert!(s[2] < 0.0 && U.determinant() > 0.0 && V.determinant() > 0.0);
        assert!((U * Matrix3::from_diagonal(&s) * V.transpose() - F).norm() < 1e-14);
    }

    #[test]
    fn newton_polar_rotation_is_the_svd_rotation() {
        let R = nalgebra::Rotation3::from_euler_angles(0.3, -1.1, 2.0).into_inner();
        let shape = Matrix3::new(0.3, -0.7, 0.2, 0.5, 0.1, -0.4, -0.2, 0.6, 0.25);
        // From ice's strains under gravity to a large stretch.
        for strain in [1e-7, 1e-4, 1e-2, 0.3] {
            let F = R * (Matrix3::identity() + shape * strain);
            let newton = polar_rotation_newton(&F).expect("converges for det F > 0.1");
            let (U, _, V) = signed_svd(&F);
            // Both are the polar factor to round-off (each ~1e-16 per entry).
            assert!(
                (newton - U * V.transpose()).amax() < 1e-14,
                "strain {strain}"
            );
            assert!((newton.transpose() * newton - Matrix3::identity()).amax() < 1e-15);
        }
        // Inverted (or nearly): the signed SVD decides.
        let inverted = Matrix3::from_diagonal(&Vector3::new(1.0, 0.5, -0.2));
        assert!(polar_rotation_newton(&inverted).is_none());
        assert!(polar_rotation(&inverted).determinant() > 0.0);
    }
}
