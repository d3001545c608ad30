//! # ferrofmm-testing
//!
//! The fixtures that the tests, benches and examples of every ferrofmm crate
//! share, kept in one place so that each fact (how a seeded point set is
//! drawn, what "relative error" means, how a scratch directory is cleaned
//! up) is written once.
//!
//! The crate depends on no ferrofmm crate, so that each of them can take it
//! as a dev-dependency without a cycle. Everything is in `f64`; tests in
//! another precision convert at the call (`T::from_f64`).
//!
//! * [`rng`]: [`SplitMix64`], a tiny deterministic generator, and
//!   [`seeded`], a seeded `StdRng` for tests that want the `rand` API;
//! * [`points`]: uniform cubes, boxes and cube shells, sphere surfaces,
//!   clustered sets with planes and lines;
//! * [`charges`]: positive and zero-mean charges ([`ChargeSign`]) and
//!   uniform charges in a range;
//! * [`errors`]: relative L2 errors (whole vectors or chosen columns of
//!   interleaved rows), max-norm relative differences, norms;
//! * [`scratch`]: [`TempDir`], a fresh directory removed on drop;
//! * [`operator_cache`]: [`shared_operator_cache`], one operator cache
//!   folder for all the tests of a test binary;
//! * [`files`]: input files in every form the front ends read, and the
//!   shared table of malformed files and their messages.
//!
//! ```
//! use ferrofmm_testing::{ChargeSign, charges, errors, points};
//!
//! let x = points::uniform_cube(100, 0.0, 1.0, 7);
//! let q = charges::with_sign(100, ChargeSign::ZeroMean, 7);
//! assert_eq!(x.len(), 300);
//! assert!(q.iter().sum::<f64>().abs() < 1e-12);
//! assert_eq!(errors::relative_l2(&q, &q), 0.0);
//! ```

pub mod charges;
pub mod errors;
pub mod files;
pub mod operator_cache;
pub mod points;
pub mod rng;
pub mod scratch;

pub use charges::ChargeSign;
pub use operator_cache::shared_operator_cache;
pub use rng::{SplitMix64, seeded};
pub use scratch::TempDir;
