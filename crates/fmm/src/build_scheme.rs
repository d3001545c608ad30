//! [`BuildScheme`]: build an [`FmmBuilder`] with a scheme chosen by type.

use ferrofmm_field::{DenseM2l, FftM2l, M2lScheme, SvdM2l};
use ferrofmm_kernels::{Kernel, Real};

use crate::{Fmm, FmmBuilder, FmmError};

/// How a front end generic over the M2L scheme `S` builds: through the
/// builder's own method for each scheme, so that with a tolerance the SVD
/// scheme takes the SVD tolerance chosen for it (and keeps following it
/// when verification raises the order), and the others their default
/// configuration.
///
/// ```
/// use ferrofmm_field::FftM2l;
/// use ferrofmm_fmm::{BuildScheme, FmmBuilder};
/// let points: Vec<f64> = (0..300).map(|i| (i as f64 * 0.618).fract()).collect();
/// let fmm = FftM2l::<f64>::build(FmmBuilder::new(&points).order(4).leaf_size(16)).unwrap();
/// assert_eq!(fmm.order(), 4);
/// ```
pub trait BuildScheme<T: Real>: M2lScheme<T> {
    /// Build the FMM described by `builder` with this scheme.
    ///
    /// # Errors
    /// As the builder's `build_*` methods.
    fn build<K: Kernel>(builder: FmmBuilder<'_, T, K>) -> Result<Fmm<T, K, Self>, FmmError>;
}

impl<T: Real> BuildScheme<T> for SvdM2l<T> {
    fn build<K: Kernel>(builder: FmmBuilder<'_, T, K>) -> Result<Fmm<T, K, Self>, FmmError> {
        builder.build_svd()
    }
}

impl<T: Real> BuildScheme<T> for DenseM2l<T> {
    fn build<K: Kernel>(builder: FmmBuilder<'_, T, K>) -> Result<Fmm<T, K, Self>, FmmError> {
        builder.build_dense()
    }
}

impl<T: Real> BuildScheme<T> for FftM2l<T> {
    fn build<K: Kernel>(builder: FmmBuilder<'_, T, K>) -> Result<Fmm<T, K, Self>, FmmError> {
        builder.build_with(Default::default())
    }
}
