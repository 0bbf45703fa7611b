//! Static equilibrium by relaxation: explicit pseudo-time iterations on the finest mesh alone,
//! the single-level baselines the multigrid and Newton solvers are measured against, and the
//! dynamic relaxation of the T∞ references.
//!
//! - [`dynamic`]: symplectic Euler with kinetic damping (velocities zeroed at each peak of the
//!   kinetic energy), the references far below a run's tolerance;
//! - [`adaptive`]: adaptive dynamic relaxation (Joldes, Wittek & Miller 2011), critically
//!   damped on the lowest mode estimated on the fly;
//! - [`chebyshev`]: the Chebyshev semi-iteration over a Lanczos-estimated interval.
//!
//! The first two step fictitious per-node masses ([`fictitious_mass`]) that bring every node
//! to the same stable step.

pub mod adaptive;
pub mod chebyshev;
pub mod dynamic;
#[cfg(test)]
pub(crate) mod tests;

/// Per-node fictitious masses `D_a = Σ_{e∋a} c² G_e ρ|e|/npe` (dynamic relaxation's, Underwood
/// 1983): the element bound `K_e ≤ c² G_e M_e` ([`crate::fem::gradient_sums`]) summed at
/// the node, so `λ_max(D⁻¹K) ≤ 1` at small strain; `c² = λ_max / max_e G_e`, `ρ` the mass over
/// the measure (one material). A node in no element keeps `λ_max m_a`. As a diagonal
/// preconditioner it equilibrates meshes with slivers, where `M` alone does not.
pub fn fictitious_mass(mesh: &crate::mesh::Mesh, mass: &[f64], lambda_max: f64) -> Vec<f64> {
    let g = crate::fem::gradient_sums(mesh);
    let gmax = g.iter().fold(0.0f64, |a, &b| a.max(b));
    let c2 = if gmax > 0.0 { lambda_max / gmax } else { 0.0 };
    let npe = mesh.kind.nodes_per_element();
    let measure: f64 = (0..mesh.num_elements())
        .map(|e| mesh.element_measure(e).abs())
        .sum();
    let rho = mass.iter().sum::<f64>() / measure.max(f64::MIN_POSITIVE);
    let mut d = vec![0.0; mesh.num_nodes()];
    for (e, ge) in g.iter().enumerate() {
        let share = c2 * ge * rho * mesh.element_measure(e).abs() / npe as f64;
        for &a in mesh.element(e) {
            d[a as usize] += share;
        }
    }
    for (da, m) in d.iter_mut().zip(mass) {
        if *da <= 0.0 {
            *da = lambda_max * m;
        }
    }
    d
}
