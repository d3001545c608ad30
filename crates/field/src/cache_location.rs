//! Where the on-disk operator cache lives, decided in one place for every
//! front end (the `ferrofmm` command, `ferrofmm-mpi`, the Python module)
//! and for library users who ask for it ([`CacheSetting`]).
//!
//! # Resolution ([`CacheSetting::resolve`])
//!
//! 1. An explicit folder ([`CacheSetting::Dir`]: `--cache-dir`,
//!    `cache_dir=`/`cache="path"`, `FmmBuilder::cache_dir`) wins.
//! 2. [`CacheSetting::Default`] reads [`CACHE_ENV`] (`FERROFMM_CACHE`):
//!    `off`, `0`, `false` or `no` (any case) turns the cache off; any other
//!    non-empty value is the folder.
//! 3. Else `$XDG_CACHE_HOME/ferrofmm` (an absolute `XDG_CACHE_HOME`, as
//!    the XDG base directory specification asks), else
//!    `$HOME/.cache/ferrofmm`.
//! 4. Else (no home) the operators are kept in memory only.
//!
//! [`CacheSetting::Off`] (`--no-cache`, `cache=False`, and the library's
//! default) keeps them in memory only.
//!
//! # Size
//!
//! A folder holds at most [`DEFAULT_CACHE_SIZE`] (2 GiB) of cache files,
//! or what [`CACHE_SIZE_ENV`] (`FERROFMM_CACHE_SIZE`) says: bytes with an
//! optional `K`, `M`, `G` or `T` suffix (powers of 1024, an optional `B` or
//! `iB` after it, e.g. `500M`, `1.5GiB`), or `unlimited`. After each file
//! written, the least recently used cache files (by modification time; a
//! hit refreshes it) are deleted until the folder is under the cap; the
//! file just written is never deleted, and only files of ours (our name
//! pattern and our magic bytes) are ever touched. A value that is not a
//! size is an error ([`FieldError::InvalidParams`]), never ignored.
//!
//! Uses only [`FieldError`] and the byte-count parser of `environment`.

use std::ffi::OsString;
use std::fmt;
use std::path::PathBuf;

use crate::FieldError;
use crate::environment::parse_bytes;

/// The environment variable that places or disables the default cache.
pub const CACHE_ENV: &str = "FERROFMM_CACHE";

/// The environment variable that caps the cache folder's size.
pub const CACHE_SIZE_ENV: &str = "FERROFMM_CACHE_SIZE";

/// The cap of a cache folder without [`CACHE_SIZE_ENV`]: 2 GiB (the
/// operators of one order and kernel take 1-100 MiB for a homogeneous
/// kernel, up to a few hundred MiB for per-level sets at high order).
pub const DEFAULT_CACHE_SIZE: u64 = 2 << 30;

/// The folder below the platform's cache folder.
const CACHE_SUBFOLDER: &str = "ferrofmm";

/// Which on-disk cache a run asks for.
///
/// # Resolution ([`CacheSetting::resolve`])
///
/// 1. An explicit folder ([`CacheSetting::Dir`]: `--cache-dir`,
///    `cache_dir=` / `cache="path"`, `FmmBuilder::cache_dir`) wins.
/// 2. [`CacheSetting::Default`] reads [`CACHE_ENV`] (`FERROFMM_CACHE`):
///    `off`, `0`, `false` or `no` (any case) turns the cache off; any other
///    non-empty value is the folder.
/// 3. Else `$XDG_CACHE_HOME/ferrofmm` (an absolute `XDG_CACHE_HOME`), else
///    `$HOME/.cache/ferrofmm`.
/// 4. Else (no home) the operators are kept in memory only.
///
/// [`CacheSetting::Off`] (`--no-cache`, `cache=False`, the library's
/// default) keeps them in memory only.
///
/// # Size
///
/// A folder holds at most [`DEFAULT_CACHE_SIZE`] (2 GiB) of cache files,
/// or what [`CACHE_SIZE_ENV`] (`FERROFMM_CACHE_SIZE`) says
/// ([`parse_cache_size`]). After each file written, the least recently
/// used cache files (by modification time; a hit refreshes it) are deleted
/// until the folder is under the cap; the file just written is never
/// deleted, and only files of ours (our name pattern and our magic bytes)
/// are ever touched.
///
/// ```
/// use ferrofmm_field::{CacheLocation, CacheSetting};
/// let here = std::env::temp_dir().join("my-operators");
/// match CacheSetting::Dir(here.clone()).resolve().unwrap() {
///     CacheLocation::Folder { dir, .. } => assert_eq!(dir, here),
///     other => panic!("{other:?}"),
/// }
/// assert!(CacheSetting::Off.resolve().unwrap().dir().is_none());
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum CacheSetting {
    /// No on-disk cache: operators are computed by every run (the
    /// library's default, `--no-cache`, Python `cache=False`).
    #[default]
    Off,
    /// The default location: [`CACHE_ENV`], else `$XDG_CACHE_HOME/ferrofmm`,
    /// else `$HOME/.cache/ferrofmm`, else memory only (what the front ends
    /// use unless told otherwise).
    Default,
    /// This folder, whatever the environment says (created when missing).
    Dir(PathBuf),
}

