//! Compressed sparse row (CSR) storage: one list of box indices per box.
//!
//! Row `b` is `indices[offsets[b]..offsets[b + 1]]`; `offsets` has one entry
//! more than there are rows and starts at 0. Rows are built in parallel over
//! chunks of consecutive boxes and assembled into two flat arrays.

use rayon::prelude::*;

/// Boxes per parallel work item.
const CHUNK: usize = 256;

/// A list per box in compressed sparse row form.
#[derive(Clone, Debug, Default)]
pub struct Csr {
    offsets: Vec<usize>,
    indices: Vec<usize>,
}

impl Csr {
    /// Row `b`: the entries of box `b`.
    #[inline]
    pub fn get(&self, b: usize) -> &[usize] {
        &self.indices[self.offsets[b]..self.offsets[b + 1]]
    }

    /// Row offsets (`n_rows() + 1` entries, starting at 0).
    pub fn offsets(&self) -> &[usize] {
        &self.offsets
    }

    /// All entries, row after row.
    pub fn indices(&self) -> &[usize] {
        &self.indices
    }

    /// Number of rows (boxes).
    pub fn n_rows(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }

    /// Total number of entries.
    pub fn n_entries(&self) -> usize {
        self.indices.len()
    }

    /// Length of the longest row (0 if none).
    pub fn max_row_len(&self) -> usize {
        self.offsets
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .unwrap_or(0)
    }

    /// A CSR array from rows given one after another (row `b` is
    /// `rows[b]`), for lists computed elsewhere.
    ///
    /// ```
    /// use ferrofmm_tree::Csr;
    /// let c = Csr::from_rows(&[vec![1, 2], vec![], vec![0]]);
    /// assert_eq!(c.n_rows(), 3);
    /// assert_eq!(c.get(0), &[1, 2]);
    /// assert!(c.get(1).is_empty());
    /// assert_eq!(c.offsets(), &[0, 2, 2, 3]);
    /// ```
    pub fn from_rows(rows: &[Vec<usize>]) -> Self {
        let mut offsets = Vec::with_capacity(rows.len() + 1);
        offsets.push(0);
        let mut indices = Vec::with_capacity(rows.iter().map(Vec::len).sum());
        for r in rows {
            indices.extend_from_slice(r);
            offsets.push(indices.len());
        }
        Csr { offsets, indices }
    }

    /// Builds `n` rows in parallel; `row(b, out)` appends row `b` to `out`.
    pub(crate) fn build<F>(n: usize, row: F) -> Self
    where
        F: Fn(usize, &mut Vec<usize>) + Sync,
    {
        let parts: Vec<(Vec<usize>, Vec<usize>)> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let boxes = c * CHUNK..n.min((c + 1) * CHUNK);
                let mut lens = Vec::with_capacity(boxes.len());
                let mut idx = Vec::new();
                for b in boxes {
                    let before = idx.len();
                    row(b, &mut idx);
                    lens.push(idx.len() - before);
                }
                (lens, idx)
            })
            .collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        let mut starts = Vec::with_capacity(parts.len());
        for (lens, _) in &parts {
            starts.push(*offsets.last().unwrap_or(&0));
            for len in lens {
                offsets.push(offsets.last().copied().unwrap_or(0) + len);
            }
        }
        // Copy the parts into place in parallel.
        let mut indices = vec![0usize; offsets[n]];
        let mut slices = Vec::with_capacity(parts.len());
        let mut rest: &mut [usize] = &mut indices;
        for (_, idx) in &parts {
            let (head, tail) = rest.split_at_mut(idx.len());
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .zip(parts.par_iter())
            .for_each(|(dst, (_, src))| dst.copy_from_slice(src));
        Csr { offsets, indices }
    }

    /// Builds `n` rows in two passes: `count(b)` gives the length of row
    /// `b`, then `fill(scratch, b, row)` writes it in place (in parallel;
    /// `scratch` is per work chunk of consecutive boxes).
    pub(crate) fn build_counted<S, C, F>(n: usize, count: C, fill: F) -> Self
    where
        S: Default,
        C: Fn(usize) -> usize + Sync,
        F: Fn(&mut S, usize, &mut [usize]) + Sync,
    {
        let counts: Vec<usize> = (0..n).into_par_iter().map(&count).collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for &c in &counts {
            offsets.push(offsets.last().copied().unwrap_or(0) + c);
        }
        let mut indices = vec![0usize; offsets[n]];
        let mut slices = Vec::with_capacity(n.div_ceil(CHUNK));
        let mut rest: &mut [usize] = &mut indices;
        for c in 0..n.div_ceil(CHUNK) {
            let (s, e) = (c * CHUNK, n.min((c + 1) * CHUNK));
            let (head, tail) = rest.split_at_mut(offsets[e] - offsets[s]);
            slices.push(head);
            rest = tail;
        }
        slices.into_par_iter().enumerate().for_each(|(c, slice)| {
            let mut scratch = S::default();
            let mut pos = 0;
            for b in c * CHUNK..n.min((c + 1) * CHUNK) {
                fill(&mut scratch, b, &mut slice[pos..pos + counts[b]]);
                pos += counts[b];
            }
        });
        Csr { offsets, indices }
    }
}
