//! [`OperatorParams`]: order, surface radii, pseudo-inverse cutoff, cache.

use std::path::PathBuf;

use ferrofmm_kernels::Precision;

use crate::{FieldError, MemoryLimit, PrecomputeMonitor, SurfaceRadii};

/// Lowest accepted expansion order (a surface of `6 (p - 1)^2 + 2 = 8`
/// points, the cube's corners).
pub const MIN_ORDER: usize = 2;

/// Highest accepted expansion order, here and in the FMM driver (which
/// re-exports it). Beyond it the f64 check-to-equivalent inversion has no
/// digits left to gain (the error stops falling at `p ~ 16`, see
/// docs/stability.md), while one expansion holds `6 (p - 1)^2 + 2` values
/// (2168 at `p = 20`) and a dense M2L set `316` squares of that.
pub const MAX_ORDER: usize = 20;

/// Default relative cutoff of the check-to-equivalent pseudo-inverse for a
/// float type: singular values `sigma_i <= rcond * sigma_0` are dropped.
///
/// Chosen by the stability measurements in `docs/stability.md`:
/// `1e-15` for `f64` (the error of P2M->M2L->L2P keeps falling up to
/// `p = 12` and stays flat beyond) and `1e-7` for `f32` (a tighter cutoff
/// lets `f32` rounding of the check potential, amplified by up to
/// `1 / rcond`, dominate; a looser one truncates the expansion).
///
/// ```
/// use ferrofmm_field::default_pinv_rcond;
/// use ferrofmm_kernels::Precision;
/// assert!(default_pinv_rcond(Precision::F32) > default_pinv_rcond(Precision::F64));
/// ```
pub fn default_pinv_rcond(precision: Precision) -> f64 {
    match precision {
        Precision::F64 => 1e-13,
        Precision::F32 => 1e-7,
    }
}

/// Parameters shared by all translation operators of one FMM.
///
/// ```
/// use ferrofmm_field::OperatorParams;
/// let mut params = OperatorParams::new(6);
/// params.pinv_rcond = Some(1e-12);
/// params.validate().unwrap();
/// assert!(OperatorParams::new(1).validate().is_err());
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct OperatorParams {
    /// Expansion order `p >= 2`: `6 (p-1)^2 + 2` equivalent points per box.
    pub order: usize,
    /// Surface radii as multiples of the box half-width.
    pub radii: SurfaceRadii,
    /// Relative cutoff of the check-to-equivalent pseudo-inverse
    /// (`sigma_i <= rcond * sigma_0` dropped). `None`: the per-type default
    /// [`default_pinv_rcond`]; `Some(0.0)`: no cutoff (only exactly zero
    /// singular values are dropped; see `docs/stability.md` for why this is
    /// a bad idea at high order).
    pub pinv_rcond: Option<f64>,
    /// Directory of the on-disk operator cache; `None` disables the cache.
    /// The directory is created when missing. [`CacheSetting::resolve`](crate::CacheSetting::resolve)
    /// finds the default one.
    pub cache_dir: Option<PathBuf>,
    /// Most bytes of cache files kept in [`OperatorParams::cache_dir`]:
    /// after writing a file, the least recently used others are deleted
    /// until the folder is under it (`None`: no cap).
    pub cache_size_limit: Option<u64>,
    /// Progress callback and cancel flag of the precomputation (observes
    /// it, takes no part in the result; the default reports nothing).
    pub monitor: PrecomputeMonitor,
    /// Memory the precomputation may take, checked by the FMM driver
    /// against [`M2lScheme::estimate`](crate::M2lScheme::estimate) before
    /// it starts (default: [`MemoryLimit::Auto`]).
    pub memory_limit: MemoryLimit,
}

impl OperatorParams {
    /// Order `order`, default radii, default cutoff, no cache.
    pub fn new(order: usize) -> Self {
        OperatorParams {
            order,
            radii: SurfaceRadii::default(),
            pinv_rcond: None,
            cache_dir: None,
            cache_size_limit: None,
            monitor: PrecomputeMonitor::default(),
            memory_limit: MemoryLimit::default(),
        }
    }

    /// The cutoff used for `kernel` in float type `precision`: the one set,
    /// else the larger of the precision's default and the kernel's
    /// [`Kernel::pinv_rcond_floor`](ferrofmm_kernels::Kernel::pinv_rcond_floor)
    /// at this order.
    pub fn rcond_for_kernel<K: ferrofmm_kernels::Kernel>(
        &self,
        kernel: &K,
        precision: Precision,
    ) -> f64 {
        self.pinv_rcond.unwrap_or_else(|| {
            default_pinv_rcond(precision).max(kernel.pinv_rcond_floor(self.order).unwrap_or(0.0))
        })
    }

