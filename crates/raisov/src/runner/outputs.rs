//! The output directory at the start of a run: what an earlier run left there is cleared, so
//! that whatever this run leaves (however it ends) is its own.
//!
//! [`prepare`] checks the scenario's name ([`crate::io::check_name`]) and runs once the run holds the directory's [`crate::io::OutputLock`] (so that two
//! runs never clear each other's files), in this order:
//!
//! 1. a symbolic link at any name the run writes (`measures.csv`, `frames.csv`,
//!    `nodal_stress.csv`, `summary.txt`, `NAME.pvd`, `NAME_surface.pvd`, `frames/`) is an
//!    error naming it, before anything is removed ([`crate::io::output`]);
//! 2. the results of the previous run in the directory are removed: those four files (one
//!    run's results per directory, whatever its scenario) and the two collections of this
//!    scenario name, so that a run killed or diverging before its end never leaves an older
//!    summary or nodal stress beside its own measures;
//! 3. the numbered frames of this scenario name in `frames/` ([`clear_old_frames`]);
//! 4. the temporary files a killed writer left in the directory, in `frames/` and in each
//!    level cache under `cache/` ([`crate::io::sweep_temporaries`]).
//!
//! Nothing else is touched: other scenarios' frames and collections, the level caches, the
//! lock file and every file of another name stay.

use super::RunOptions;
use crate::error::{Error, Result};
use crate::io::{refuse_link, sweep_temporaries, write_atomic, OutputLock};
use crate::metrics::CsvStream;
use crate::scenario::Scenario;
use std::path::{Path, PathBuf};

/// The results one run leaves in its directory, whatever its scenario's name.
pub(crate) const RESULTS: [&str; 4] = [
    "measures.csv",
    "frames.csv",
    "nodal_stress.csv",
    "summary.txt",
];

/// Clear `out` for a run of scenario `name` (module docs). The caller holds its lock.
pub(crate) fn prepare(out: &Path, name: &str) -> Result<()> {
    // `Scenario::name` is public: a name set in code is checked as a scenario's is.
    crate::io::check_name(name).map_err(|e| Error::param("name", e))?;
    let pvds = [format!("{name}.pvd"), format!("{name}_surface.pvd")];
    let ours = RESULTS
        .iter()
        .map(|s| s.to_string())
        .chain(pvds)
        .map(|f| out.join(f))
        .collect::<Vec<_>>();
    let frames = out.join("frames");
    for p in ours.iter().chain([&frames]) {
        refuse_link(p)?;
    }
    for p in &ours {
        match std::fs::remove_file(p) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(p, e)),
        }
    }
    std::fs::create_dir_all(&frames).map_err(|e| Error::io(&frames, e))?;
    clear_old_frames(out, name)?;
    sweep_temporaries(out, true)?;
    sweep_temporaries(&frames, true)?;
    let cache = out.join(crate::scenario::surface::CACHE_DIR);
    if let Ok(entries) = std::fs::read_dir(&cache) {
        for e in entries.flatten() {
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                // Levels are cached while a scenario loads, before any lock is taken.
                sweep_temporaries(&e.path(), false)?;
            }
        }
    }
    Ok(())
}

/// Remove the frames an earlier run of scenario `name` left in `out/frames`
/// (`NAME_NNNNNN.vtu`, `NAME_surface_NNNNNN.vtp`), so that the collection holds this run's
/// frames only. Nothing else is touched: other scenarios' frames and `out/cache` stay.
fn clear_old_frames(out: &Path, name: &str) -> Result<()> {
    let dir = out.join("frames");
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Ok(());
    };
    let numbered = |rest: &str, ext: &str| {
        rest.strip_suffix(ext)
            .is_some_and(|n| n.len() == 6 && n.bytes().all(|b| b.is_ascii_digit()))
    };
    for e in entries {
        let e = e.map_err(|e| Error::io(&dir, e))?;
        let file = e.file_name();
        let Some(f) = file.to_str() else { continue };
        let Some(rest) = f.strip_prefix(name).and_then(|r| r.strip_prefix('_')) else {
            continue;
        };
        let ours = numbered(rest, ".vtu")
            || rest
                .strip_prefix("surface_")
                .is_some_and(|r| numbered(r, ".vtp"));
        if ours {
            let p = e.path();
            std::fs::remove_file(&p).map_err(|e| Error::io(&p, e))?;
        }
    }
    Ok(())
}

/// Where a run's results go: its output directory, locked for the run, or nowhere
/// ([`RunOptions::in_memory`]).
pub(crate) struct OutDir {
    dir: Option<PathBuf>,
    _lock: Option<OutputLock>,
}

