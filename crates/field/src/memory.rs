//! How much memory a precomputation may take ([`MemoryLimit`]): a number
//! of bytes, no limit, or (the default) what the environment says, else
//! what the machine can still give this process.
//!
//! Uses the environment variable of [`crate::environment`] and the probe of
//! [`crate::sysmem`].

use crate::FieldError;
use crate::environment::memory_limit_from_env;
use crate::sysmem::available_memory;

/// How much memory a precomputation may take.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MemoryLimit {
    /// The environment variable `FERROFMM_MEMORY_LIMIT` when set (bytes,
    /// with an optional `K`, `M`, `G` or `T` suffix in powers of 1024, or
    /// `unlimited`), else the memory this process can still allocate
    /// ([`available_memory`](crate::available_memory): `MemAvailable` of `/proc/meminfo`, lowered
    /// by `RLIMIT_AS`; no limit where neither can be read).
    #[default]
    Auto,
    /// At most this many bytes.
    Bytes(u64),
    /// No limit: precompute whatever it costs.
    Unlimited,
}

impl MemoryLimit {
    /// The limit in bytes (`None`: unlimited), resolving
    /// [`MemoryLimit::Auto`]. An unparsable environment variable is an
    /// [`FieldError::InvalidParams`].
    pub fn resolve(self) -> Result<Option<u64>, FieldError> {
        match self {
            MemoryLimit::Bytes(b) => Ok(Some(b)),
            MemoryLimit::Unlimited => Ok(None),
            MemoryLimit::Auto => match memory_limit_from_env() {
                Some(limit) => limit,
                None => Ok(available_memory()),
            },
        }
    }
}
