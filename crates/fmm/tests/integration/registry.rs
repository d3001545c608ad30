//! Every kernel of the registry, found by name, through the FMM: a kernel
//! registered tomorrow is tested here without a new line. Each runs with
//! the scheme its `auto` resolves to and with a tolerance (the library
//! picks the order and verifies it), on zero-mean and positive densities,
//! against direct summation; every source kind its description lists is
//! accepted.

use ferrofmm_fmm::{
    Charges, FmmBuilder, Geometry, SchemeChoice, relative_errors_sources, sample_indices,
};
use ferrofmm_kernels::{EvalMode, Kernel, KernelChoice, KernelVisitor, Precision, SourceKind};

/// The registered kernels, each with its example parameter.
fn registered() -> Vec<KernelChoice> {
    KernelChoice::registered()
        .iter()
        .map(|d| d.example())
        .collect()
}

/// One run of `eps` with the resolved scheme; returns the worst relative
/// error of potential and gradient against direct summation.
struct Run {
    eps: f64,
    kind: SourceKind,
    charges: Charges,
    scheme: SchemeChoice,
}

impl KernelVisitor for Run {
    type Output = f64;

    fn visit<K: Kernel>(self, kernel: K) -> f64 {
        let n = 3000;
        let mode = EvalMode::PotentialGradient;
        let points: Vec<f64> = Geometry::Cube.points(n, 11);
        let densities: Vec<f64> = self
            .charges
            .generate(n * kernel.values_per_source(self.kind), 12);
        let builder = FmmBuilder::new(&points)
            .kernel(kernel.clone())
            .tolerance(self.eps)
            // A tree, not the direct sum 3000 points would get.
            .leaf_size(64)
            .mode(mode)
            .source_kind(self.kind);
        let values = match self.scheme {
            SchemeChoice::Fft => builder
                .build_with::<ferrofmm_field::FftM2l<f64>>(Default::default())
                .unwrap()
                .evaluate(&densities),
            _ => builder.build_svd().unwrap().evaluate(&densities),
        }
        .unwrap();
        let sample = sample_indices(n, 200);
        let e = relative_errors_sources(
            &kernel, self.kind, mode, &points, &densities, &points, &values, &sample,
        );
        eprintln!(
            "{} {:?} {} {}: {:.2e} {:?}",
            kernel.name(),
            self.scheme,
            self.kind.name(),
            self.charges.name(),
            e.potential,
            e.gradient
        );
        assert!(e.worst() > 0.0, "nothing was compared");
        e.worst()
    }
}

#[test]
fn every_registered_kernel_meets_a_tolerance_through_its_auto_scheme() {
    let eps = 1e-4;
    for choice in registered() {
        let scheme = SchemeChoice::Auto
            .resolve(
                choice,
                None,
                None,
                None,
                EvalMode::PotentialGradient,
                Precision::F64,
                false,
                None,
            )
            .unwrap();
        for (kind, charges) in [
            (SourceKind::Charge, Charges::Signed),
            (SourceKind::Charge, Charges::Positive),
        ] {
            let worst = choice.visit(Run {
                eps,
                kind,
                charges,
                scheme,
            });
            // The verified tolerance, with the sampling's slack (the
            // verification samples other targets than this check).
            assert!(worst < 2.0 * eps, "{choice}: {worst:.2e} above {eps:e}");
        }
    }
}

#[test]
fn every_registered_source_kind_is_accepted() {
    struct Supports(SourceKind);
    impl KernelVisitor for Supports {
        type Output = bool;
        fn visit<K: Kernel>(self, kernel: K) -> bool {
            kernel.supports(self.0, EvalMode::PotentialGradient)
        }
    }
    for choice in registered() {
        let d = choice.description();
        for kind in [
            SourceKind::Charge,
            SourceKind::Dipole,
            SourceKind::ChargeDipole,
        ] {
            assert_eq!(
                choice.visit(Supports(kind)),
                d.source_kinds.contains(&kind),
                "{choice} {kind:?}: the description and the kernel disagree"
            );
        }
        assert_eq!(
            choice.takes_dipoles(),
            d.source_kinds.contains(&SourceKind::Dipole)
        );
    }
}
