//! Scenarios on a closed surface (`[mesh] surface`): the levels generated at load, their
//! cache, and the visual surface written with every frame.
//!
//! **Levels.** The surface is read ([`crate::io::load_surface`]), scaled by `[mesh] scale`,
//! checked and its orientation repaired ([`check_surface`]), then meshed by isosurface
//! stuffing into `levels` independent meshes whose node counts form the series
//! `n_0 ratioᶦ` ([`mesh_levels`]); `n_0` is `[mesh] nodes`, or level 0 has the lattice
//! spacing `[mesh] size` (m). Without `[multigrid]` one level is meshed.
//!
//! **Cache.** The levels are written as Gmsh 2.2 files `OUT/cache/STEM-KEY/L0.msh ...`
//! (coordinates in metres, bit-exact) with `key.txt` last, and the scenario reads those
//! files back, on the first run as on every rerun, so that both see the same bits. `KEY` is
//! the 128-bit FNV-1a hash of the surface file's bytes followed by the parameters (scale,
//! nodes or size as IEEE bits, levels, ratio, [`MESHER_VERSION`] and the crate version);
//! `key.txt` holds them in words and must match for a directory to be reused. Nothing else
//! under `cache/` is read or removed.
//!
//! **Visual surface.** The surface's vertices `p_θ` are embedded in the finest level:
//! host element `e(θ)` and barycentric weights `ω_θj` with `p_θ = Σ_j ω_θj x_j`
//! ([`Transfer::build`]; vertices just outside the mesh boundary, where the lattice cuts
//! corners, take the extrapolating weights of eq. 7, so a rigid motion of the mesh moves the
//! surface rigidly). A frame writes the surface's reference vertices with the point field
//! `displacement` `u(p_θ) = Σ_j ω_θj u_j` ([`Transfer::interpolate`]) as
//! `frames/NAME_surface_NNNNNN.vtp` ([`crate::io::write_vtp`]), in the volume frames'
//! storage, listed in `NAME_surface.pvd`.

use super::err;
use super::spec::{defaults, MeshSize, MeshSpec, MultigridSpec};
use crate::error::Result;
use crate::hierarchy::Transfer;
use crate::io::{load_mesh, load_surface, write_atomic, write_msh22, write_vtp, Field, FieldData};
use crate::io::{PvdWriter, VtuFormat};
use crate::mesh::stuffing::{mesh_levels, LevelTarget};
use crate::mesh::{check_surface, looks_like_millimetres, Mesh, Surface};
use crate::Error;
use std::path::{Path, PathBuf};

pub use crate::mesh::stuffing::MESHER_VERSION;

/// The folder under the output directory that holds generated levels.
pub const CACHE_DIR: &str = "cache";

/// The surface a scenario's mesh was generated from.
#[derive(Clone, Debug, PartialEq)]
pub struct VisualSurface {
    /// The surface file.
    pub path: PathBuf,
    /// Checked and oriented, coordinates in metres (after `[mesh] scale`).
    pub surface: Surface,
    /// The cache folder of the levels.
    pub cache: PathBuf,
    /// Whether the levels were read from an earlier run's cache (no meshing).
    pub from_cache: bool,
}

/// The levels of a `[mesh] surface`: their files (finest first) and the surface.
pub(super) struct SurfaceLevels {
    pub files: Vec<PathBuf>,
    pub visual: VisualSurface,
    pub notes: Vec<String>,
}

/// 128-bit FNV-1a.
struct Fnv(u128);

impl Fnv {
    const PRIME: u128 = 0x0000_0000_0100_0000_0000_0000_0000_013B;
    fn new() -> Fnv {
        Fnv(0x6c62_272e_07bb_0142_62b8_2175_6295_c58d)
    }
    fn eat(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u128;
            self.0 = self.0.wrapping_mul(Self::PRIME);
        }
    }
}

