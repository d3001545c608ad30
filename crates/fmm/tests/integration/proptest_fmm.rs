//! Stability suite, property test: on random small clustered inputs (1 to
//! 299 points in 1 to 4 clusters of sizes 1e-6 to 1, charges of both signs,
//! targets the sources or a separate random set, leaf sizes 1 to 8 so the
//! tree has several levels) the order-8 FMM agrees with direct summation.
//!
//! The bound: with mixed signs the potential can cancel to anything, so the
//! error is measured against the size of the terms, `||e||_2 <= tol(8) *
//! || sum_i |q_i| K(x_i, y_j) ||_2` (`tol`: stability_common). Exactly
//! coincident pairs contribute nothing on either side.

use crate::stability_common;

use ferrofmm_fmm::FmmBuilder;
use ferrofmm_kernels::Real;
use ferrofmm_testing::TempDir;
use proptest::prelude::*;
use stability_common::{direct, norm2, tol};

const ORDER: usize = 8;

#[derive(Clone, Debug)]
struct Case {
    sources: Vec<f64>,
    charges: Vec<f64>,
    targets: Option<Vec<f64>>,
    leaf_size: usize,
}

/// Points `centre + 10^log_size * offset` for offsets in `[-0.5, 0.5)^3`.
fn place(clusters: &[([f64; 3], f64)], raw: &[(usize, [f64; 3])]) -> Vec<f64> {
    raw.iter()
        .flat_map(|&(c, off)| {
            let (centre, log_size) = clusters[c % clusters.len()];
            let s = 10f64.powf(log_size);
            [0, 1, 2].map(|i| centre[i] + s * off[i])
        })
        .collect()
}

fn clusters() -> impl Strategy<Value = Vec<([f64; 3], f64)>> {
    prop::collection::vec((prop::array::uniform3(0.0f64..1.0), -6.0f64..0.0), 1..=4)
}

fn case() -> impl Strategy<Value = Case> {
    (
        clusters(),
        prop::collection::vec(
            (0usize..4, prop::array::uniform3(-0.5f64..0.5), -1.0f64..1.0),
            1..300,
        ),
        prop::option::of(prop::collection::vec(
            (0usize..4, prop::array::uniform3(-0.5f64..0.5)),
            1..100,
        )),
        1usize..=8,
    )
        .prop_map(|(cl, src, tgt, leaf_size)| {
            let raw: Vec<(usize, [f64; 3])> = src.iter().map(|&(c, o, _)| (c, o)).collect();
            Case {
                sources: place(&cl, &raw),
                charges: src.iter().map(|s| s.2).collect(),
                targets: tgt.map(|t| place(&cl, &t)),
                leaf_size,
            }
        })
}

fn check(case: &Case, cache: &std::path::Path) -> Result<(), TestCaseError> {
    let mut b = FmmBuilder::new(&case.sources)
        .order(ORDER)
        .leaf_size(case.leaf_size)
        .cache_dir(cache);
    if let Some(t) = &case.targets {
        b = b.targets(t);
    }
    let fmm = b.build_dense().unwrap();
    let values = fmm.evaluate(&case.charges).unwrap();
    let targets = case.targets.as_deref().unwrap_or(&case.sources);
    let exact = direct(&case.sources, &case.charges, targets);
    let abs_q: Vec<f64> = case.charges.iter().map(|q| q.abs()).collect();
    let magnitude = norm2(&direct(&case.sources, &abs_q, targets));
    let diff: Vec<f64> = values
        .iter()
        .zip(&exact)
        .map(|(v, e)| v.to_f64() - e)
        .collect();
    let err = norm2(&diff);
    prop_assert!(
        err <= tol::<f64>(ORDER) * magnitude,
        "error {err:.3e} > {:.1e} * {magnitude:.3e} (depth {}, {} sources)",
        tol::<f64>(ORDER),
        fmm.tree().depth(),
        case.charges.len()
    );
    Ok(())
}

#[test]
fn fmm_agrees_with_direct_summation_on_random_clustered_inputs() {
    // Operators are the same for every case: compute them once, then load
    // them from a private cache directory.
    let cache = TempDir::new("proptest");
    let config = ProptestConfig {
        cases: 16,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(c in case())| {
        check(&c, cache.path())?;
    });
}
