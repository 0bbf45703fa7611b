//! How long the viewer's "RaISoV (paper)" method lasts on the shipped liver levels (L1-L3 of
//! `examples/liver_interactive.toml`) with nothing acting on the organ: frames of 40 cycles
//! from rest, for both readings of the paper, three switch thresholds ε (the default, 0:
//! always the state branch, 1e9 m: always the variation branch) and three time steps
//! (`[integrator] safety` × the estimated critical step). It prints, every 100 frames or at
//! the first rejected frame, the largest displacement (m) that grew from rounding alone.
//!
//! `cargo run --release -p raisov-serve --example raisov_drift`

use raisov::SchemeKind;
use raisov_serve::session::Source;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    for reading in ["correction", "paper"] {
        for eps in [None, Some(0.0), Some(1e9)] {
            for safety in [0.5, 0.1, 0.02] {
                let mut src =
                    Source::from_scenario_file("examples/liver_interactive.toml".as_ref())?;
                if let Some(toml::Value::Table(t)) = src.table.get_mut("integrator") {
                    t.insert("safety".into(), toml::Value::Float(safety));
                }
                if let Some(toml::Value::Table(t)) = src.table.get_mut("multigrid") {
                    t.insert("reading".into(), toml::Value::String(reading.into()));
                    if let Some(e) = eps {
                        t.insert("epsilon".into(), toml::Value::Float(e));
                    }
                }
                let mut sim = src.build(SchemeKind::RaisovPaper)?;
                let mut line = String::new();
                for k in 0..400 {
                    let r = sim.step_frame(raisov::sim::Budget::Cycles(40));
                    if k % 100 == 99 || !r.accepted {
                        let u = sim
                            .displacements()
                            .iter()
                            .fold(0.0f64, |a, b| a.max(b.abs()));
                        line += &format!(
                            " | frame {k}: t {:.3} s, max|u| {u:.1e} m{}",
                            sim.time(),
                            if r.accepted { "" } else { ", rejected" }
                        );
                        if !r.accepted {
                            break;
                        }
                    }
                }
                let eps = eps.map_or("default".to_string(), |e| format!("{e:e} m"));
                println!("reading {reading}, ε {eps}, safety {safety}{line}");
            }
        }
    }
    Ok(())
}
