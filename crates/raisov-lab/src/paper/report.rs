//! The files of `raisov paper`: CSV series, plots and `report.md` (its claims table in
//! `claims.rs`).
//!
//! One concern, the written record of the experiments: one function per experiment's CSV
//! files, plots and report section, in one file so the report and its series stay in step.

use super::claims::claims;
use super::experiments::{fmt_eps, Sim, MEMBRANE_PHYSICS, TISSUE_MATERIAL};
use super::{outcome_text, rel, tail_mean, Results, STEADY_TARGET};
use crate::plot::{write_chart, Panel};
use raisov::error::Result;
use raisov::io::write_atomic;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A number for CSV: empty when not finite.
fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.6e}")
    } else {
        String::new()
    }
}

fn opt(x: Option<f64>) -> String {
    x.map_or(String::new(), num)
}

fn write_text(path: &Path, text: &str, files: &mut Vec<PathBuf>) -> Result<()> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))?;
    files.push(path.to_path_buf());
    Ok(())
}

/// Time at which mean |T − T∞| first falls to `frac` of its initial value.
pub fn time_to(s: &Sim, frac: f64, max: bool) -> Option<f64> {
    let v = |p: &super::experiments::Pt| if max { p.max } else { p.mean };
    let v0 = v(&s.points[0]);
    s.points.iter().find(|p| v(p) <= frac * v0).map(|p| p.t)
}

fn series_csv(sims: &[Sim]) -> String {
    let mut t = String::from("method,dt_s,t_s,max_abs_T_minus_Tinf_Pa,mean_abs_T_minus_Tinf_Pa,residual_N,force_evals,wall_s\n");
    for s in sims {
        for p in &s.points {
            if !(p.max.is_finite() && p.mean.is_finite()) {
                continue;
            }
            let _ = writeln!(
                t,
                "{},{},{},{},{},{},{},{}",
                s.label,
                num(s.dt),
                num(p.t),
                num(p.max),
                num(p.mean),
                num(p.residual),
                p.evals,
                num(p.wall)
            );
        }
    }
    t
}

fn fig_panels(sims: &[Sim], what: &str) -> Vec<Panel> {
    let mk = |max: bool| Panel {
        title: format!(
            "{what}: {} |T - T_inf| over free nodes",
            if max { "max" } else { "mean" }
        ),
        x_label: "time (s)".into(),
        y_label: format!("{} |T - T_inf| (Pa)", if max { "max" } else { "mean" }),
        series: sims
            .iter()
            .map(|s| {
                (
                    s.label.clone(),
                    s.points
                        .iter()
                        .map(|p| (p.t, if max { p.max } else { p.mean }))
                        .collect(),
                )
            })
            .collect(),
        log_x: false,
        log_y: true,
        markers: false,
    };
    vec![mk(true), mk(false)]
}

/// Whether a method label is the FAS multigrid's.
fn is_fas(method: &str) -> bool {
    method.starts_with("FAS")
}

pub(super) fn fmt_opt_t(x: Option<f64>) -> String {
    x.map_or("not reached".into(), |t| format!("{t:.3} s"))
}

