//! The frames of an interactive run stepped through a [`Simulation`], as a host program or
//! the viewer steps its own ([`crate::sim::frame`]): each frame holds the scenario's
//! prescribed displacements at the frame's values (their moves counted in the frame
//! predictor's, [`crate::sim::frame`]), makes
//! the cuts, lets go of the grasps, takes the pins and the grasps before the frames the
//! scenario says (what `raisov serve` records; the rules of [`crate::scenario::grasps`]),
//! moves the grasps along their paths, and runs the frame's budget
//! ([`Simulation::step_frame`]); [`super::run_frames`] writes the frames and the summary.
//!
//! A scenario that takes nothing during the run is run as its own stepper would run it alone:
//! the stepper keeps the scenario's kinetic-energy ceiling and a diverging step ends the run
//! ([`crate::Error::Diverged`]) instead of being rejected and retried.

use super::frames::{no_interactive, run_frames, FrameStepper, InteractiveSummary};
use super::RunOptions;
use crate::error::{Error, Result};
use crate::integrate::Stepper;
use crate::numbers::compact;
use crate::scenario::grasps::{frame_of, Grasp, Pin};
use crate::scenario::interactive;
use crate::scenario::Scenario;
use crate::sim::{Budget, Coupling, GrabId, GrabOptions, Simulation};
use std::path::PathBuf;

/// Run the scenario interactively with `stepper` (the scenario's, [`Scenario::stepper`]), what
/// `raisov run` does: its frames stepped through a [`Simulation`]
/// ([`Replay`], [`run_frames`]), which takes, moves and lets go of the grasps and takes the pins and cuts the
/// scenario says, if any. Errors: the scenario has no `[interactive]` section, a diverging
/// stepper in a scenario that takes nothing during the run (with step and element), a grasp
/// or pin whose patch is all constrained already (naming its entry and frame), a reference
/// solve that inverts an element, or an output file that cannot be written.
pub fn run_interactive(
    sc: &Scenario,
    stepper: Box<dyn Stepper>,
    opts: RunOptions,
) -> Result<InteractiveSummary> {
    let mut replay = Replay::new(sc, stepper)?;
    run_frames(sc, &mut replay, opts)
}

/// The frames of an interactive run through a [`Simulation`] (module docs).
pub struct Replay {
    sim: Simulation,
    path: PathBuf,
    grasps: Vec<Grasp>,
    pins: Vec<Pin>,
    cuts: Vec<crate::scenario::cuts::Cut>,
    fps: f64,
    budget: Budget,
    /// Nothing is taken during the run: a diverging step is the run's error (module docs).
    strict: bool,
    /// Per grasp, while held: its id and grasp point `g`.
    held: Vec<Option<(GrabId, [f64; 3])>>,
    /// A frame that moved a grasp was rejected: later ones are tried once.
    stuck: bool,
    retries: u32,
}

impl Replay {
    /// The replay of `sc`'s frames on `stepper` (the scenario's); an error for a scenario
    /// without `[interactive]`.
    pub fn new(sc: &Scenario, stepper: Box<dyn Stepper>) -> Result<Replay> {
        let Some(settings) = sc.interactive else {
            return Err(no_interactive(sc));
        };
        let budget = match settings.budget {
            interactive::Budget::Cycles(c) => Budget::Cycles(c.min(u32::MAX as usize) as u32),
            interactive::Budget::Wall(w) => Budget::Millis(w * 1e3),
        };
        let strict = sc.grasps.is_empty() && sc.pins.is_empty() && sc.cuts.is_empty();
        let mut sim = Simulation::with_stepper(sc, stepper, strict)?;
        sim.set_predictor(settings.predictor);
        let retries = sim.max_retries();
        Ok(Replay {
            sim,
            path: sc.path.clone(),
            grasps: sc.grasps.clone(),
            pins: sc.pins.clone(),
            cuts: sc.cuts.clone(),
            fps: settings.fps,
            budget,
            strict,
            held: vec![None; sc.grasps.len()],
            stuck: false,
            retries,
        })
    }

    /// The simulation (its state after the last frame).
    pub fn simulation(&self) -> &Simulation {
        &self.sim
    }

