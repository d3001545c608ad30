//! On-disk operator cache.
//!
//! # File format (version [`CACHE_FORMAT_VERSION`])
//!
//! | bytes | content |
//! |---|---|
//! | 8 | magic `b"FFMMOPS\0"` |
//! | 4 | format version, `u32` little-endian |
//! | 4 | header length `L`, `u32` little-endian |
//! | `L` | header: bincode 2 (standard config) of [`CacheHeader`]: the full [`CacheKey`], the payload's typed layout ([`CachePayload::Layout`], itself bincode-encoded), payload length (elements) and checksum |
//! | rest | payload: the operator values of the working type, raw little-endian (`bytemuck`) |
//!
//! The checksum is XXH64 (seed 0) of the payload bytes. A file is used only
//! when magic, version, key (compared field by field, not by hash), exact
//! file length, checksum and layout all agree; otherwise it is recomputed and
//! rewritten. The layout is a typed description of the stored arrays
//! (named factors, ranks, summaries: [`StoreLayout`]); it must decode, agree
//! with the payload length ([`StoreLayout::n_values`]) and with the
//! parameters of the caller. Files are written to a temporary name in the same directory
//! and renamed into place, so a reader never sees a half-written file.
//! The file name carries a hash of the key, so different parameters live in
//! different files.
//!
//! # Several writers, eviction
//!
//! Every writer has its own temporary name (process id, a per-process
//! random number, a counter), so processes, threads or MPI ranks that fill
//! the same entry at once each write a whole file and the last rename wins:
//! one valid file is left. A reader that opens a file renamed or deleted
//! under it still reads the file it opened (POSIX), and one that finds no
//! file recomputes: never an error, never wrong values.
//!
//! With a size cap ([`OperatorParams::cache_size_limit`](crate::OperatorParams::cache_size_limit)),
//! each write is followed by an eviction: the folder's cache files (our
//! name pattern *and* our magic bytes; nothing else is ever touched) are
//! deleted oldest modification time first until their total is under the
//! cap, never the file just written. A hit refreshes the file's
//! modification time, so the order is least recently used. Temporary files
//! of ours older than a day (a writer killed mid-write) are deleted too.

use std::fs::{self, File};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, SystemTime};

use ferrofmm_kernels::{Kernel, Real};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

use crate::FieldError;

/// Version of the cache file layout; bump on any change of header or
/// payload layout (old files are then rebuilt).
pub const CACHE_FORMAT_VERSION: u32 = 2;

const MAGIC: &[u8; 8] = b"FFMMOPS\0";
const MAX_HEADER: usize = 1 << 20;

/// Everything that determines the contents of a cache file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct CacheKey {
    /// `"operators"`, `"m2l-dense"`, `"m2l-svd"`.
    pub kind: String,
    pub kernel_name: String,
    pub kernel_parameters: Vec<f64>,
    pub kernel_homogeneity: Option<f64>,
    pub order: u64,
    /// `[r_ue, r_uc, r_de, r_dc]`.
    pub radii: [f64; 4],
    /// Resolved pseudo-inverse cutoff (operators only).
    pub rcond: Option<f64>,
    /// Scheme configuration (M2L schemes), an exact textual form.
    pub scheme_config: String,
    /// `"f32"` / `"f64"`.
    pub float_type: String,
    /// `(domain_width, depth)` when the payload depends on them (kernels
    /// without homogeneity), plus anything else structural.
    pub geometry: Option<(f64, u32)>,
    /// Structural flags (e.g. whether child operators are included).
    pub flags: Vec<u64>,
}

impl CacheKey {
    /// Key fields shared by every operator kind.
    pub fn new<K: Kernel, T: Real>(kind: &str, kernel: &K, order: usize, radii: [f64; 4]) -> Self {
        CacheKey {
            kind: kind.to_string(),
            kernel_name: kernel.name(),
            kernel_parameters: kernel.parameters(),
            kernel_homogeneity: kernel.homogeneity(),
            order: order as u64,
            radii,
            rcond: None,
            scheme_config: String::new(),
            float_type: T::PRECISION.name().to_string(),
            geometry: None,
            flags: Vec::new(),
        }
    }