/// A CSV field: quoted (inner quotes doubled, RFC 4180) where it holds a comma, a quote or a
/// line break, as it is otherwise.
pub(super) fn q(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// CSV of the epsilon sweep (experiment 1).
fn csv_eps_sweep(res: &Results) -> String {
    let mut t = String::from("reading,epsilon_m,tail_mean_abs_T_minus_Tinf_Pa,outcome\n");
    for (r, e, s, o) in &res.eps_sweep {
        let _ = writeln!(t, "{},{},{},{}", q(r), num(*e), num(*s), q(o));
    }
    t
}

/// CSV of the largest stable steps and every bisection test (experiment 3).
fn csv_stability(res: &Results) -> (String, String) {
    let mut t = String::from("case,method,largest_stable_safety,smallest_unstable_safety,dt_estimate_s,largest_stable_dt_s,residual_drop_at_largest_stable\n");
    let mut tt = String::from("case,method,safety,stable\n");
    for r in res.stability.iter().filter(|r| !is_fas(&r.method)) {
        let _ = writeln!(
            t,
            "{},{},{},{},{},{},{}",
            q(&r.case),
            q(&r.method),
            opt(r.bisection.stable),
            opt(r.bisection.unstable),
            num(r.dt_estimate),
            opt(r.dt_stable()),
            opt(r.residual_drop)
        );
        for (s, ok) in &r.bisection.tests {
            let _ = writeln!(tt, "{},{},{},{}", q(&r.case), q(&r.method), num(*s), ok);
        }
    }
    (t, tt)
}

/// CSV of the largest pull each method survives (experiment 4).
fn csv_inversion(res: &Results) -> String {
    let mut t = String::from("method,law,largest_surviving_pull_m,smallest_failing_pull_m,failure,inverted_elements_at_end,min_det_f_at_end\n");
    for r in &res.inversion {
        let _ = writeln!(
            t,
            "{},{},{},{},{},{},{}",
            q(&r.method),
            r.law,
            opt(r.bisection.stable),
            opt(r.bisection.unstable),
            q(&r.failure.clone().unwrap_or_default()),
            r.end_state.map_or(String::new(), |e| e.0.to_string()),
            opt(r.end_state.map(|e| e.1))
        );
    }
    t
}

/// CSV of the cost of one step or cycle (experiment 5).
fn csv_cost(res: &Results) -> String {
    let mut t = String::from("mesh,level_nodes,slim_rk4_step_s,raisov_cycle_s,fas_cycle_s,raisov_over_slim,fas_over_slim,sum_nodes_over_finest,setup_s\n");
    for c in &res.cost {
        let sum: usize = c.level_nodes.iter().sum();
        let _ = writeln!(
            t,
            "{},{},{},{},{},{},{},{},{}",
            q(&c.mesh),
            c.level_nodes
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join("/"),
            num(c.slim_step),
            num(c.raisov_cycle),
            num(c.fas_cycle),
            num(c.raisov_cycle / c.slim_step),
            num(c.fas_cycle / c.slim_step),
            num(sum as f64 / c.level_nodes[0] as f64),
            num(c.setup)
        );
    }
    t
}

/// CSV of the time-to-steady runs and their series (experiment 6).
fn csv_steady(res: &Results) -> (String, String) {
    let mut t = String::from("mesh,finest_nodes,method,safety,dt_s,reached,sim_time_s,wall_s,force_evals,final_mean_over_initial,outcome\n");
    let mut ts = String::from("mesh,method,t_s,mean_abs_T_minus_Tinf_Pa,force_evals,wall_s\n");
    for r in &res.steady {
        match &r.sim {
            Some(s) => {
                let l = s.last();
                let (rt, rw, re) = match s.reached {
                    Some(p) => (num(p.t), num(p.wall), format!("{}", p.evals)),
                    None => (String::new(), String::new(), String::new()),
                };
                let _ = writeln!(
                    t,
                    "{},{},{},{},{},{},{},{},{},{},{}",
                    q(&r.mesh),
                    r.nodes,
                    q(&r.method),
                    num(r.safety),
                    num(s.dt),
                    s.reached.is_some(),
                    rt,
                    rw,
                    re,
                    num(l.mean / s.points[0].mean),
                    q(&outcome_text(s))
                );
                for p in &s.points {
                    if p.mean.is_finite() {
                        let _ = writeln!(
                            ts,
                            "{},{},{},{},{},{}",
                            q(&r.mesh),
                            q(&r.method),
                            num(p.t),
                            num(p.mean),
                            p.evals,
                            num(p.wall)
                        );
                    }
                }
            }
            None => {
                let _ = writeln!(
                    t,
                    "{},{},{},{},,false,,,,,{}",
                    q(&r.mesh),
                    r.nodes,
                    q(&r.method),
                    num(r.safety),
                    q(&r.note)
                );
            }
        }
    }
    (t, ts)
}

/// Write every CSV, plot and the report; fills `res.files`.
pub fn write_all(out: &Path, res: &mut Results) -> Result<()> {
    let mut files = std::mem::take(&mut res.files);
    // ---- CSV ----
    write_text(
        &out.join("fig5_lift.csv"),
        &series_csv(&res.lift),
        &mut files,
    )?;
    write_text(
        &out.join("fig5_drape.csv"),
        &series_csv(&res.drape),
        &mut files,
    )?;
    write_text(&out.join("eps_sweep.csv"), &csv_eps_sweep(res), &mut files)?;
    let (t, tt) = csv_stability(res);
    write_text(&out.join("stability.csv"), &t, &mut files)?;
    write_text(&out.join("stability_tests.csv"), &tt, &mut files)?;
    write_text(&out.join("inversion.csv"), &csv_inversion(res), &mut files)?;
    write_text(&out.join("cost.csv"), &csv_cost(res), &mut files)?;
    let (t, ts) = csv_steady(res);
    write_text(&out.join("steady_state.csv"), &t, &mut files)?;
    write_text(&out.join("steady_state_series.csv"), &ts, &mut files)?;
    if !res.equilibrium.is_empty() {
        write_text(
            &out.join("equilibrium.md"),
            &(crate::equilibrium::to_markdown(&res.equilibrium)
                + "\n"
                + &crate::equilibrium::summary_markdown(&res.equilibrium)
                + "\n"
                + &crate::equilibrium::goal_markdown(&res.equilibrium)),
            &mut files,
        )?;
    }

    // ---- plots ----
    files.extend(write_chart(
        out,
        "fig5_left_lift",
        &fig_panels(&res.lift, "Lift 3.0 cm"),
    )?);
    files.extend(write_chart(
        out,
        "fig5_right_drape",
        &fig_panels(&res.drape, "Drape"),
    )?);
    let mut methods: Vec<String> = Vec::new();
    for r in &res.steady {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    let steady_panel = |title: &str, y: &str, f: &dyn Fn(&super::experiments::Pt) -> f64| Panel {
        title: title.into(),
        x_label: "finest-level nodes".into(),
        y_label: y.into(),
        series: methods
            .iter()
            .map(|m| {
                (
                    m.clone(),
                    res.steady
                        .iter()
                        // Membranes only: the liver is another problem, not a point of the
                        // membrane size series (its numbers are in the table).
                        .filter(|r| &r.method == m && !r.mesh.starts_with("liver"))
                        .filter_map(|r| {
                            r.sim
                                .as_ref()
                                .and_then(|s| s.reached)
                                .map(|p| (r.nodes as f64, f(&p)))
                        })
                        .collect(),
                )
            })
            .collect(),
        log_x: true,
        log_y: true,
        markers: true,
    };
    files.extend(write_chart(
        out,
        "time_to_steady",
        &[
            steady_panel(
                "Time to steady state, membranes (mean |T-T_inf| <= 1e-3 of start): wall time",
                "wall time (s)",
                &|p| p.wall,
            ),
            steady_panel(
                "Time to steady state, membranes: force evaluations (finest-level units)",
                "force evaluations",
                &|p| p.evals,
            ),
        ],
    )?);
    let report_path = out.join("report.md");
    files.push(report_path.clone());
    res.files = files;
    let text = report_text(out, res);
    write_atomic(&report_path, |w| w.write_all(text.as_bytes()))?;
    Ok(())
}

/// Whether some RaISoV run reaches steady state before SLIM: SLIM's time, RaISoV's best
/// time, the verdict, and each RaISoV run's late mean (or "diverged").
pub(super) fn steady_sooner(
    slim: &Sim,
    rai: &[&Sim],
) -> (Option<f64>, Option<f64>, bool, Vec<String>) {
    let ts = time_to(slim, STEADY_TARGET, false);
    let best = rai
        .iter()
        .filter_map(|s| time_to(s, STEADY_TARGET, false))
        .fold(None, |a: Option<f64>, t| Some(a.map_or(t, |a| a.min(t))));
    let holds = match (best, ts) {
        (Some(a), Some(b)) => a < b,
        (Some(_), None) => true,
        _ => false,
    };
    let levels = rai
        .iter()
        .map(|s| {
            let state = if s.diverged() {
                "diverged".to_string()
            } else {
                format!("late mean {:.2e} Pa", tail_mean(s))
            };
            format!("{}: {state}", s.label)
        })
        .collect();
    (ts, best, holds, levels)
}

pub(super) fn find<'a>(sims: &'a [Sim], prefix: &str) -> Vec<&'a Sim> {
    sims.iter()
        .filter(|s| s.label.starts_with(prefix))
        .collect()
}

