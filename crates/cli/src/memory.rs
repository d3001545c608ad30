//! Peak resident memory of this process.
//!
//! On Linux the kernel keeps the high-water mark of the resident set size,
//! `VmHWM` in `/proc/self/status`. It covers the whole process and only
//! grows, so it describes the largest configuration run so far: `sweep`
//! therefore runs every configuration in a child process of its own
//! (`ferrofmm demo --json`) to get a true per-configuration figure.
//! Elsewhere the figure is unavailable and reported as such.

/// Peak resident set size of this process in bytes, when the platform tells.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    parse_vm_hwm(&status)
}

/// The `VmHWM:` line of a `/proc/<pid>/status` text, in bytes.
fn parse_vm_hwm(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let mut parts = line["VmHWM:".len()..].split_whitespace();
    let value: u64 = parts.next()?.parse().ok()?;
    let scale = match parts.next() {
        Some("kB") | Some("KB") | None => 1024,
        Some("MB") => 1024 * 1024,
        Some("B") => 1,
        Some(_) => return None,
    };
    value.checked_mul(scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_high_water_mark() {
        let status = "Name:\tferrofmm\nVmPeak:\t  999 kB\nVmHWM:\t    4096 kB\nVmRSS:\t 12 kB\n";
        assert_eq!(parse_vm_hwm(status), Some(4096 * 1024));
        assert_eq!(parse_vm_hwm("Name: x\n"), None);
        assert_eq!(parse_vm_hwm("VmHWM: lots\n"), None);
    }

    #[test]
    fn reads_this_process_on_linux() {
        if cfg!(target_os = "linux") {
            assert!(peak_rss_bytes().unwrap() > 0);
        }
    }
}
