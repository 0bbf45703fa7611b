//! Memory for large allocations, checked before they are made: a mesher, a generator, a force
//! model, a mesh reader or a solver that would need more than the process may still allocate
//! says so and stops, instead of being killed part-way. The estimates are upper bounds of
//! bytes per node, element or lattice vertex, stated where each check is made.
//!
//! The memory available is the smallest of the limits that apply (Linux; elsewhere it is
//! unknown and nothing is refused):
//! - the machine's free memory: `MemAvailable` of `/proc/meminfo`;
//! - the cgroup's limit: for cgroup v2, `memory.max − memory.current` (`max`: no limit), for
//!   cgroup v1, `memory.limit_in_bytes − memory.usage_in_bytes` of the `memory` controller,
//!   in the process's cgroup (its path in `/proc/self/cgroup`, under the controller's mount
//!   point in `/proc/self/mountinfo`) and in every cgroup above it up to that mount point
//!   (a parent's limit holds for its children);
//! - the address-space limit `RLIMIT_AS` (`ulimit -v`) less the process's virtual size
//!   (`VmSize` of `/proc/self/status`): what `RLIMIT_AS` bounds is the virtual size, address
//!   space reserved but never touched (thread stacks, allocator arenas) included.
//!
//! A refusal names the limit that was the smallest ([`Limit`]).

use std::path::PathBuf;

/// Which limit bounds the memory available.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Limit {
    /// The machine's free memory (`MemAvailable`).
    FreeMemory,
    /// A cgroup v2 limit (`memory.max`).
    CgroupV2,
    /// A cgroup v1 limit (`memory.limit_in_bytes`).
    CgroupV1,
    /// The address-space limit (`RLIMIT_AS`, `ulimit -v`).
    AddressSpace,
}

impl Limit {
    /// The limit in words, for messages.
    pub fn describe(self) -> &'static str {
        match self {
            Limit::FreeMemory => "the machine's free memory, MemAvailable",
            Limit::CgroupV2 => "the cgroup's memory limit, memory.max",
            Limit::CgroupV1 => "the cgroup's memory limit, memory.limit_in_bytes",
            Limit::AddressSpace => "the address-space limit, ulimit -v",
        }
    }
}

/// Bytes the process may still allocate, and the limit that says so.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Available {
    /// Bytes.
    pub bytes: u64,
    /// The smallest of the limits that apply.
    pub limit: Limit,
}

/// Bytes of memory available to new allocations, where the platform says (the smallest of
/// the limits of the module docs).
pub fn available() -> Option<u64> {
    smallest_limit().map(|a| a.bytes)
}

/// The smallest of the limits of the module docs, and which one it is; `None` where none is
/// known.
pub fn smallest_limit() -> Option<Available> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    let free = read("/proc/meminfo").and_then(|t| meminfo_available(&t));
    let (mut v2, mut v1) = (None, None);
    if let (Some(cg), Some(mi)) = (read("/proc/self/cgroup"), read("/proc/self/mountinfo")) {
        for (version, dirs) in cgroup_dirs(&cg, &mi) {
            let room = dirs
                .iter()
                .filter_map(|d| {
                    let (limit, usage) = version.files();
                    let l = std::fs::read_to_string(d.join(limit)).ok()?;
                    let u = std::fs::read_to_string(d.join(usage)).ok()?;
                    cgroup_room(&l, &u)
                })
                .min();
            match version {
                Limit::CgroupV2 => v2 = room,
                _ => v1 = room,
            }
        }
    }
    let space = address_space_room(
        rlimit_as(),
        read("/proc/self/status").and_then(|t| vm_size(&t)),
    );
    smallest([
        (Limit::FreeMemory, free),
        (Limit::CgroupV2, v2),
        (Limit::CgroupV1, v1),
        (Limit::AddressSpace, space),
    ])
}

/// The smallest of the known limits (the first of equal ones).
fn smallest(limits: impl IntoIterator<Item = (Limit, Option<u64>)>) -> Option<Available> {
    limits
        .into_iter()
        .filter_map(|(limit, bytes)| bytes.map(|bytes| Available { bytes, limit }))
        .fold(None, |best: Option<Available>, a| match best {
            Some(b) if b.bytes <= a.bytes => Some(b),
            _ => Some(a),
        })
}

/// `MemAvailable` of `/proc/meminfo` (bytes).
fn meminfo_available(meminfo: &str) -> Option<u64> {
    kib_field(meminfo, "MemAvailable:")
}

/// `VmSize` of `/proc/self/status` (bytes).
fn vm_size(status: &str) -> Option<u64> {
    kib_field(status, "VmSize:")
}