    /// The same key for a domain of width `width` and depth `depth`,
    /// which matter only to a kernel without homogeneity (its operators
    /// are computed per level).
    pub fn for_domain(mut self, width: f64, depth: u32) -> Self {
        if self.kernel_homogeneity.is_none() {
            self.geometry = Some((width, depth));
        }
        self
    }
}

/// The bincode-encoded header.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct CacheHeader {
    pub key: CacheKey,
    /// The payload's [`StoreLayout`], bincode-encoded.
    pub layout: Vec<u8>,
    pub payload_len: u64,
    pub checksum: u64,
}

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

/// The typed description of what a cache file's payload holds: which
/// arrays, of which shapes, in which order (named fields, never positional
/// words). Written in the header, checked against the payload on reading.
pub(crate) trait StoreLayout: Serialize + DeserializeOwned {
    /// Number of values the arrays of this layout hold together; `Err`
    /// when the layout contradicts itself (a rank above the surface size,
    /// say).
    fn n_values(&self) -> Result<usize, String>;

    /// A check for [`load_or_compute`] that a file's layout is exactly
    /// `self` (for layouts fixed by the parameters alone).
    fn accept(self) -> impl Fn(&Self) -> Result<(), String>
    where
        Self: PartialEq + std::fmt::Debug + Sized,
    {
        move |found| {
            if *found == self {
                Ok(())
            } else {
                Err(format!("layout {found:?}, expected {self:?}"))
            }
        }
    }
}

/// Something stored in the cache: a [`StoreLayout`] and the values of its
/// arrays, written one after another in layout order.
pub(crate) trait CachePayload<T: Real>: Sized {
    /// The layout written in the header.
    type Layout: StoreLayout;
    /// The layout of `self`.
    fn layout(&self) -> Self::Layout;
    /// The arrays, in the order the layout lists them.
    fn arrays(&self) -> Vec<&[T]>;
    /// Rebuild from a layout and its values (their number already checked
    /// against [`StoreLayout::n_values`]).
    fn from_values(layout: Self::Layout, values: Vec<T>) -> Result<Self, String>;
}

/// Reads the arrays of a payload back in layout order.
pub(crate) struct ValueReader<T> {
    values: std::vec::IntoIter<T>,
}

impl<T: Real> ValueReader<T> {
    /// A reader over `values`.
    pub fn new(values: Vec<T>) -> Self {
        ValueReader {
            values: values.into_iter(),
        }
    }

    /// The next `len` values.
    pub fn take(&mut self, len: usize) -> Result<Vec<T>, String> {
        let v: Vec<T> = self.values.by_ref().take(len).collect();
        if v.len() == len {
            Ok(v)
        } else {
            Err("payload shorter than its layout".into())
        }
    }

    /// `Err` unless every value was read.
    pub fn finish(self) -> Result<(), String> {
        if self.values.len() == 0 {
            Ok(())
        } else {
            Err("payload longer than its layout".into())
        }
    }
}

/// The payload of a scheme whose values are one flat array (slots indexed
/// by set and transfer vector): a typed layout and the array.
pub(crate) struct FlatStore<L, T> {
    /// What the values are.
    pub layout: L,
    /// The values.
    pub data: Vec<T>,
}

impl<T: Real, L: StoreLayout + Clone> CachePayload<T> for FlatStore<L, T> {
    type Layout = L;

    fn layout(&self) -> L {
        self.layout.clone()
    }

    fn arrays(&self) -> Vec<&[T]> {
        vec![&self.data]
    }

    fn from_values(layout: L, data: Vec<T>) -> Result<Self, String> {
        Ok(FlatStore { layout, data })
    }
}

