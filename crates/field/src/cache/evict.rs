//! Trimming a cache folder to its size cap ([`evict`]): our files only
//! (name pattern and magic bytes), least recently used first, and stale
//! temporary files of killed writers.

use std::fs::{self, File};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

use super::MAGIC;

/// Temporary files older than this are left over by a killed writer.
const STALE_TMP: Duration = Duration::from_secs(24 * 3600);

/// `<kind>_<kernel>_p<order>_<float>_<16 hex digits>.ffmm`, as
/// [`file_path`](super::file::file_path) names them.
fn is_cache_file_name(name: &str) -> bool {
    let Some(stem) = name.strip_suffix(".ffmm") else {
        return false;
    };
    let Some((front, hash)) = stem.rsplit_once('_') else {
        return false;
    };
    hash.len() == 16
        && hash.bytes().all(|b| b.is_ascii_hexdigit())
        && front.contains("_p")
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b))
}

/// `.<cache file name>.<pid>.<nonce>.<n>.tmp`, as [`write`] names them.
fn is_temporary_name(name: &str) -> bool {
    name.strip_prefix('.')
        .and_then(|n| n.strip_suffix(".tmp"))
        .and_then(|n| n.split_once(".ffmm."))
        .is_some_and(|(file, rest)| {
            is_cache_file_name(&format!("{file}.ffmm"))
                && rest.split('.').count() == 3
                && rest.bytes().all(|b| b.is_ascii_hexdigit() || b == b'.')
        })
}

/// Whether `path` starts with the cache's magic bytes.
fn has_magic(path: &Path) -> bool {
    let mut m = [0u8; 8];
    File::open(path)
        .and_then(|mut f| f.read_exact(&mut m))
        .is_ok_and(|()| &m == MAGIC)
}

/// Trim the cache folder `dir` to at most `limit` bytes of cache files:
/// delete ours (name pattern and magic) oldest modification time first,
/// never `keep`; also delete our temporary files older than a day.
/// Returns how many cache files were deleted. Errors (a file another
/// process deleted first, a folder that cannot be listed) are ignored:
/// eviction is housekeeping and never fails a run.
pub(crate) fn evict(dir: &Path, limit: u64, keep: &Path) -> usize {
    let Ok(entries) = fs::read_dir(dir) else {
        return 0;
    };
    let now = SystemTime::now();
    let mut files: Vec<(SystemTime, u64, PathBuf)> = Vec::new();
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Ok(meta) = entry.metadata() else { continue };
        if !meta.is_file() {
            continue;
        }
        let modified = meta.modified().unwrap_or(now);
        let path = entry.path();
        if is_cache_file_name(name) {
            if has_magic(&path) {
                files.push((modified, meta.len(), path));
            }
        } else if is_temporary_name(name)
            && now.duration_since(modified).unwrap_or_default() > STALE_TMP
        {
            let _ = fs::remove_file(&path);
        }
    }
    let mut total: u64 = files.iter().map(|f| f.1).sum();
    if total <= limit {
        return 0;
    }
    files.sort();
    let mut removed = 0;
    for (_, len, path) in files {
        if total <= limit {
            break;
        }
        if path == keep {
            continue;
        }
        if fs::remove_file(&path).is_ok() {
            removed += 1;
        }
        // Gone either way (deleted here or by another process).
        total = total.saturating_sub(len);
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cache::CacheKey;
    use crate::cache::file::file_path;

    #[test]
    fn our_names_only() {
        let key = CacheKey::new::<ferrofmm_kernels::Laplace3d, f64>(
            "operators",
            &ferrofmm_kernels::Laplace3d,
            6,
            [1.05, 2.95, 2.95, 1.05],
        );
        let path = file_path(Path::new("/x"), &key);
        let name = path.file_name().unwrap().to_str().unwrap();
        assert!(is_cache_file_name(name), "{name}");
        let tmp = format!(".{name}.123.00ff00ff00ff00ff.7.tmp");
        assert!(is_temporary_name(&tmp), "{tmp}");
        for other in [
            "notes.txt",
            "data.ffmm",
            "a_p6_f64_0123.ffmm",
            "a_p6_f64_0123456789abcdeg.ffmm",
            "operators_laplace_p6_f64_0123456789abcdef.ffmm.bak",
            ".notes.txt.1.2.3.tmp",
            ".data.ffmm.1.2.3.tmp",
        ] {
            assert!(!is_cache_file_name(other), "{other}");
            assert!(!is_temporary_name(other), "{other}");
        }
    }
}