/// The value of a `Name:   123 kB` line, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Room under a cgroup limit: `limit − usage` from the two files' texts; `None` without a
/// limit (`max`) or where a text is not a number.
fn cgroup_room(limit: &str, usage: &str) -> Option<u64> {
    let limit: u64 = limit.trim().parse().ok()?;
    let usage: u64 = usage.trim().parse().ok()?;
    Some(limit.saturating_sub(usage))
}

/// Room under the address-space limit: `rlimit − vm_size` (no limit: `None`; an unknown
/// virtual size counts as 0).
fn address_space_room(rlimit: Option<u64>, vm_size: Option<u64>) -> Option<u64> {
    Some(rlimit?.saturating_sub(vm_size.unwrap_or(0)))
}

impl Limit {
    /// The limit and usage files of a cgroup version.
    fn files(self) -> (&'static str, &'static str) {
        match self {
            Limit::CgroupV2 => ("memory.max", "memory.current"),
            _ => ("memory.limit_in_bytes", "memory.usage_in_bytes"),
        }
    }
}

/// The cgroup directories whose memory limits hold for this process, per version
/// ([`Limit::CgroupV2`], [`Limit::CgroupV1`]): its own cgroup's directory and every one above
/// it up to the controller's mount point, from the texts of `/proc/self/cgroup` (lines
/// `id:controllers:path`, `0::path` for v2) and `/proc/self/mountinfo` (`cgroup2` mounts; v1
/// `cgroup` mounts whose options name `memory`).
fn cgroup_dirs(cgroup: &str, mountinfo: &str) -> Vec<(Limit, Vec<PathBuf>)> {
    let mut out = Vec::new();
    for line in cgroup.lines() {
        let mut f = line.splitn(3, ':');
        let (Some(id), Some(ctrl), Some(path)) = (f.next(), f.next(), f.next()) else {
            continue;
        };
        let version = if id == "0" && ctrl.is_empty() {
            Limit::CgroupV2
        } else if ctrl.split(',').any(|c| c == "memory") {
            Limit::CgroupV1
        } else {
            continue;
        };
        let Some((root, mount)) = cgroup_mount(mountinfo, version) else {
            continue;
        };
        // The cgroup's path relative to the mount's root (inside a cgroup namespace the
        // mount's root is the namespace's).
        let rel = path
            .strip_prefix(root.trim_end_matches('/'))
            .filter(|r| r.is_empty() || r.starts_with('/'))
            .unwrap_or("")
            .trim_start_matches('/');
        let mount = PathBuf::from(mount);
        let mut dirs = Vec::new();
        let mut d = mount.join(rel);
        loop {
            dirs.push(d.clone());
            if d == mount || !d.pop() || !d.starts_with(&mount) {
                break;
            }
        }
        out.push((version, dirs));
    }
    out
}

/// The root and mount point of the cgroup mount of `version` in a `/proc/self/mountinfo`
/// text (fields: id, parent, device, root, mount point, options, optional fields, `-`,
/// filesystem type, source, super options).
fn cgroup_mount(mountinfo: &str, version: Limit) -> Option<(String, String)> {
    mountinfo.lines().find_map(|line| {
        let (left, right) = line.split_once(" - ")?;
        let l: Vec<&str> = left.split_whitespace().collect();
        let r: Vec<&str> = right.split_whitespace().collect();
        let (root, mount) = (l.get(3)?, l.get(4)?);
        let fstype = r.first()?;
        let fits = match version {
            Limit::CgroupV2 => *fstype == "cgroup2",
            _ => *fstype == "cgroup" && r.get(2)?.split(',').any(|o| o == "memory"),
        };
        fits.then(|| (unescape(root), unescape(mount)))
    })
}

