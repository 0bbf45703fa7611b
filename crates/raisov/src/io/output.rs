//! Output files: opened without following symbolic links, and the temporary files of
//! [`super::write_atomic`] that a killed process left behind.
//!
//! **Links.** A symbolic link planted where raisov writes a result (`measures.csv`, a
//! `.pvd`, `frames/`) would send the writes wherever it points. [`open_for_writing`] refuses
//! one with an error naming it (on Linux also atomically, by `O_NOFOLLOW`), and
//! [`refuse_link`] checks a name before a run starts. The output directory itself may be a
//! link: that is the user's choice; only the entries in it are checked. A file written by
//! [`super::write_atomic`] needs no check: its temporary file is created new (`O_EXCL`,
//! which does not follow a link either) and the rename replaces a link at the final name
//! instead of writing through it.
//!
//! **Temporaries.** [`super::write_atomic`] writes `.NAME.PID.N.tmp` (`PID` the writer's
//! process id, `N` a counter) and renames it; a process killed by SIGKILL between the two
//! leaves it. [`sweep_temporaries`] removes, in one directory, the files of exactly that
//! pattern whose writer is known to be gone: on Linux a `PID` that names no process (`kill(PID,
//! 0)` answers `ESRCH`); elsewhere, where that cannot be asked, only when the caller holds the
//! directory's [`super::OutputLock`] (no other run writes there). Nothing else is touched.

use std::path::Path;

use crate::{Error, Result};

/// The error for a symbolic link at `path`.
fn link_error(path: &Path) -> Error {
    let target = std::fs::read_link(path)
        .map(|t| format!(" (to {})", t.display()))
        .unwrap_or_default();
    Error::io(
        path,
        std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "is a symbolic link{target}; raisov does not write through links in its output \
                 directory: remove it"
            ),
        ),
    )
}

/// An error naming `path` if it is a symbolic link; `Ok` if it is anything else or absent.
pub fn refuse_link(path: &Path) -> Result<()> {
    match std::fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => Err(link_error(path)),
        _ => Ok(()),
    }
}

/// Open `path` for writing, created if absent, truncated if `truncate`, never through a
/// symbolic link (module docs): a link there is an error naming it.
pub fn open_for_writing(path: &Path, truncate: bool) -> Result<std::fs::File> {
    refuse_link(path)?;
    let mut o = std::fs::OpenOptions::new();
    o.write(true).create(true).truncate(truncate);
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NOFOLLOW);
    }
    o.open(path).map_err(|e| {
        // A link that appeared after the check: O_NOFOLLOW answers ELOOP.
        #[cfg(target_os = "linux")]
        if e.raw_os_error() == Some(libc::ELOOP) {
            return link_error(path);
        }
        Error::io(path, e)
    })
}

/// The process id in a temporary file name of [`super::write_atomic`], `.NAME.PID.N.tmp`;
/// `None` for any other name.
pub fn temporary_writer(file_name: &str) -> Option<u32> {
    let rest = file_name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let (rest, n) = rest.rsplit_once('.')?;
    let (name, pid) = rest.rsplit_once('.')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    if name.is_empty() || !digits(n) || !digits(pid) {
        return None;
    }
    pid.parse().ok()
}

/// Whether process `pid` is known to be gone: `Some(false)` while it runs (or is another
/// user's), `None` where the system cannot be asked.
fn process_gone(pid: u32) -> Option<bool> {
    if pid == std::process::id() {
        return Some(false);
    }
    #[cfg(target_os = "linux")]
    {
        let Ok(p) = libc::pid_t::try_from(pid) else {
            return Some(false);
        };
        if p <= 0 {
            return Some(false);
        }
        // SAFETY: signal 0 only asks whether the process exists; nothing is sent.
        let r = unsafe { libc::kill(p, 0) };
        Some(r != 0 && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH))
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Remove the temporary files of [`super::write_atomic`] in `dir` (not below it) whose writer
/// is gone (module docs); `locked`: the caller holds `dir`'s output lock, so on systems where
/// a process cannot be asked about, every such file but this process's own is a leftover.
/// Returns how many were removed; a missing `dir` has none.
pub fn sweep_temporaries(dir: &Path, locked: bool) -> Result<usize> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut removed = 0;
    for e in entries {
        let e = e.map_err(|e| Error::io(dir, e))?;
        let Some(pid) = e.file_name().to_str().and_then(temporary_writer) else {
            continue;
        };
        let gone = process_gone(pid).unwrap_or(locked && pid != std::process::id());
        if !gone || !e.file_type().is_ok_and(|t| t.is_file()) {
            continue;
        }
        let p = e.path();
        match std::fs::remove_file(&p) {
            Ok(()) => removed += 1,
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
            Err(err) => return Err(Error::io(&p, err)),
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn temporary_names_are_recognised_exactly() {
        assert_eq!(temporary_writer(".summary.txt.1234.0.tmp"), Some(1234));
        assert_eq!(temporary_writer(".a_000001.vtu.77.12.tmp"), Some(77));
        for other in [
            "summary.txt",
            ".summary.txt.tmp",
            ".x.12.tmp",
            "..12.3.tmp",
            ".x.12a.3.tmp",
            "x.12.3.tmp",
            ".x.12.3.tmp.png",
            "notes.tmp",
        ] {
            assert_eq!(temporary_writer(other), None, "{other}");
        }
    }

    /// A symbolic link at an output's name is refused, naming it, and its target is left as
    /// it was.
    #[cfg(unix)]
    #[test]
    fn output_opened_through_a_symlink_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("elsewhere.txt");
        std::fs::write(&target, "keep").unwrap();
        let link = dir.path().join("measures.csv");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        for truncate in [true, false] {
            let e = open_for_writing(&link, truncate).unwrap_err().to_string();
            assert!(
                e.contains("measures.csv") && e.contains("symbolic link") && e.contains("remove"),
                "{e}"
            );
        }
        assert_eq!(std::fs::read_to_string(&target).unwrap(), "keep");
        refuse_link(&dir.path().join("absent")).unwrap();
        refuse_link(&target).unwrap();
    }

    /// Leftovers of a dead writer go, the files of a live one (this process) and every other
    /// name stay.
    #[test]
    fn sweep_removes_only_temporaries_of_gone_writers() {
        let dir = tempfile::tempdir().unwrap();
        let me = std::process::id();
        // A pid above Linux's maximum (2^22) names no process.
        let dead = 4_194_304 + 17;
        let keep = [
            format!(".summary.txt.{me}.0.tmp"),
            "user.tmp".to_string(),
            ".notes.tmp".to_string(),
            "summary.txt".to_string(),
        ];
        for f in &keep {
            std::fs::write(dir.path().join(f), "").unwrap();
        }
        let gone = [
            format!(".summary.txt.{dead}.3.tmp"),
            format!(".x_000001.vtu.{dead}.0.tmp"),
        ];
        for f in &gone {
            std::fs::write(dir.path().join(f), "").unwrap();
        }
        assert_eq!(sweep_temporaries(dir.path(), true).unwrap(), 2);
        for f in &keep {
            assert!(dir.path().join(f).exists(), "{f}");
        }
        for f in &gone {
            assert!(!dir.path().join(f).exists(), "{f}");
        }
        assert_eq!(
            sweep_temporaries(&dir.path().join("none"), true).unwrap(),
            0
        );
    }
}
