//! Scalar pairwise reference loops, used as the default trait methods and as
//! the ground truth in tests of the vectorised paths.

use crate::{EvalMode, Kernel, Real};

/// Pairwise `out += K q` with [`Kernel::kernel_value`] / [`Kernel::kernel_gradient`].
pub fn evaluate_pairwise<K: Kernel, T: Real>(
    kernel: &K,
    mode: EvalMode,
    sources: &[T],
    charges: &[T],
    targets: &[T],
    out: &mut [T],
) {
    let ns = sources.len() / 3;
    let nt = targets.len() / 3;
    let w = mode.values_per_target();
    assert_eq!(
        kernel.components(),
        1,
        "{}: a kernel with several components overrides Kernel::evaluate",
        kernel.name()
    );
    assert!(
        !mode.has_hessian(),
        "{}: the pairwise reference has no Hessians (Kernel::supports)",
        kernel.name()
    );
    debug_assert_eq!(sources.len(), 3 * ns);
    debug_assert_eq!(charges.len(), ns);
    debug_assert_eq!(out.len(), w * nt);
    for j in 0..nt {
        let y = [targets[3 * j], targets[3 * j + 1], targets[3 * j + 2]];
        let mut acc = [T::ZERO; 4];
        for i in 0..ns {
            let d = [
                y[0] - sources[3 * i],
                y[1] - sources[3 * i + 1],
                y[2] - sources[3 * i + 2],
            ];
            if d[0] == T::ZERO && d[1] == T::ZERO && d[2] == T::ZERO {
                continue;
            }
            let q = charges[i];
            acc[0] += kernel.kernel_value(d) * q;
            if w == 4 {
                let g = kernel.kernel_gradient(d);
                acc[1] += g[0] * q;
                acc[2] += g[1] * q;
                acc[3] += g[2] * q;
            }
        }
        for k in 0..w {
            out[w * j + k] += acc[k];
        }
    }
}

/// Pairwise dense matrix `A[j, i] = K(x_i, y_j)`, zero for coincident pairs.
pub fn assemble_pairwise<K: Kernel, T: Real>(
    kernel: &K,
    sources: &[T],
    targets: &[T],
    matrix: &mut [T],
) {
    let ns = sources.len() / 3;
    let nt = targets.len() / 3;
    assert_eq!(
        kernel.components(),
        1,
        "{}: a kernel with several components overrides Kernel::assemble",
        kernel.name()
    );
    debug_assert_eq!(matrix.len(), ns * nt);
    for j in 0..nt {
        for i in 0..ns {
            let d = [
                targets[3 * j] - sources[3 * i],
                targets[3 * j + 1] - sources[3 * i + 1],
                targets[3 * j + 2] - sources[3 * i + 2],
            ];
            matrix[j * ns + i] = if d[0] == T::ZERO && d[1] == T::ZERO && d[2] == T::ZERO {
                T::ZERO
            } else {
                kernel.kernel_value(d)
            };
        }
    }
}