/// Read, check and mesh (or read from the cache) the levels of `[mesh] surface`.
pub(super) fn prepare(
    m: &MeshSpec,
    mg: Option<&MultigridSpec>,
    path: &Path,
    base: &Path,
    out_dir: &Path,
) -> Result<SurfaceLevels> {
    let rel = m.surface.as_deref().expect("a surface scenario");
    let file = base.join(rel);
    let key = "mesh.surface";
    for (k, set) in [
        ("polygon", m.polygon.is_some()),
        ("divisions", m.divisions.is_some()),
        ("pattern", m.pattern.is_some()),
    ] {
        if set {
            return Err(err(
                path,
                format!("[mesh]: `{k}` does not apply to `surface`"),
            ));
        }
    }
    let scale = super::positive(path, "mesh.scale", m.scale.unwrap_or(defaults::SCALE))?;
    let target = match (m.nodes, &m.size) {
        (Some(n), None) if n >= 4 => LevelTarget::Nodes(n),
        (Some(n), None) => {
            return Err(err(
                path,
                format!("`mesh.nodes` = {n}: a surface's level 0 needs at least 4 nodes"),
            ))
        }
        (None, Some(MeshSize::Length(h))) => {
            LevelTarget::Size(super::positive(path, "mesh.size", *h)?)
        }
        (None, Some(MeshSize::Lengths(v))) => {
            return Err(err(
                path,
                format!("`mesh.size` = {v:?}: with `surface`, give one length (m, the lattice spacing of level 0), e.g. size = 0.005"),
            ))
        }
        (Some(_), Some(_)) => {
            return Err(err(
                path,
                "[mesh]: give `nodes` or `size` with `surface`, not both",
            ))
        }
        (None, None) => {
            return Err(err(
                path,
                "[mesh]: `surface` needs `nodes` (level 0's target node count) or `size` (its lattice spacing, m)",
            ))
        }
    };
    let (levels, ratio) = match mg {
        None => (1, defaults::LEVEL_RATIO),
        Some(mg) => {
            if mg.files.is_some() || mg.level_nodes.is_some() {
                return Err(err(path, "[multigrid]: with [mesh] surface the levels are generated: give `levels` (and `ratio`), not `files` or `level_nodes`"));
            }
            let levels = match mg.levels {
                Some(n) if n >= 1 => n,
                Some(_) => return Err(err(path, "`multigrid.levels` must be at least 1")),
                None => {
                    return Err(err(
                        path,
                        "[multigrid]: with [mesh] surface give `levels` (the number of generated levels)",
                    ))
                }
            };
            let ratio = match mg.ratio {
                Some(r) if !(r > 0.0 && r < 1.0) => {
                    return Err(err(
                        path,
                        format!(
                            "`multigrid.ratio` = {}: must be in (0, 1)",
                            crate::numbers::compact(r)
                        ),
                    ))
                }
                Some(r) => r,
                None => defaults::LEVEL_RATIO,
            };
            (levels, ratio)
        }
    };
    let bytes = std::fs::read(&file).map_err(|e| {
        err(
            path,
            format!("`{key}` = \"{}\": {}", file.display(), Error::io(&file, e)),
        )
    })?;
    let mut surface = load_surface(&file)
        .map_err(|e| err(path, format!("`{key}` = \"{}\": {e}", file.display())))?;
    surface.scale(scale);
    let report = check_surface(&mut surface)
        .map_err(|e| err(path, format!("`{key}` = \"{}\": {e}", file.display())))?;
    let mut notes = Vec::new();
    if report.flipped > 0 {
        notes.push(format!(
            "{}: reoriented {} triangles (normals out of the solid)",
            file.display(),
            report.flipped
        ));
    }
    if looks_like_millimetres((report.bbox_min, report.bbox_max), 1.0) {
        notes.push(format!(
            "warning: {} spans more than {} m after scale = {}; if its coordinates are millimetres, set [mesh] scale = 0.001",
            file.display(),
            crate::mesh::surface_check::MAX_ORGAN_EXTENT_M,
            crate::numbers::compact(scale)
        ));
    }
    // The cache key.
    let (target_words, target_bits) = match target {
        LevelTarget::Nodes(n) => (format!("nodes {n}"), n as u64),
        LevelTarget::Size(h) => (format!("size {h:e} m"), h.to_bits()),
    };
    let words = format!(
        "surface {}\nsurface bytes {}\nscale {scale:e}\n{target_words}\nlevels {levels}\nratio {ratio:e}\nmesher version {MESHER_VERSION}\nraisov {}\n",
        file.display(),
        bytes.len(),
        env!("CARGO_PKG_VERSION")
    );
    let mut h = Fnv::new();
    h.eat(&bytes);
    h.eat(&scale.to_bits().to_le_bytes());
    h.eat(&[matches!(target, LevelTarget::Size(_)) as u8]);
    h.eat(&target_bits.to_le_bytes());
    h.eat(&(levels as u64).to_le_bytes());
    h.eat(&ratio.to_bits().to_le_bytes());
    h.eat(&MESHER_VERSION.to_le_bytes());
    h.eat(env!("CARGO_PKG_VERSION").as_bytes());
    let stem = file
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "surface".into());
    let stem: String = stem
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    let cache = out_dir.join(CACHE_DIR).join(format!("{stem}-{:032x}", h.0));
    let files: Vec<PathBuf> = (0..levels)
        .map(|i| cache.join(format!("L{i}.msh")))
        .collect();
    let key_file = cache.join("key.txt");
    // Only the key's words after the path: the same surface moved keeps its cache.
    let words_key = |w: &str| w.split_once('\n').map(|(_, r)| r.to_string());
    let cached = std::fs::read_to_string(&key_file)
        .ok()
        .is_some_and(|k| words_key(&k) == words_key(&words))
        && files.iter().all(|f| f.is_file());
    if !cached {
        let meshes: Vec<Mesh> = mesh_levels(&surface, levels, ratio, target).map_err(|e| {
            err(
                path,
                format!("`{key}` = \"{}\": meshing failed: {e}", file.display()),
            )
        })?;
        std::fs::create_dir_all(&cache).map_err(|e| Error::io(&cache, e))?;
        for (m, f) in meshes.iter().zip(&files) {
            write_msh22(f, m)?;
        }
        write_atomic(&key_file, |w| w.write_all(words.as_bytes()))?;
        notes.push(format!(
            "{}: meshed {levels} level(s), cached in {}",
            file.display(),
            cache.display()
        ));
    } else {
        notes.push(format!(
            "{}: {levels} level(s) read from the cache {}",
            file.display(),
            cache.display()
        ));
    }
    // Check that the files read back (a damaged cache is meshed again on the next run).
    for f in &files {
        load_mesh(f).map_err(|e| {
            err(
                path,
                format!(
                    "cached level {}: {e}; remove {} to mesh again",
                    f.display(),
                    cache.display()
                ),
            )
        })?;
    }
    Ok(SurfaceLevels {
        files,
        visual: VisualSurface {
            path: file,
            surface,
            cache,
            from_cache: cached,
        },
        notes,
    })
}