/// Where the folder of a [`CacheLocation::Folder`] came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CacheOrigin {
    /// Given explicitly ([`CacheSetting::Dir`]).
    Explicit,
    /// The [`CACHE_ENV`] variable.
    Environment,
    /// `$XDG_CACHE_HOME/ferrofmm`.
    XdgCacheHome,
    /// `$HOME/.cache/ferrofmm`.
    Home,
}

/// Why a run has no on-disk cache.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheOff {
    /// [`CacheSetting::Off`] was asked for.
    Requested,
    /// [`CACHE_ENV`] has this value (`off`, `0`, `false`, `no`).
    Environment(String),
    /// [`CacheSetting::Default`], but none of [`CACHE_ENV`],
    /// `XDG_CACHE_HOME` and `HOME` names a folder.
    NoFolder,
}

impl fmt::Display for CacheOff {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CacheOff::Requested => write!(f, "off"),
            CacheOff::Environment(v) => write!(f, "off ({CACHE_ENV}={v})"),
            CacheOff::NoFolder => write!(
                f,
                "memory only: no cache folder ({CACHE_ENV}, XDG_CACHE_HOME and HOME are unset)"
            ),
        }
    }
}

/// A resolved [`CacheSetting`]: a folder with its size cap, or none.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum CacheLocation {
    /// Cache files live in `dir` (created on the first write; a folder
    /// that cannot be created or written leaves the run in memory, see
    /// [`CacheStatus::Computed`](crate::CacheStatus::Computed)).
    Folder {
        /// The folder.
        dir: PathBuf,
        /// Most bytes of cache files kept there ([`DEFAULT_CACHE_SIZE`] or
        /// [`CACHE_SIZE_ENV`]; `u64::MAX` for `unlimited`).
        size_limit: u64,
        /// Where `dir` came from.
        origin: CacheOrigin,
    },
    /// No on-disk cache, and why.
    Off(CacheOff),
}

impl CacheLocation {
    /// The folder, if there is one.
    pub fn dir(&self) -> Option<&std::path::Path> {
        match self {
            CacheLocation::Folder { dir, .. } => Some(dir),
            CacheLocation::Off(_) => None,
        }
    }

    /// The size cap, if there is a folder.
    pub fn size_limit(&self) -> Option<u64> {
        match self {
            CacheLocation::Folder { size_limit, .. } => Some(*size_limit),
            CacheLocation::Off(_) => None,
        }
    }
}

impl CacheSetting {
    /// The folder and cap this setting means in the current environment
    /// (the rules are those of [`CacheSetting`]).
    ///
    /// # Errors
    /// [`FieldError::InvalidParams`] when a folder is used and
    /// [`CACHE_SIZE_ENV`] is set to something that is not a size.
    pub fn resolve(&self) -> Result<CacheLocation, FieldError> {
        self.resolve_with(|name| std::env::var_os(name))
    }

