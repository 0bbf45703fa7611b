//! Memory for large allocations, checked before they are made: a mesher, a generator, a force
//! model or a solver that would need more than the machine has free says so and stops,
//! instead of being killed part-way. The estimates are upper bounds of bytes per node,
//! element or lattice vertex, stated where each check is made.
//!
//! The free memory is `MemAvailable` of `/proc/meminfo` (Linux); elsewhere it is unknown and
//! nothing is refused.

/// Bytes of memory available to new allocations, where the platform says.
pub fn available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// What a solver's refusal suggests.
const SOLVER_REMEDY: &str = "use a coarser mesh, or a solver that does not form it";

/// `Ok` where `bytes` fit in the available memory (or it is unknown); otherwise a message
/// naming `what`, the bytes it needs and the bytes available, both in GiB.
pub fn check(what: &str, bytes: u64) -> Result<(), String> {
    check_against(what, bytes, available())
}

/// [`check`] with the message's remedy given (for a solver: a coarser mesh or another solver).
pub fn check_for(what: &str, bytes: u64, remedy: &str) -> Result<(), String> {
    refuse(what, bytes, available(), remedy)
}

/// [`check`] against a given amount of available memory.
pub fn check_against(what: &str, bytes: u64, available: Option<u64>) -> Result<(), String> {
    refuse(what, bytes, available, SOLVER_REMEDY)
}

fn refuse(what: &str, bytes: u64, available: Option<u64>, remedy: &str) -> Result<(), String> {
    match available {
        Some(free) if bytes > free => Err(format!(
            "{what} needs {:.2} GiB of memory but {:.2} GiB are available; {remedy}",
            gib(bytes),
            gib(free)
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

    #[test]
    fn a_request_beyond_the_available_memory_is_refused_with_both_sizes() {
        let e = check_against("the factor", 3 << 30, Some(1 << 30)).unwrap_err();
        assert!(e.contains("the factor needs 3.00 GiB"), "{e}");
        assert!(e.contains("1.00 GiB are available"), "{e}");
        assert!(check_against("x", 1 << 20, Some(1 << 30)).is_ok());
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
        let e = refuse("meshing", 3 << 30, Some(1 << 30), "ask for fewer nodes").unwrap_err();
        assert!(e.starts_with("meshing needs 3.00 GiB"), "{e}");
        assert!(e.ends_with("; ask for fewer nodes"), "{e}");
        assert!(check_for("meshing", 1, "x").is_ok());
    }
}