    /// The cutoff actually used for float type `precision`.
    pub fn rcond_for(&self, precision: Precision) -> f64 {
        self.pinv_rcond
            .unwrap_or_else(|| default_pinv_rcond(precision))
    }

    /// Number of points per surface, `6 (p-1)^2 + 2` (requires a valid order).
    pub fn n_surface(&self) -> usize {
        crate::n_surface_points(self.order)
    }

    /// Check the parameters:
    /// * `MIN_ORDER <= order <= MAX_ORDER`;
    /// * all radii finite, `1 < r_ue < r_uc <= 3`, `1 <= r_dc < r_de <= 3`
    ///   (equivalent surfaces enclose the box, check surfaces lie between
    ///   the equivalent surface and the far field three half-widths out);
    /// * `r_ue + r_dc < 4` and `r_ue + r_de <= 4`: for the closest V-list
    ///   pair (centers two box widths = four half-widths apart) the source's
    ///   equivalent surface neither meets the target's check surface nor
    ///   enters its downward equivalent surface;
    /// * `pinv_rcond`, if given, finite and in `[0, 1)`.
    pub fn validate(&self) -> Result<(), FieldError> {
        let bad = |m: String| Err(FieldError::InvalidParams(m));
        let order = self.order;
        if !(MIN_ORDER..=MAX_ORDER).contains(&order) {
            let (bound, limit) = if order < MIN_ORDER {
                ("at least", MIN_ORDER)
            } else {
                ("at most", MAX_ORDER)
            };
            return bad(format!("order must be {bound} {limit}, got {order}"));
        }
        let r = &self.radii;
        if !r.to_array().iter().all(|x| x.is_finite()) {
            return bad(format!("surface radii must be finite: {r:?}"));
        }
        if r.upward_equivalent <= 1.0 {
            return bad(format!(
                "upward equivalent radius must exceed 1 (enclose the box), got {}",
                r.upward_equivalent
            ));
        }
        // Two radii `inner < outer <= 3`, named in the message.
        let nested = |(a, inner): (&str, f64), (b, outer): (&str, f64)| {
            if inner < outer && outer <= 3.0 {
                Ok(())
            } else {
                bad(format!("need {a} < {b} <= 3, got {inner} / {outer}"))
            }
        };
        nested(
            ("upward equivalent", r.upward_equivalent),
            ("upward check", r.upward_check),
        )?;
        if r.downward_check < 1.0 {
            return bad(format!(
                "downward check radius must be at least 1 (enclose the box), got {}",
                r.downward_check
            ));
        }
        nested(
            ("downward check", r.downward_check),
            ("downward equivalent", r.downward_equivalent),
        )?;
        if r.upward_equivalent + r.downward_check >= 4.0 {
            return bad(format!(
                "upward equivalent + downward check radii must be < 4 (surfaces of the closest \
                 M2L pair would touch), got {} + {}",
                r.upward_equivalent, r.downward_check
            ));
        }
        if r.upward_equivalent + r.downward_equivalent > 4.0 + 1e-12 {
            return bad(format!(
                "upward equivalent + downward equivalent radii must be <= 4, got {} + {}",
                r.upward_equivalent, r.downward_equivalent
            ));
        }
        if let Some(c) = self.pinv_rcond
            && !(c.is_finite() && (0.0..1.0).contains(&c))
        {
            return bad(format!("pinv_rcond must be finite and in [0, 1), got {c}"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn validation() {
        assert!(OperatorParams::new(MIN_ORDER).validate().is_ok());
        assert!(OperatorParams::new(MAX_ORDER).validate().is_ok());
        for p in [0, MIN_ORDER - 1, MAX_ORDER + 1, 1000] {
            assert!(OperatorParams::new(p).validate().is_err(), "order {p}");
        }
        let mut q = OperatorParams::new(4);
        q.radii.upward_check = 1.0;
        assert!(q.validate().is_err());
        let mut q = OperatorParams::new(4);
        q.radii.downward_equivalent = f64::NAN;
        assert!(q.validate().is_err());
        let mut q = OperatorParams::new(4);
        q.radii.upward_equivalent = 0.9;
        assert!(q.validate().is_err());
        let mut q = OperatorParams::new(4);
        q.radii.downward_check = 3.0;
        assert!(q.validate().is_err());
        let mut q = OperatorParams::new(4);
        q.pinv_rcond = Some(-1.0);
        assert!(q.validate().is_err());
        q.pinv_rcond = Some(0.0);
        assert!(q.validate().is_ok());
        let mut q = OperatorParams::new(4);
        q.radii = SurfaceRadii {
            upward_equivalent: 1.5,
            upward_check: 2.5,
            downward_equivalent: 2.9,
            downward_check: 1.1,
        };
        assert!(q.validate().is_err()); // 1.5 + 2.9 > 4
    }
}
