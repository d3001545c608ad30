//! What an M2L precomputation must build ([`M2lUsage`]), how it reports
//! progress and is cancelled ([`PrecomputeMonitor`]), how much memory it
//! may take ([`MemoryLimit`]) and what it is predicted to cost
//! ([`PrecomputeEstimate`]).

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::{FieldError, N_TRANSFER_VECTORS};

/// Which M2L operators a tree needs: for each level `l`, the set `V_l` of
/// transfer vectors (indices into [`transfer_vectors`](crate::transfer_vectors))
/// that occur in the V lists of its boxes.
///
/// A tree with no V list at all (few points, one leaf level) needs no M2L
/// operator; a large uniform tree needs all 316 vectors at most levels
/// `2..=d`. For a homogeneous
/// kernel one operator set serves every level, so only
/// `V = U_l V_l` ([`M2lUsage::union`]) is computed.
///
/// ```
/// use ferrofmm_field::M2lUsage;
/// let mut usage = M2lUsage::none();
/// assert!(usage.is_empty());
/// usage.mark(3, 17);
/// assert!(usage.is_used(3, 17) && !usage.is_used(2, 17));
/// assert_eq!(usage.levels().collect::<Vec<_>>(), vec![3]);
/// assert_eq!(M2lUsage::all(4).n_used(), 3 * 316);
/// ```
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct M2lUsage {
    /// Index = level; each entry empty (unused level) or 316 flags.
    used: Vec<Vec<bool>>,
}

impl M2lUsage {
    /// Nothing used (no V list anywhere).
    pub fn none() -> Self {
        M2lUsage::default()
    }

    /// Every transfer vector at every level `2..=depth`: what
    /// [`M2lScheme::precompute`](crate::M2lScheme::precompute) builds.
    pub fn all(depth: u32) -> Self {
        let mut usage = M2lUsage::none();
        for level in crate::m2l::FIRST_M2L_LEVEL..=depth {
            for v in 0..N_TRANSFER_VECTORS {
                usage.mark(level, v);
            }
        }
        usage
    }

    /// Mark transfer vector `vector` (an index `< 316`) as used at `level`.
    ///
    /// # Panics
    /// When `vector >= 316`.
    pub fn mark(&mut self, level: u32, vector: usize) {
        assert!(
            vector < N_TRANSFER_VECTORS,
            "transfer vector index {vector} out of range"
        );
        let l = level as usize;
        if self.used.len() <= l {
            self.used.resize(l + 1, Vec::new());
        }
        if self.used[l].is_empty() {
            self.used[l] = vec![false; N_TRANSFER_VECTORS];
        }
        self.used[l][vector] = true;
    }

    /// Whether `vector` is used at `level`.
    pub fn is_used(&self, level: u32, vector: usize) -> bool {
        self.used
            .get(level as usize)
            .and_then(|l| l.get(vector))
            .copied()
            .unwrap_or(false)
    }

    /// True when no level uses any transfer vector.
    pub fn is_empty(&self) -> bool {
        self.used.iter().all(|l| !l.contains(&true))
    }

    /// Levels with at least one used transfer vector, in increasing order.
    pub fn levels(&self) -> impl Iterator<Item = u32> + '_ {
        self.used
            .iter()
            .enumerate()
            .filter(|(_, l)| l.contains(&true))
            .map(|(i, _)| i as u32)
    }

    /// Used transfer vectors of `level` (increasing indices).
    pub fn vectors_at(&self, level: u32) -> Vec<usize> {
        match self.used.get(level as usize) {
            Some(l) => (0..l.len()).filter(|&v| l[v]).collect(),
            None => Vec::new(),
        }
    }

    /// Transfer vectors used at any level (increasing indices).
    pub fn union(&self) -> Vec<usize> {
        (0..N_TRANSFER_VECTORS)
            .filter(|&v| self.used.iter().any(|l| l.get(v) == Some(&true)))
            .collect()
    }

    /// Number of `(level, vector)` pairs used.
    pub fn n_used(&self) -> usize {
        self.used
            .iter()
            .map(|l| l.iter().filter(|&&u| u).count())
            .sum()
    }

    /// Deepest level with a used vector (`None` when empty).
    pub fn deepest_level(&self) -> Option<u32> {
        self.levels().last()
    }

    /// Per operator set (homogeneous kernel: one set, the union; otherwise
    /// one per level `first..=depth`), the used vector indices.
    pub(crate) fn per_set(&self, homogeneous: bool, first: u32, depth: u32) -> Vec<Vec<usize>> {
        if homogeneous {
            vec![self.union()]
        } else {
            (first..=depth).map(|l| self.vectors_at(l)).collect()
        }
    }
}

