//! Memory checks under the process's own limits, tested on the built binary: a mesh beyond
//! an address-space limit (`ulimit -v`) is refused with exit status 2 and a message naming
//! that limit; it aborted (SIGABRT) when only the machine's free memory was checked.
#![cfg(target_os = "linux")]

use std::os::unix::process::CommandExt;
use std::process::{Command, Output};

/// The address-space limit of the runs (bytes).
const LIMIT: u64 = 2 << 30;

/// `raisov ARGS` with `RLIMIT_AS` lowered to [`LIMIT`].
fn raisov_under_limit(args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_raisov"));
    cmd.args(args);
    // SAFETY: between fork and exec the closure only calls `setrlimit`, which is
    // async-signal-safe, on a value it owns.
    unsafe {
        cmd.pre_exec(|| {
            let r = libc::rlimit {
                rlim_cur: LIMIT as libc::rlim_t,
                rlim_max: LIMIT as libc::rlim_t,
            };
            if libc::setrlimit(libc::RLIMIT_AS, &r) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    cmd.output().unwrap()
}

#[test]
fn a_box_beyond_the_address_space_limit_is_refused_naming_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let msh = dir.path().join("x.msh");
    let msh = msh.to_str().unwrap();
    let box_of = |nodes: &str| {
        raisov_under_limit(&[
            "mesh", "generate", "box", "--nodes", nodes, "--size", "1,1,1", "--out", msh,
        ])
    };
    let out = box_of("90000000");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{:?}: {err}", out.status);
    assert!(err.contains("generating a box of"), "{err}");
    assert!(err.contains("GiB are available"), "{err}");
    // The limit named is the address space's, unless a cgroup here allows even less.
    let cgroup_below = raisov::memory::smallest_limit().is_some_and(|a| {
        matches!(
            a.limit,
            raisov::memory::Limit::CgroupV1 | raisov::memory::Limit::CgroupV2
        ) && a.bytes < LIMIT
    });
    if !cgroup_below {
        assert!(
            err.contains("(the address-space limit, ulimit -v)"),
            "{err}"
        );
    }
    assert!(!std::path::Path::new(msh).exists());
    // A box that fits is generated under the same limit: the threads' reserved stacks and
    // the allocator's arenas count against it, but leave room.
    let out = box_of("1000");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{:?}: {err}", out.status);
    assert!(std::fs::metadata(msh).unwrap().len() > 0);
}
