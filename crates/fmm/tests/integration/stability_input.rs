//! Stability suite, input: everything a caller can get wrong ends in a typed
//! [`FmmError`] with a one-line message, never a panic and never a result.
//! (errors.rs has the basic cases; these extend them to every input and
//! parameter.)

use crate::stability_common;

use ferrofmm_field::{FieldError, SurfaceRadii, SvdConfig, SvdM2l};
use ferrofmm_fmm::{FmmBuilder, FmmError, MAX_ORDER, MIN_ORDER};
use ferrofmm_kernels::{EvalMode, KernelError, ModifiedHelmholtz3d};
use ferrofmm_tree::{Domain, TreeError};
use stability_common::uniform;

fn points(n: usize) -> Vec<f64> {
    uniform(n, 0.0, 1.0, 1)
}

/// The error of a build, checked for a one-line, non-empty message.
fn build_error(b: FmmBuilder<'_, f64, impl ferrofmm_kernels::Kernel>) -> FmmError {
    let e = match b.build_dense() {
        Ok(_) => panic!("build accepted bad input"),
        Err(e) => e,
    };
    check_message(&e);
    e
}

fn check_message(e: &FmmError) {
    let m = e.to_string();
    assert!(!m.trim().is_empty() && !m.contains('\n'), "message {m:?}");
}

#[test]
fn non_finite_coordinates_anywhere() {
    let p = points(50);
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for index in [0, 1, 2, 77, 149] {
            let mut s = p.clone();
            s[index] = bad;
            let e = build_error(FmmBuilder::new(&s));
            assert!(
                matches!(e, FmmError::NonFiniteCoordinate { what: "sources", index: i, .. } if i == index),
                "{e:?}"
            );
            let e = build_error(FmmBuilder::new(&p).targets(&s));
            assert!(
                matches!(e, FmmError::NonFiniteCoordinate { what: "targets", index: i, .. } if i == index),
                "{e:?}"
            );
        }
    }
    // f32: a value that is finite in f64 but not in f32 cannot be given;
    // f32 NaN is caught the same way.
    let mut s: Vec<f32> = uniform(10, 0.0, 1.0, 2);
    s[4] = f32::NAN;
    assert!(matches!(
        FmmBuilder::new(&s).build_dense(),
        Err(FmmError::NonFiniteCoordinate { index: 4, .. })
    ));
}

#[test]
fn non_finite_charges_anywhere() {
    let p = points(50);
    let fmm = FmmBuilder::new(&p)
        .order(3)
        .leaf_size(8)
        .build_dense()
        .unwrap();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        for index in [0, 25, 49] {
            let mut q = vec![1.0; 50];
            q[index] = bad;
            let e = fmm.evaluate(&q).unwrap_err();
            check_message(&e);
            assert!(
                matches!(e, FmmError::NonFiniteCharge { index: i, .. } if i == index),
                "{e:?}"
            );
        }
        // In the second of three vectors of evaluate_many: flat index.
        let mut q = vec![1.0; 150];
        q[60] = bad;
        assert!(matches!(
            fmm.evaluate_many(&q, 3),
            Err(FmmError::NonFiniteCharge { index: 60, .. })
        ));
    }
    // Huge but finite charges are accepted (overflow is the caller's).
    assert!(fmm.evaluate(&vec![1e300; 50]).is_ok());
}

#[test]
fn mismatched_lengths() {
    let p = points(50);
    for len in [1, 2, 4, 149] {
        let e = build_error(FmmBuilder::new(&p[..len]));
        assert!(
            matches!(e, FmmError::RaggedPoints { what: "sources", len: l } if l == len),
            "{e:?}"
        );
        let e = build_error(FmmBuilder::new(&p).targets(&p[..len]));
        assert!(
            matches!(
                e,
                FmmError::RaggedPoints {
                    what: "targets",
                    ..
                }
            ),
            "{e:?}"
        );
    }
    let fmm = FmmBuilder::new(&p)
        .targets(&p[..30])
        .order(3)
        .build_dense()
        .unwrap();
    for n in [0, 10, 49, 51, 100] {
        let e = fmm.evaluate(&vec![1.0; n]).unwrap_err();
        check_message(&e);
        assert!(
            matches!(e, FmmError::ChargeCount { expected: 50, got } if got == n),
            "{e:?}"
        );
    }
    assert!(matches!(
        fmm.evaluate_many(&vec![1.0; 100], 3),
        Err(FmmError::ChargeCount {
            expected: 150,
            got: 100
        })
    ));
    // Ten targets, one value each.
    assert_eq!(fmm.evaluate(&[1.0; 50]).unwrap().len(), 10);
}