/// A snapshot of a precomputation's progress, given to the callback of a
/// [`PrecomputeMonitor`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PrecomputeProgress {
    /// Work units done (weighted by their cost, see `total`).
    pub done: u64,
    /// Work units in all; `done / total` is the fraction done, so the
    /// remaining time is about `elapsed (total - done) / done`.
    pub total: u64,
}

type ProgressFn = dyn Fn(PrecomputeProgress) + Send + Sync;

/// Observes and controls a long operator precomputation: a progress
/// callback, called from worker threads after each unit of work (one
/// kernel matrix, one block factorisation), and a cancel flag, checked
/// between units (and between the column panels of a factorisation), so
/// that setting it ends the precomputation within a fraction of a second
/// with [`FieldError::Cancelled`].
///
/// Cloning shares the flag and the callback. The default monitor reports
/// nothing and cannot be cancelled.
///
/// ```
/// use std::sync::Arc;
/// use std::sync::atomic::{AtomicBool, Ordering};
/// use ferrofmm_field::{DenseM2l, DenseConfig, FieldError, M2lScheme, M2lUsage, OperatorParams, PrecomputeMonitor};
/// use ferrofmm_kernels::Laplace3d;
/// let cancel = Arc::new(AtomicBool::new(true));
/// let mut params = OperatorParams::new(3);
/// params.monitor = PrecomputeMonitor::new().with_cancel_flag(cancel.clone());
/// let r = DenseM2l::<f64>::precompute_for(&Laplace3d, &params, &DenseConfig, 1.0, 3, &M2lUsage::all(3));
/// assert!(matches!(r, Err(FieldError::Cancelled)));
/// ```
#[derive(Clone, Default)]
pub struct PrecomputeMonitor {
    cancel: Option<Arc<AtomicBool>>,
    progress: Option<Arc<ProgressFn>>,
}

impl PrecomputeMonitor {
    /// No callback, no cancel flag.
    pub fn new() -> Self {
        Self::default()
    }

    /// Cancel when `flag` becomes true (e.g. set by a Ctrl-C handler).
    pub fn with_cancel_flag(mut self, flag: Arc<AtomicBool>) -> Self {
        self.cancel = Some(flag);
        self
    }

    /// Call `f` after each unit of work.
    pub fn with_progress(mut self, f: impl Fn(PrecomputeProgress) + Send + Sync + 'static) -> Self {
        self.progress = Some(Arc::new(f));
        self
    }

    /// Whether cancellation was asked for.
    pub fn is_cancelled(&self) -> bool {
        self.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    }

    /// `Err(FieldError::Cancelled)` once cancellation was asked for.
    pub fn check(&self) -> Result<(), FieldError> {
        if self.is_cancelled() {
            Err(FieldError::Cancelled)
        } else {
            Ok(())
        }
    }

    /// A counter of `total` units reporting to this monitor.
    pub(crate) fn units(&self, total: u64) -> Units<'_> {
        let units = Units {
            monitor: self,
            done: AtomicU64::new(0),
            total,
        };
        units.report(0);
        units
    }
}

