//! What the machine can still give this process: `MemAvailable` of
//! `/proc/meminfo`, lowered by the address-space limit (`RLIMIT_AS`, the
//! soft value in `/proc/self/limits`) less the process's size (`VmSize`
//! of `/proc/self/status`):
//!
//! ```text
//! available = min(MemAvailable, RLIMIT_AS - VmSize)
//! ```
//!
//! (either term alone where the other is unknown). Linux only; elsewhere
//! nothing is known and [`available_memory`] is `None`. Uses nothing else
//! of the crate.

/// The memory this process can still allocate, in bytes: `MemAvailable`
/// of `/proc/meminfo`, lowered to what the address-space limit
/// (`RLIMIT_AS`, `ulimit -v`, the soft value in `/proc/self/limits`)
/// leaves above the process's current size (`VmSize` of
/// `/proc/self/status`). `None` where neither is known.
///
/// Under `RLIMIT_AS` an allocation beyond the limit fails (in Rust: an
/// abort, "memory allocation of N bytes failed") however much memory the
/// machine has, so a check against `MemAvailable` alone lets such runs
/// through.
pub fn available_memory() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|info| kib_field(&info, "MemAvailable:"));
    let limited = address_space_limit().map(|limit| {
        let used = std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| kib_field(&s, "VmSize:"))
            .unwrap_or(0);
        limit.saturating_sub(used)
    });
    match (system, limited) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The soft `RLIMIT_AS` in bytes (`None`: unlimited or unknown).
pub fn address_space_limit() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    parse_address_space_limit(&limits)
}

/// The soft value of the `Max address space` row of `/proc/self/limits`.
fn parse_address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// `NAME:  1234 kB` of a `/proc` file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_address_space_limit() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max stack size            8388608              unlimited            bytes     \n\
                      Max address space         2147483648           unlimited            bytes     \n";
        assert_eq!(parse_address_space_limit(limits), Some(2147483648));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(parse_address_space_limit(unlimited), None);
        assert_eq!(kib_field("VmSize:\t  1024 kB\n", "VmSize:"), Some(1 << 20));
    }
}
