//! Ask for an accuracy, get the cheapest parameters that reach it.
//!
//! [`FmmBuilder::tolerance`](crate::FmmBuilder::tolerance) takes a target
//! relative L2 error `eps` of the potential (and of the gradient when it is
//! evaluated) and picks the expansion order
//! `p`, the leaf size and the SVD compression tolerance of the M2L operators
//! from `eps`, the float type and the point distribution
//! ([`Tuner::choose`]). Two models make the choice, both measured on this
//! code and both easy to re-measure (`docs/tolerance.md` has the commands
//! and the tables).
//!
//! # The error model ([`ErrorModel`])
//!
//! The relative L2 error of the Laplace FMM depends mostly on the order:
//! over seven geometries (uniform cube, sphere surface, Plummer sphere, two
//! clusters 1000x apart in size, a plane, a trefoil curve, a torus),
//! zero-mean and all-positive charges and leaf sizes 32 to 400, the worst
//! error at an order is within about 10x of the best. So the model is a
//! table of the **worst** error measured at each order with the default
//! SVD tolerance (`E_p` for the potential, `G_p` for the gradient, used as
//! `max(E_p, G_p)` when gradients are evaluated: [`ErrorModel::laplace_for`]),
//! what a looser SVD tolerance `tau` adds, and what rounding adds:
//!
//! ```text
//! predicted(p, tau, R) = sqrt(E_p^2 + e_svd(tau)^2) + floor(R)
//! e_svd(tau)           = 1.2 tau (potential), 3.0 tau (with gradients)
//! floor(R)             = max(F, r u R),  r = 0.1 (potential), 0.3 (with gradients)
//! ```
//!
//! `e_svd` is the upper envelope of the measured extra error of dropping
//! singular values below `tau sigma_0` of the stacked M2L operators, on
//! zero-mean charges (0.5 to 1.1 `tau` for the potential, 1.9 to 2.4 `tau`
//! for the gradient); the two truncations are independent and add in
//! quadrature. `u` is the unit roundoff of the float type, `R` the largest
//! `|center - o| / half-width` of the leaves, `o` the point near the domain
//! the coordinates are made relative to ([`WorkCounts::rounding_ratio`]:
//! surfaces of small boxes far from `o` are off by `u |center - o|`) and
//! `F` the float type's floor on well-centred points (0 in `f64`;
//! [`F32_ERROR_FLOOR`], or [`F32_GRADIENT_FLOOR`] with gradients, in `f32`).
//! An order is admissible for `eps` when `S predicted <= eps` with the
//! safety factor `S` = [`SAFETY_FACTOR`], the room left for sizes and inputs
//! that were not measured; [`crate::verify`] checks the result afterwards.
//! `f32` cannot promise less than about `S F32_ERROR_FLOOR` (see
//! [`f32_reaches`]) and uses orders up to [`MAX_F32_ORDER`]; in `f64` the
//! table ends at order [`MAX_TUNED_ORDER`] (the Helmholtz model goes on to
//! [`MAX_OSCILLATORY_ORDER`], [`HELMHOLTZ_HIGH_ORDER_ERRORS`]).
//!
//! For an admissible order the SVD tolerance is the loosest `tau` that keeps
//! `S predicted <= eps`, never tighter than the measured one and never
//! looser than [`MAX_SVD_TOLERANCE`]: at a loose `eps` the M2L rank, and
//! with it the M2L time, drops several-fold.
//!
//! # The cost model ([`CostModel`], [`WorkCounts`])
//!
//! The leaf size sets the balance between the near field (P2P, growing with
//! the points per leaf) and the far field (M2L and the dense level
//! operators, growing with the number of boxes, the more the higher the
//! order). For uniform points the adaptive tree is a step function of the
//! leaf size (a level splits or it does not; in between, mixed depths pay
//! for W and X lists), for clustered points it varies from box to box, so
//! no fixed "points per leaf" rule fits all inputs. The chooser runs a
//! cheap pre-pass instead ([`Occupancy`]): Morton codes of all points and
//! one sort; then, for candidate leaf sizes from [`LEAF_SIZE_CANDIDATES`],
//! a simulation of the adaptive refinement and the 2:1 balance on the
//! sorted codes, from which it counts the work ([`WorkCounts`]: P2P pairs,
//! U-, V-, W- and X-list work, boxes). The simulation is the tree crate's
//! own refinement and balance ([`ferrofmm_tree::MortonCodes`],
//! [`ferrofmm_tree::TreeShape`]), so the boxes and leaves are exactly those
//! of the tree that will be built; the list work is counted from child
//! masks without the lists' pruning, within a few percent.
//! [`CostModel`] turns work into seconds with one coefficient per kind of
//! work, fitted by [`CostModel::fit`] on measured runs (the example
//! `tolerance_grid -- fit` prints a new set when the operators get faster).
//! The chooser predicts the time of the tree plus one evaluation for the
//! three smallest admissible orders and the candidate leaf sizes, and takes
//! the cheapest ([`Tuner::candidates`] describes the search and what bounds
//! its cost). Precomputing operators is not counted (it does not depend on
//! the points and is cached on disk with
//! [`FmmBuilder::cache_dir`](crate::FmmBuilder::cache_dir) or
//! [`FmmBuilder::default_cache`](crate::FmmBuilder::default_cache)), but a higher
//! order must be predicted at least [`HIGHER_ORDER_GAIN`] cheaper to be
//! taken, since it costs more to precompute and to store.
//!
//! # Models per kernel and scheme ([`TuningModel`])
//!
//! Both models come from a [`TuningModel`], asked for the float type, the
//! evaluation mode and the M2L scheme's cost shape
//! ([`M2lScheme::COST_SHAPE`](ferrofmm_field::M2lScheme::COST_SHAPE)):
//! [`default_model`] gives [`LaplaceModel`] for the Laplace kernel,
//! [`YukawaModel`] for modified Helmholtz (Laplace's error tables, which
//! bound it where measured, `k W <=` [`YUKAWA_MEASURED_K`]; a P2P cost
//! [`YUKAWA_P2P_FACTOR`] times Laplace's) and, for any other kernel, the
//! Laplace model as a [`BorrowedModel`] (reported with
//! [`ChosenParameters::model_measured`] `false`). A kernel's author supplies
//! a model of their own with
//! [`FmmBuilder::tuning_model`](crate::FmmBuilder::tuning_model).
//!
//! # Scope of the promise
//!
//! The error tables were measured for the Laplace kernel (potential and
//! gradient) with the [`SvdM2l`](ferrofmm_field::SvdM2l) and
//! [`DenseM2l`](ferrofmm_field::DenseM2l) schemes; the FFT scheme applies
//! the same operators without truncation. A borrowed model makes the same
//! choice without a measurement behind it; the verification of
//! [`crate::verify`] measures whatever the kernel.

