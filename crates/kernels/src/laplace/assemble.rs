//! Dense Laplace kernel matrices `A[j, i] = 1 / (4 pi |y_j - x_i|)` for
//! operator precomputation.
//!
//! Sources are de-interleaved once, then each row is a unit-stride loop over
//! sources that the compiler vectorises; the loop is compiled three times
//! (portable, AVX2, AVX-512) and picked at run time. Entries use exact `sqrt`
//! and division with the same operation order as
//! [`Laplace3d::kernel_value`](crate::Kernel::kernel_value), so they equal
//! the scalar reference bit for bit. Large matrices are split over rows with
//! rayon.

use rayon::prelude::*;

use crate::{Real, SimdLevel};

/// Matrices with at least this many entries are assembled in parallel.
const PAR_ENTRIES: usize = 1 << 15;

/// Write the dense Laplace matrix `A[j, i] = 1 / (4 pi |y_j - x_i|)`
/// (`0` for coincident pairs), row-major `n_targets x n_sources`, into
/// `matrix` using instruction-set `level` (clamped to what the CPU supports).
///
/// # Panics
/// When a coordinate slice's length is not a multiple of 3 or
/// `matrix.len() != n_targets * n_sources`.
///
/// ```
/// use ferrofmm_kernels::{laplace_assemble_with, SimdLevel};
/// let sources = [0.0f64, 0.0, 0.0, 1.0, 0.0, 0.0];
/// let targets = [0.0f64, 0.0, 2.0];
/// let mut a = [0.0f64; 2];
/// laplace_assemble_with(SimdLevel::detected(), &sources, &targets, &mut a);
/// let k = 1.0 / (4.0 * std::f64::consts::PI);
/// assert_eq!(a[0], k / 2.0);
/// assert!((a[1] - k / 5f64.sqrt()).abs() < 1e-17);
/// ```
pub fn laplace_assemble_with<T: Real>(
    level: SimdLevel,
    sources: &[T],
    targets: &[T],
    matrix: &mut [T],
) {
    assert!(
        sources.len().is_multiple_of(3) && targets.len().is_multiple_of(3),
        "laplace_assemble: coordinate slices must hold interleaved xyz triples"
    );
    let ns = sources.len() / 3;
    let nt = targets.len() / 3;
    assert_eq!(matrix.len(), ns * nt, "laplace_assemble: matrix length");
    if ns == 0 || nt == 0 {
        return;
    }
    let mut sx = Vec::with_capacity(ns);
    let mut sy = Vec::with_capacity(ns);
    let mut sz = Vec::with_capacity(ns);
    for p in sources.chunks_exact(3) {
        sx.push(p[0]);
        sy.push(p[1]);
        sz.push(p[2]);
    }
    let soa = [&sx[..], &sy[..], &sz[..]];
    let level = level.clamp_supported();
    if matrix.len() >= PAR_ENTRIES && nt > 1 {
        let rows_per_task = (PAR_ENTRIES / ns).clamp(1, nt);
        matrix
            .par_chunks_mut(rows_per_task * ns)
            .zip(targets.par_chunks(rows_per_task * 3))
            .for_each(|(m, t)| rows(level, soa, t, m));
    } else {
        rows(level, soa, targets, matrix);
    }
}

/// Rows for `targets` (interleaved) into `matrix` (`n_targets x ns`).
fn rows<T: Real>(level: SimdLevel, soa: [&[T]; 3], targets: &[T], matrix: &mut [T]) {
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `level` was clamped to `SimdLevel::detected()`: the CPU
        // supports avx512f.
        SimdLevel::Avx512 => unsafe { rows_avx512(soa, targets, matrix) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above, the CPU supports avx2 and fma.
        SimdLevel::Avx2 => unsafe { rows_avx2(soa, targets, matrix) },
        _ => rows_portable(soa, targets, matrix),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn rows_avx512<T: Real>(soa: [&[T]; 3], targets: &[T], matrix: &mut [T]) {
    rows_portable(soa, targets, matrix);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn rows_avx2<T: Real>(soa: [&[T]; 3], targets: &[T], matrix: &mut [T]) {
    rows_portable(soa, targets, matrix);
}

/// Inlined into each `target_feature` wrapper so it is vectorised for it.
#[inline(always)]
fn rows_portable<T: Real>(soa: [&[T]; 3], targets: &[T], matrix: &mut [T]) {
    let [sx, sy, sz] = soa;
    let ns = sx.len();
    let inv_4pi = T::from_f64(crate::INV_4PI);
    for (t, row) in targets.chunks_exact(3).zip(matrix.chunks_exact_mut(ns)) {
        let (tx, ty, tz) = (t[0], t[1], t[2]);
        for (((a, &x), &y), &z) in row.iter_mut().zip(sx).zip(sy).zip(sz) {
            let dx = tx - x;
            let dy = ty - y;
            let dz = tz - z;
            let r2 = dx * dx + dy * dy + dz * dz;
            *a = if r2 != T::ZERO {
                inv_4pi / r2.sqrt()
            } else {
                T::ZERO
            };
        }
    }
}
