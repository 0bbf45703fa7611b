//! The frame loop's view of the equilibrium benchmark's solvers: FAS and Newton-multigrid
//! given a fixed amount of work per frame, warm started from the last frame, and the residual
//! they leave after given frames ([`FRAME_MARKS`]).

use super::{max_nodal, newton_mg_hierarchy, Case, ABS_TOL, REL_TOL};
use raisov::statics::newton::{DirectNewton, DirectNewtonParams, MultigridPcg};
use raisov::{Error, Result};
use std::time::Instant;

/// The frame loop's view of a solver: one row per budget (FAS: V-cycles per frame;
/// Newton-multigrid: Newton iterations per frame), the largest nodal residual over free nodes
/// relative to the largest nodal load after each of the frames in [`FRAME_MARKS`], from rest,
/// and the mean wall time per frame (ms).
#[derive(Clone, Debug)]
pub struct FrameRow {
    pub case: String,
    /// "FAS" or "Newton-multigrid".
    pub solver: &'static str,
    /// V-cycles or Newton iterations per frame.
    pub cycles: u64,
    /// Relative residual after frame [`FRAME_MARKS`]`[i]`.
    pub residuals: Vec<f64>,
    /// Mean wall time per frame (ms); for Newton-multigrid over the frames that iterated
    /// (a frame that starts within the stopping rule only evaluates the residual).
    pub ms_per_frame: f64,
}

/// The frames after which [`frame_budgets`] reads the residual.
pub const FRAME_MARKS: [usize; 5] = [1, 3, 10, 30, 100];

/// FAS as the interactive frame loop runs it (a frame = a fixed number of V-cycles, warm
/// started from the last frame) on `case` from rest, for each budget in `cycles`.
pub fn frame_budgets(case: &Case, cycles: &[u64]) -> Result<Vec<FrameRow>> {
    let sc = &case.scenario;
    let n = sc.mesh.num_nodes();
    let mut rows = Vec::new();
    for &k in cycles {
        let mut st = sc.stepper()?;
        let vmax = max_nodal(&st.finest().0.f_ext);
        let mut r = vec![0.0; 3 * n];
        let mut residuals = Vec::new();
        let mut wall = 0.0;
        let last = *FRAME_MARKS.last().unwrap_or(&1);
        for frame in 1..=last {
            let t0 = Instant::now();
            for _ in 0..k {
                st.advance()?;
            }
            wall += t0.elapsed().as_secs_f64();
            if FRAME_MARKS.contains(&frame) {
                let (sys, s) = st.finest();
                let u = s.u.clone();
                sys.residual(&u, &mut r)
                    .map_err(|e| Error::param("FAS", format!("{e:?}")))?;
                residuals.push(max_nodal(&r) / vmax);
            }
        }
        rows.push(FrameRow {
            case: case.name.clone(),
            solver: "FAS",
            cycles: k,
            residuals,
            ms_per_frame: 1e3 * wall / last as f64,
        });
    }
    Ok(rows)
}

/// Newton-multigrid as a frame loop would run it: `k` Newton iterations per frame
/// ([`DirectNewtonParams::max_newton`]), warm started from the last frame with the kept
/// hierarchy (the settings of a static scenario: [`MultigridPcg`]'s defaults with the
/// smoother of the element kind, [`raisov::scenario::StaticSolve::default_smoother`]), on
/// `case` from rest, for each budget in `iterations`. Each frame is one call of
/// [`DirectNewton::solve`], so its first iteration's forcing term is the loosest (0.5) and it
/// evaluates the residual once more.
pub fn newton_frame_budgets(case: &Case, iterations: &[usize]) -> Result<Vec<FrameRow>> {
    let sc = &case.scenario;
    let n = sc.mesh.num_nodes();
    let (_, down) = newton_mg_hierarchy(sc)?;
    let mut rows = Vec::new();
    for &k in iterations {
        let mut sys = sc.build_system()?;
        let vmax = max_nodal(&sys.f_ext);
        let f = sys.f_ext.clone();
        let model = &mut *sys.force;
        let mut newton = DirectNewton::with_levels(&*model, &sys.mass, &sys.constraints, &down)
            .map_err(|e| Error::param("Newton-multigrid", e.to_string()))?;
        let params = DirectNewtonParams {
            rel_tol: REL_TOL,
            abs_tol: ABS_TOL,
            max_newton: k,
            multigrid: Some(MultigridPcg {
                smoother: raisov::scenario::StaticSolve::default_smoother(sc.mesh.kind),
                ..Default::default()
            }),
            ..Default::default()
        };
        let mut u = vec![0.0; 3 * n];
        let mut residuals = Vec::new();
        let (mut wall, mut iterating) = (0.0, 0usize);
        let last = *FRAME_MARKS.last().unwrap_or(&1);
        for frame in 1..=last {
            let t0 = Instant::now();
            let out = newton
                .solve(
                    model,
                    &sys.springs,
                    &sys.constraints,
                    &f,
                    0.0,
                    &mut u,
                    params,
                )
                .map_err(|e| Error::param("Newton-multigrid", e.to_string()))?;
            if out.newton_steps > 0 {
                wall += t0.elapsed().as_secs_f64();
                iterating += 1;
            }
            if FRAME_MARKS.contains(&frame) {
                residuals.push(out.residual / vmax);
            }
        }
        rows.push(FrameRow {
            case: case.name.clone(),
            solver: "Newton-multigrid",
            cycles: k as u64,
            residuals,
            ms_per_frame: 1e3 * wall / iterating.max(1) as f64,
        });
    }
    Ok(rows)
}

/// The frame rows as a Markdown table.
pub fn frames_to_markdown(rows: &[FrameRow]) -> String {
    let mut s = String::from(
        "The frame loop, from rest: max nodal residual / max nodal load after frame k; work per frame: FAS V-cycles or Newton-multigrid iterations (ms per frame: Newton-multigrid's over the frames that iterated).\n\n| case | solver | work per frame | ms per frame |",
    );
    for m in FRAME_MARKS {
        s += &format!(" k = {m} |");
    }
    s += "\n|---|---|---:|---:|";
    for _ in FRAME_MARKS {
        s += "---:|";
    }
    s += "\n";
    for r in rows {
        s += &format!(
            "| {} | {} | {} | {:.1} |",
            r.case, r.solver, r.cycles, r.ms_per_frame
        );
        for x in &r.residuals {
            s += &format!(" {x:.2e} |");
        }
        s += "\n";
    }
    s
}