/// Load `S` from the cache when a valid file exists (and `accept` agrees
/// with its layout), else compute it and (try to) write the file.
///
/// After a successful write, the folder is trimmed to `size_limit` bytes
/// ([`evict`]); a hit refreshes the file's modification time.
pub(crate) fn load_or_compute<T: Real, S: CachePayload<T>>(
    dir: Option<&Path>,
    size_limit: Option<u64>,
    key: &CacheKey,
    accept: impl Fn(&S::Layout) -> Result<(), String>,
    compute: impl FnOnce() -> Result<S, FieldError>,
) -> Result<(S, CacheStatus), FieldError> {
    let Some(dir) = dir else {
        return Ok((compute()?, CacheStatus::Disabled));
    };
    let path = file_path(dir, key);
    let loaded = read::<T>(&path, key).map(|(layout, data)| {
        let layout: S::Layout = decode_layout(&layout)?;
        if layout.n_values()? != data.len() {
            return Err("payload length disagrees with the layout".to_string());
        }
        accept(&layout)?;
        S::from_values(layout, data)
    });
    let rejected = match loaded {
        Ok(Ok(s)) => {
            touch(&path);
            return Ok((s, CacheStatus::Hit { path }));
        }
        Ok(Err(reason)) => Some(format!("inconsistent layout: {reason}")),
        // No file (or no folder yet, or a folder path through a file: the
        // write below says why it cannot be saved).
        Err(FieldError::CacheIo { source, .. })
            if matches!(
                source.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) =>
        {
            None
        }
        Err(e) => Some(e.to_string()),
    };
    let s = compute()?;
    let write_error = bincode::serde::encode_to_vec(s.layout(), bincode::config::standard())
        .map_err(|e| invalid(&path, format!("layout does not encode: {e}")))
        .and_then(|layout| write::<T>(&path, key, &layout, &s.arrays()))
        .err()
        .map(|e| e.to_string());
    if let (None, Some(limit)) = (&write_error, size_limit) {
        evict(dir, limit, &path);
    }
    Ok((
        s,
        CacheStatus::Computed {
            path,
            rejected,
            write_error,
        },
    ))
}

fn decode_layout<L: StoreLayout>(bytes: &[u8]) -> Result<L, String> {
    match bincode::serde::decode_from_slice(bytes, bincode::config::standard()) {
        Ok((layout, used)) if used == bytes.len() => Ok(layout),
        Ok(_) => Err("layout has trailing bytes".into()),
        Err(e) => Err(format!("undecodable layout: {e}")),
    }
}

/// `dir/<kind>_<kernel>_p<order>_<float>_<hash of key>.ffmm`.
pub(crate) fn file_path(dir: &Path, key: &CacheKey) -> PathBuf {
    let encoded =
        bincode::serde::encode_to_vec(key, bincode::config::standard()).expect("key encodes");
    let hash = xxh64(&encoded, 0);
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .take(40)
            .collect()
    };
    dir.join(format!(
        "{}_{}_p{}_{}_{hash:016x}.ffmm",
        clean(&key.kind),
        clean(&key.kernel_name),
        key.order,
        key.float_type
    ))
}

fn invalid(path: &Path, reason: impl Into<String>) -> FieldError {
    FieldError::CacheInvalid {
        path: path.to_path_buf(),
        reason: reason.into(),
    }
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> FieldError + '_ {
    move |source| FieldError::CacheIo {
        path: path.to_path_buf(),
        source,
    }
}

/// Read and fully validate a cache file against `key`: the encoded layout
/// and the values.
pub(crate) fn read<T: Real>(path: &Path, key: &CacheKey) -> Result<(Vec<u8>, Vec<T>), FieldError> {
    let mut file = File::open(path).map_err(io_err(path))?;
    let file_len = file.metadata().map_err(io_err(path))?.len();
    let mut prefix = [0u8; 16];
    file.read_exact(&mut prefix)
        .map_err(|_| invalid(path, "truncated (no complete preamble)"))?;
    if &prefix[0..8] != MAGIC {
        return Err(invalid(path, "not a ferrofmm operator cache (bad magic)"));
    }
    let version = u32::from_le_bytes(prefix[8..12].try_into().expect("4 bytes"));
    if version != CACHE_FORMAT_VERSION {
        return Err(invalid(
            path,
            format!("format version {version}, expected {CACHE_FORMAT_VERSION}"),
        ));
    }
    let header_len = u32::from_le_bytes(prefix[12..16].try_into().expect("4 bytes")) as usize;
    if header_len > MAX_HEADER || 16 + header_len as u64 > file_len {
        return Err(invalid(
            path,
            format!("truncated or bad header length {header_len}"),
        ));
    }
    let mut header_bytes = vec![0u8; header_len];
    file.read_exact(&mut header_bytes)
        .map_err(|_| invalid(path, "truncated header"))?;
    let (header, used): (CacheHeader, usize) =
        bincode::serde::decode_from_slice(&header_bytes, bincode::config::standard())
            .map_err(|e| invalid(path, format!("undecodable header: {e}")))?;
    if used != header_len {
        return Err(invalid(path, "header length mismatch"));
    }
    if header.key != *key {
        return Err(invalid(
            path,
            format!("stale: written for {:?}", header.key),
        ));
    }
    let elem = std::mem::size_of::<T>() as u64;
    let expected = 16 + header_len as u64 + header.payload_len.saturating_mul(elem);
    if file_len != expected {
        return Err(invalid(
            path,
            format!("file has {file_len} bytes, header promises {expected} (truncated or padded)"),
        ));
    }
    let mut data = vec![T::ZERO; header.payload_len as usize];
    file.read_exact(bytemuck::cast_slice_mut(&mut data))
        .map_err(|_| invalid(path, "truncated payload"))?;
    // The bytes on disk are little-endian; hash them as stored.
    let checksum = xxh64(bytemuck::cast_slice(&data), 0);
    if checksum != header.checksum {
        return Err(invalid(
            path,
            format!(
                "checksum {checksum:016x} != {:016x} (corrupt)",
                header.checksum
            ),
        ));
    }
    from_le_in_place(&mut data);
    Ok((header.layout, data))
}

