//! One on-disk operator cache for all the tests of a test binary.
//!
//! The library computes operators (pseudo-inverses, M2M/L2L, M2L
//! precomputations) afresh for every FMM unless it is given a cache
//! folder. Tests that build many FMMs of the same kernel and order (the
//! Stokeslet at orders 3 to 10, twice over, for instance) spend most of
//! their time there; with [`shared_operator_cache`] the first test to need
//! an operator computes and stores it and the others read it back (the
//! cache files are checksummed and written under a temporary name, then
//! renamed, so tests running in parallel never read a half-written one).
//!
//! Each test process gets its own folder, so a run never reads operators
//! that an older build of the code computed; folders of processes that
//! have ended are removed when the next process makes its own.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Folder names are this prefix and the process id.
const PREFIX: &str = "operator-cache-";

/// Folders of ended processes are removed after this long where it cannot
/// be told whether their process is still running (not Linux).
const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(6 * 3600);

/// The operator cache folder of this test process, under `base` (an
/// integration test passes `env!("CARGO_TARGET_TMPDIR")`): made on the
/// first call, the same path afterwards.
///
/// # Panics
/// If the folder cannot be made (a test cannot go on without it).
///
/// ```
/// let base = std::env::temp_dir();
/// let dir = ferrofmm_testing::shared_operator_cache(&base);
/// assert!(dir.is_dir());
/// assert_eq!(dir, ferrofmm_testing::shared_operator_cache(&base));
/// ```
pub fn shared_operator_cache(base: &Path) -> PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        remove_ended(base);
        let dir = base.join(format!("{PREFIX}{}", std::process::id()));
        std::fs::create_dir_all(&dir)
            .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
        dir
    })
    .clone()
}

/// Remove the cache folders under `base` whose process has ended.
fn remove_ended(base: &Path) {
    let Ok(entries) = std::fs::read_dir(base) else {
        return;
    };
    let me = std::process::id();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(PREFIX))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != me && has_ended(pid, &entry.path()) {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}

/// Whether process `pid` (the owner of `dir`) has ended: on Linux, its
/// `/proc` entry is gone; elsewhere, its folder is older than
/// [`STALE_AFTER`].
fn has_ended(pid: u32, dir: &Path) -> bool {
    let proc = Path::new("/proc");
    if proc.join("self").exists() {
        return !proc.join(pid.to_string()).exists();
    }
    std::fs::metadata(dir)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age > STALE_AFTER)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::TempDir;

    #[test]
    fn folders_of_ended_processes_are_removed_and_ours_is_kept() {
        let base = TempDir::new("operator-cache");
        // No process has id u32::MAX - 1 (Linux caps ids at 2^22).
        let ended = base.join(format!("{PREFIX}{}", u32::MAX - 1));
        let other = base.join("not-a-cache");
        std::fs::create_dir_all(&ended).unwrap();
        std::fs::create_dir_all(&other).unwrap();
        let ours = shared_operator_cache(&base);
        if Path::new("/proc/self").exists() {
            assert!(!ended.exists());
        }
        assert!(other.exists());
        assert!(ours.is_dir());
        assert!(ours.ends_with(format!("{PREFIX}{}", std::process::id())));
    }
}