    /// [`CacheSetting::resolve`] with the environment read through `env`
    /// (for tests and for callers with their own environment).
    ///
    /// ```
    /// use std::ffi::OsString;
    /// use ferrofmm_field::{CacheLocation, CacheOff, CacheOrigin, CacheSetting};
    /// let env = |vars: &'static [(&'static str, &'static str)]| {
    ///     move |name: &str| vars.iter().find(|v| v.0 == name).map(|v| OsString::from(v.1))
    /// };
    /// let home = CacheSetting::Default.resolve_with(env(&[("HOME", "/home/me")])).unwrap();
    /// assert_eq!(home.dir().unwrap(), std::path::Path::new("/home/me/.cache/ferrofmm"));
    /// let off = CacheSetting::Default.resolve_with(env(&[("FERROFMM_CACHE", "off")])).unwrap();
    /// assert_eq!(off, CacheLocation::Off(CacheOff::Environment("off".into())));
    /// let small = CacheSetting::Default
    ///     .resolve_with(env(&[("FERROFMM_CACHE", "/c"), ("FERROFMM_CACHE_SIZE", "10M")]))
    ///     .unwrap();
    /// assert_eq!(small.size_limit(), Some(10 << 20));
    /// ```
    ///
    /// # Errors
    /// As [`CacheSetting::resolve`].
    pub fn resolve_with(
        &self,
        env: impl Fn(&str) -> Option<OsString>,
    ) -> Result<CacheLocation, FieldError> {
        let var = |name: &str| env(name).filter(|v| !v.is_empty());
        let (dir, origin) = match self {
            CacheSetting::Off => return Ok(CacheLocation::Off(CacheOff::Requested)),
            CacheSetting::Dir(dir) => (dir.clone(), CacheOrigin::Explicit),
            CacheSetting::Default => {
                if let Some(v) = var(CACHE_ENV) {
                    if is_off_word(&v) {
                        return Ok(CacheLocation::Off(CacheOff::Environment(
                            v.to_string_lossy().into_owned(),
                        )));
                    }
                    (PathBuf::from(v), CacheOrigin::Environment)
                } else if let Some(x) = var("XDG_CACHE_HOME").map(PathBuf::from)
                    && x.is_absolute()
                {
                    (x.join(CACHE_SUBFOLDER), CacheOrigin::XdgCacheHome)
                } else if let Some(h) = var("HOME") {
                    (
                        PathBuf::from(h).join(".cache").join(CACHE_SUBFOLDER),
                        CacheOrigin::Home,
                    )
                } else {
                    return Ok(CacheLocation::Off(CacheOff::NoFolder));
                }
            }
        };
        let size_limit = match var(CACHE_SIZE_ENV) {
            None => DEFAULT_CACHE_SIZE,
            Some(v) => parse_cache_size(&v.to_string_lossy())?,
        };
        Ok(CacheLocation::Folder {
            dir,
            size_limit,
            origin,
        })
    }
}

/// `off`, `0`, `false`, `no` (any case, surrounding blanks ignored).
fn is_off_word(v: &std::ffi::OsStr) -> bool {
    v.to_str().is_some_and(|s| {
        let s = s.trim();
        ["off", "0", "false", "no"]
            .iter()
            .any(|w| s.eq_ignore_ascii_case(w))
    })
}

