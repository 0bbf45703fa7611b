//! The project's convergent multigrid: a full approximation scheme (FAS) built from the
//! paper's ingredients (independent levels, host weights both ways, explicit damped
//! integrators as smoothers, coarse changes carried up as variations). Not in the paper; see
//! `../shared/design/raisov-reading.md`, "A multigrid that converges".
//!
//! One step is one V-cycle from level 0, recursively on level l with equation
//! `R_l(u) = F_l` (`F_0 = V`, the real loads):
//!
//! ```text
//! 1. ν1 explicit damped steps on level l                        (pre-smoothing)
//! 2. u_c0 = R u_l          each coarse node interpolated from its fine host (state restriction)
//! 3. r_l = F_l − R_l(u_l);  F_c = R_c(u_c0) + Pᵀ r_l            (τ-correction: the coarse level
//!                                                              works on the fine level's error)
//! 4. level l+1: recurse; the coarsest level takes k explicit steps at its own larger stable
//!    step from rest, or a Newton-Krylov solve (the paper's section 4 suggestion)
//! 5. u_l += P (u_c − u_c0)                                       (variation carried up)
//! 6. ν2 explicit damped steps on level l                        (post-smoothing)
//! ```
//!
//! Coarse levels hold their constrained nodes at the restricted values (the correction is zero
//! there); level 0 keeps its real constraints. At a fixed point `r_0 = 0`, so `F_c = R_c(u_c0)`,
//! the coarse solution is `u_c0` and the correction vanishes: level 0 sits exactly on SLIM's
//! equilibrium (a test). The fine velocity is kept across the correction; coarse levels start
//! each visit at rest. Per-cycle work is O(n): each level's work is proportional to its nodes.

use super::{Level, Links};
use crate::error::{Divergence, DivergenceCause};
use crate::fem::ElementFailure;
use crate::integrate::statics::{NewtonParams, NewtonSolver};
use crate::integrate::{check_state, Constraints, Motion, Stepper};

/// How the coarsest level solves its problem.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CoarseSolve {
    /// Explicit damped steps from rest for this much simulated time (s) at the level's step.
    Explicit { time: f64 },
    /// Matrix-free Newton-Krylov to this relative residual.
    Newton { rel_tol: f64 },
}

/// Parameters of the FAS cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FasParams {
    /// Pre-smoothing steps ν1 per level. Default 2.
    pub pre_smooth: usize,
    /// Post-smoothing steps ν2 per level. Default 2.
    pub post_smooth: usize,
    /// Coarsest-level solve. Default explicit for 0.1 s.
    pub coarse: CoarseSolve,
    /// Kinetic-energy ceiling of the finest level (J), for divergence detection.
    pub kinetic_limit: f64,
}

impl Default for FasParams {
    fn default() -> Self {
        FasParams {
            pre_smooth: 2,
            post_smooth: 2,
            coarse: CoarseSolve::Explicit { time: 0.1 },
            kinetic_limit: f64::INFINITY,
        }
    }
}

/// The FAS multigrid stepper.
pub struct Fas {
    pub levels: Vec<Level>,
    pub links: Links,
    pub params: FasParams,
    /// Restricted state u_c0 per level (unused for level 0).
    u0: Vec<Vec<f64>>,
    /// Residual scratch per level.
    r: Vec<Vec<f64>>,
    newton: Option<NewtonSolver>,
    steps: u64,
}

fn diverged(step: u64, time: f64, f: ElementFailure) -> Divergence {
    Divergence {
        time,
        step,
        element: Some(f.element),
        cause: DivergenceCause::Inverted { det_f: f.det_f },
    }
}

impl Fas {
    /// Coarse levels' constraints become "hold at the restricted value" (set every visit).
    pub fn new(mut levels: Vec<Level>, links: Links, params: FasParams) -> Self {
        assert_eq!(links.len() + 1, levels.len());
        for l in levels.iter_mut().skip(1) {
            let c = &l.sys.constraints;
            let mut nodes: Vec<u32> = c.fixed.clone();
            nodes.extend(c.prescribed.iter().map(|(a, _)| *a));
            nodes.sort_unstable();
            nodes.dedup();
            let held = nodes
                .into_iter()
                .map(|a| (a, Motion::Held { d: [0.0; 3] }))
                .collect();
            l.sys.constraints = Constraints::new(vec![], held).with_nodes(l.num_nodes());
        }
        let m = levels.len();
        let newton = match params.coarse {
            CoarseSolve::Newton { .. } => Some(NewtonSolver::new(&levels[m - 1].sys)),
            _ => None,
        };
        Fas {
            u0: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            r: levels
                .iter()
                .map(|l| vec![0.0; 3 * l.num_nodes()])
                .collect(),
            levels,
            links,
            params,
            newton,
            steps: 0,
        }
    }

    fn smooth(&mut self, l: usize, steps: usize, t: f64) -> Result<(), Divergence> {
        let step_no = self.steps + 1;
        let lv = &mut self.levels[l];
        for _ in 0..steps {
            lv.integrator
                .step(&mut lv.sys, &mut lv.state, lv.dt)
                .map_err(|f| diverged(step_no, t, f))?;
            lv.evaluations += lv.integrator.method().evaluations();
            if l > 0 {
                // Coarse levels solve at the frozen time of the visit.
                lv.state.t = t;
            }
        }
        Ok(())
    }

