//! Typed errors of the FMM driver.

use ferrofmm_field::FieldError;
use ferrofmm_kernels::KernelError;
use ferrofmm_tree::TreeError;

/// Everything that can go wrong building or evaluating an [`crate::Fmm`].
///
/// Bad user input always ends here, never in a panic.
#[derive(Debug, thiserror::Error)]
pub enum FmmError {
    /// The point set or tree parameters were rejected by the octree.
    #[error("tree: {0}")]
    Tree(#[from] TreeError),
    /// The translation operators could not be built.
    #[error("operators: {0}")]
    Field(#[from] FieldError),
    /// A kernel rejected its inputs or parameters.
    #[error("kernel: {0}")]
    Kernel(#[from] KernelError),
    /// The expansion order is outside the supported range.
    #[error("expansion order {order} is not supported (use {min}..={max})")]
    InvalidOrder {
        /// The order asked for.
        order: usize,
        /// Smallest supported order.
        min: usize,
        /// Largest supported order.
        max: usize,
    },
    /// `leaf_size` must be at least 1.
    #[error("leaf size must be at least 1 (got {0})")]
    InvalidLeafSize(usize),
    /// A coordinate array whose length is not a multiple of 3.
    #[error("{what} has {len} values, which is not a multiple of 3 (interleaved x, y, z)")]
    RaggedPoints {
        /// "sources" or "targets".
        what: &'static str,
        /// Length of the array.
        len: usize,
    },
    /// No points given.
    #[error("{0} are empty")]
    Empty(&'static str),
    /// A NaN or infinite coordinate.
    #[error("{what} coordinate {index} is not finite ({value})")]
    NonFiniteCoordinate {
        /// "sources" or "targets".
        what: &'static str,
        /// Index into the flat coordinate array.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The charge array does not match the number of sources.
    #[error("expected {expected} charges (one per source per vector), got {got}")]
    ChargeCount {
        /// Number of charges expected.
        expected: usize,
        /// Number given.
        got: usize,
    },
    /// The densities of sources with dipoles do not match the number of
    /// sources (see `FmmBuilder::source_kind`).
    #[error(
        "expected {expected} values ({per_source} per source per vector for {kind} sources, interleaved), got {got}"
    )]
    DensityCount {
        /// The source kind's name.
        kind: &'static str,
        /// Values per source: 3 (dipole) or 4 (charge + dipole).
        per_source: usize,
        /// Values expected.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// An oscillatory kernel whose wavenumber times the domain width is
    /// beyond what the (low-frequency) operators resolve.
    #[error(
        "kernel {kernel} with wavenumber k = {wavenumber:e} on a domain of width {width:.3e}: k * width = {kw:.3} exceeds the low-frequency limit {limit} of this FMM (about {wavelengths:.1} wavelengths across the domain); use a domain narrower than {max_width:.3e} or a smaller k", kw = wavenumber * width, wavelengths = limit / (2.0 * std::f64::consts::PI), max_width = limit / wavenumber
    )]
    BeyondLowFrequency {
        /// The kernel's name.
        kernel: String,
        /// Its wavenumber `k`.
        wavenumber: f64,
        /// The width of the tree's domain (a cluster's own cube when the
        /// points form separated clusters).
        width: f64,
        /// [`MAX_WAVENUMBER_WIDTH`](crate::MAX_WAVENUMBER_WIDTH).
        limit: f64,
    },
    /// A NaN or infinite charge (or dipole component).
    #[error("charge {index} is not finite ({value})")]
    NonFiniteCharge {
        /// Index into the flat charge array.
        index: usize,
        /// The offending value.
        value: f64,
    },
    /// The evaluation produced an infinite or NaN value although every
    /// input was finite: the sums overflow the float type (see
    /// [`crate::check_finite_output`]). No result is returned.
    #[error(
        "the result overflowed {precision} (output {component} of target {target} is {value}; \
         largest |density| {largest_density:.3e}): the sums exceed the largest {precision} \
         number; scale the densities down (the result is linear in them){}",
        if *precision == "f32" { " or use f64" } else { "" }
    )]
    NonFiniteResult {
        /// Index of the target (in the caller's order).
        target: usize,
        /// Index of the value within the target's values (0: potential).
        component: usize,
        /// The value found.
        value: f64,
        /// Largest absolute density given.
        largest_density: f64,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
    },
    /// A density given in `f64` beyond the largest value of the run's float
    /// type (see [`crate::check_representable`]).
    #[error(
        "density {index} ({value:.3e}) exceeds the largest {precision} number ({largest:.3e}): \
         use f64 or scale the densities down (the result is linear in them)"
    )]
    DensityBeyondPrecision {
        /// Index into the flat density array.
        index: usize,
        /// The value given.
        value: f64,
        /// The largest value of the float type.
        largest: f64,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
    },
    /// The domain is so small or so large that squared distances between
    /// points and expansion surfaces underflow or overflow the float type
    /// (every pair would count as coincident, or every value as infinite).
    #[error(
        "domain width {width:e} is outside the range {min:e} ..= {max:e} that {precision} \
         resolves at tree depth {depth} (squared distances would underflow or overflow): \
         rescale the coordinates"
    )]
    DomainOutOfRange {
        /// Width of the (computed or given) domain.
        width: f64,
        /// Smallest width accepted at this depth.
        min: f64,
        /// Largest width accepted.
        max: f64,
        /// Depth of the tree.
        depth: u32,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
    },
    /// The check-to-equivalent pseudo-inverses amplify rounding errors of
    /// the float type so much that results would be noise (a pseudo-inverse
    /// cutoff set below what the float type supports; see
    /// docs/stability.md).
    #[error(
        "order {order} with pseudo-inverse cutoff {rcond:e} is ill-conditioned in {precision}: \
         rounding errors would be amplified {amplification:.1e}-fold (limit {limit:.0e}); use the \
         default cutoff (pinv_rcond(None)) or a lower order"
    )]
    IllConditioned {
        /// Expansion order.
        order: usize,
        /// Cutoff used.
        rcond: f64,
        /// `eps_T * condition` of the worst pseudo-inverse.
        amplification: f64,
        /// The largest amplification accepted
        /// ([`ferrofmm_field::AMPLIFICATION_WARNING`]).
        limit: f64,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
    },
    /// A tolerance outside (0, 1) or otherwise unreachable.
    #[error("invalid tolerance {0}: use a value in (0, 1), e.g. 1e-6")]
    InvalidTolerance(f64),
    /// A tolerance the float type (or the measured error model) cannot
    /// promise: ask for a larger one, or use `f64` (see
    /// [`crate::tuning::f32_reaches`]).
    #[error(
        "tolerance {tolerance:e} is beyond what {precision} can promise (smallest: {:.1e}); \
         use a larger tolerance{}",
        up_to_two_digits(*limit),
        if *precision == "f32" { " or f64" } else { "" }
    )]
    ToleranceBeyondPrecision {
        /// The tolerance asked for.
        tolerance: f64,
        /// `"f32"` or `"f64"`.
        precision: &'static str,
        /// The smallest tolerance that precision can promise.
        limit: f64,
    },
    /// A periodic Laplace cell whose charges do not sum to zero (the
    /// lattice sum diverges; see [`crate::periodic`]).
    #[error(
        "the periodic cell is not neutral: its charges sum to {total:e} (sum of |q| \
         {absolute:e}, allowed {limit:e} of it); the Laplace lattice sum needs a neutral cell: \
         add a compensating charge or subtract the mean charge"
    )]
    NotNeutral {
        /// Sum of the charges.
        total: f64,
        /// Sum of their magnitudes.
        absolute: f64,
        /// The allowed share of `absolute`.
        limit: f64,
    },
    /// Any other impossible parameter.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// The M2L precomputation is predicted to need more memory than the
    /// limit (by default the memory available; see
    /// [`ferrofmm_field::MemoryLimit`]). Nothing was computed; force it with
    /// [`crate::FmmBuilder::memory_limit`]`(MemoryLimit::Unlimited)`, the
    /// environment variable `FERROFMM_MEMORY_LIMIT=unlimited`, or `--force`
    /// on the command line.
    #[error(
        "the M2L precomputation at order {order} ({matrices} operators) is predicted to need \
         {} but the limit is {} (the memory available, or FERROFMM_MEMORY_LIMIT; predicted \
         time {seconds:.0} s): lower the order, or force \
         it with --force (FERROFMM_MEMORY_LIMIT=unlimited, or \
         FmmBuilder::memory_limit(MemoryLimit::Unlimited))",
        crate::precompute::human_bytes(estimate_bytes),
        crate::precompute::human_bytes(limit_bytes)
    )]
    PrecomputeMemory {
        /// Predicted peak bytes of the precomputation.
        estimate_bytes: u64,
        /// The limit in bytes (available memory or the configured limit).
        limit_bytes: u64,
        /// Predicted seconds.
        seconds: f64,
        /// Expansion order.
        order: usize,
        /// Kernel matrices the precomputation would assemble.
        matrices: usize,
    },
    /// A run whose buffers (points, densities, results) are predicted to
    /// need more memory than the limit ([`crate::check_memory`]; by
    /// default the memory available, which honours `RLIMIT_AS`). Nothing
    /// was allocated.
    #[error(
        "{what} is predicted to need at least {} but the limit is {} (the memory available, \
         lowered by the address-space limit RLIMIT_AS when set, or FERROFMM_MEMORY_LIMIT): \
         use fewer points or density vectors, or force it with FERROFMM_MEMORY_LIMIT=unlimited",
        crate::precompute::human_bytes(estimate_bytes),
        crate::precompute::human_bytes(limit_bytes)
    )]
    RunMemory {
        /// The run, as the message names it.
        what: String,
        /// Predicted bytes (a lower bound, [`crate::MemoryReport::predict`]).
        estimate_bytes: u64,
        /// The limit in bytes.
        limit_bytes: u64,
    },
}