impl fmt::Debug for PrecomputeMonitor {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PrecomputeMonitor")
            .field("cancel", &self.cancel)
            .field("progress", &self.progress.as_ref().map(|_| "Fn"))
            .finish()
    }
}

/// Monitors observe a computation and take no part in its result: any two
/// compare equal (so [`OperatorParams`](crate::OperatorParams) compare by
/// what they compute).
impl PartialEq for PrecomputeMonitor {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// Progress counter of one precomputation.
pub(crate) struct Units<'a> {
    monitor: &'a PrecomputeMonitor,
    done: AtomicU64,
    total: u64,
}

impl Units<'_> {
    /// `Err(Cancelled)` when cancelled.
    pub fn check(&self) -> Result<(), FieldError> {
        self.monitor.check()
    }

    /// Whether cancellation was asked for.
    pub fn cancelled(&self) -> bool {
        self.monitor.is_cancelled()
    }

    /// Count `n` more units done, then check for cancellation.
    pub fn add(&self, n: u64) -> Result<(), FieldError> {
        let done = self.done.fetch_add(n, Ordering::Relaxed) + n;
        self.report(done);
        self.check()
    }

    fn report(&self, done: u64) {
        if let Some(f) = &self.monitor.progress {
            f(PrecomputeProgress {
                done: done.min(self.total),
                total: self.total,
            });
        }
    }
}

/// How much memory a precomputation may take.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MemoryLimit {
    /// The environment variable `FERROFMM_MEMORY_LIMIT` when set (bytes,
    /// with an optional `K`, `M`, `G` or `T` suffix in powers of 1024, or
    /// `unlimited`), else the memory this process can still allocate
    /// ([`available_memory`]: `MemAvailable` of `/proc/meminfo`, lowered
    /// by `RLIMIT_AS`; no limit where neither can be read).
    #[default]
    Auto,
    /// At most this many bytes.
    Bytes(u64),
    /// No limit: precompute whatever it costs.
    Unlimited,
}

/// Name of the environment variable read by [`MemoryLimit::Auto`].
pub const MEMORY_LIMIT_ENV: &str = "FERROFMM_MEMORY_LIMIT";

impl MemoryLimit {
    /// The limit in bytes (`None`: unlimited), resolving
    /// [`MemoryLimit::Auto`]. An unparsable environment variable is an
    /// [`FieldError::InvalidParams`].
    pub fn resolve(self) -> Result<Option<u64>, FieldError> {
        match self {
            MemoryLimit::Bytes(b) => Ok(Some(b)),
            MemoryLimit::Unlimited => Ok(None),
            MemoryLimit::Auto => match std::env::var(MEMORY_LIMIT_ENV) {
                Ok(s) => parse_bytes(&s).ok_or_else(|| {
                    FieldError::InvalidParams(format!(
                        "{MEMORY_LIMIT_ENV}={s:?} is not a byte count (e.g. 512M, 8G, unlimited)"
                    ))
                }),
                Err(_) => Ok(available_memory()),
            },
        }
    }
}

/// `"123"`, `"64K"`, `"512M"`, `"8G"`, `"1T"` (powers of 1024, optional
/// trailing `B`/`iB`), or `"unlimited"` (`Some(None)`).
fn parse_bytes(s: &str) -> Option<Option<u64>> {
    let s = s.trim();
    if s.eq_ignore_ascii_case("unlimited") || s.eq_ignore_ascii_case("off") {
        return Some(None);
    }
    let s = s
        .trim_end_matches(['B', 'b'])
        .trim_end_matches(['i', 'I'])
        .trim();
    let (num, mult) = match s.chars().last()? {
        'k' | 'K' => (&s[..s.len() - 1], 1u64 << 10),
        'm' | 'M' => (&s[..s.len() - 1], 1 << 20),
        'g' | 'G' => (&s[..s.len() - 1], 1 << 30),
        't' | 'T' => (&s[..s.len() - 1], 1 << 40),
        _ => (s, 1),
    };
    let x: f64 = num.trim().parse().ok()?;
    (x.is_finite() && x >= 0.0).then_some(Some((x * mult as f64) as u64))
}