/// Writes the visual surface with every frame (see the module docs).
pub(crate) struct SurfaceFrames<'a> {
    surface: &'a Surface,
    transfer: Transfer,
    dir: PathBuf,
    name: String,
    pvd: PvdWriter,
    u: Vec<f64>,
    format: VtuFormat,
}

impl<'a> SurfaceFrames<'a> {
    /// Embed `visual` in `mesh` (the finest level) and prepare `out/NAME_surface.pvd`.
    pub fn new(
        visual: &'a VisualSurface,
        mesh: &Mesh,
        out: &Path,
        name: &str,
        format: VtuFormat,
    ) -> Result<Self> {
        let transfer = Transfer::build(&visual.surface.points, mesh)?;
        Ok(SurfaceFrames {
            surface: &visual.surface,
            u: vec![0.0; 3 * transfer.len()],
            transfer,
            dir: out.join("frames"),
            name: format!("{name}_surface"),
            pvd: PvdWriter::new(out.join(format!("{name}_surface.pvd"))),
            format,
        })
    }

    /// Write frame `count` at time `t` for the finest level's displacement `u`.
    pub fn write(&mut self, t: f64, count: usize, u: &[f64]) -> Result<()> {
        self.transfer.interpolate(u, 3, &mut self.u)?;
        let file = format!("{}_{count:06}.vtp", self.name);
        write_vtp(
            &self.dir.join(&file),
            &self.surface.points,
            &self.surface.triangles,
            &[Field {
                name: "displacement",
                data: FieldData::Vector(&self.u),
            }],
            self.format,
        )?;
        self.pvd.add(t, &format!("frames/{file}"))
    }