    fn coarsest(&mut self, l: usize, t: f64) -> Result<(), Divergence> {
        match self.params.coarse {
            CoarseSolve::Explicit { time } => {
                let k = (time / self.levels[l].dt).ceil().max(1.0) as usize;
                self.smooth(l, k, t)
            }
            CoarseSolve::Newton { rel_tol } => {
                let lv = &mut self.levels[l];
                let solver = self.newton.as_mut().expect("built for Newton");
                let p = NewtonParams {
                    rel_tol,
                    max_newton: 10,
                    ..Default::default()
                };
                let mut u = std::mem::take(&mut lv.state.u);
                let res = solver.solve(&mut lv.sys, t, &mut u, p);
                lv.state.u = u;
                match res {
                    Ok(s) => {
                        lv.evaluations += s.force_evaluations;
                        Ok(())
                    }
                    // An inverting Newton step is no divergence of the run: keep u_c0.
                    Err(_) => {
                        let u0 = &self.u0[l];
                        lv.state.u.copy_from_slice(u0);
                        Ok(())
                    }
                }
            }
        }
    }

    fn visit(&mut self, l: usize, t: f64) -> Result<(), Divergence> {
        let m = self.levels.len();
        if l + 1 == m {
            return self.coarsest(l, t);
        }
        let step_no = self.steps + 1;
        self.smooth(l, self.params.pre_smooth, t)?;
        // Restrict the state and build the coarse right-hand side.
        {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (f, c) = (&mut fine[l], &mut coarse[0]);
            let link = &self.links[l];
            link.up
                .interpolate(&f.state.u, 3, &mut self.u0[l + 1])
                .expect("sizes match");
            // Hold coarse constrained nodes at the restricted values.
            let u0c = &self.u0[l + 1];
            for (a, mo) in c.sys.constraints.prescribed.iter_mut() {
                let k = 3 * *a as usize;
                *mo = Motion::Held {
                    d: [u0c[k], u0c[k + 1], u0c[k + 2]],
                };
            }
            c.state.u.copy_from_slice(u0c);
            c.state.v.iter_mut().for_each(|x| *x = 0.0);
            c.state.t = t;
            f.sys
                .residual(&f.state.u, &mut self.r[l])
                .map_err(|e| diverged(step_no, t, e))?;
            f.evaluations += 1;
            // F_c = R_c(u_c0) + Pᵀ r_f
            let fc = &mut c.sys.f_ext;
            c.sys
                .force
                .internal_forces(u0c, fc)
                .map_err(|e| diverged(step_no, t, e))?;
            c.evaluations += 1;
            link.down
                .transpose_add(&self.r[l], 3, fc)
                .expect("sizes match");
        }
        self.visit(l + 1, t)?;
        // Carry the coarse change up as a variation.
        {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let (f, c) = (&mut fine[l], &coarse[0]);
            let e = &mut self.r[l + 1];
            for k in 0..e.len() {
                e[k] = c.state.u[k] - self.u0[l + 1][k];
            }
            self.links[l]
                .down
                .interpolate_add(e, 3, &mut f.state.u)
                .expect("sizes match");
            let tt = f.state.t;
            let v = std::mem::take(&mut f.state.v);
            let mut vv = v;
            f.sys.impose(tt, &mut f.state.u, &mut vv);
            f.state.v = vv;
        }
        self.smooth(l, self.params.post_smooth, t)
    }
}

impl Stepper for Fas {
    fn advance(&mut self) -> Result<(), Divergence> {
        let t = self.levels[0].state.t;
        if self.levels.len() == 1 {
            self.coarsest(0, t)?;
        } else {
            self.visit(0, t)?;
        }
        self.steps += 1;
        let l = &self.levels[0];
        check_state(&l.sys, &l.state, self.steps, self.params.kinetic_limit)
    }
    fn finest(&mut self) -> (&mut crate::integrate::System, &crate::integrate::State) {
        let l = &mut self.levels[0];
        (&mut l.sys, &l.state)
    }
    fn steps(&self) -> u64 {
        self.steps
    }
    fn force_evaluations(&self) -> f64 {
        let n0 = self.levels[0].num_nodes() as f64;
        self.levels
            .iter()
            .map(|l| l.evaluations as f64 * l.num_nodes() as f64 / n0)
            .sum()
    }
    fn dt(&self) -> f64 {
        self.levels[0].dt * (self.params.pre_smooth + self.params.post_smooth).max(1) as f64
    }
    fn describe(&self) -> String {
        let nodes: Vec<String> = self
            .levels
            .iter()
            .map(|l| l.num_nodes().to_string())
            .collect();
        format!(
            "fas multigrid, {} levels ({} nodes), nu1 = {}, nu2 = {}, coarsest {:?}, {}, fine dt = {:.4e} s",
            self.levels.len(),
            nodes.join("/"),
            self.params.pre_smooth,
            self.params.post_smooth,
            self.params.coarse,
            self.levels[0].integrator.method().name(),
            self.levels[0].dt
        )
    }
}
