//! The operator cache in a report's words (`cache` and `cache_dir`).

use ferrofmm_field::{CacheLocation, CacheOff, CacheSetting, CacheStatus};

/// The cache's part in a run, from the status of the operator file and of
/// the M2L file ([`CacheStatus::summary`]): `hit`, `miss (computed,
/// saved)`, ... for both, or `operators X; M2L Y` when they differ. `None`
/// when caching is off.
pub fn cache_summary(operators: &CacheStatus, m2l: &CacheStatus) -> Option<String> {
    CacheStatus::summary(operators, m2l)
}

/// The cache's part in a run and its folder, for the report: the words
/// of [`cache_summary`] when there is a folder, else why there is none
/// (`off (--no-cache)`, `off (FERROFMM_CACHE=off)`, `memory only: no
/// cache folder (...)`).
pub fn cache_report(
    setting: &CacheSetting,
    operators: &CacheStatus,
    m2l: &CacheStatus,
) -> (Option<String>, Option<String>) {
    match setting.resolve() {
        Ok(CacheLocation::Folder { dir, .. }) => (
            Some(cache_summary(operators, m2l).unwrap_or_else(|| "not needed".into())),
            Some(dir.display().to_string()),
        ),
        Ok(CacheLocation::Off(CacheOff::Requested)) => (Some("off (--no-cache)".into()), None),
        Ok(CacheLocation::Off(why)) => (Some(why.to_string()), None),
        // The build read the same environment and succeeded.
        Err(e) => (Some(format!("unknown: {e}")), None),
    }
}