pub(super) fn yes(b: bool) -> &'static str {
    if b {
        "yes"
    } else {
        "**no**"
    }
}

/// "yes" when every decided case holds, "partly" when some do, "no" when none; cases where
/// nothing was reached within the caps are undecided and said so.
pub(super) fn verdict(holds: usize, decided: usize, undecided: usize) -> String {
    let v = if decided == 0 {
        "undecided".to_string()
    } else if holds == decided {
        "yes".to_string()
    } else if holds > 0 {
        format!("**partly** ({holds} of {decided})")
    } else {
        "**no**".to_string()
    };
    if undecided > 0 {
        format!(
            "{v}; {undecided} mesh(es) undecided (nothing reached steady state within the caps)"
        )
    } else {
        v
    }
}

pub(super) fn stab<'a>(
    res: &'a Results,
    case: &str,
    key_prefix: &str,
) -> Vec<&'a super::StabilityRow> {
    res.stability
        .iter()
        .filter(|r| r.case == case && r.key.starts_with(key_prefix))
        .collect()
}

pub(super) fn fmt_safety(b: &super::experiments::Bisection) -> String {
    match (b.stable, b.unstable) {
        (Some(s), Some(u)) => format!("{s:.3} (fails at {u:.3})"),
        (Some(s), None) => format!(">= {s:.3} (range top)"),
        (None, Some(u)) => format!("< {u:.3} (range bottom)"),
        (None, None) => "-".into(),
    }
}

