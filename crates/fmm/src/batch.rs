//! Batched application of one dense operator to many boxes.
//!
//! Applying an `n x n` operator box by box is a matrix-vector product
//! (memory bound). Gathering the boxes that share an operator into the
//! columns of one matrix turns the work into a matrix-matrix product that
//! runs near the machine's peak. This module does the gather, the product
//! (in parallel over column blocks) and the scatter-add.

use ferrofmm_kernels::Real;
use rayon::prelude::*;

/// Columns per parallel block: large enough for GEMM efficiency, small
/// enough to balance two to sixteen threads on a level of a few thousand boxes.
const BLOCK: usize = 128;

/// For every pair `(s, d)`: `dst[:, d] += Op * src[:, s]`, where columns
/// have `n` entries and `op(input, output)` computes `output += Op * input`
/// for a column-major block. Destinations may repeat across pairs.
pub(crate) fn gather_apply_scatter<T: Real>(
    n: usize,
    pairs: &[(usize, usize)],
    src: &[T],
    dst: &mut [T],
    op: impl Fn(&[T], &mut [T]) + Sync,
) {
    if pairs.is_empty() {
        return;
    }
    let products: Vec<Vec<T>> = pairs
        .par_chunks(BLOCK)
        .map(|block| {
            let mut input = Vec::with_capacity(n * block.len());
            for &(s, _) in block {
                input.extend_from_slice(&src[n * s..n * (s + 1)]);
            }
            let mut output = vec![T::ZERO; n * block.len()];
            op(&input, &mut output);
            output
        })
        .collect();
    for (block, product) in pairs.chunks(BLOCK).zip(products) {
        for (&(_, d), col) in block.iter().zip(product.chunks_exact(n)) {
            for (x, y) in dst[n * d..n * (d + 1)].iter_mut().zip(col) {
                *x += *y;
            }
        }
    }
}

/// `f(input_block, output_block)` over matching column blocks of two
/// column-major matrices with `n` rows, in parallel.
pub(crate) fn par_columns<T: Real>(
    n: usize,
    input: &[T],
    output: &mut [T],
    f: impl Fn(&[T], &mut [T]) + Sync,
) {
    debug_assert_eq!(input.len(), output.len());
    if n == 0 || input.is_empty() {
        return;
    }
    input
        .par_chunks(n * BLOCK)
        .zip(output.par_chunks_mut(n * BLOCK))
        .for_each(|(i, o)| f(i, o));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_apply_scatter_matches_loop() {
        // Op = 2 * identity on 3-vectors; repeated destinations accumulate.
        let n = 3;
        let src: Vec<f64> = (0..3 * 300).map(|i| i as f64).collect();
        let pairs: Vec<(usize, usize)> = (0..300).map(|s| (s, s % 7)).collect();
        let mut dst = vec![1.0; 3 * 7];
        gather_apply_scatter(n, &pairs, &src, &mut dst, |i, o| {
            for (x, y) in o.iter_mut().zip(i) {
                *x += 2.0 * *y;
            }
        });
        let mut expect = vec![1.0; 3 * 7];
        for &(s, d) in &pairs {
            for k in 0..3 {
                expect[3 * d + k] += 2.0 * src[3 * s + k];
            }
        }
        assert_eq!(dst, expect);
    }
}
