//! One cache file: its name ([`file_path`]), reading with full validation
//! ([`read`]) and writing under a temporary name renamed into place
//! ([`write`](write())); the payload as little-endian values.

use std::fs::{self, File};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::SystemTime;

use ferrofmm_kernels::Real;

use crate::FieldError;

use super::xxh64::xxh64;
use super::{CACHE_FORMAT_VERSION, CacheHeader, CacheKey, MAGIC, MAX_HEADER};

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

pub(super) fn invalid(path: &Path, reason: impl Into<String>) -> FieldError {
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
pub(super) fn touch(path: &Path) {
    if let Ok(f) = File::options().write(true).open(path) {
        let _ = f.set_modified(SystemTime::now());
    }
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
