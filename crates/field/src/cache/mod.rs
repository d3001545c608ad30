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

use std::path::Path;

use ferrofmm_kernels::{Kernel, Real};
use serde::{Deserialize, Serialize};

use crate::FieldError;

mod evict;
mod file;
mod payload;
mod status;
mod values;
mod xxh64;

pub(crate) use payload::{CachePayload, FlatStore, StoreLayout, ValueReader};
pub use status::CacheStatus;
pub use values::cached_values;

use evict::evict;
use file::{file_path, invalid, read, touch, write};

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

/// Load `S` from the cache when a valid file exists (and `accept` agrees
/// with its layout), else compute it and (try to) write the file.
///
/// After a successful write, the folder is trimmed to `size_limit` bytes
/// ([`evict`](evict::evict)); a hit refreshes the file's modification time.
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
