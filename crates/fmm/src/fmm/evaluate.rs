//! Evaluating a built [`Fmm`]: one or many charge vectors, timed, checked;
//! the energy of a charge vector.

use std::sync::Arc;

use ferrofmm_field::M2lScheme;
use ferrofmm_kernels::{Kernel, Real, SourceKind};

use crate::progress::ProgressFn;
use crate::timings::EvalTimings;
use crate::{FmmError, passes};

use super::Fmm;

impl<T: Real, K: Kernel, S: M2lScheme<T>> Fmm<T, K, S> {
    /// Potentials (and gradients and Hessians, depending on the mode) at
    /// the targets for one charge per source (or the densities of the
    /// [source kind](crate::FmmBuilder::source_kind): `[nx, ny, nz]` or
    /// `[q, nx, ny, nz]` per source), in the caller's original target
    /// order: `values_per_target` values per target (`[phi]`,
    /// `[phi, gx, gy, gz]`, or those and `[H11, H22, H33, H12, H13, H23]`).
    ///
    /// `phi(y) = sum_i q_i K(x_i, y) + n_i . grad_x K(x_i, y)` with
    /// coincident pairs excluded.
    pub fn evaluate(&self, charges: &[T]) -> Result<Vec<T>, FmmError> {
        self.evaluate_timed(charges).map(|(v, _)| v)
    }

    /// Tell `f` the progress of every later evaluation (from worker
    /// threads, at most about a thousand times an evaluation; the work is
    /// weighted by a rough cost estimate of each pass), or stop telling
    /// with `None`. Costs nothing measurable and changes no result.
    pub fn set_progress(&mut self, f: Option<Arc<ProgressFn>>) {
        self.progress = f;
    }

    /// As [`Fmm::evaluate`], and the time spent in each operator.
    pub fn evaluate_timed(&self, charges: &[T]) -> Result<(Vec<T>, EvalTimings), FmmError> {
        self.check_charges(charges, 1)?;
        let (values, timings) = passes::evaluate(self, charges);
        let per_target = self.kernel.values_per_target(self.mode);
        crate::check_finite_output(&values, per_target, charges)?;
        Ok((values, timings))
    }

    /// Evaluate `n_vectors` charge vectors stored one after another in
    /// `charges` (length `n_vectors * n_sources`); results are stored the
    /// same way (vector-major). Nothing is rebuilt between vectors.
    pub fn evaluate_many(&self, charges: &[T], n_vectors: usize) -> Result<Vec<T>, FmmError> {
        self.check_charges(charges, n_vectors)?;
        let mut out = Vec::with_capacity(
            n_vectors * self.n_targets * self.kernel.values_per_target(self.mode),
        );
        for q in
            charges.chunks_exact(self.n_sources * self.kernel.values_per_source(self.source_kind))
        {
            let values = passes::evaluate(self, q).0;
            crate::check_finite_output(&values, self.kernel.values_per_target(self.mode), q)?;
            out.extend(values);
        }
        Ok(out)
    }

    fn check_charges(&self, charges: &[T], n_vectors: usize) -> Result<(), FmmError> {
        let per_source = self.kernel.values_per_source(self.source_kind);
        let expected = n_vectors * self.n_sources * per_source;
        if charges.len() != expected || n_vectors == 0 {
            if self.source_kind == SourceKind::Charge && per_source == 1 {
                return Err(FmmError::ChargeCount {
                    expected,
                    got: charges.len(),
                });
            }
            return Err(FmmError::DensityCount {
                kind: self.source_kind.name(),
                per_source,
                expected,
                got: charges.len(),
            });
        }
        if let Some(index) = charges.iter().position(|q| !q.is_finite()) {
            return Err(FmmError::NonFiniteCharge {
                index,
                value: charges[index].to_f64(),
            });
        }
        if self.periodic.as_ref().is_some_and(|f| f.needs_neutral()) {
            for q in charges.chunks(self.n_sources * per_source) {
                crate::periodic::check_neutral(q)?;
            }
        }
        Ok(())
    }

    /// The periodic cell of a periodic run ([`FmmBuilder::periodic`](crate::FmmBuilder::periodic)).
    pub fn periodic(&self) -> Option<&crate::periodic::Periodic> {
        self.periodic.as_ref().map(|f| &f.cell)
    }

    /// The energy `E = 1/2 sum_i q_i phi_i` of charges `charges` whose
    /// potentials (one vector, `values` as [`Fmm::evaluate`] returned them)
    /// are `phi`: the electrostatic energy of the set (the kernel's own
    /// constant included, `1 / (4 pi r)` for Laplace; in a periodic cell,
    /// per cell).
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when the targets are not the
    /// sources, the sources are not charges or the kernel has more than
    /// one component; [`FmmError::ChargeCount`] for lengths that do not
    /// match.
    pub fn energy(&self, charges: &[T], values: &[T]) -> Result<f64, FmmError> {
        if self.separate_targets
            || self.source_kind != SourceKind::Charge
            || self.kernel.components() != 1
        {
            return Err(FmmError::InvalidParameter(
                "an energy needs charges of a scalar kernel evaluated at the sources themselves"
                    .to_string(),
            ));
        }
        let w = self.kernel.values_per_target(self.mode);
        if charges.len() != self.n_sources || values.len() != w * self.n_sources {
            return Err(FmmError::ChargeCount {
                expected: self.n_sources,
                got: charges.len(),
            });
        }
        Ok(0.5
            * charges
                .iter()
                .zip(values.chunks_exact(w))
                .map(|(q, v)| q.to_f64() * v[0].to_f64())
                .sum::<f64>())
    }
}
