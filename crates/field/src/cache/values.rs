//! Values a caller computes once per kernel, order and geometry and keeps
//! in the operator cache beside the operators: e.g. the periodic FMM's
//! periodisation operator, whose Ewald sums cost seconds at high orders.

use ferrofmm_kernels::Kernel;
use serde::{Deserialize, Serialize};

use super::{CacheKey, CacheStatus, FlatStore, StoreLayout, load_or_compute};
use crate::{FieldError, OperatorParams};

/// The layout of a cached value array: what it is and how many values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct ValuesLayout {
    description: String,
    len: u64,
}

impl StoreLayout for ValuesLayout {
    fn n_values(&self) -> Result<usize, String> {
        usize::try_from(self.len).map_err(|e| e.to_string())
    }
}

/// `len` values (`f64`) for `kernel` at `params.order` and
/// `params.radii`, described exactly by `kind` and `description` (e.g. the
/// cell and the lattice sum), loaded from `params.cache_dir` when a valid
/// file holds them, else computed by `compute` and written there (with the
/// checks, atomic writes and eviction of the operator cache); computed
/// without a file when the cache is off.
///
/// # Errors
/// What `compute` returns, or [`FieldError::InvalidParams`] when it does
/// not return `len` values. A cache file that cannot be read or written
/// is not an error (the status says why).
pub fn cached_values<K: Kernel>(
    params: &OperatorParams,
    kernel: &K,
    kind: &str,
    description: &str,
    len: usize,
    compute: impl FnOnce() -> Result<Vec<f64>, FieldError>,
) -> Result<(Vec<f64>, CacheStatus), FieldError> {
    let mut key = CacheKey::new::<K, f64>(kind, kernel, params.order, params.radii.to_array());
    key.scheme_config = description.to_string();
    let layout = ValuesLayout {
        description: description.to_string(),
        len: len as u64,
    };
    let (store, status) = load_or_compute::<f64, FlatStore<ValuesLayout, f64>>(
        params.cache_dir.as_deref(),
        params.cache_size_limit,
        &key,
        layout.clone().accept(),
        || {
            let data = compute()?;
            if data.len() != len {
                return Err(FieldError::InvalidParams(format!(
                    "{kind}: computed {} values, expected {len}",
                    data.len()
                )));
            }
            Ok(FlatStore { layout, data })
        },
    )?;
    Ok((store.data, status))
}

#[cfg(test)]
mod tests {
    use super::*;
    use ferrofmm_kernels::Laplace3d;

    #[test]
    fn values_are_computed_once_and_read_back() {
        let dir = std::env::temp_dir().join(format!("ferrofmm-values-{}", std::process::id()));
        let mut params = OperatorParams::new(4);
        params.cache_dir = Some(dir.clone());
        let make = || Ok(vec![1.0, 2.0, 3.0]);
        let (a, first) = cached_values(&params, &Laplace3d, "test", "cell 1", 3, make).unwrap();
        assert!(!first.is_hit());
        let (b, second) = cached_values(&params, &Laplace3d, "test", "cell 1", 3, || {
            panic!("read from the cache")
        })
        .unwrap();
        assert!(second.is_hit());
        assert_eq!(a, b);
        // Another description is another entry; a wrong length is an error.
        let (_, other) = cached_values(&params, &Laplace3d, "test", "cell 2", 3, make).unwrap();
        assert!(!other.is_hit());
        assert!(cached_values(&params, &Laplace3d, "test", "cell 3", 4, make).is_err());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