    /// The `.pvd` path.
    pub fn pvd_path(&self) -> &Path {
        self.pvd.path()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{read_vtp, read_vtu_array};
    use crate::mesh::surface_check::tests::icosphere;
    use crate::runner::{run, RunOptions};
    use crate::scenario::Scenario;
    use std::fmt::Write as _;

    /// A unit icosphere as OBJ text (radius 1; the scenarios scale it to 5 cm), with its
    /// triangles turned inside out so that the check has something to repair.
    fn write_sphere(dir: &Path) -> PathBuf {
        let s = icosphere(2);
        let mut o = String::new();
        for p in &s.points {
            writeln!(o, "v {:?} {:?} {:?}", p[0], p[1], p[2]).unwrap();
        }
        for t in &s.triangles {
            writeln!(o, "f {} {} {}", t[0] + 1, t[2] + 1, t[1] + 1).unwrap();
        }
        let p = dir.join("ball.obj");
        std::fs::write(&p, o).unwrap();
        p
    }

    /// A sphere of radius 5 cm held on its top cap, under gravity, two generated levels,
    /// five FAS cycles (8 steps of 1 ms each).
    fn scenario_text(mesh_extra: &str, multigrid: &str) -> String {
        format!(
            r#"
name = "ball"
gravity = [0.0, 0.0, -9.81]
[mesh]
surface = "ball.obj"
scale = 0.05
{mesh_extra}
[material]
law = "neo-hookean"
young = 5000.0
poisson = 0.45
density = 1060.0
[[fix]]
plane = {{ point = [0.0, 0.0, 0.035], normal = [0.0, 0.0, -1.0] }}
[integrator]
dt = 1e-3
[run]
duration = 0.04
[output]
dir = "out"
frame_interval = 0.016
{multigrid}
"#
        )
    }

    fn setup(mesh_extra: &str, multigrid: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        write_sphere(dir.path());
        let p = dir.path().join("ball.toml");
        std::fs::write(&p, scenario_text(mesh_extra, multigrid)).unwrap();
        (dir, p)
    }

    fn load_err(mesh_extra: &str, multigrid: &str) -> String {
        let (_dir, p) = setup(mesh_extra, multigrid);
        Scenario::load(&p).expect_err("refused").to_string()
    }

    /// The Simulation API carries the visual surface: after frames of sagging every surface
    /// vertex sits at its reference point plus the interpolated volume displacement (the same
    /// bits), and the surface moved down.
    #[test]
    fn simulation_surface_positions_follow_the_volume() {
        let (_dir, p) = setup("nodes = 600", "[multigrid]\nlevels = 2\nratio = 0.5");
        let sc = Scenario::load(&p).unwrap();
        let vs = sc.surface.clone().unwrap();
        let mut sim = crate::sim::Simulation::from_scenario(&sc).unwrap();
        assert_eq!(sim.surface_positions(), &vs.surface.points[..]);
        assert_eq!(sim.surface_triangles(), &vs.surface.triangles[..]);
        let rep = sim.step_frame(crate::sim::Budget::Cycles(3));
        assert!(rep.accepted, "{rep:?}");
        let t = Transfer::build(&vs.surface.points, &sc.mesh).unwrap();
        let mut want = vec![0.0; 3 * t.len()];
        t.interpolate(sim.displacements(), 3, &mut want).unwrap();
        let mut lowest = 0.0f64;
        for (i, x) in sim.surface_positions().iter().enumerate() {
            for k in 0..3 {
                assert_eq!(x[k], vs.surface.points[i][k] + want[3 * i + k]);
            }
            lowest = lowest.min(want[3 * i + 2]);
        }
        assert!(lowest < 0.0, "{lowest}");
    }

    #[test]
    fn surface_levels_are_cached_reused_and_give_the_same_bits() {
        let (dir, p) = setup("nodes = 600", "[multigrid]\nlevels = 2\nratio = 0.5");
        let out = dir.path().join("out");
        let sc = Scenario::load(&p).unwrap();
        let vs = sc.surface.clone().unwrap();
        assert!(!vs.from_cache);
        assert_eq!(sc.num_levels(), 2);
        // Level 0 near its target, the coarser one about half as many nodes.
        let n0 = sc.mesh.num_nodes();
        assert!((n0 as f64 / 600.0 - 1.0).abs() < 0.05, "{n0}");
        let l1 = sc.level_meshes().unwrap()[1].num_nodes();
        assert!((l1 as f64 / n0 as f64 - 0.5).abs() < 0.06, "{l1} / {n0}");
        // The surface was checked and reoriented (outward, radius 5 cm), and the note says so.
        assert!(vs.surface.enclosed_volume() > 0.0);
        assert!(
            sc.notes.iter().any(|n| n.contains("reoriented")),
            "{:?}",
            sc.notes
        );
        let r = vs
            .surface
            .points
            .iter()
            .map(|p| crate::mesh::norm(*p))
            .fold(0.0, f64::max);
        assert!((r - 0.05).abs() < 1e-12, "{r}");
        // The cache: under OUT/cache, one folder with the levels and the key.
        assert!(vs.cache.starts_with(out.join(CACHE_DIR)));
        let l0 = vs.cache.join("L0.msh");
        for f in ["L0.msh", "L1.msh", "key.txt"] {
            assert!(vs.cache.join(f).is_file(), "{f}");
        }
        let mtime = std::fs::metadata(&l0).unwrap().modified().unwrap();
        let first = run(&sc, RunOptions::default()).unwrap();
        let frames = out.join("frames");
        let last_vtu = frames.join("ball_000003.vtu");
        let last_vtp = frames.join("ball_surface_000003.vtp");
        let listing: Vec<_> = std::fs::read_dir(&frames)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(
            last_vtu.is_file() && last_vtp.is_file(),
            "{listing:?} {first}"
        );
        assert!(out.join("ball_surface.pvd").is_file());
        assert!(first.files.contains(&out.join("ball_surface.pvd")));
        // The VTP frame: the surface's reference points and triangles, and the displacement
        // interpolated from the volume frame's.
        let s = read_vtp(&last_vtp).unwrap();
        assert_eq!(s, vs.surface);
        let (k, u_vol) = read_vtu_array(&last_vtu, "displacement").unwrap();
        assert_eq!(k, 3);
        let t = Transfer::build(&vs.surface.points, &sc.mesh).unwrap();
        let mut want = vec![0.0; 3 * t.len()];
        t.interpolate(&u_vol, 3, &mut want).unwrap();
        let (k, got) = read_vtu_array(&last_vtp, "displacement").unwrap();
        assert_eq!(k, 3);
        assert_eq!(got, want);
        // The body sags: the interpolated surface moves down, and by no more than the mesh.
        let max_vol = u_vol.chunks(3).map(|u| -u[2]).fold(0.0, f64::max);
        let max_surf = got.chunks(3).map(|u| -u[2]).fold(0.0, f64::max);
        assert!(
            max_surf > 0.0 && max_surf <= 1.05 * max_vol,
            "{max_surf} {max_vol}"
        );
        let stress1 = std::fs::read(out.join("nodal_stress.csv")).unwrap();
        let vtu1 = std::fs::read(&last_vtu).unwrap();
        let vtp1 = std::fs::read(&last_vtp).unwrap();
        // A stale frame of an earlier, longer run goes; the cache stays.
        std::fs::write(frames.join("ball_000099.vtu"), "old").unwrap();
        std::fs::write(frames.join("ball_surface_000099.vtp"), "old").unwrap();
        std::fs::write(frames.join("other_000099.vtu"), "other scenario").unwrap();
        // The rerun reads the cache: no meshing (the files are untouched), the same bits.
        let sc2 = Scenario::load(&p).unwrap();
        assert!(sc2.surface.as_ref().unwrap().from_cache);
        assert!(sc2.notes.iter().any(|n| n.contains("read from the cache")));
        assert_eq!(std::fs::metadata(&l0).unwrap().modified().unwrap(), mtime);
        assert_eq!(sc2.mesh.nodes, sc.mesh.nodes);
        assert_eq!(sc2.mesh.cells, sc.mesh.cells);
        run(&sc2, RunOptions::default()).unwrap();
        assert_eq!(
            std::fs::read(out.join("nodal_stress.csv")).unwrap(),
            stress1
        );
        assert_eq!(std::fs::read(&last_vtu).unwrap(), vtu1);
        assert_eq!(std::fs::read(&last_vtp).unwrap(), vtp1);
        assert!(!frames.join("ball_000099.vtu").exists());
        assert!(!frames.join("ball_surface_000099.vtp").exists());
        assert!(frames.join("other_000099.vtu").exists());
        assert!(l0.is_file());
        assert_eq!(std::fs::metadata(&l0).unwrap().modified().unwrap(), mtime);
        // Other parameters: another key, another folder, meshed anew.
        std::fs::write(
            &p,
            scenario_text("nodes = 500", "[multigrid]\nlevels = 2\nratio = 0.5"),
        )
        .unwrap();
        let sc3 = Scenario::load(&p).unwrap();
        let vs3 = sc3.surface.unwrap();
        assert!(!vs3.from_cache);
        assert_ne!(vs3.cache, vs.cache);
        assert!(l0.is_file());
    }

    #[test]
    fn one_level_by_size_without_multigrid_and_ascii_frames() {
        let (dir, p) = setup("size = 0.02", "");
        let text = scenario_text("size = 0.02", "").replace(
            "frame_interval = 0.016",
            "frame_interval = 0.016\nvtu = \"ascii\"",
        );
        std::fs::write(&p, text).unwrap();
        let sc = Scenario::load(&p).unwrap();
        assert_eq!(sc.num_levels(), 1);
        assert!(sc.multigrid.is_none());
        run(&sc, RunOptions::default()).unwrap();
        let f = dir.path().join("out/frames/ball_surface_000000.vtp");
        let text = std::fs::read_to_string(&f).unwrap();
        assert!(text.contains("type=\"PolyData\"") && text.contains("format=\"ascii\""));
        assert_eq!(read_vtp(&f).unwrap(), sc.surface.unwrap().surface);
    }

    #[test]
    fn bad_surface_scenarios_are_named() {
        let e = load_err("nodes = 600\nfile = \"ball.msh\"", "");
        assert!(e.contains("one of `file`, `generate` or `surface`"), "{e}");
        let e = load_err("nodes = 600\ngenerate = \"box\"", "");
        assert!(e.contains("one of `file`, `generate` or `surface`"), "{e}");
        let e = load_err("", "");
        assert!(
            e.contains("needs `nodes`") && e.contains("or `size`"),
            "{e}"
        );
        let e = load_err("nodes = 600\nsize = 0.01", "");
        assert!(
            e.contains("`nodes` or `size`") && e.contains("not both"),
            "{e}"
        );
        let e = load_err("size = [0.1, 0.1]", "");
        assert!(e.contains("give one length"), "{e}");
        let e = load_err("nodes = 600", "[multigrid]\nfiles = [\"L1.msh\"]");
        assert!(e.contains("levels are generated"), "{e}");
        let e = load_err("nodes = 600", "[multigrid]\nlevels = 2\nratio = 1.5");
        assert!(e.contains("`multigrid.ratio` = 1.5"), "{e}");
        // A missing file, a malformed one, an open one: the message names the file.
        let (dir, p) = setup("nodes = 600", "");
        std::fs::remove_file(dir.path().join("ball.obj")).unwrap();
        let e = Scenario::load(&p).err().unwrap().to_string();
        assert!(e.contains("mesh.surface") && e.contains("ball.obj"), "{e}");
        std::fs::write(dir.path().join("ball.obj"), "v 0 0 zero\nf 1 2 3\n").unwrap();
        let e = Scenario::load(&p).err().unwrap().to_string();
        assert!(e.contains("ball.obj") && e.contains("line 1"), "{e}");
        std::fs::write(
            dir.path().join("ball.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n",
        )
        .unwrap();
        let e = Scenario::load(&p).err().unwrap().to_string();
        assert!(e.contains("ball.obj") && e.contains("edge"), "{e}");
        assert!(!dir.path().join("out/cache").exists());
    }

    /// Interactive mode writes the surface with every frame too.
    #[test]
    fn interactive_frames_hold_the_surface() {
        let (dir, p) = setup("nodes = 300", "");
        let text = scenario_text("nodes = 300", "").replace("duration = 0.04", "duration = 0.1")
            + "[[displace]]\npoint = [0.0, 0.0, -0.05]\nmode = \"ramp\"\n\
               displacement = [0.0, 0.0, -0.005]\nduration = 0.1\n\
               [interactive]\nfps = 30.0\ncycles = 2\nreference = \"none\"\n";
        std::fs::write(&p, text).unwrap();
        let sc = Scenario::load(&p).unwrap();
        let st = sc.stepper().unwrap();
        let s = crate::runner::run_interactive(&sc, st, RunOptions::default()).unwrap();
        assert_eq!(s.frames, 3);
        let frames = dir.path().join("out/frames");
        let vtp = frames.join("ball_surface_000003.vtp");
        let (_, u_vol) = read_vtu_array(&frames.join("ball_000003.vtu"), "displacement").unwrap();
        let vs = sc.surface.as_ref().unwrap();
        let t = Transfer::build(&vs.surface.points, &sc.mesh).unwrap();
        let mut want = vec![0.0; 3 * t.len()];
        t.interpolate(&u_vol, 3, &mut want).unwrap();
        assert_eq!(read_vtu_array(&vtp, "displacement").unwrap(), (3, want));
        let pvd = std::fs::read_to_string(dir.path().join("out/ball_surface.pvd")).unwrap();
        assert_eq!(pvd.matches("<DataSet ").count(), 3, "{pvd}");
    }

    /// The shipped liver examples parse, on the shipped data, with the same physics.
    #[test]
    fn liver_examples_parse() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let spec = |f: &str| {
            let p = root.join("examples").join(f);
            crate::scenario::spec::parse(&std::fs::read_to_string(&p).unwrap(), &p).unwrap()
        };
        let a = spec("liver_surface.toml");
        let b = spec("liver_levels_sag.toml");
        let surface = a.mesh.surface.as_deref().unwrap();
        assert!(root.join("examples").join(surface).is_file(), "{surface}");
        assert_eq!(a.mesh.nodes, Some(16700));
        assert_eq!(a.multigrid.as_ref().unwrap().levels, Some(4));
        for f in b.multigrid.as_ref().unwrap().files.as_ref().unwrap() {
            assert!(root.join("examples").join(f).is_file(), "{f}");
        }
        assert_eq!(format!("{:?}", a.material), format!("{:?}", b.material));
        assert_eq!(format!("{:?}", a.fix), format!("{:?}", b.fix));
        assert_eq!(format!("{:?}", a.run), format!("{:?}", b.run));
        assert_eq!(a.gravity, b.gravity);
        assert_eq!(a.mesh.scale, b.mesh.scale);
    }

    #[test]
    fn millimetre_surfaces_in_a_metre_scene_are_warned_about() {
        let (dir, p) = setup("nodes = 300", "");
        let text = scenario_text("nodes = 300", "").replace("scale = 0.05", "scale = 100.0");
        std::fs::write(&p, text).unwrap();
        let sc = Scenario::load(&p).unwrap();
        assert!(
            sc.notes
                .iter()
                .any(|n| n.starts_with("warning") && n.contains("scale = 0.001")),
            "{:?}",
            sc.notes
        );
        drop(dir);
    }
}