impl OutDir {
    /// Take the run's directory (`opts.out_dir`, else the scenario's) and its lock; nothing
    /// for a run in memory.
    pub(crate) fn lock(sc: &Scenario, opts: &RunOptions) -> Result<OutDir> {
        if opts.in_memory {
            return Ok(OutDir {
                dir: None,
                _lock: None,
            });
        }
        let dir = opts
            .out_dir
            .clone()
            .unwrap_or_else(|| sc.output.dir.clone());
        let lock = OutputLock::acquire(&dir)?;
        Ok(OutDir {
            dir: Some(dir),
            _lock: Some(lock),
        })
    }

    /// Clear what an earlier run left (module docs).
    pub(crate) fn prepare(&self, name: &str) -> Result<()> {
        match &self.dir {
            Some(d) => prepare(d, name),
            None => crate::io::check_name(name).map_err(|e| Error::param("name", e)),
        }
    }

    /// The directory; `None` for a run in memory.
    pub(crate) fn dir(&self) -> Option<&Path> {
        self.dir.as_deref()
    }

    /// `file` in the directory (for a run in memory, its bare name: what messages call it).
    pub(crate) fn path(&self, file: &str) -> PathBuf {
        match &self.dir {
            Some(d) => d.join(file),
            None => PathBuf::from(file),
        }
    }

    /// `measures.csv`, streamed, or counted and dropped; with the friction columns where
    /// `friction`.
    pub(crate) fn measures(&self, friction: bool) -> Result<CsvStream> {
        let p = self.path("measures.csv");
        match self.dir {
            Some(_) => CsvStream::create(&p, friction),
            None => CsvStream::discard(&p, friction),
        }
    }

    /// Write `file` atomically from `body`; nothing for a run in memory.
    pub(crate) fn write(
        &self,
        file: &str,
        body: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> Result<()> {
        match &self.dir {
            Some(d) => write_atomic(&d.join(file), |w| body(w)),
            None => Ok(()),
        }
    }
}

/// The summary's last line: the output directory, or that the run kept its results in
/// memory.
pub(crate) fn write_output(
    f: &mut std::fmt::Formatter<'_>,
    dir: Option<&Path>,
) -> std::fmt::Result {
    match dir {
        Some(d) => write!(f, "output          {}", d.display()),
        None => write!(f, "output          none (kept in memory)"),
    }
}
#[cfg(test)]
mod tests {
    use super::*;

    /// The previous run's results and this scenario's frames, collections and leftover
    /// temporaries go; other scenarios' files, caches and user files stay.
    #[test]
    fn a_rerun_clears_the_previous_results_and_only_them() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let dead = 4_194_304 + 5; // above Linux's largest pid
        let gone = [
            "summary.txt".to_string(),
            "nodal_stress.csv".into(),
            "measures.csv".into(),
            "frames.csv".into(),
            "ball.pvd".into(),
            "ball_surface.pvd".into(),
            "frames/ball_000003.vtu".into(),
            "frames/ball_surface_000003.vtp".into(),
            format!(".summary.txt.{dead}.0.tmp"),
            format!("frames/.ball_000004.vtu.{dead}.1.tmp"),
        ];
        // Elsewhere a cache's temporaries stay: no run's lock covers the loading.
        #[cfg(target_os = "linux")]
        let gone = [
            &gone[..],
            &[format!("cache/ball-00ff/.L0.msh.{dead}.0.tmp")],
        ]
        .concat();
        let stay = [
            "other.pvd",
            "frames/other_000003.vtu",
            "cache/ball-00ff/L0.msh",
            "notes.txt",
            "user.tmp",
            ".raisov.lock",
        ];
        std::fs::create_dir_all(out.join("frames")).unwrap();
        std::fs::create_dir_all(out.join("cache/ball-00ff")).unwrap();
        for f in gone.iter().map(String::as_str).chain(stay) {
            std::fs::write(out.join(f), "old").unwrap();
        }
        prepare(out, "ball").unwrap();
        for f in &gone {
            assert!(!out.join(f).exists(), "{f} stayed");
        }
        for f in stay {
            assert!(out.join(f).exists(), "{f} was removed");
        }
    }

    /// A link at a result's name stops the run before anything is removed, naming it; its
    /// target is untouched.
    #[cfg(unix)]
    #[test]
    fn a_symlink_among_the_results_stops_the_run_before_clearing() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        std::fs::create_dir_all(&out).unwrap();
        let target = dir.path().join("precious.txt");
        std::fs::write(&target, "precious").unwrap();
        std::fs::write(out.join("summary.txt"), "old").unwrap();
        for link in ["measures.csv", "ball.pvd", "frames"] {
            let l = out.join(link);
            std::os::unix::fs::symlink(&target, &l).unwrap();
            let e = prepare(&out, "ball").unwrap_err().to_string();
            assert!(e.contains(link) && e.contains("symbolic link"), "{e}");
            assert!(out.join("summary.txt").exists());
            std::fs::remove_file(&l).unwrap();
        }
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "precious");
    }
}