impl FmmError {
    /// True when the operator precomputation was cancelled through its
    /// [`ferrofmm_field::PrecomputeMonitor`].
    pub fn is_cancelled(&self) -> bool {
        matches!(self, FmmError::Field(FieldError::Cancelled))
    }
}

/// `x > 0` rounded up to two significant digits, so that the limit a
/// message prints can be asked for (`1.04e-5` reads `1.1e-5`, not
/// `1.0e-5`, which is still beyond the limit).
fn up_to_two_digits(x: f64) -> f64 {
    if !(x.is_finite() && x > 0.0) {
        return x;
    }
    let unit = 10f64.powi(x.log10().floor() as i32 - 1);
    (x / unit * (1.0 - 1e-12)).ceil() * unit
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The printed limit is never below the real one, so asking for it
    /// is not refused again.
    #[test]
    fn printed_limit_can_be_asked_for() {
        for (x, printed) in [(1.04e-5, "1.1e-5"), (1.0e-5, "1.0e-5"), (9.99e-8, "1.0e-7")] {
            let e = FmmError::ToleranceBeyondPrecision {
                tolerance: x / 2.0,
                precision: "f32",
                limit: x,
            };
            let text = e.to_string();
            assert!(text.contains(&format!("(smallest: {printed})")), "{text}");
            assert!(text.ends_with("or f64"), "{text}");
            let asked: f64 = printed.parse().unwrap();
            assert!(asked >= x, "{printed} < {x}");
        }
    }
}