static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Write a cache file atomically (temporary file in the same directory,
/// then rename): the encoded layout and the arrays, one after another.
pub(crate) fn write<T: Real>(
    path: &Path,
    key: &CacheKey,
    layout: &[u8],
    arrays: &[&[T]],
) -> Result<(), FieldError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    // Errors name the file, as every other error of the cache does.
    fs::create_dir_all(dir).map_err(io_err(path))?;
    let joined: Vec<T>;
    let le = match arrays {
        [one] => to_le(one),
        _ => {
            joined = arrays.concat();
            to_le(&joined)
        }
    };
    let bytes: &[u8] = bytemuck::cast_slice(&le);
    let header = CacheHeader {
        key: key.clone(),
        layout: layout.to_vec(),
        payload_len: le.len() as u64,
        checksum: xxh64(bytes, 0),
    };
    let header_bytes = bincode::serde::encode_to_vec(&header, bincode::config::standard())
        .map_err(|e| invalid(path, format!("header does not encode: {e}")))?;
    let file_name = path.file_name().and_then(|s| s.to_str()).unwrap_or("cache");
    let tmp = dir.join(format!(
        ".{file_name}.{}.{:016x}.{}.tmp",
        std::process::id(),
        process_nonce(),
        TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let result = (|| -> std::io::Result<()> {
        let mut f = std::io::BufWriter::new(File::create(&tmp)?);
        f.write_all(MAGIC)?;
        f.write_all(&CACHE_FORMAT_VERSION.to_le_bytes())?;
        f.write_all(&(header_bytes.len() as u32).to_le_bytes())?;
        f.write_all(&header_bytes)?;
        f.write_all(bytes)?;
        let f = f.into_inner().map_err(|e| e.into_error())?;
        f.sync_all()?;
        drop(f);
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(FieldError::CacheIo {
            path: path.to_path_buf(),
            source: e,
        });
    }
    Ok(())
}

/// A random number fixed for the life of the process: with the process id
/// and [`TMP_COUNTER`], temporary names differ between writers even across
/// machines that share a folder (MPI ranks on several nodes).
fn process_nonce() -> u64 {
    use std::hash::{BuildHasher, Hasher};
    static NONCE: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    *NONCE.get_or_init(|| {
        // `RandomState` is seeded from the operating system's randomness.
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u128(
            SystemTime::now()
                .duration_since(SystemTime::UNIX_EPOCH)
                .map_or(0, |d| d.as_nanos()),
        );
        h.finish()
    })
}

/// Mark a cache file as just used (its modification time), so eviction
/// removes it last; silently nothing where the file cannot be written.
fn touch(path: &Path) {
    if let Ok(f) = File::options().write(true).open(path) {
        let _ = f.set_modified(SystemTime::now());
    }
}

/// Temporary files older than this are left over by a killed writer.
const STALE_TMP: Duration = Duration::from_secs(24 * 3600);

/// `<kind>_<kernel>_p<order>_<float>_<16 hex digits>.ffmm`, as
/// [`file_path`] names them.
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

/// The values as little-endian (a borrow on little-endian hosts).
fn to_le<T: Real>(data: &[T]) -> std::borrow::Cow<'_, [T]> {
    if cfg!(target_endian = "little") {
        std::borrow::Cow::Borrowed(data)
    } else {
        let mut v = data.to_vec();
        swap_bytes(&mut v);
        std::borrow::Cow::Owned(v)
    }
}

fn from_le_in_place<T: Real>(data: &mut [T]) {
    if cfg!(target_endian = "big") {
        swap_bytes(data);
    }
}

fn swap_bytes<T: Real>(data: &mut [T]) {
    let size = std::mem::size_of::<T>();
    for chunk in bytemuck::cast_slice_mut::<T, u8>(data).chunks_exact_mut(size) {
        chunk.reverse();
    }
}

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;
const P4: u64 = 0x85EB_CA77_C2B2_AE63;
const P5: u64 = 0x27D4_EB2F_1656_67C5;

#[inline(always)]
fn round(acc: u64, input: u64) -> u64 {
    acc.wrapping_add(input.wrapping_mul(P2))
        .rotate_left(31)
        .wrapping_mul(P1)
}

#[inline(always)]
fn merge(acc: u64, val: u64) -> u64 {
    (acc ^ round(0, val)).wrapping_mul(P1).wrapping_add(P4)
}

#[inline(always)]
fn read_u64(b: &[u8]) -> u64 {
    u64::from_le_bytes(b[..8].try_into().expect("8 bytes"))
}

/// XXH64 of `data` (the reference algorithm of Yann Collet's xxHash).
pub(crate) fn xxh64(data: &[u8], seed: u64) -> u64 {
    let len = data.len() as u64;
    let mut rest = data;
    let mut h = if data.len() >= 32 {
        let mut v = [
            seed.wrapping_add(P1).wrapping_add(P2),
            seed.wrapping_add(P2),
            seed,
            seed.wrapping_sub(P1),
        ];
        let mut stripes = data.chunks_exact(32);
        for s in &mut stripes {
            v[0] = round(v[0], read_u64(&s[0..]));
            v[1] = round(v[1], read_u64(&s[8..]));
            v[2] = round(v[2], read_u64(&s[16..]));
            v[3] = round(v[3], read_u64(&s[24..]));
        }
        rest = stripes.remainder();
        let mut h = v[0]
            .rotate_left(1)
            .wrapping_add(v[1].rotate_left(7))
            .wrapping_add(v[2].rotate_left(12))
            .wrapping_add(v[3].rotate_left(18));
        for x in v {
            h = merge(h, x);
        }
        h
    } else {
        seed.wrapping_add(P5)
    };
    h = h.wrapping_add(len);
    while rest.len() >= 8 {
        h ^= round(0, read_u64(rest));
        h = h.rotate_left(27).wrapping_mul(P1).wrapping_add(P4);
        rest = &rest[8..];
    }
    if rest.len() >= 4 {
        let k = u32::from_le_bytes(rest[..4].try_into().expect("4 bytes")) as u64;
        h ^= k.wrapping_mul(P1);
        h = h.rotate_left(23).wrapping_mul(P2).wrapping_add(P3);
        rest = &rest[4..];
    }
    for &b in rest {
        h ^= (b as u64).wrapping_mul(P5);
        h = h.rotate_left(11).wrapping_mul(P1);
    }
    h ^= h >> 33;
    h = h.wrapping_mul(P2);
    h ^= h >> 29;
    h = h.wrapping_mul(P3);
    h ^= h >> 32;
    h
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn xxh64_reference_vectors() {
        assert_eq!(xxh64(b"", 0), 0xEF46_DB37_51D8_E999);
        assert_eq!(xxh64(b"abc", 0), 0x44BC_2CF5_AD77_0999);
        // Longer than one stripe; any change of a byte changes the hash.
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 % 251) as u8).collect();
        let h = xxh64(&data, 0);
        let mut d2 = data.clone();
        d2[500] ^= 1;
        assert_ne!(h, xxh64(&d2, 0));
    }
}
