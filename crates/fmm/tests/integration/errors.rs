//! Bad input gives a typed error, never a panic.

use ferrofmm_fmm::{FmmBuilder, FmmError};

fn points(n: usize) -> Vec<f64> {
    ferrofmm_testing::points::uniform_cube(n, 0.0, 1.0, 1)
}

#[test]
fn rejects_bad_points_and_parameters() {
    let p = points(100);
    let mut nan = p.clone();
    nan[17] = f64::NAN;
    let mut inf = p.clone();
    inf[3] = f64::INFINITY;
    assert!(matches!(
        FmmBuilder::new(&nan).build_svd(),
        Err(FmmError::NonFiniteCoordinate { index: 17, .. })
    ));
    assert!(matches!(
        FmmBuilder::new(&inf).build_svd(),
        Err(FmmError::NonFiniteCoordinate { index: 3, .. })
    ));
    assert!(matches!(
        FmmBuilder::new(&p[..10]).build_svd(),
        Err(FmmError::RaggedPoints { .. })
    ));
    let empty: Vec<f64> = Vec::new();
    assert!(matches!(
        FmmBuilder::new(&empty).build_svd(),
        Err(FmmError::Empty(_))
    ));
    assert!(matches!(
        FmmBuilder::new(&p).targets(&empty).build_svd(),
        Err(FmmError::Empty(_))
    ));
    assert!(matches!(
        FmmBuilder::new(&p).order(0).build_svd(),
        Err(FmmError::InvalidOrder { .. })
    ));
    assert!(matches!(
        FmmBuilder::new(&p).order(1).build_svd(),
        Err(FmmError::InvalidOrder { .. })
    ));
    assert!(matches!(
        FmmBuilder::new(&p).leaf_size(0).build_svd(),
        Err(FmmError::InvalidLeafSize(0))
    ));
    assert!(matches!(
        FmmBuilder::new(&p).max_level(99).build_svd(),
        Err(FmmError::InvalidParameter(_))
    ));
}

#[test]
fn rejects_bad_charges() {
    let p = points(100);
    let fmm = FmmBuilder::new(&p)
        .order(3)
        .leaf_size(16)
        .build_svd()
        .unwrap();
    assert!(matches!(
        fmm.evaluate(&[1.0; 99]),
        Err(FmmError::ChargeCount {
            expected: 100,
            got: 99
        })
    ));
    let mut q = vec![1.0; 100];
    q[42] = f64::NAN;
    assert!(matches!(
        fmm.evaluate(&q),
        Err(FmmError::NonFiniteCharge { index: 42, .. })
    ));
    assert!(matches!(
        fmm.evaluate_many(&[1.0; 150], 2),
        Err(FmmError::ChargeCount { .. })
    ));
    assert!(matches!(
        fmm.evaluate_many(&[], 0),
        Err(FmmError::ChargeCount { .. })
    ));
}
