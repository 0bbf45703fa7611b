//! The tables of `raisov bench equilibrium`: every row, the fastest solver of each case, and
//! Newton-multigrid (the default of a static scenario) against the goal of [`GOAL`] times
//! the best other solver's speed, with where its time went.

use super::{Row, ABS_TOL, AGREE_TOL, REL_TOL};

/// How many times faster than the best other solver the default static solver,
/// Newton-multigrid, is meant to be on every case.
pub const GOAL: f64 = 5.0;

/// The rows as a Markdown table, with the stopping rule above it.
pub fn to_markdown(rows: &[Row]) -> String {
    let mut s = format!(
        "Stop: max nodal residual over free nodes <= {REL_TOL:e} x max nodal load + {ABS_TOL:e} N; \
         agreement: max |u - u_Newton| <= {AGREE_TOL:e} x max |u|.\n\n\
         | case | nodes | solver | wall (s) | iterations | force evals (finest units) | final residual (N) | target (N) | converged | max \\|u\\| (m) | max \\|u - u_Newton\\| (m) | agrees | notes |\n\
         |---|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---|---|\n"
    );
    for r in rows {
        let iter_unit = match r.solver.as_str() {
            "direct Newton" | "Newton-multigrid" => "iterations",
            "FAS" => "cycles",
            "Chebyshev" => "iterations",
            _ => "steps",
        };
        let diff = r
            .diff_newton
            .map_or("-".to_string(), |d| format!("{d:.2e}"));
        let agrees = match r.agrees() {
            Some(true) => "yes",
            Some(false) => "**NO**",
            None => "-",
        };
        s += &format!(
            "| {} | {} | {} | {:.2} | {} {iter_unit} | {:.0} | {:.2e} | {:.2e} | {} | {:.4e} | {diff} | {agrees} | {} |\n",
            r.case,
            r.nodes,
            r.solver,
            r.wall_s,
            r.iterations,
            r.force_evaluations,
            r.residual,
            r.target,
            if r.converged { "yes" } else { "**NO**" },
            r.max_u,
            r.note
        );
    }
    s
}

/// Per case: the fastest solver that converged; the wall times of FAS (the default of a
/// `[multigrid]` run to steady state) and of Newton-multigrid (the default of a static
/// scenario, `method = "newton"` with `[multigrid]` levels); and for each of the two, the
/// fastest other solver's wall time over its own (> 1: it is that many times faster than
/// every other solver; [`GOAL`] is the goal for the default).
pub fn summary_markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| case | fastest | its wall (s) | FAS wall (s) | Newton-multigrid wall (s) | best other / FAS | best other / Newton-multigrid |\n|---|---|---:|---:|---:|---:|---:|\n",
    );
    for name in case_names(rows) {
        let done = converged(rows, name);
        let of = |solver: &str| done.iter().find(|r| r.solver == solver).copied();
        let ratio = |solver: &str| match (of(solver), fastest_other(&done, solver)) {
            (Some(r), Some(b)) => format!("{:.2}", b.wall_s / r.wall_s),
            _ => "-".to_string(),
        };
        let wall =
            |solver: &str| of(solver).map_or("-".to_string(), |r| format!("{:.2}", r.wall_s));
        match done.iter().min_by(|a, b| a.wall_s.total_cmp(&b.wall_s)) {
            Some(f) => {
                s += &format!(
                    "| {name} | {} | {:.2} | {} | {} | {} | {} |\n",
                    f.solver,
                    f.wall_s,
                    wall("FAS"),
                    wall("Newton-multigrid"),
                    ratio("FAS"),
                    ratio("Newton-multigrid"),
                )
            }
            None => s += &format!("| {name} | - | - | - | - | - | - (no solver converged) |\n"),
        }
    }
    s
}

/// The rows of case `name` that met the stopping rule.
fn converged<'a>(rows: &'a [Row], name: &str) -> Vec<&'a Row> {
    rows.iter()
        .filter(|r| r.case == name && r.converged)
        .collect()
}

/// The fastest of `done` other than `solver`.
fn fastest_other<'a>(done: &[&'a Row], solver: &str) -> Option<&'a Row> {
    done.iter()
        .filter(|r| r.solver != solver)
        .min_by(|a, b| a.wall_s.total_cmp(&b.wall_s))
        .copied()
}

/// The rows' case names, each once, in their first row's order.
fn case_names(rows: &[Row]) -> Vec<&str> {
    let mut names: Vec<&str> = Vec::new();
    for r in rows {
        if !names.contains(&r.case.as_str()) {
            names.push(&r.case);
        }
    }
    names
}