/// A cache size as [`CACHE_SIZE_ENV`] takes it: `123` (bytes), `64K`,
/// `500M`, `2G`, `1T` (powers of 1024; `1.5G`, `2GiB` and `2GB` too), or
/// `unlimited` (`u64::MAX`).
///
/// ```
/// use ferrofmm_field::parse_cache_size;
/// assert_eq!(parse_cache_size("2G").unwrap(), 2 << 30);
/// assert_eq!(parse_cache_size("1536").unwrap(), 1536);
/// assert!(parse_cache_size("big").is_err());
/// ```
///
/// # Errors
/// [`FieldError::InvalidParams`], naming the variable and the value.
pub fn parse_cache_size(value: &str) -> Result<u64, FieldError> {
    let bad = || {
        FieldError::InvalidParams(format!(
            "{CACHE_SIZE_ENV}={value:?} is not a size (bytes with an optional K, M, G or T \
             suffix, e.g. 500M or 2G, or unlimited)"
        ))
    };
    if value.trim().eq_ignore_ascii_case("unlimited") {
        return Ok(u64::MAX);
    }
    match parse_bytes(value) {
        // `off` means "no limit" to the memory limit; a cache size of
        // "off" is ambiguous (disable? no cap?), so it is refused.
        Some(Some(bytes)) if !value.trim().eq_ignore_ascii_case("off") => Ok(bytes),
        _ => Err(bad()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn env(vars: &[(&str, &str)]) -> impl Fn(&str) -> Option<OsString> {
        let vars: Vec<(String, String)> = vars
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect();
        move |name| {
            vars.iter()
                .find(|v| v.0 == name)
                .map(|v| OsString::from(&v.1))
        }
    }

    fn resolve(setting: &CacheSetting, vars: &[(&str, &str)]) -> CacheLocation {
        setting.resolve_with(env(vars)).unwrap()
    }

    #[test]
    fn explicit_folder_wins_over_the_environment() {
        let loc = resolve(
            &CacheSetting::Dir("/mine".into()),
            &[("FERROFMM_CACHE", "off"), ("HOME", "/home/me")],
        );
        assert_eq!(
            loc,
            CacheLocation::Folder {
                dir: "/mine".into(),
                size_limit: DEFAULT_CACHE_SIZE,
                origin: CacheOrigin::Explicit
            }
        );
    }

    #[test]
    fn off_words_disable_the_default() {
        for w in ["off", "OFF", "0", "false", "No", " off "] {
            assert_eq!(
                resolve(
                    &CacheSetting::Default,
                    &[("FERROFMM_CACHE", w), ("HOME", "/h")]
                ),
                CacheLocation::Off(CacheOff::Environment(w.into())),
                "{w:?}"
            );
        }
        // Not an off word: a folder of that name.
        let loc = resolve(&CacheSetting::Default, &[("FERROFMM_CACHE", "offline")]);
        assert_eq!(loc.dir(), Some(Path::new("offline")));
    }

    #[test]
    fn default_order_env_then_xdg_then_home_then_memory() {
        let d = CacheSetting::Default;
        let all = [
            ("FERROFMM_CACHE", "/env"),
            ("XDG_CACHE_HOME", "/xdg"),
            ("HOME", "/home/me"),
        ];
        let loc = resolve(&d, &all);
        assert_eq!(loc.dir(), Some(Path::new("/env")));
        assert!(matches!(
            loc,
            CacheLocation::Folder {
                origin: CacheOrigin::Environment,
                ..
            }
        ));
        let loc = resolve(&d, &all[1..]);
        assert_eq!(loc.dir(), Some(Path::new("/xdg/ferrofmm")));
        // An empty variable counts as unset; a relative XDG_CACHE_HOME is
        // ignored (the XDG specification).
        for xdg in ["", "relative"] {
            let loc = resolve(
                &d,
                &[
                    ("FERROFMM_CACHE", ""),
                    ("XDG_CACHE_HOME", xdg),
                    ("HOME", "/home/me"),
                ],
            );
            assert_eq!(loc.dir(), Some(Path::new("/home/me/.cache/ferrofmm")));
        }
        assert_eq!(
            resolve(&d, &[]),
            CacheLocation::Off(CacheOff::NoFolder),
            "no home: memory only"
        );
        assert_eq!(
            resolve(&CacheSetting::Off, &all),
            CacheLocation::Off(CacheOff::Requested)
        );
    }

    #[test]
    fn sizes() {
        assert_eq!(parse_cache_size("0").unwrap(), 0);
        assert_eq!(parse_cache_size("4096").unwrap(), 4096);
        assert_eq!(parse_cache_size("64K").unwrap(), 64 << 10);
        assert_eq!(parse_cache_size("500m").unwrap(), 500 << 20);
        assert_eq!(parse_cache_size("2G").unwrap(), 2 << 30);
        assert_eq!(parse_cache_size("2GiB").unwrap(), 2 << 30);
        assert_eq!(parse_cache_size("1.5G").unwrap(), 3 << 29);
        assert_eq!(parse_cache_size("1T").unwrap(), 1 << 40);
        assert_eq!(parse_cache_size("unlimited").unwrap(), u64::MAX);
        for bad in ["", "big", "-1", "1X", "off", "NaN", "G"] {
            let e = parse_cache_size(bad).unwrap_err().to_string();
            assert!(
                e.contains("FERROFMM_CACHE_SIZE") && e.contains("not a size"),
                "{e}"
            );
        }
        let loc = resolve(
            &CacheSetting::Default,
            &[("FERROFMM_CACHE", "/c"), ("FERROFMM_CACHE_SIZE", "1M")],
        );
        assert_eq!(loc.size_limit(), Some(1 << 20));
        // A bad size is an error, also for an explicit folder ...
        let e = CacheSetting::Dir("/c".into())
            .resolve_with(env(&[("FERROFMM_CACHE_SIZE", "lots")]))
            .unwrap_err();
        assert!(matches!(e, FieldError::InvalidParams(_)));
        // ... but not read at all when there is no folder.
        let off = CacheSetting::Default
            .resolve_with(env(&[
                ("FERROFMM_CACHE", "off"),
                ("FERROFMM_CACHE_SIZE", "lots"),
            ]))
            .unwrap();
        assert_eq!(off.dir(), None);
    }
}