fn report_text(out: &Path, res: &Results) -> String {
    let mut r = String::new();
    let w = &mut r;
    parameters(w, res);
    abbreviations(w);
    claims(w, res);
    section_perturbation(w, res);
    section_drape(w, res);
    section_stability(w, res);
    section_inversion(w, res);
    section_cost(w, res);
    section_steady(w, res);
    section_equilibrium(w, res);
    closing(w, out, res);
    r
}

/// The title, the configuration and the parameters every claim uses.
fn parameters(w: &mut String, res: &Results) {
    let _ = writeln!(w, "# raisov paper: Wu & Tendick 2004 reproduced\n");
    let _ = writeln!(
        w,
        "Configuration: {}. Total wall time {:.1} s (2-core machine shared with other work; timings are best-of-repetitions where stated).\n",
        if res.tiny {
            "tiny (test)"
        } else if res.quick {
            "--quick (smaller hierarchies, fewer bisection steps, no 100k-node runs)"
        } else {
            "full"
        },
        res.wall
    );
    let _ = writeln!(w, "## Parameters (chosen once, used for every claim)\n");
    let _ = writeln!(w, "- Membrane (sections 3.1, 3.2): 10 cm x 10 cm, all four sides fixed, levels of {:?} node targets (generated quality triangulations, not the paper's Triangle meshes), Mooney-Rivlin C1 = C2 = 1 kPa (the paper's `1.0` read as kPa), density 1000 kg/m^3, thickness 1 mm, SI units throughout.", res.membrane_nodes);
    let _ = writeln!(w, "- Damping: mass-proportional D = alpha M with the paper's ratio 1.0 read as alpha = 2 zeta omega, zeta = 1, omega = 177.7 rad/s (lowest in-plane mode of the fixed square): alpha = {:.1} 1/s.", res.alpha);
    let _ = writeln!(w, "- Damping per method: SLIM (every integrator) and RaISoV (every level) integrate eq. 5 with this alpha, the same for all, not tuned per method. Its effect: the drape's sag is governed by a transverse mode, not the in-plane one alpha is set on, and a transverse mode near 50-55 rad/s (issue 23's measurement on the 187-node membrane) is about 3x over-damped (critical there is alpha of about 100-110 1/s), which slows single-level integration's approach to steady state; alpha is not tuned per method in this report. FAS does not use alpha: it solves the static problem (its cycles are not time steps). 3-D cases: the rule below, the same for every method.");
    let _ = writeln!(w, "- Integrators: RK4 (the paper's) for SLIM and on every RaISoV level, one step size for all RaISoV levels (as the paper); SLIM at 0.5 x its estimated critical step, dt = {:.3e} s; RaISoV at twice that in the lift (the paper's 10 ms against 5 ms) and at the same step in the drape (the paper's 10 ms for both); the project's FAS multigrid at its defaults (Chebyshev smoother over [1.2 lambda_max / 100, 1.2 lambda_max] of M^-1 K with lambda_max by power iteration, 4+4 sweeps per level, 60 Chebyshev sweeps on the coarsest level, each cycle preconditioning a Polak-Ribiere nonlinear conjugate-gradient step with a secant line search).", res.dt_slim);
    let _ = writeln!(w, "- RaISoV epsilon: the default is 1e-3 x the finest mesh's shortest edge = {}; the best epsilon per reading is chosen by the sweep below (lowest late mean |T - T_inf| on the 3 cm lift) and then used everywhere. Readings `paper` (eq. 8 literally) and `correction` (classic coarse-grid correction), see the documentation of `raisov::multigrid::raisov`.", fmt_eps(res.eps_default));
    let _ = writeln!(w, "- Liver (`liver_L*.msh`, mm scaled by 0.001): held on the cap of its top (z >= 195 mm: 249/127/72/43 nodes on L0..L3), under gravity (0, 0, -9.81) m/s^2 from rest; T_inf by Newton-Krylov on the finest mesh with the load in 4 increments, to 1e-7 of the load (dynamic relaxation if a Newton step inverts an element); time-to-steady runs capped at 3x the membranes' wall cap.
- 3-D (block, liver): neo-Hookean E = 5 kPa, nu = 0.45, density 1060 kg/m^3, damping ratio 1 at omega = pi sqrt(2) c_s / L (c_s = sqrt(mu/rho), L the body's size, the membrane's rule).");
    let _ = writeln!(w, "- |T - T_inf|: Frobenius norm of the nodal Cauchy stress difference on the finest mesh, max and mean over non-fixed nodes. T_inf: {} (lift); {} (drape).", res.lift_ref, res.drape_ref);
    let _ = writeln!(w, "- Steady state: mean |T - T_inf| <= {STEADY_TARGET:e} x its initial value. Stable: the run completes with no non-finite value, no inverted element and no kinetic-energy blow-up.\n");
}

/// Every abbreviation the report, the tables and the plots use.
fn abbreviations(w: &mut String) {
    let _ = writeln!(w, "## Abbreviations\n");
    for (a, what) in [
        ("SLIM", "single-level integration method: one integrator step per time step on the finest mesh alone (the paper's term)"),
        ("RaISoV", "the multigrid integrator of Wu & Tendick (2004): one V-cycle per time step, RK4 on every level"),
        ("FAS", "full approximation scheme: the project's convergent multigrid built from the paper's ingredients"),
        ("V-cycle", "one pass from the finest level down to the coarsest and back up"),
        ("RK4", "the classic fourth-order Runge-Kutta integrator"),
        ("eps (epsilon)", "RaISoV's switch threshold of eqs. 10 and 12 (m): a transferred displacement change larger than it is passed on as a state, a smaller one as a variation"),
        ("T, T_inf", "nodal Cauchy stress, and its value at steady state"),
        ("dt", "time step (s)"),
        ("L0..L3", "the liver meshes, finest (L0) to coarsest (L3)"),
    ] {
        let _ = writeln!(w, "- **{a}**: {what}");
    }
    let _ = writeln!(w);
}

/// One row per run: step, outcome, times to the targets, late level.
fn sim_table(w: &mut String, sims: &[Sim]) {
    let _ = writeln!(w, "| method | dt (s) | outcome | time to max <= 10% | time to mean <= 1e-3 | late mean abs(T - T_inf) (Pa) | residual last/peak |");
    let _ = writeln!(w, "|---|---|---|---|---|---|---|");
    for s in sims {
        let _ = writeln!(
            w,
            "| {} | {:.3e} | {} | {} | {} | {:.3e} | {:.1e} |",
            s.label,
            s.dt,
            outcome_text(s),
            fmt_opt_t(time_to(s, 0.1, true)),
            fmt_opt_t(time_to(s, STEADY_TARGET, false)),
            tail_mean(s),
            s.residual_drop
        );
    }
    let _ = writeln!(w);
}

/// Section 1: the lift runs and the epsilon sweep.
fn section_perturbation(w: &mut String, res: &Results) {
    let _ = writeln!(
        w,
        "## 1. Perturbation response (section 3.1, Fig. 5 left)\n"
    );
    let _ = writeln!(w, "Centre node lifted 3.0 cm at t = 0 and held. Plot: `fig5_left_lift.png` / `.svg`; series: `fig5_lift.csv`.\n");
    sim_table(w, &res.lift);
    regulation_and_switches(w, &res.lift);
    let _ = writeln!(w, "RaISoV epsilon sweep (3 cm lift, RaISoV at twice SLIM's step; score: mean abs(T - T_inf) over the last tenth of the run; `eps_sweep.csv`):\n");
    let _ = writeln!(w, "| reading | epsilon | late mean (Pa) | outcome |");
    let _ = writeln!(w, "|---|---|---|---|");
    for (rd, e, s, o) in &res.eps_sweep {
        let _ = writeln!(
            w,
            "| {rd} | {} | {} | {o} |",
            fmt_eps(*e),
            if s.is_finite() {
                format!("{s:.3e}")
            } else {
                "diverged".into()
            }
        );
    }
    let _ = writeln!(w);
}

/// Section 2: the drape runs.
fn section_drape(w: &mut String, res: &Results) {
    let _ = writeln!(
        w,
        "## 2. Draping under gravity (section 3.2, Fig. 5 right)\n"
    );
    let _ = writeln!(
        w,
        "Plot: `fig5_right_drape.png` / `.svg`; series: `fig5_drape.csv`.\n"
    );
    sim_table(w, &res.drape);
}

/// Section 3: the largest stable steps.
fn section_stability(w: &mut String, res: &Results) {
    let _ = writeln!(w, "## 3. Largest stable time step\n");
    let _ = writeln!(w, "Bisection (geometric) on the step as a multiple of the finest mesh's estimated critical step for the method's integrator, in [0.25, 8]; a test runs as many steps (V-cycles for the multigrids) as SLIM RK4 at its default step needed to reach steady state in experiments 1-2 ({}), stopping early once steady (residual 1e-6 of its peak). `converges` = the run at the largest stable step brought the residual down by 1e-6 of its peak; otherwise it only stayed bounded. `stability.csv`, `stability_tests.csv`.\n",
        res.stab_steps.iter().map(|(k, v)| format!("{k}: {v} steps")).collect::<Vec<_>>().join(", "));
    let _ = writeln!(w, "FAS has no rows here: its smoother and coarse solves do not use the time step Δ (they are not time integrators), so a largest stable Δ means nothing for it.\n");
    let _ = writeln!(w, "| case | method | largest stable (x estimate) | largest stable dt (s) | over SLIM RK4 | residual last/peak | converges? |");
    let _ = writeln!(w, "|---|---|---|---|---|---|---|");
    for r in res.stability.iter().filter(|r| !is_fas(&r.method)) {
        let slim = stab(res, &r.case, "slim-rk4")
            .first()
            .and_then(|x| x.dt_stable());
        let _ = writeln!(
            w,
            "| {} | {} | {} | {} | {} | {} | {} |",
            r.case,
            r.method,
            fmt_safety(&r.bisection),
            r.dt_stable().map_or("-".into(), |d| format!("{d:.3e}")),
            match (r.dt_stable(), slim) {
                (Some(a), Some(b)) => format!("{:.2}x", a / b),
                _ => "-".into(),
            },
            r.residual_drop.map_or("-".into(), |d| format!("{d:.1e}")),
            r.residual_drop.map_or("-", |d| if d <= 1e-6 {
                "converges"
            } else {
                "bounded only"
            })
        );
    }
    let _ = writeln!(w);
}

/// Section 4: element inversion.
fn section_inversion(w: &mut String, res: &Results) {
    let _ = writeln!(w, "## 4. Element inversion in 3-D (section 3.3)\n");
    let _ = writeln!(w, "{}. Bisection on the pull distance in [0.2, 18] mm. With the neo-Hookean law a method survives a pull if no element inverts and the run stays finite and bounded; with stable neo-Hookean (finite energy through inversion, Smith, de Goes & Kim 2018) an inverted element does not end the run, so a method survives if the run stays finite and bounded, and the last columns count the elements still inverted at the end of the hold of the largest pull survived (the law's restoring force should bring them back). `inversion.csv`.\n", res.block_desc);
    let _ = writeln!(
        w,
        "| method | law | largest pull survived | smallest pull failed | failure | inverted at the end | min det F at the end |"
    );
    let _ = writeln!(w, "|---|---|---|---|---|---|---|");
    for r in &res.inversion {
        let _ = writeln!(
            w,
            "| {} | {} | {} | {} | {} | {} | {} |",
            r.method,
            r.law,
            r.bisection
                .stable
                .map_or("< 0.2 mm".into(), |x| format!("{:.2} mm", x * 1e3)),
            r.bisection
                .unstable
                .map_or("none up to 18 mm".into(), |x| format!("{:.2} mm", x * 1e3)),
            r.failure.clone().unwrap_or_default(),
            r.end_state.map_or("-".into(), |e| e.0.to_string()),
            r.end_state.map_or("-".into(), |e| format!("{:.3}", e.1)),
        );
    }
    let _ = writeln!(w);
}

/// Section 5: the cost of one V-cycle.
fn section_cost(w: &mut String, res: &Results) {
    let _ = writeln!(w, "## 5. Cost of one V-cycle (eq. 14)\n");
    let _ = writeln!(w, "Wall time per step, best of several repetitions, all measured in one process side by side (drape, RK4 on every level, Rayon on the machine's cores). The flop-count bound is sum of level nodes over finest nodes (about 2 for ratio 0.5) plus transfers. `cost.csv`.\n");
    let _ = writeln!(w, "| mesh | level nodes | SLIM RK4 step | RaISoV cycle | RaISoV / SLIM | node sum / finest | FAS cycle | FAS / SLIM | setup (mesh, levels, maps) |");
    let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|");
    for c in &res.cost {
        let sum: usize = c.level_nodes.iter().sum();
        let _ = writeln!(
            w,
            "| {} | {} | {:.3e} s | {:.3e} s | {:.2} | {:.2} | {:.3e} s | {:.1} | {:.1} s |",
            c.mesh,
            c.level_nodes
                .iter()
                .map(|n| n.to_string())
                .collect::<Vec<_>>()
                .join("/"),
            c.slim_step,
            c.raisov_cycle,
            c.raisov_cycle / c.slim_step,
            sum as f64 / c.level_nodes[0] as f64,
            c.fas_cycle,
            c.fas_cycle / c.slim_step,
            c.setup
        );
    }
    let _ = writeln!(w);
}

/// Section 6: time to steady state.
fn section_steady(w: &mut String, res: &Results) {
    let _ = writeln!(w, "## 6. Time to steady state\n");
    let _ = writeln!(w, "Each method at 0.9 x its own largest stable step found on the paper's drape (experiment 3; as a multiple of each mesh's own estimated critical step; a run that diverges on another mesh is retried at half the step, twice at most, and says so), until mean abs(T - T_inf) <= 1e-3 of its start, capped by wall time and simulated time. The membranes of 10k+ nodes use a hierarchy of ratio 0.5 down to about 500-1000 nodes (the finest mesh, the one SLIM runs on, is the same). FAS runs first; symplectic Euler, the strongest single-level integrator, then runs until it reaches the target or has spent at least 6x FAS's wall time and force evaluations to the target (at most 3x its cap), so that the 5x comparison is decided{}. Wall time excludes setup, T_inf and the measurements themselves (stress and residual samples). Plot: `time_to_steady.png` / `.svg`; `steady_state.csv`, `steady_state_series.csv`.\n", match res.slim_cap { Some(c) => format!(" (in this run at least {c:.0} s of wall time, `--slim-cap`, so that it can reach the target)"), None => String::new() });
    let _ = writeln!(w, "| mesh | finest nodes | method | dt (s) | simulated time | wall time | force evaluations | final mean / start | residual last/peak | outcome |");
    let _ = writeln!(w, "|---|---|---|---|---|---|---|---|---|---|");
    for r in &res.steady {
        match &r.sim {
            Some(s) => {
                let l = s.last();
                let _ = writeln!(
                    w,
                    "| {} | {} | {} | {:.3e} | {} | {} | {} | {} | {:.1e} | {} |",
                    r.mesh,
                    r.nodes,
                    r.method,
                    s.dt,
                    s.reached
                        .map_or(format!("not reached by {:.3} s", l.t), |p| format!(
                            "{:.3} s",
                            p.t
                        )),
                    s.reached
                        .map_or(format!("not reached in {:.1} s", l.wall), |p| format!(
                            "{:.2} s",
                            p.wall
                        )),
                    s.reached.map_or("-".into(), |p| format!("{:.0}", p.evals)),
                    {
                        let x = l.mean / s.points[0].mean;
                        if x.is_finite() {
                            format!("{x:.1e}")
                        } else {
                            "no T_inf".into()
                        }
                    },
                    s.residual_drop,
                    if r.note.is_empty() {
                        outcome_text(s)
                    } else {
                        format!("{} ({})", outcome_text(s), r.note)
                    }
                );
            }
            None => {
                let _ = writeln!(
                    w,
                    "| {} | {} | {} | - | - | - | - | - | {} |",
                    r.mesh, r.nodes, r.method, r.note
                );
            }
        }
    }
    let _ = writeln!(w);
}

/// Section 7: the five static solvers side by side ([`crate::equilibrium`]).
fn section_equilibrium(w: &mut String, res: &Results) {
    let _ = writeln!(
        w,
        "## 7. Static equilibrium, five solvers side by side
"
    );
    if res.equilibrium.is_empty() {
        let _ = writeln!(
            w,
            "Not run in this configuration (see the notes).
"
        );
        return;
    }
    let _ = writeln!(w, "Direct Newton (sparse Cholesky), FAS, adaptive dynamic relaxation, single-level Chebyshev and Newton-multigrid (CG preconditioned by a Galerkin V-cycle) from rest to one stopping rule, each at the fastest of its variants; cases, settings and what is timed: module docs of `raisov_lab::equilibrium` (the same run as `raisov bench equilibrium`{}). Also in `equilibrium.md`.
", if res.equilibrium_full { "" } else { " --quick" });
    let _ = writeln!(w, "{}\n", equilibrium_cases_line(res));
    let _ = writeln!(w, "{}", crate::equilibrium::to_markdown(&res.equilibrium));
    let _ = writeln!(
        w,
        "{}",
        crate::equilibrium::summary_markdown(&res.equilibrium)
    );
    let _ = writeln!(w, "{}", crate::equilibrium::goal_markdown(&res.equilibrium));
}

/// Which of section 7's cases ran: its quick cases unless `raisov paper --equilibrium`.
pub(super) fn equilibrium_cases_line(res: &Results) -> String {
    let cases = res.equilibrium_cases.join(", ");
    if res.equilibrium_full {
        format!("Cases run: {cases} (every case, `raisov paper --equilibrium`).")
    } else {
        format!(
            "Cases run: {cases}, the quick cases of `raisov bench equilibrium --quick`; \
             `raisov paper --equilibrium` (or `raisov bench equilibrium`) runs every case: the \
             liver L1 and L0, the liver L1 pulled, the heart L0 and the 10k and 100k drapes."
        )
    }
}

/// Stage times, notes, abbreviations, the scenario text and the list of files.
fn closing(w: &mut String, out: &Path, res: &Results) {
    let _ = writeln!(
        w,
        "Stage wall times (cumulative): {}.\n",
        res.stages
            .iter()
            .map(|(k, v)| format!("{k} {v:.1} s"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if !res.notes.is_empty() {
        let _ = writeln!(w, "## Notes\n");
        for n in &res.notes {
            let _ = writeln!(w, "- {n}");
        }
        let _ = writeln!(w);
    }
    let _ = writeln!(w, "## Scenario text\n");
    let _ = writeln!(w, "Every run is a scenario; one per case and method (at its default step) is under `scenarios/` and runs alone with `raisov run FILE`. The membrane's physics in all of them:\n\n```toml\n{MEMBRANE_PHYSICS}```\n\nThe 3-D material:\n\n```toml\n{TISSUE_MATERIAL}```\n");
    let _ = writeln!(w, "## Files\n");
    for f in &res.files {
        let _ = writeln!(w, "- `{}`", rel(f, out));
    }
}

/// Decay rates of max |T − T∞| over the first tenth of a run and over the rest:
/// `(early, late)` in 1/s, `ln(m(0)/m(t1))/t1` and `ln(m(t1)/m(T))/(T − t1)`, with `t1`
/// the first sample at or after a tenth of the run. `None` without enough finite samples.
pub(crate) fn regulation_rates(s: &Sim) -> Option<(f64, f64)> {
    let pts: Vec<_> = s
        .points
        .iter()
        .filter(|p| p.max.is_finite() && p.max > 0.0)
        .collect();
    let (first, last) = (pts.first()?, pts.last()?);
    let span = last.t - first.t;
    if span <= 0.0 {
        return None;
    }
    let mid = pts.iter().find(|p| p.t - first.t >= 0.1 * span)?;
    let (t1, t2) = (mid.t - first.t, last.t - mid.t);
    if t1 <= 0.0 || t2 <= 0.0 {
        return None;
    }
    Some((
        (first.max / mid.max).ln() / t1,
        (mid.max / last.max).ln() / t2,
    ))
}

/// Whether the lift's early regulation plateaus (decay rates of max |T − T∞| early and
/// late), and how often RaISoV's transfers took the state branch of eqs. 10 and 12.
fn regulation_and_switches(w: &mut String, lift: &[Sim]) {
    let _ = writeln!(w, "Early regulation and its plateau (3 cm lift): decay rate of m = max abs(T - T_inf), ln(m(0)/m(t1))/t1 over the first tenth of the run and ln(m(t1)/m(T))/(T - t1) over the rest (T: the run's last sample); \"plateaus\" when the late rate is below a tenth of the early one while m(T)/m(0) is still above {STEADY_TARGET:e} (a run that has settled is not on a plateau):\n");
    let _ = writeln!(
        w,
        "| method | early rate (1/s) | late rate (1/s) | late / early | m(T)/m(0) | plateaus |"
    );
    let _ = writeln!(w, "|---|---|---|---|---|---|");
    for s in lift {
        let first = s.points.first().map_or(f64::NAN, |p| p.max);
        let drop = s.last().max / first;
        match regulation_rates(s) {
            Some((e, l)) => {
                let ratio = l / e;
                let plateau = e > 0.0 && ratio < 0.1 && drop > STEADY_TARGET;
                let _ = writeln!(
                    w,
                    "| {} | {e:.3} | {l:.3} | {ratio:.3} | {drop:.2e} | {} |",
                    s.label,
                    if plateau { "yes" } else { "no" }
                );
            }
            None => {
                let _ = writeln!(w, "| {} | - | - | - | {drop:.2e} | - |", s.label);
            }
        }
    }
    let _ = writeln!(w);
    let runs: Vec<_> = lift
        .iter()
        .filter_map(|s| s.switches.map(|c| (s, c)))
        .collect();
    if runs.is_empty() {
        return;
    }
    let _ = writeln!(w, "RaISoV's switches over the lift (the paper says condition (10) is \"not satisfied for most nodes\"): node transfers per stroke that passed the state (transferred displacement change above eps, eqs. 10 and 12) or a variation (at most eps), summed over the run:\n");
    let _ = writeln!(w, "| method | down: state / variation | up: state / variation | state fraction, down (eq. 10) | state fraction, all |");
    let _ = writeln!(w, "|---|---|---|---|---|");
    let frac = |f: Option<f64>| f.map_or("-".to_string(), |f| format!("{f:.4}"));
    for (s, c) in runs {
        let _ = writeln!(
            w,
            "| {} | {} / {} | {} / {} | {} | {} |",
            s.label,
            c.down_state,
            c.down_variation,
            c.up_state,
            c.up_variation,
            frac(c.down_state_fraction()),
            frac(c.state_fraction())
        );
    }
    let _ = writeln!(w);
}
