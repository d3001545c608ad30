//! The distributed FMM behind the object-safe [`Engine`]: one type for
//! every float type, kernel and scheme, and the agreed check of its
//! values ([`finite_output`]).

use ferrofmm_field::{CacheLocation, CacheStatus, DenseM2l, FftM2l, M2lScheme, SvdConfig, SvdM2l};
use ferrofmm_fmm::FmmError;
use ferrofmm_kernels::{EvalMode, Kernel, Precision, Real, SourceKind};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::error::agree_message;
use crate::{
    DistError, DistFmmOptions, DistributedFmm, DistributedTree, EvalStats, SetupStats,
    sampled_errors_at,
};

use super::{DistPlan, DistRequest, target_counts};

/// A [`DistributedFmm`] with its float type, kernel and scheme erased.
pub(super) trait Engine<C> {
    fn evaluate(
        &self,
        comm: &C,
        tree: &DistributedTree,
        densities: &[f64],
    ) -> Result<(Vec<f64>, EvalStats), DistError>;
    #[allow(clippy::too_many_arguments)]
    fn sampled_errors(
        &self,
        comm: &C,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[f64],
        densities: &[f64],
        targets: &[f64],
        values: &[f64],
        samples: usize,
    ) -> [f64; 2];
    /// The same kernel, float type and scheme for another plan.
    fn with_plan(
        &self,
        comm: &C,
        tree: &DistributedTree,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError>;
    fn setup_stats(&self) -> &SetupStats;
    fn cache_summary(&self) -> Option<String>;
    fn values_per_source(&self) -> usize;
    fn values_per_target(&self) -> usize;
}

/// The configuration of a scheme for an SVD tolerance (`None`: the
/// scheme's default; only the SVD scheme has one).
trait SchemeConfig<T: Real>: M2lScheme<T> {
    fn config(svd_tolerance: Option<f64>) -> Self::Config;
}

impl<T: Real> SchemeConfig<T> for SvdM2l<T> {
    fn config(svd_tolerance: Option<f64>) -> SvdConfig {
        SvdConfig {
            rank: None,
            tolerance: svd_tolerance.unwrap_or(0.0),
        }
    }
}

impl<T: Real> SchemeConfig<T> for DenseM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

impl<T: Real> SchemeConfig<T> for FftM2l<T> {
    fn config(_: Option<f64>) -> Self::Config {
        Default::default()
    }
}

/// The engine for the plan's float type and scheme.
pub(super) fn engine_for<C: Communicator + 'static, K: Kernel>(
    comm: &C,
    tree: &DistributedTree,
    kernel: K,
    plan: &DistPlan,
    request: &DistRequest,
    cache: &CacheLocation,
) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
    fn make<C: Communicator + 'static, T: Real, K: Kernel, S: SchemeConfig<T> + 'static>(
        comm: &C,
        tree: &DistributedTree,
        kernel: K,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
        let options = DistFmmOptions {
            sources: request.sources,
            cache_dir: cache.dir().map(std::path::PathBuf::from),
            cache_size_limit: cache.size_limit(),
            ..DistFmmOptions::new(plan.order, request.mode)
        };
        let config = S::config(plan.svd_tolerance);
        let fmm = DistributedFmm::<T, K, S>::build(comm, tree, kernel, &config, &options)?;
        Ok(Box::new(fmm))
    }
    let make = match (request.precision, plan.scheme) {
        (Precision::F64, "svd") => make::<C, f64, K, SvdM2l<f64>>,
        (Precision::F64, "dense") => make::<C, f64, K, DenseM2l<f64>>,
        (Precision::F64, _) => make::<C, f64, K, FftM2l<f64>>,
        (_, "svd") => make::<C, f32, K, SvdM2l<f32>>,
        (_, "dense") => make::<C, f32, K, DenseM2l<f32>>,
        (_, _) => make::<C, f32, K, FftM2l<f32>>,
    };
    make(comm, tree, kernel, plan, request, cache)
}

impl<C, T, K, S> Engine<C> for DistributedFmm<T, K, S>
where
    C: Communicator + 'static,
    T: Real,
    K: Kernel,
    S: SchemeConfig<T> + 'static,
{
    fn evaluate(
        &self,
        comm: &C,
        tree: &DistributedTree,
        densities: &[f64],
    ) -> Result<(Vec<f64>, EvalStats), DistError> {
        let q: Vec<T> = densities.iter().map(|&x| T::from_f64(x)).collect();
        let (values, stats) = DistributedFmm::evaluate(self, comm, &q)?;
        // Finite inputs can still overflow (densities near the float
        // type's largest value): an error on every rank, naming the first
        // bad value in the global input order.
        finite_output(comm, tree, &values, self.values_per_target(), &q)?;
        Ok((values.iter().map(|v| v.to_f64()).collect(), stats))
    }

    fn sampled_errors(
        &self,
        comm: &C,
        kind: SourceKind,
        mode: EvalMode,
        sources: &[f64],
        densities: &[f64],
        targets: &[f64],
        values: &[f64],
        samples: usize,
    ) -> [f64; 2] {
        sampled_errors_at(
            comm,
            self.local().kernel(),
            kind,
            mode,
            sources,
            densities,
            targets,
            values,
            samples,
        )
    }

    fn with_plan(
        &self,
        comm: &C,
        tree: &DistributedTree,
        plan: &DistPlan,
        request: &DistRequest,
        cache: &CacheLocation,
    ) -> Result<Box<dyn Engine<C> + Send + Sync>, DistError> {
        engine_for(
            comm,
            tree,
            self.local().kernel().clone(),
            plan,
            request,
            cache,
        )
    }

    fn setup_stats(&self) -> &SetupStats {
        DistributedFmm::setup_stats(self)
    }

    fn cache_summary(&self) -> Option<String> {
        CacheStatus::summary(
            self.local().operators().cache_status(),
            &self.local().m2l_scheme().cache_status(),
        )
    }

    fn values_per_source(&self) -> usize {
        DistributedFmm::values_per_source(self)
    }

    fn values_per_target(&self) -> usize {
        DistributedFmm::values_per_target(self)
    }
}

/// [`ferrofmm_fmm::check_finite_output`] on this rank's values (the
/// target index made global: input rows before this rank added; the
/// largest density over all ranks), agreed by every rank (a collective).
fn finite_output<C: Communicator, T: Real>(
    comm: &C,
    tree: &DistributedTree,
    values: &[T],
    per_target: usize,
    densities: &[T],
) -> Result<(), DistError> {
    let local_max = densities
        .iter()
        .map(|q| q.to_f64().abs())
        .fold(0.0, f64::max);
    let mut largest = 0.0f64;
    comm.all_reduce_into(&local_max, &mut largest, SystemOperation::max());
    let me = comm.rank() as usize;
    let first: u64 = target_counts(tree)[..me].iter().sum();
    let local = ferrofmm_fmm::check_finite_output(values, per_target, densities).map_err(|e| {
        match e {
            FmmError::NonFiniteResult {
                target,
                component,
                value,
                precision,
                ..
            } => FmmError::NonFiniteResult {
                target: target + first as usize,
                component,
                value,
                largest_density: largest,
                precision,
            },
            other => other,
        }
        .to_string()
    });
    agree_message(comm, local)
}
