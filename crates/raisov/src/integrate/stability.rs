//! Stable step of the explicit integrators on lumped-mass linear elements.
//!
//! An explicit scheme is stable while `Δ ω_max ≤ b`, `b` = 2 for the symplectic schemes and
//! 2√2 for RK4 ([`Method::stability_bound`]), `ω_max² = λ_max(M⁻¹K)` the highest frequency.
//! Element by element, with `c² = Material::stability_modulus / ρ`,
//!
//! ```text
//! λ_max(M⁻¹K) ≤ c² max_e G_e,     G_e = npe Σ_a |∇N_a|²          (1/m²)
//! Δ_crit ≈ b / sqrt(c² max_e G_e)
//! ```
//!
//! (the element stiffness is at most `P V Σ_a |∇N_a|²` in norm, `P` the stability modulus,
//! and each of its `npe` nodes carries `ρ V / npe` of lumped mass; [`crate::fem::gradient_sums`]
//! gives `G_e`). The bound holds at small strain; hyperelastic laws stiffen under large
//! stretch, hence a safety factor on top (a scenario's `[integrator] safety`). A step given
//! above [`TOO_LARGE_STEP`] times the estimate is too large for an explicit run
//! ([`step_too_large`]: the one rule a scenario warns by and `SimulationBuilder` refuses by).

use super::Method;
use crate::material::Material;
use crate::mesh::Mesh;

/// `max_e G_e = max_e npe Σ_a |∇N_a|²` over the elements (1/m²).
pub fn max_gradient_sum(mesh: &Mesh) -> f64 {
    crate::fem::gradient_sums(mesh)
        .into_iter()
        .fold(0.0, f64::max)
}

/// The bound `c² max_e G_e ≥ λ_max(M⁻¹K)` at small strain (1/s²).
pub fn lambda_max_bound(mesh: &Mesh, material: &Material, density: f64) -> f64 {
    material.stability_modulus(mesh.kind) / density * max_gradient_sum(mesh)
}

/// Estimated critical time step `b / sqrt(c² max_e G_e)` (s) of `method` on `mesh`.
pub fn critical_step_estimate(
    mesh: &Mesh,
    material: &Material,
    density: f64,
    method: Method,
) -> f64 {
    method.stability_bound() / lambda_max_bound(mesh, material, density).sqrt()
}

/// A given explicit step above this many estimated critical steps is too large: an explicit
/// run this coarse usually diverges. A scenario warns (`Scenario::warnings`), and
/// `SimulationBuilder` refuses the step ([`step_too_large`]).
pub const TOO_LARGE_STEP: f64 = 2.0;

/// Where a given step `dt` (s) of the explicit `method` is above [`TOO_LARGE_STEP`] times
/// `critical`, the estimated critical step ([`critical_step_estimate`]), what is wrong:
/// `dt = 1.000e-3 s is 4.2 times the estimated critical step 2.381e-4 s of
/// symplectic-euler: an explicit run this coarse usually diverges`; `None` within it. Both
/// front doors take the rule from here (each adds its key and its remedy).
pub fn step_too_large(dt: f64, critical: f64, method: Method) -> Option<String> {
    (dt > TOO_LARGE_STEP * critical).then(|| {
        format!(
            "dt = {dt:.3e} s is {} times the estimated critical step {critical:.3e} s of {}: \
             an explicit run this coarse usually diverges",
            crate::numbers::rounded(dt / critical, 1),
            method.name()
        )
    })
}
