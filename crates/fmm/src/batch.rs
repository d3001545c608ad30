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

/// `data[:, j] = Op * data[:, j]` for the columns `j` with `keep(j)` (every
/// column without `keep`), the others set to zero; `op(input, output)`
/// computes `output += Op * input` for a column-major block. Each block of
/// [`BLOCK`] columns is copied aside, zeroed and written back, so the
/// working memory is one block per thread, not a second copy of `data`
/// (the upward and downward passes turn check potentials into
/// expansions in the same buffer this way).
pub(crate) fn par_columns_in_place<T: Real>(
    n: usize,
    data: &mut [T],
    keep: Option<&(dyn Fn(usize) -> bool + Sync)>,
    op: impl Fn(&[T], &mut [T]) + Sync,
) {
    if n == 0 || data.is_empty() {
        return;
    }
    data.par_chunks_mut(n * BLOCK)
        .enumerate()
        .for_each(|(k, block)| match keep {
            None => {
                let input = block.to_vec();
                block.fill(T::ZERO);
                op(&input, block);
            }
            Some(keep) => {
                let kept: Vec<usize> = (0..block.len() / n)
                    .filter(|&c| keep(k * BLOCK + c))
                    .collect();
                let mut input = Vec::with_capacity(n * kept.len());
                for &c in &kept {
                    input.extend_from_slice(&block[n * c..n * (c + 1)]);
                }
                let mut output = vec![T::ZERO; n * kept.len()];
                op(&input, &mut output);
                block.fill(T::ZERO);
                for (&c, col) in kept.iter().zip(output.chunks_exact(n)) {
                    block[n * c..n * (c + 1)].copy_from_slice(col);
                }
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_in_place_match_a_separate_output() {
        // Op = [[1, 2], [3, 4]] on 2-vectors, over more than one block.
        let n = 2;
        let op = |i: &[f64], o: &mut [f64]| {
            for (x, y) in i.chunks_exact(2).zip(o.chunks_exact_mut(2)) {
                y[0] += x[0] + 2.0 * x[1];
                y[1] += 3.0 * x[0] + 4.0 * x[1];
            }
        };
        let cols = 3 * BLOCK + 5;
        let data: Vec<f64> = (0..n * cols).map(|i| (i % 13) as f64 - 6.0).collect();
        let mut expect = vec![0.0; data.len()];
        op(&data, &mut expect);
        let mut all = data.clone();
        par_columns_in_place(n, &mut all, None, op);
        assert_eq!(all, expect);
        let keep = |j: usize| j % 3 != 1;
        let mut some = data.clone();
        par_columns_in_place(n, &mut some, Some(&keep), op);
        for j in 0..cols {
            let want = if keep(j) {
                &expect[n * j..n * (j + 1)]
            } else {
                &[0.0, 0.0][..]
            };
            assert_eq!(&some[n * j..n * (j + 1)], want, "column {j}");
        }
    }

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
