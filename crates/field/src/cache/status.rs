//! [`CacheStatus`]: what the cache did when an operator set was built,
//! and its one-line descriptions.

use std::path::{Path, PathBuf};

/// What happened with the cache when an operator set was built.
///
/// Never an error: a bad cache file is rebuilt, and a failure to write the
/// new file only leaves `write_error` set (the operators are still correct).
#[derive(Clone, Debug, PartialEq)]
pub enum CacheStatus {
    /// `OperatorParams::cache_dir` was `None`.
    Disabled,
    /// Loaded from this file.
    Hit {
        /// The cache file.
        path: PathBuf,
    },
    /// Computed, then written to `path` unless `write_error` says otherwise.
    Computed {
        /// The cache file.
        path: PathBuf,
        /// Why an existing file was not used (`None`: there was no file).
        rejected: Option<String>,
        /// Why writing the file failed (`None`: written).
        write_error: Option<String>,
    },
}

impl CacheStatus {
    /// True for [`CacheStatus::Hit`].
    pub fn is_hit(&self) -> bool {
        matches!(self, CacheStatus::Hit { .. })
    }

    /// The cache file, if caching is enabled.
    pub fn path(&self) -> Option<&Path> {
        match self {
            CacheStatus::Disabled => None,
            CacheStatus::Hit { path } | CacheStatus::Computed { path, .. } => Some(path),
        }
    }

    /// What happened, in words for a report (the file's path left out of
    /// the reasons): `hit`, `miss (computed, saved)`, `recomputed (cached
    /// file rejected: WHY; saved)`, `memory only (computed, not saved:
    /// WHY)`, `memory only (cached file rejected: WHY; recomputed, not
    /// saved: WHY)`. `None` for [`CacheStatus::Disabled`].
    pub fn describe(&self) -> Option<String> {
        let short = |s: &str| -> String {
            let line = s.lines().next().unwrap_or_default();
            if line.chars().count() > 70 {
                format!("{}...", line.chars().take(70).collect::<String>())
            } else {
                line.to_string()
            }
        };
        match self {
            CacheStatus::Disabled => None,
            CacheStatus::Hit { .. } => Some("hit".into()),
            CacheStatus::Computed {
                path,
                rejected,
                write_error,
            } => {
                // The messages name the file ("cache file PATH rejected:
                // why"); keep the reason only.
                let path = path.display().to_string();
                let short = |s: &str| -> String {
                    let s = match s.find(&path) {
                        Some(k) => s[k + path.len()..]
                            .trim_start_matches(" rejected")
                            .trim_start_matches(':')
                            .trim_start(),
                        None => s,
                    };
                    short(s)
                };
                Some(match (rejected, write_error) {
                    (None, None) => "miss (computed, saved)".to_string(),
                    (Some(r), None) => {
                        format!("recomputed (cached file rejected: {}; saved)", short(r))
                    }
                    (None, Some(e)) => format!("memory only (computed, not saved: {})", short(e)),
                    (Some(r), Some(e)) => format!(
                        "memory only (cached file rejected: {}; recomputed, not saved: {})",
                        short(r),
                        short(e)
                    ),
                })
            }
        }
    }

    /// The cache's part in a build from the status of the operator file
    /// and of the M2L file: their [`CacheStatus::describe`] when they
    /// agree, else `operators X; M2L Y`. `None` when both are disabled.
    pub fn summary(operators: &CacheStatus, m2l: &CacheStatus) -> Option<String> {
        match (operators.describe(), m2l.describe()) {
            (None, None) => None,
            (Some(a), Some(b)) if a == b => Some(a),
            (a, b) => Some(format!(
                "operators {}; M2L {}",
                a.unwrap_or_else(|| "not cached".into()),
                b.unwrap_or_else(|| "not cached".into())
            )),
        }
    }
}