    /// Per `[[displace]]` grasp of the scenario (in file order), the force the tissue
    /// exerts on it now ([`Simulation::grab_force`], N); `None` for one not held.
    pub fn grasp_forces(&self) -> Vec<Option<[f64; 3]>> {
        self.held
            .iter()
            .map(|h| h.and_then(|(id, _)| self.sim.grab_force(id).ok()))
            .collect()
    }

    fn unstick(&mut self) {
        if self.stuck {
            self.stuck = false;
            self.sim.set_max_retries(self.retries);
        }
    }
}

impl FrameStepper for Replay {
    fn stepper(&mut self) -> &mut dyn Stepper {
        self.sim.stepper_mut()
    }

    fn cut_mesh(&self) -> Option<&crate::mesh::cut::CutMesh> {
        self.sim.cut_mesh()
    }

    fn frame(&mut self, k: usize, t: f64, values: &[[f64; 3]]) -> Result<Option<String>> {
        self.sim.hold_prescribed(values);
        let path = &self.path;
        let at = |what: String, e: Error| Error::Scenario {
            path: path.clone(),
            line: None,
            msg: format!("{what}: at t = {} s (frame {k}): {e}", compact(t)),
        };
        let fps = self.fps;
        for c in self.cuts.iter().filter(|c| frame_of(c.time, fps) == k) {
            self.sim
                .cut(&c.blade)
                .map_err(|e| at(format!("cut[{}]", c.index), e))?;
        }
        let mut released = false;
        for (g, held) in self.grasps.iter().zip(&mut self.held) {
            if g.release.is_some_and(|r| frame_of(r, fps) == k) {
                if let Some((id, _)) = held.take() {
                    self.sim
                        .release(id)
                        .map_err(|e| at(format!("displace[{}]", g.index), e))?;
                    released = true;
                }
            }
        }
        for p in self.pins.iter().filter(|p| frame_of(p.start, fps) == k) {
            self.sim
                .pin(p.point, p.radius)
                .map_err(|e| at(format!("pin[{}]", p.index), e))?;
        }
        for (g, held) in self.grasps.iter().zip(&mut self.held) {
            if frame_of(g.start, fps) == k {
                let coupling = match g.stiffness {
                    Some(stiffness) => Coupling::Spring { stiffness },
                    None => Coupling::Hard,
                };
                let options = GrabOptions {
                    radius: g.radius,
                    coupling,
                    grip: g.grip,
                };
                let id = self
                    .sim
                    .grab_with(g.point, options)
                    .map_err(|e| at(format!("displace[{}]", g.index), e))?;
                *held = Some((id, self.sim.grab_position(id)?));
            }
        }
        if released {
            self.unstick();
        }
        let mut moving = false;
        for (g, held) in self.grasps.iter().zip(&self.held) {
            if let Some((id, p)) = *held {
                let d = g.motion.displacement(t);
                let target = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                self.sim.move_grab(id, target)?;
                moving |= self.sim.grab_position(id)? != target;
            }
        }
        let report = if self.strict {
            self.sim
                .step_frame_strict(self.budget)
                .map_err(Error::Diverged)?
        } else {
            self.sim.step_frame(self.budget)
        };
        if moving && report.accepted {
            self.unstick();
        } else if moving && !self.stuck {
            self.stuck = true;
            self.sim.set_max_retries(0);
        }
        Ok(if report.accepted {
            None
        } else {
            Some(report.rejection.unwrap_or_else(|| "rejected".into()))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runner::read_frames_csv;
    use std::path::Path;

    /// A 4 cm cube of soft tissue fixed at its base, damped explicit dynamics, `extra` added
    /// (grasps, pins), frames at 30 per second of path time with 40 steps each, `reference`
    /// the `[interactive]` lines of the static reference.
    fn cube(extra: &str, duration: f64, reference: &str) -> Scenario {
        let text = format!(
            r#"
[mesh]
generate = "box"
size = [0.04, 0.04, 0.04]
divisions = [4, 4, 4]
[material]
law = "neo-hookean"
young = 5e3
poisson = 0.45
[damping]
alpha = 50.0
[[fix]]
plane = {{ point = [0, 0, 0], normal = [0, 0, 1] }}
[run]
duration = {duration}
[interactive]
fps = 30.0
cycles = 40
{reference}
{extra}
"#
        );
        Scenario::from_toml(&text, Path::new("replay-test.toml")).unwrap()
    }

    /// Per frame, per grasp entry: the grasped nodes while it is held.
    type Held = Vec<Vec<Option<Vec<u32>>>>;

    /// Step every frame of `sc`: per frame, the positions and the grasped nodes.
    fn frames(sc: &Scenario) -> (Replay, Vec<Vec<[f64; 3]>>, Held) {
        let mut r = Replay::new(sc, sc.stepper().unwrap()).unwrap();
        let fps = sc.interactive.unwrap().fps;
        let n = match sc.run.stop {
            crate::scenario::StopRule::Duration(d) => (d * fps - 1e-9).ceil() as usize,
            _ => unreachable!(),
        };
        let (mut x, mut nodes) = (Vec::new(), Vec::new());
        for k in 1..=n {
            let why = r.frame(k, k as f64 / fps, &[]).unwrap();
            assert_eq!(why, None, "frame {k}");
            x.push(r.simulation().positions().to_vec());
            nodes.push(
                r.held
                    .iter()
                    .map(|h| h.map(|(id, _)| r.sim.grab_nodes(id).unwrap().to_vec()))
                    .collect(),
            );
        }
        (r, x, nodes)
    }

    const NONE: &str = "reference = \"none\"";

    /// The node nearest `p` in the reference configuration.
    fn node(sc: &Scenario, p: [f64; 3]) -> usize {
        sc.mesh.nearest_node(p).unwrap()
    }

    /// A grasp let go and taken again at the same spot: `raisov serve` recorded this as two
    /// `[[displace]]` prescribing the same nodes, which the scenario refused. Grasps taken
    /// during the run are selected when taken: the second takes the nodes the first let go.
    #[test]
    fn grasping_the_same_spot_twice_replays() {
        let grasp = |start: f64, release: f64| {
            format!(
                "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\nstart = {start}\n\
                 release = {release}\ntable = [[{start}, 0, 0, 0], [{release}, 0, 0, 0.003]]\n"
            )
        };
        let sc = cube(&(grasp(0.1, 0.4) + &grasp(0.6, 0.9)), 1.0, NONE);
        let (_, x, nodes) = frames(&sc);
        // Held in frames 3..=11 and 18..=26 (frame k at k/30 s), the same five nodes.
        for (k, held) in nodes.iter().enumerate().map(|(i, h)| (i + 1, h)) {
            assert_eq!(held[0].is_some(), (3..12).contains(&k), "frame {k}");
            assert_eq!(held[1].is_some(), (18..27).contains(&k), "frame {k}");
        }
        assert_eq!(nodes[2][0].as_ref().unwrap().len(), 5);
        assert_eq!(nodes[2][0], nodes[17][1]);
        // Each moves the centre along its path from where it stood when taken (frame 11 is
        // at 11/30 s of the first 0.1 .. 0.4 s ramp, frame 26 of the second's 0.6 .. 0.9 s),
        // and lets it go: it springs back.
        let c = node(&sc, [0.02, 0.02, 0.04]);
        let uz = |k: usize| x[k - 1][c][2] - 0.04;
        let d = |k: usize, start: f64| 0.003 * (k as f64 / 30.0 - start) / 0.3;
        assert!((uz(11) - d(11, 0.1)).abs() < 1e-12, "{}", uz(11));
        assert!(uz(17).abs() > 1e-6 && uz(17) < 0.1 * uz(11), "{}", uz(17));
        assert!((uz(26) - uz(17) - d(26, 0.6)).abs() < 1e-12, "{}", uz(26));
        // The whole path through the run's outputs.
        let dir = tempfile::tempdir().unwrap();
        let s = run_interactive(
            &sc,
            sc.stepper().unwrap(),
            RunOptions {
                out_dir: Some(dir.path().to_path_buf()),
                ..Default::default()
            },
        )
        .unwrap();
        assert_eq!((s.frames, s.rejected_frames), (30, 0));
    }

    /// `raisov serve` grasps by springs by default; its recordings held the patch rigidly,
    /// and held it at its last place after the release. A spring grasp lags behind its
    /// target, a hard one sits on it; after the release the patch is free and springs back.
    #[test]
    fn a_spring_grasp_replays_as_springs_and_a_release_frees_the_patch() {
        let run = |stiffness: &str, release: &str| {
            let sc = cube(
                &format!(
                    "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\n{stiffness}\n\
                     {release}\ntable = [[0.0, 0, 0, 0], [0.3, 0, 0, 0.004]]\n"
                ),
                1.5,
                NONE,
            );
            let (r, x, _) = frames(&sc);
            let c = node(&sc, [0.02, 0.02, 0.04]);
            let uz: Vec<f64> = x.iter().map(|x| x[c][2] - 0.04).collect();
            (sc, r, uz)
        };
        // Frame 15 (0.5 s): the target 4 mm up since 0.3 s; released before frame 16.
        let (_, _, hard) = run("", "release = 0.52");
        let (_, _, spring) = run("stiffness = 20.0", "release = 0.52");
        let (_, held, kept) = run("stiffness = 20.0", "");
        assert!((hard[14] - 0.004).abs() < 1e-12, "{}", hard[14]);
        assert!(
            spring[14] > 0.0003 && spring[14] < 0.5 * 0.004,
            "{}",
            spring[14]
        );
        assert!((kept[14] - spring[14]).abs() < 1e-15);
        // The springs pull the tool down by k times the lag of the patch (mass-weighted).
        let id = held.held[0].unwrap().0;
        let f = held.sim.grab_force(id).unwrap();
        assert!(f[2] < -20.0 * 0.5 * 0.004 && f[2] > -20.0 * 0.004, "{f:?}");
        // Released, the patch returns to rest; held, it stays up.
        for uz in [&hard, &spring] {
            assert!(uz[44].abs() < 1e-5, "{}", uz[44]);
        }
        assert!(kept[44] > 0.9 * kept[14], "{} vs {}", kept[44], kept[14]);
        // The lag is measured against the static solution with the same grasp: hard, the
        // grasped node sits on the target in it; by springs, below; released, at rest. (The
        // path moves in every frame it holds and only the frames up to the first after the
        // release are checked: a warm-started static solve of a frame that changes nothing
        // stalls against its own, already tiny, starting residual, as with any interactive
        // path that holds still without loads.)
        for stiffness in ["", "stiffness = 20.0"] {
            let sc = &cube(
                &format!(
                    "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\n{stiffness}\n\
                     release = 0.52\ntable = [[0.0, 0, 0, 0], [0.52, 0, 0, 0.004]]\n"
                ),
                1.5,
                "reference = \"newton\"",
            );
            let dir = tempfile::tempdir().unwrap();
            let s = run_interactive(
                sc,
                sc.stepper().unwrap(),
                RunOptions {
                    out_dir: Some(dir.path().to_path_buf()),
                    ..Default::default()
                },
            )
            .unwrap();
            let rows = read_frames_csv(&dir.path().join("frames.csv")).unwrap();
            assert_eq!(rows.len(), 45);
            assert!(rows[..16].iter().all(|r| r.lag_max.is_finite()), "{s}");
            let (up, target) = (rows[14].static_max_u, 0.004 * 0.5 / 0.52);
            if stiffness.is_empty() {
                assert!((up - target).abs() < 1e-6, "{up}");
            } else {
                assert!(up > 1e-4 && up < 0.5 * target, "{up}");
            }
            assert!(rows[15].static_max_u < 1e-9, "{:?}", rows[15]);
        }
    }

    /// A grasp whose patch is all pinned already is an error naming the entry and frame.
    #[test]
    fn a_grasp_of_a_pinned_patch_is_an_error_naming_it() {
        let sc = cube(
            "[[pin]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\n\
             [[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.005\nstart = 0.1\n",
            0.2,
            NONE,
        );
        let dir = tempfile::tempdir().unwrap();
        let opts = RunOptions {
            out_dir: Some(dir.path().to_path_buf()),
            ..Default::default()
        };
        let e = run_interactive(&sc, sc.stepper().unwrap(), opts)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("displace[0]: at t = 0.1 s (frame 3):") && e.contains("constrained already"),
            "{e}"
        );
    }

    /// A pin holds its patch where it stands when taken (the recordings fixed a box of
    /// reference positions at zero displacement from the start, nodes beside the patch
    /// included), on from its start.
    #[test]
    fn a_pin_holds_where_it_stands_from_its_start() {
        let sc = cube(
            "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\nrelease = 0.5\n\
             table = [[0.0, 0, 0, 0], [0.3, 0.002, 0, 0.004]]\n\
             [[pin]]\npoint = [0.04, 0.02, 0.04]\nstart = 0.4\n",
            1.0,
            NONE,
        );
        let (_, x, _) = frames(&sc);
        let a = node(&sc, [0.04, 0.02, 0.04]);
        let moved = |k: usize| x[k - 1][a][2] - 0.04;
        // Free before frame 12 (0.4 s): it moves with the grasp; from then on it stays.
        assert!(moved(11) > 1e-4, "{}", moved(11));
        assert_ne!(x[9][a], x[10][a]);
        for k in 12..=30 {
            assert_eq!(x[k - 1][a], x[10][a], "frame {k}");
        }
    }

    /// A friction grasp in a scenario (`friction` and `clamp_force` with `stiffness`): pulled
    /// 4 mm up over 0.3 s, the spring grasp of the same stiffness pulls the tool down by more
    /// than μN = 5 mN; the friction grasp's pull is bounded by μN (to rounding), its patch
    /// rises less, and its sliding dissipated work.
    #[test]
    fn a_friction_grasp_replays_and_slides_at_mu_n() {
        let run = |grip: &str| {
            let sc = cube(
                &format!(
                    "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\nstiffness = 20.0\n\
                     {grip}\ntable = [[0.0, 0, 0, 0], [0.3, 0, 0, 0.004]]\n"
                ),
                0.5,
                NONE,
            );
            let (r, x, _) = frames(&sc);
            let c = node(&sc, [0.02, 0.02, 0.04]);
            let id = r.held[0].unwrap().0;
            let f = r.sim.grab_force(id).unwrap();
            let f = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt();
            let d = r.sim.grab_dissipation(id).unwrap();
            (f, x.last().unwrap()[c][2] - 0.04, d)
        };
        let (fs, us, ds) = run("");
        let (ff, uf, df) = run("friction = 0.5\nclamp_force = 0.01");
        assert!(fs > 0.005, "{fs}");
        assert!(ff <= 0.005 * (1.0 + 1e-9) && ff > 0.9 * 0.005, "{ff}");
        assert!(uf < us, "{uf} vs {us}");
        assert!(ds == 0.0 && df > 0.0, "{ds} {df}");
    }

    /// Bad keys of grasps and pins name the key and what is valid.
    #[test]
    fn bad_grasp_and_pin_keys_are_named() {
        let base = "[mesh]\ngenerate = \"box\"\nsize = [0.04, 0.04, 0.04]\ndivisions = [2, 2, 2]\n\
                    [material]\nlaw = \"neo-hookean\"\nyoung = 5e3\npoisson = 0.45\n\
                    [run]\nduration = 1.0\n";
        let g = "[[displace]]\npoint = [0.02, 0.02, 0.04]\n";
        let p = "[[pin]]\npoint = [0.02, 0.02, 0.04]\n";
        let i = "[interactive]\ncycles = 2\n";
        for (extra, want) in [
            (format!("{g}start = 0.5\n"), "displace[0] (`start`, `release`, `stiffness`, `friction` or `clamp_force`: a grasp) is taken during the run and replayed frame by frame: the scenario needs an [interactive] section"),
            (p.to_string(), "pin[0] is taken during the run"),
            (format!("{i}{g}start = -1.0\n"), "`displace[0].start` = -1: must be >= 0 (s)"),
            (format!("{i}{g}start = 0.5\nrelease = 0.5\n"), "`displace[0].release` = 0.5: must come after `start` = 0.5 (s)"),
            (format!("{i}{g}stiffness = 0.0\n"), "`displace[0].stiffness` = 0: must be a positive number"),
            (format!("{i}{g}radius = -0.1\nrelease = 1.0\n"), "`displace[0].radius` = -0.1: must be >= 0 (m)"),
            (format!("{i}{g}start = 0.1\nmode = \"ramp\"\n"), "displace[0]: mode = \"ramp\" needs `displacement`"),
            (format!("{i}{p}radius = -1.0\n"), "`pin[0].radius` = -1: must be >= 0 (m)"),
            (format!("{i}{p}start = inf\n"), "pin[0].start"),
            (format!("{i}{p}stiffness = 3.0\n"), "stiffness"),
            (format!("{i}{g}friction = 0.4\nclamp_force = 2.0\n"), "`displace[0].friction` needs `displace[0].stiffness` (N/m"),
            (format!("{i}{g}stiffness = 100.0\nfriction = 0.4\n"), "`displace[0].friction` needs `displace[0].clamp_force` (N)"),
            (format!("{i}{g}stiffness = 100.0\nclamp_force = 2.0\n"), "`displace[0].clamp_force` needs `displace[0].friction`"),
            (format!("{i}{g}stiffness = 100.0\nfriction = -0.4\nclamp_force = 2.0\n"), "`displace[0].friction` = -0.4: must be a positive number"),
            (format!("{i}{g}stiffness = 100.0\nfriction = 0.4\nclamp_force = 0.0\n"), "`displace[0].clamp_force` = 0: must be a positive number"),
        ] {
            let e = Scenario::from_toml(&format!("{base}{extra}"), Path::new("bad.toml"))
                .err()
                .unwrap_or_else(|| panic!("{extra}: accepted"))
                .to_string();
            assert!(e.contains(want), "{extra}: {e}");
        }
    }

    /// Frames with the predictor (`[interactive] predictor = true`) on FAS over two levels,
    /// a patch grasp pulled up 4 mm over 0.3 s and then held for 1.7 s: once held, the
    /// frames settle at the static solver's equilibrium with the grasp held (the last
    /// frame's lag within 1e-7 of max |u*|); every frame's lag is measured, and `frames.csv`
    /// counts each frame's force evaluations (its sum is the summary's).
    #[test]
    fn predicted_frames_settle_at_the_static_equilibrium_once_the_grasp_holds() {
        let mut sc = cube(
            "[[displace]]\npoint = [0.02, 0.02, 0.04]\nradius = 0.011\nstart = 0.0\n\
             table = [[0.0, 0, 0, 0], [0.3, 0, 0, 0.004], [2.0, 0, 0, 0.004]]\n\
             [multigrid]\nscheme = \"fas\"\nlevels = 2\n",
            2.0,
            "reference = \"newton\"\npredictor = true",
        );
        if let Some(i) = sc.interactive.as_mut() {
            i.budget = interactive::Budget::Cycles(2);
        }
        let dir = tempfile::tempdir().unwrap();
        let s = run_interactive(
            &sc,
            sc.stepper().unwrap(),
            RunOptions {
                out_dir: Some(dir.path().to_path_buf()),
                ..Default::default()
            },
        )
        .unwrap();
        assert!(s.settings.predictor);
        assert_eq!((s.frames, s.reference_failures), (60, 0), "{s}");
        assert_eq!(s.lag_frames, 60, "{s}");
        let rows = read_frames_csv(&dir.path().join("frames.csv")).unwrap();
        let last = rows.last().unwrap();
        assert!(last.static_max_u > 3e-3, "{last:?}");
        assert!(last.lag_rel() <= 1e-7, "{last:?}");
        let sum: f64 = rows.iter().map(|r| r.force_evals).sum();
        assert!(
            (sum - s.force_evals).abs() <= 1e-9 * sum && sum > 0.0,
            "{sum} vs {}",
            s.force_evals
        );
        assert!(rows.iter().all(|r| r.force_evals > 1.0), "{rows:?}");
    }
}