/// A mountinfo path with its octal escapes (`\040` for a space) decoded.
fn unescape(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let oct = b.get(i + 1..i + 4).filter(|d| {
            b[i] == b'\\' && d.iter().all(|c| (b'0'..=b'7').contains(c)) && d[0] <= b'3'
        });
        match oct {
            Some(d) => {
                out.push((d[0] - b'0') * 64 + (d[1] - b'0') * 8 + (d[2] - b'0'));
                i += 4;
            }
            None => {
                out.push(b[i]);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The soft address-space limit (`RLIMIT_AS`); `None` where there is none.
#[cfg(target_os = "linux")]
fn rlimit_as() -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `getrlimit` writes only the `rlimit` it is given, which lives for the call.
    let ok = unsafe { libc::getrlimit(libc::RLIMIT_AS, &mut r) } == 0;
    // `rlim_t` is `u64` on 64-bit Linux, narrower on some 32-bit targets.
    #[allow(clippy::unnecessary_cast)]
    (ok && r.rlim_cur != libc::RLIM_INFINITY).then_some(r.rlim_cur as u64)
}

#[cfg(not(target_os = "linux"))]
fn rlimit_as() -> Option<u64> {
    None
}

/// What a solver's refusal suggests.
const SOLVER_REMEDY: &str = "use a coarser mesh, or a solver that does not form it";

/// `Ok` where `bytes` fit in the available memory (or it is unknown); otherwise a message
/// naming `what`, the bytes it needs and the bytes available, both in GiB, and the limit.
pub fn check(what: &str, bytes: u64) -> Result<(), String> {
    check_against(what, bytes, smallest_limit())
}

/// [`check`] with the message's remedy given (for a solver: a coarser mesh or another solver).
pub fn check_for(what: &str, bytes: u64, remedy: &str) -> Result<(), String> {
    refuse(what, bytes, smallest_limit(), remedy)
}

/// [`check`] against a given amount of available memory.
pub fn check_against(what: &str, bytes: u64, available: Option<Available>) -> Result<(), String> {
    refuse(what, bytes, available, SOLVER_REMEDY)
}

fn refuse(
    what: &str,
    bytes: u64,
    available: Option<Available>,
    remedy: &str,
) -> Result<(), String> {
    match available {
        Some(a) if bytes > a.bytes => Err(format!(
            "{what} needs {:.2} GiB of memory but {:.2} GiB are available ({}); {remedy}",
            gib(bytes),
            gib(a.bytes),
            a.limit.describe()
        )),
        _ => Ok(()),
    }
}

fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn names(dirs: &[PathBuf]) -> Vec<&Path> {
        dirs.iter().map(PathBuf::as_path).collect()
    }

    fn free(bytes: u64) -> Option<Available> {
        Some(Available {
            bytes,
            limit: Limit::FreeMemory,
        })
    }

    #[test]
    fn a_request_beyond_the_available_memory_is_refused_with_both_sizes() {
        let e = check_against("the factor", 3 << 30, free(1 << 30)).unwrap_err();
        assert!(e.contains("the factor needs 3.00 GiB"), "{e}");
        assert!(e.contains("1.00 GiB are available"), "{e}");
        assert!(check_against("x", 1 << 20, free(1 << 30)).is_ok());
        assert!(check_against("x", u64::MAX, None).is_ok());
        if cfg!(target_os = "linux") {
            let free = available().expect("MemAvailable on Linux");
            assert!(free > 0);
            assert!(check("more than the machine", free.saturating_mul(4)).is_err());
        }
    }

    /// A refusal with a given remedy names the work, both sizes and that remedy.
    #[test]
    fn a_refusal_ends_with_the_remedy_it_is_given() {
        let e = refuse("meshing", 3 << 30, free(1 << 30), "ask for fewer nodes").unwrap_err();
        assert!(e.starts_with("meshing needs 3.00 GiB"), "{e}");
        assert!(e.ends_with("; ask for fewer nodes"), "{e}");
        assert!(check_for("meshing", 1, "x").is_ok());
    }

    /// The smallest limit wins, and the refusal names it.
    #[test]
    fn the_smallest_limit_is_taken_and_named() {
        let a = smallest([
            (Limit::FreeMemory, Some(20 << 30)),
            (Limit::CgroupV2, None),
            (Limit::CgroupV1, Some(8 << 30)),
            (Limit::AddressSpace, Some(2 << 30)),
        ])
        .unwrap();
        assert_eq!(a.bytes, 2 << 30);
        assert_eq!(a.limit, Limit::AddressSpace);
        let e = check_against("generating a box", 3 << 30, Some(a)).unwrap_err();
        assert!(
            e.contains("2.00 GiB are available (the address-space limit, ulimit -v)"),
            "{e}"
        );
        let a = smallest([
            (Limit::FreeMemory, Some(20 << 30)),
            (Limit::CgroupV2, Some(4 << 30)),
            (Limit::AddressSpace, None),
        ])
        .unwrap();
        assert_eq!(a.limit, Limit::CgroupV2);
        assert_eq!(smallest([(Limit::FreeMemory, None)]), None);
    }

    #[test]
    fn proc_fields_and_cgroup_files_are_parsed() {
        let meminfo = "MemTotal:       32000000 kB\nMemFree:         1000 kB\n\
                       MemAvailable:   22202044 kB\n";
        assert_eq!(meminfo_available(meminfo), Some(22202044 * 1024));
        assert_eq!(meminfo_available("MemTotal: 1 kB\n"), None);
        let status = "Name:\traisov\nVmPeak:\t  5000 kB\nVmSize:\t    3892 kB\n";
        assert_eq!(vm_size(status), Some(3892 * 1024));
        // v2: `max` is no limit.
        assert_eq!(cgroup_room("max\n", "123\n"), None);
        assert_eq!(
            cgroup_room("1073741824\n", "73741824\n"),
            Some(1_000_000_000)
        );
        assert_eq!(cgroup_room("100\n", "200\n"), Some(0));
        // v1 without a limit: the largest page-aligned i64.
        assert_eq!(
            cgroup_room("9223372036854771712\n", "1068744704\n"),
            Some(9223372036854771712 - 1068744704)
        );
        assert_eq!(address_space_room(None, Some(1 << 30)), None);
        assert_eq!(
            address_space_room(Some(2 << 30), Some(1 << 30)),
            Some(1 << 30)
        );
        assert_eq!(address_space_room(Some(1 << 30), Some(2 << 30)), Some(0));
        assert_eq!(address_space_room(Some(1 << 30), None), Some(1 << 30));
    }

    /// The process's cgroup and every one above it up to the mount point, for v2 (also
    /// inside a cgroup namespace) and v1 (a hybrid layout with the v2 tree beside it).
    #[test]
    fn cgroup_directories_are_found_from_the_proc_files() {
        let v2 = "0::/user.slice/user-1000.slice/session-3.scope\n";
        let mi = "25 30 0:23 / /sys/fs/cgroup rw,nosuid shared:9 - cgroup2 cgroup2 rw,nsdelegate\n";
        let got = cgroup_dirs(v2, mi);
        assert_eq!(got.len(), 1);
        assert_eq!(got[0].0, Limit::CgroupV2);
        assert_eq!(
            names(&got[0].1),
            [
                "/sys/fs/cgroup/user.slice/user-1000.slice/session-3.scope",
                "/sys/fs/cgroup/user.slice/user-1000.slice",
                "/sys/fs/cgroup/user.slice",
                "/sys/fs/cgroup",
            ]
            .map(Path::new)
        );
        // A container: the namespace's root is the cgroup itself.
        let got = cgroup_dirs("0::/\n", mi);
        assert_eq!(names(&got[0].1), [Path::new("/sys/fs/cgroup")]);
        // A mount whose root is a cgroup below the hierarchy's root.
        let mi_sub = "25 30 0:23 /docker/abc /sys/fs/cgroup ro - cgroup2 cgroup2 rw\n";
        let got = cgroup_dirs("0::/docker/abc/inner\n", mi_sub);
        assert_eq!(
            names(&got[0].1),
            ["/sys/fs/cgroup/inner", "/sys/fs/cgroup"].map(Path::new)
        );
        let got = cgroup_dirs("0::/docker/abcdef\n", mi_sub);
        assert_eq!(names(&got[0].1), [Path::new("/sys/fs/cgroup")]);
        let hybrid = "9:name=systemd:/\n4:memory:/process_api/fbca\n3:cpuset:/\n0::/\n";
        let mi = "31 23 0:28 / /sys/fs/cgroup rw,relatime - tmpfs tmpfs rw,mode=755\n\
                  32 31 0:29 / /sys/fs/cgroup/cpu rw,relatime - cgroup cgroup rw,cpu\n\
                  35 31 0:32 / /sys/fs/cgroup/memory rw,relatime - cgroup cgroup rw,memory\n\
                  41 31 0:38 / /sys/fs/cgroup/unified rw,relatime - cgroup2 cgroup2 rw\n";
        let got = cgroup_dirs(hybrid, mi);
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].0, Limit::CgroupV1);
        assert_eq!(
            names(&got[0].1),
            [
                "/sys/fs/cgroup/memory/process_api/fbca",
                "/sys/fs/cgroup/memory/process_api",
                "/sys/fs/cgroup/memory",
            ]
            .map(Path::new)
        );
        assert_eq!(got[1].0, Limit::CgroupV2);
        assert_eq!(names(&got[1].1), [Path::new("/sys/fs/cgroup/unified")]);
        // No cgroup mount: nothing.
        assert!(cgroup_dirs(v2, "").is_empty());
        assert_eq!(unescape(r"/mnt/a\040b"), "/mnt/a b");
    }

    /// On this machine: the smallest limit is no more than the free memory, and under the
    /// address-space limit where one is set.
    #[test]
    fn the_limit_here_is_no_more_than_the_free_memory() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let a = smallest_limit().expect("MemAvailable on Linux");
        let free = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|t| meminfo_available(&t))
            .unwrap();
        // Memory freed or taken meanwhile moves MemAvailable a little.
        assert!(a.bytes <= free + (free >> 3), "{a:?} vs {free}");
        if let Some(r) = rlimit_as() {
            assert!(a.bytes <= r, "{a:?} vs RLIMIT_AS {r}");
        }
    }
}
