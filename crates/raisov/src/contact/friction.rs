//! Regularised Coulomb friction of one node against a tool: a tangential stick spring to an
//! anchor and a return map (the equations are in the [`super`] module documentation).
//!
//! Each node in contact with a tool carries a state: its anchor `z` (the point of the tool's
//! frame where it stuck, `x − d(t)` when it stuck), whether it slipped in the last committed
//! step, and its normal force magnitude at that commit, `N = k |φ|`. For a node at `x`, a
//! tool at offset `d` and normal `n`:
//!
//! ```text
//! s   = x − (z + d),   s_t = s − (s·n) n              (slip vector, tangent plane)
//! μ   = μ_k if the node slipped in the last step, else μ_s
//! stick  (k_t |s_t| ≤ μ N):  f_t = −k_t s_t,             energy ½ k_t |s_t|²
//! slip   (k_t |s_t| > μ N):  f_t = −μ_k N s_t / |s_t|,   energy ½ k_t s*² + μ_k N (|s_t| − s*),
//!                            s* = μ N / k_t
//! ```
//!
//! The forces at any `u` between two commits use the committed anchors and normal forces
//! (`N` lags one step), so every stage of an integrator and every Newton iterate sees the same
//! law, and within a step it is the gradient of its energy (exactly for a plane, whose `n` is
//! constant): a Huber potential of `s_t`, convex, which the implicit solvers' line searches
//! need. Committing a step
//! ([`commit`]) moves a slipping node's anchor along `s_t` until the spring carries the kinetic
//! force, `z ← z + (1 − μ_k N / (k_t |s_t|)) s_t`, adds `μ_k N |Δz| ≥ 0` to the dissipated
//! energy and stores the node's new `N`; a node that enters contact is anchored where it
//! stands (`s = 0`: no friction force until the step after), one that leaves it loses its
//! anchor.

use crate::geometry::{dot, sub};

/// Coulomb friction of a tool: `μ_s` (static), `μ_k ≤ μ_s` (kinetic) and the tangential
/// stick stiffness `k_t` (N/m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Friction {
    /// Static coefficient μ_s ≥ 0: a stuck node slips when `|f_t| > μ_s N`.
    pub static_coefficient: f64,
    /// Kinetic coefficient μ_k, `0 ≤ μ_k ≤ μ_s`: a slipping node carries `|f_t| = μ_k N`.
    pub kinetic_coefficient: f64,
    /// Tangential stiffness k_t (N/m) of the stick spring.
    pub stiffness: f64,
}

/// Values per node of a tool's friction state: the anchor (3; NaN without one), the slip
/// flag (1.0 slipped in the last committed step, 0.0 stuck) and the committed normal force
/// magnitude `N` (N).
pub const STATE: usize = 5;

/// The state of a node without an anchor.
pub const FREE: [f64; STATE] = [f64::NAN, f64::NAN, f64::NAN, 0.0, 0.0];

/// The friction law evaluated at one node with the committed state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trial {
    /// The friction force on the node (N).
    pub force: [f64; 3],
    /// The stick spring's energy, continued linearly in slip (J).
    pub energy: f64,
    /// The tangential slip vector `s_t` (m).
    pub slip: [f64; 3],
    /// Whether the trial force exceeds the threshold (the node slips).
    pub slipping: bool,
    /// The committed normal force magnitude the law used (N).
    pub normal: f64,
}

impl Friction {
    /// The friction on a node at `x` against a tool at offset `d` with normal `n`, from its
    /// committed `state` ([`STATE`] values, the normal force among them); `None` without an
    /// anchor.
    pub fn trial(&self, x: [f64; 3], d: [f64; 3], n: [f64; 3], state: &[f64]) -> Option<Trial> {
        let normal = state[4];
        let z = [state[0], state[1], state[2]];
        if z[0].is_nan() {
            return None;
        }
        let s = sub(x, [z[0] + d[0], z[1] + d[1], z[2] + d[2]]);
        let sn = dot(s, n);
        let st = [s[0] - sn * n[0], s[1] - sn * n[1], s[2] - sn * n[2]];
        let l = dot(st, st).sqrt();
        let kt = self.stiffness;
        let mu = if state[3] != 0.0 {
            self.kinetic_coefficient
        } else {
            self.static_coefficient
        };
        let limit = mu * normal;
        if kt * l <= limit {
            return Some(Trial {
                force: st.map(|c| -kt * c),
                energy: 0.5 * kt * l * l,
                slip: st,
                slipping: false,
                normal,
            });
        }
        let fk = self.kinetic_coefficient * normal;
        let star = limit / kt;
        Some(Trial {
            force: st.map(|c| -fk * c / l),
            energy: 0.5 * kt * star * star + fk * (l - star),
            slip: st,
            slipping: true,
            normal,
        })
    }

    /// The tangent block of the friction force's negative derivative at a node (3 × 3,
    /// row-major, symmetric; exact for a plane): `k_t (I − n nᵀ)` in stick,
    /// `μ_k N / |s_t| (I − n nᵀ − ŝ ŝᵀ)` in slip.
    pub fn tangent(&self, n: [f64; 3], trial: &Trial) -> [f64; 9] {
        let normal = trial.normal;
        let mut b = [0.0; 9];
        let l = dot(trial.slip, trial.slip).sqrt();
        let (c, e) = if trial.slipping {
            (
                self.kinetic_coefficient * normal / l,
                trial.slip.map(|x| x / l),
            )
        } else {
            (self.stiffness, [0.0; 3])
        };
        for i in 0..3 {
            for j in 0..3 {
                let id = if i == j { 1.0 } else { 0.0 };
                b[3 * i + j] = c * (id - n[i] * n[j] - e[i] * e[j]);
            }
        }
        b
    }
}

/// Commit one node's `state` ([`STATE`] values) after an accepted step: `contact` is
/// `Some((x − d, N, trial))` for a node in contact (its position in the tool's frame, its
/// normal force magnitude now and the law evaluated there), `None` for one out of contact.
/// Returns the energy dissipated by its slip (J, ≥ 0).
pub fn commit(
    fr: &Friction,
    state: &mut [f64],
    contact: Option<([f64; 3], f64, Option<Trial>)>,
) -> f64 {
    let Some((p, normal, trial)) = contact else {
        state.copy_from_slice(&FREE);
        return 0.0;
    };
    let Some(trial) = trial else {
        state.copy_from_slice(&[p[0], p[1], p[2], 0.0, normal]);
        return 0.0;
    };
    state[4] = normal;
    if !trial.slipping {
        state[3] = 0.0;
        return 0.0;
    }
    let l = dot(trial.slip, trial.slip).sqrt();
    let fk = fr.kinetic_coefficient * trial.normal;
    let r = 1.0 - fk / (fr.stiffness * l);
    for c in 0..3 {
        state[c] += r * trial.slip[c];
    }
    state[3] = 1.0;
    fk * r * l
}
