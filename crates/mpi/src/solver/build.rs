//! Planning and building a [`DistSolver`] for the kernel the request
//! names: the kernel's check, the memory check, the plan (order, leaf
//! size, scheme) and the distributed tree.

use ferrofmm_field::CacheLocation;
use ferrofmm_fmm::tuning::MachineCalibration;
use ferrofmm_fmm::{DEFAULT_LEAF_SIZE, DEFAULT_ORDER, SchemeChoice, effective_tolerance};
use ferrofmm_kernels::{EvalMode, Kernel, KernelVisitor, Precision, SourceKind};
use mpi::traits::*;

use crate::{DistError, DistOptions, DistributedTree, choose_parameters};

use super::engine::engine_for;
use super::{DistPlan, DistRequest, DistSolver};

/// Whether a kernel takes a source kind in a mode.
pub(super) struct Supports(pub(super) SourceKind, pub(super) EvalMode);

impl KernelVisitor for Supports {
    type Output = bool;
    fn visit<K: Kernel>(self, kernel: K) -> bool {
        kernel.supports(self.0, self.1)
    }
}

/// Plan and build for the kernel the request names.
pub(super) struct Build<'a, C> {
    pub(super) comm: &'a C,
    pub(super) points: Vec<f64>,
    pub(super) targets: Option<Vec<f64>>,
    pub(super) request: DistRequest,
    pub(super) cache: CacheLocation,
}

impl<C: Communicator + 'static> KernelVisitor for Build<'_, C> {
    type Output = Result<DistSolver<C>, DistError>;

    fn visit<K: Kernel>(self, kernel: K) -> Self::Output {
        let Build {
            comm,
            points,
            targets,
            request,
            cache,
        } = self;
        // Refused on every rank before the tree is built when some rank's
        // points, densities and results are predicted not to fit.
        let size = ferrofmm_fmm::RunSize {
            n_sources: points.len() / 3,
            n_targets: targets.as_ref().map(|t| t.len() / 3),
            values_per_source: kernel.values_per_source(request.sources),
            values_per_target: kernel.values_per_target(request.mode),
            n_vectors: 1,
        };
        let what = "the distributed run";
        match request.precision {
            Precision::F64 => crate::check_rank_memory::<C, f64>(comm, &size, what)?,
            Precision::F32 => crate::check_rank_memory::<C, f32>(comm, &size, what)?,
        }
        let plan = plan(comm, &points, &kernel, &request, &cache)?;
        let options = DistOptions::adaptive(plan.leaf_size);
        let tree = match &targets {
            None => DistributedTree::build(comm, &points, &options)?,
            Some(t) => DistributedTree::build_with_targets(comm, &points, t, &options)?,
        };
        let engine = engine_for(comm, &tree, kernel, &plan, &request, &cache)?;
        Ok(DistSolver {
            request,
            plan,
            tree,
            points,
            targets,
            engine,
            cache,
            attempts: Vec::new(),
            verified: false,
        })
    }
}

/// The one default rule: no order and no tolerance means the default
/// tolerance; an order alone gets its leaf size and scheme from the cost
/// model; an order and a leaf size are used as given. The cost model is
/// calibrated where the cache folder holds a calibration of this processor
/// at this rank's thread count (read on rank 0, where the chooser runs).
fn plan<C: Communicator, K: Kernel>(
    comm: &C,
    points: &[f64],
    kernel: &K,
    request: &DistRequest,
    cache: &CacheLocation,
) -> Result<DistPlan, DistError> {
    let eps = effective_tolerance(
        request.tolerance,
        request.order.or(request.leaf_size.map(|_| DEFAULT_ORDER)),
        request.precision,
    );
    Ok(match (eps, request.order, request.leaf_size) {
        (None, Some(_), Some(_)) | (None, None, _) => DistPlan {
            order: request.order.unwrap_or(DEFAULT_ORDER),
            leaf_size: request.leaf_size.unwrap_or(DEFAULT_LEAF_SIZE),
            scheme: match request.scheme {
                SchemeChoice::Auto if SchemeChoice::auto_is_fft(kernel) => "fft",
                SchemeChoice::Auto => "svd",
                s => s.name(),
            },
            svd_tolerance: None,
            choice: None,
            tolerance: None,
        },
        (eps, order, _) => {
            let calibration = cache
                .dir()
                .filter(|_| comm.rank() == 0)
                .and_then(|dir| MachineCalibration::load(dir, rayon::current_num_threads()));
            let choice = choose_parameters(
                comm,
                points,
                kernel,
                eps,
                order,
                request.precision,
                request.mode,
                request.scheme.shape(),
                cache.dir().is_some(),
                calibration.as_ref(),
            )?;
            DistPlan {
                order: choice.order,
                leaf_size: choice.leaf_size,
                scheme: SchemeChoice::of_shape(choice.shape).name(),
                svd_tolerance: Some(choice.svd_tolerance),
                choice: Some(choice),
                tolerance: eps,
            }
        }
    })
}