#[test]
fn empty_input() {
    let p = points(10);
    let empty: Vec<f64> = Vec::new();
    let e = build_error(FmmBuilder::new(&empty));
    assert!(matches!(e, FmmError::Empty("sources")), "{e:?}");
    let e = build_error(FmmBuilder::new(&p).targets(&empty));
    assert!(matches!(e, FmmError::Empty("targets")), "{e:?}");
    let fmm = FmmBuilder::new(&p).order(3).build_dense().unwrap();
    assert!(matches!(
        fmm.evaluate(&[]),
        Err(FmmError::ChargeCount { .. })
    ));
    assert!(matches!(
        fmm.evaluate_many(&[], 0),
        Err(FmmError::ChargeCount { .. })
    ));
}

#[test]
fn orders_leaf_sizes_and_levels() {
    let p = points(100);
    for order in [0, 1, MAX_ORDER + 1, 1000, usize::MAX] {
        let e = build_error(FmmBuilder::new(&p).order(order));
        assert!(
            matches!(e, FmmError::InvalidOrder { order: o, min: MIN_ORDER, max: MAX_ORDER } if o == order),
            "{e:?}"
        );
    }
    assert!(FmmBuilder::new(&p).order(MIN_ORDER).build_dense().is_ok());
    let e = build_error(FmmBuilder::new(&p).leaf_size(0));
    assert!(matches!(e, FmmError::InvalidLeafSize(0)), "{e:?}");
    assert!(
        FmmBuilder::new(&p)
            .leaf_size(usize::MAX)
            .build_dense()
            .is_ok()
    );
    let e = build_error(FmmBuilder::new(&p).max_level(20));
    assert!(matches!(e, FmmError::InvalidParameter(_)), "{e:?}");
    // max_level 0: the root is the only leaf, a valid (direct) evaluation.
    let fmm = FmmBuilder::new(&p)
        .max_level(0)
        .leaf_size(1)
        .order(3)
        .build_dense()
        .unwrap();
    assert_eq!(fmm.tree().depth(), 0);
}

#[test]
fn operator_parameters() {
    let p = points(100);
    for rcond in [-1.0, 1.0, 2.0, f64::NAN, f64::INFINITY] {
        let e = build_error(FmmBuilder::new(&p).order(3).pinv_rcond(Some(rcond)));
        assert!(
            matches!(e, FmmError::Field(FieldError::InvalidParams(_))),
            "rcond {rcond}: {e:?}"
        );
    }
    let bad_radii = [
        SurfaceRadii {
            upward_equivalent: 0.9,
            ..SurfaceRadii::default()
        },
        SurfaceRadii {
            downward_check: f64::NAN,
            ..SurfaceRadii::default()
        },
        SurfaceRadii {
            upward_equivalent: 1.5,
            upward_check: 2.5,
            downward_equivalent: 2.9,
            downward_check: 1.1,
        },
    ];
    for radii in bad_radii {
        let e = build_error(FmmBuilder::new(&p).order(3).surface_radii(radii));
        assert!(
            matches!(e, FmmError::Field(FieldError::InvalidParams(_))),
            "{radii:?}: {e:?}"
        );
    }
    for tolerance in [f64::NAN, 1.0, 5.0] {
        let r = FmmBuilder::new(&p)
            .order(3)
            .build_with::<SvdM2l<f64>>(SvdConfig {
                rank: None,
                tolerance,
            });
        let e = r.err().expect("bad SVD tolerance accepted");
        check_message(&e);
        assert!(
            matches!(e, FmmError::Field(FieldError::InvalidParams(_))),
            "{e:?}"
        );
    }
}

#[test]
fn kernel_and_domain_parameters() {
    let p = points(100);
    // A kernel parameter the kernel rejects is the kernel's typed error.
    assert!(matches!(
        ModifiedHelmholtz3d::new(f64::NAN),
        Err(KernelError::InvalidParameter { .. })
    ));
    // Points outside a given domain.
    let domain = Domain::new([0.0; 3], 0.5).unwrap();
    let e = build_error(FmmBuilder::new(&p).domain(domain));
    assert!(
        matches!(e, FmmError::Tree(TreeError::OutsideDomain { .. })),
        "{e:?}"
    );
    // A domain too small for the float type (see stability_geometry.rs).
    let tiny: Vec<f64> = p.iter().map(|x| x * 1e-300).collect();
    let e = build_error(FmmBuilder::new(&tiny).mode(EvalMode::PotentialGradient));
    assert!(matches!(e, FmmError::DomainOutOfRange { .. }), "{e:?}");
}