pub use ferrofmm_field::M2lCostShape;

// One job per module: `error_model` (errors per order, SVD and rounding
// terms, limits), `work` (work counts of a built tree), `occupancy` (the
// simulated tree for any leaf size), `cost` (seconds from work, and the
// fit), `model` (the models per kernel and scheme), `chooser` (the
// cheapest admissible parameters). Each imports what it uses from the
// others by name.
mod calibration;
mod chooser;
mod cost;
mod error_model;
mod model;
mod occupancy;
mod precompute_cost;
mod root;
mod scene;
mod work;

pub use crate::validate::validate_tolerance;
pub use calibration::{
    CALIBRATION_FILE, CALIBRATION_POINTS, CALIBRATION_REPEATS, CalibrationRun, CalibrationSetting,
    GroupScales, MachineCalibration, this_processor,
};
pub use chooser::{
    Candidate, ChosenParameters, Tuner, choose_parameters, choose_precision, choose_scheme,
    choose_scheme_for, svd_precompute_seconds,
};
pub use cost::{CostModel, CostPrediction, CostSample, GRADIENT_COST_FACTOR, HESSIAN_COST_FACTOR};
pub use error_model::{
    CHOICE_BUDGET, CURVE_DIMENSION, ErrorModel, F32_ERROR_FLOOR, F32_GRADIENT_FLOOR,
    HESSIAN_ERROR_FACTOR, HIGHER_ORDER_GAIN, LEAF_SIZE_CANDIDATES, MAX_F32_ORDER,
    MAX_OSCILLATORY_ORDER, MAX_SVD_TOLERANCE, MAX_TUNED_ORDER, MIN_CHOICE_SECONDS, MIN_TUNED_ORDER,
    ROUNDING_FACTOR, SAFETY_FACTOR, SCENE_POTENTIAL_GROWTH, SCENE_REFERENCE_POINTS,
    SCENE_SAFETY_FACTOR, SECONDS_PER_SIMULATED_BOX, SURFACE_DIMENSIONS, VOLUME_DIMENSION,
    estimated_svd_rank, f32_reaches, smallest_tolerance,
};
pub use model::{
    BorrowedModel, HELMHOLTZ_HIGH_ORDER_ERRORS, HELMHOLTZ_P2P_FACTOR, HelmholtzModel, LaplaceModel,
    STOKES_ERROR_FACTOR, STOKES_GRADIENT_P2P_FACTOR, STOKES_P2P_FACTOR, StokesModel, TuningModel,
    YUKAWA_GRADIENT_P2P_FACTOR, YUKAWA_MEASURED_K, YUKAWA_P2P_FACTOR, YukawaModel, default_model,
    helmholtz_error_factor,
};
pub use occupancy::Occupancy;
pub use precompute_cost::{
    DENSE_SET_SECONDS, FFT_SET_SECONDS, OPERATOR_ENTRY_SECONDS, OPERATOR_SET_SECONDS,
    SVD_ESTIMATE_SHARE, precompute_seconds,
};
pub use root::{
    ROOT_SCALES, ROOT_SEARCH_MIN_POINTS, ROOT_TIME_SLACK, RootChoice, box_budget, box_bytes,
    choose_root, choose_root_reporting,
};
pub use scene::{SCENE_LEAF_SIZE, Scene};
pub use work::WorkCounts;