/// Per case, Newton-multigrid against [`GOAL`]: its wall time, the best other solver's, the
/// ratio, the time the goal allows (the best other's over [`GOAL`]) and where Newton-
/// multigrid's time went ([`super::Parts`]); below the table, for each case that misses the
/// goal, how much of the allowed time the parts that fewer CG iterations would not shorten
/// take alone. Cases where Newton-multigrid did not converge or has no parts are left out.
pub fn goal_markdown(rows: &[Row]) -> String {
    let mut s = format!(
        "Newton-multigrid against the goal of {GOAL}× the best other solver's speed; the time \
         the goal allows is the best other's over {GOAL}; where its time went (s): the coarse \
         start, the setup before the first iteration (levels, transfers, the tangent's \
         pattern), the Galerkin hierarchies (products, smoothers, coarse factors), the tangent \
         assemblies, the CG iterations and the rest (line searches' residuals and energies).\n\n\
         | case | Newton-multigrid (s) | best other | its wall (s) | × | allowed (s) | met | start | setup | hierarchies | assemblies | CG | rest |\n\
         |---|---:|---|---:|---:|---:|---|---:|---:|---:|---:|---:|---:|\n"
    );
    let mut misses = String::new();
    for name in case_names(rows) {
        let done = converged(rows, name);
        let Some((nmg, p)) = done
            .iter()
            .find(|r| r.solver == "Newton-multigrid")
            .and_then(|r| r.parts.map(|p| (r, p)))
        else {
            continue;
        };
        let Some(other) = fastest_other(&done, "Newton-multigrid") else {
            continue;
        };
        let ratio = other.wall_s / nmg.wall_s;
        let allowed = other.wall_s / GOAL;
        let met = ratio >= GOAL;
        s += &format!(
            "| {name} | {:.2} | {} | {:.2} | {ratio:.2} | {allowed:.2} | {} |{}\n",
            nmg.wall_s,
            other.solver,
            other.wall_s,
            if met { "yes" } else { "**no**" },
            p.all().map(|x| format!(" {x:.2} |")).concat(),
        );
        if !met {
            let fixed = p.fixed_s();
            let rest = if fixed >= allowed {
                String::new()
            } else {
                format!(
                    "; the CG iterations and the rest would have to fit in {:.2} s (they took {:.2} s)",
                    allowed - fixed,
                    p.cg_s + p.rest_s
                )
            };
            misses += &format!(
                "- {name}: {ratio:.2}×. The start, setup, hierarchies and assemblies alone took \
                 {fixed:.2} s, {:.0} % of the {allowed:.2} s the goal allows{rest}.\n",
                100.0 * fixed / allowed,
            );
        }
    }
    if !misses.is_empty() {
        s += "\n";
        s += &misses;
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::equilibrium::Parts;

    fn row(case: &str, solver: &str, wall_s: f64, parts: Option<Parts>) -> Row {
        Row {
            case: case.into(),
            nodes: 10,
            solver: solver.into(),
            wall_s,
            iterations: 1,
            force_evaluations: 1.0,
            residual: 0.0,
            target: 1.0,
            converged: true,
            max_u: 1.0,
            diff_newton: Some(0.0),
            note: String::new(),
            parts,
        }
    }

    /// The allowed time is the best other solver's over the goal; a miss says how much of
    /// it the fixed parts took; a case that meets the goal has no such line.
    #[test]
    fn goal_table_divides_the_best_other_by_the_goal() {
        let parts = Parts {
            start_s: 0.0,
            setup_s: 0.05,
            hierarchies_s: 0.2,
            assembly_s: 0.1,
            cg_s: 0.15,
            rest_s: 0.1,
        };
        let mut slow_other = row("b", "FAS", 4.0, None);
        slow_other.converged = true;
        let mut unconverged = row("a", "FAS", 0.1, None);
        unconverged.converged = false;
        let rows = [
            row("a", "direct Newton", 3.0, None),
            row("a", "Chebyshev", 2.0, None),
            unconverged,
            row("a", "Newton-multigrid", 0.6, Some(parts)),
            slow_other,
            row("b", "Newton-multigrid", 0.6, Some(parts)),
        ];
        let md = goal_markdown(&rows);
        // Case a: best converged other is Chebyshev's 2.0 s (the faster FAS did not
        // converge): 3.33×, 0.40 s allowed, 0.35 s of fixed parts (88 %).
        assert!(
            md.contains("| a | 0.60 | Chebyshev | 2.00 | 3.33 | 0.40 | **no** | 0.00 | 0.05 | 0.20 | 0.10 | 0.15 | 0.10 |"),
            "{md}"
        );
        assert!(md.contains("- a: 3.33×. The start, setup, hierarchies and assemblies alone took 0.35 s, 88 % of the 0.40 s the goal allows; the CG iterations and the rest would have to fit in 0.05 s (they took 0.25 s)."), "{md}");
        // Case b: 4.0 / 0.6 = 6.67 ≥ 5, met, no line below the table.
        assert!(
            md.contains("| b | 0.60 | FAS | 4.00 | 6.67 | 0.80 | yes |"),
            "{md}"
        );
        assert!(!md.contains("- b:"), "{md}");
    }

    /// Fixed parts beyond the allowed time say so without a remainder.
    #[test]
    fn goal_miss_beyond_the_allowed_time_has_no_remainder() {
        let parts = Parts {
            hierarchies_s: 0.3,
            assembly_s: 0.2,
            ..Default::default()
        };
        let rows = [
            row("h", "FAS", 2.0, None),
            row("h", "Newton-multigrid", 1.0, Some(parts)),
        ];
        let md = goal_markdown(&rows);
        assert!(
            md.contains("- h: 2.00×. The start, setup, hierarchies and assemblies alone took 0.50 s, 125 % of the 0.40 s the goal allows."),
            "{md}"
        );
    }
}