/// The memory this process can still allocate, in bytes: `MemAvailable`
/// of `/proc/meminfo`, lowered to what the address-space limit
/// (`RLIMIT_AS`, `ulimit -v`, the soft value in `/proc/self/limits`)
/// leaves above the process's current size (`VmSize` of
/// `/proc/self/status`). `None` where neither is known.
///
/// Under `RLIMIT_AS` an allocation beyond the limit fails (in Rust: an
/// abort, "memory allocation of N bytes failed") however much memory the
/// machine has, so a check against `MemAvailable` alone lets such runs
/// through.
pub fn available_memory() -> Option<u64> {
    let system = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|info| kib_field(&info, "MemAvailable:"));
    let limited = address_space_limit().map(|limit| {
        let used = std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| kib_field(&s, "VmSize:"))
            .unwrap_or(0);
        limit.saturating_sub(used)
    });
    match (system, limited) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// The soft `RLIMIT_AS` in bytes (`None`: unlimited or unknown).
pub fn address_space_limit() -> Option<u64> {
    let limits = std::fs::read_to_string("/proc/self/limits").ok()?;
    parse_address_space_limit(&limits)
}

/// The soft value of the `Max address space` row of `/proc/self/limits`.
fn parse_address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

/// `NAME:  1234 kB` of a `/proc` file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Predicted cost of an M2L precomputation (see
/// [`M2lScheme::estimate`](crate::M2lScheme::estimate)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PrecomputeEstimate {
    /// Kernel matrices `K_v` to assemble.
    pub matrices: usize,
    /// Peak bytes held while precomputing (an upper bound: the stored
    /// operators plus the scratch of every worker thread).
    pub peak_bytes: u64,
    /// Floating-point operations (rough).
    pub flops: f64,
    /// Predicted seconds on `threads` threads (rough: a sustained rate of
    /// a few GFLOP/s per thread).
    pub seconds: f64,
}

/// Sustained precomputation rate per thread assumed by the estimates
/// (flop/s: blocked QR, SVD and kernel assembly on one core).
pub(crate) const FLOPS_PER_THREAD: f64 = 8e9;

/// Worker threads that really run at once: the pool, at most the cores.
pub(crate) fn effective_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get());
    rayon::current_num_threads().clamp(1, cores)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_byte_counts() {
        assert_eq!(parse_bytes("1000"), Some(Some(1000)));
        assert_eq!(parse_bytes("1K"), Some(Some(1024)));
        assert_eq!(parse_bytes("2M"), Some(Some(2 << 20)));
        assert_eq!(parse_bytes("1.5GiB"), Some(Some(3 << 29)));
        assert_eq!(parse_bytes("unlimited"), Some(None));
        assert_eq!(parse_bytes("lots"), None);
        assert_eq!(parse_bytes("-1"), None);
    }

    #[test]
    fn reads_the_address_space_limit() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max stack size            8388608              unlimited            bytes     \n\
                      Max address space         2147483648           unlimited            bytes     \n";
        assert_eq!(parse_address_space_limit(limits), Some(2147483648));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(parse_address_space_limit(unlimited), None);
        assert_eq!(kib_field("VmSize:\t  1024 kB\n", "VmSize:"), Some(1 << 20));
    }

    #[test]
    fn usage_sets() {
        let mut u = M2lUsage::none();
        u.mark(2, 5);
        u.mark(4, 7);
        u.mark(4, 5);
        assert_eq!(u.union(), vec![5, 7]);
        assert_eq!(u.per_set(false, 2, 4), vec![vec![5], vec![], vec![5, 7]]);
        assert_eq!(u.per_set(true, 2, 4), vec![vec![5, 7]]);
        assert_eq!(u.deepest_level(), Some(4));
    }
}
