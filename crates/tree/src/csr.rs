//! Compressed sparse row (CSR) storage: one list of box indices per box.
//!
//! Row `b` is `indices[offsets[b]..offsets[b + 1]]`; `offsets` has one entry
//! more than there are rows and starts at 0. Rows are built in parallel over
//! chunks of consecutive boxes and assembled into two flat arrays.
//!
//! The lists of a periodic tree carry a third array, parallel to the
//! indices: the image shift of each entry ([`Csr::shifts`]; see
//! [`lists`](crate::lists) for the convention). Free-space lists have none
//! (no extra memory).

use rayon::prelude::*;

/// Boxes per parallel work item.
const CHUNK: usize = 256;

/// A list per box in compressed sparse row form.
#[derive(Clone, Debug, Default)]
pub struct Csr {
    offsets: Vec<usize>,
    indices: Vec<usize>,
    /// Image shifts parallel to `indices` (periodic lists only).
    shifts: Option<Vec<[i8; 3]>>,
}

/// A list entry as built: a box index, with or without an image shift.
pub(crate) trait Entry: Copy + Default + Ord + Send + Sync {
    /// Whether entries carry shifts (periodic lists).
    const PERIODIC: bool;
    /// The entry for box `b` shifted by `s` (`s` is dropped without shifts).
    fn new(b: usize, s: [i8; 3]) -> Self;
    /// The box index.
    fn index(self) -> usize;
    /// The flat index and shift arrays of `entries`.
    fn unzip(entries: Vec<Self>) -> (Vec<usize>, Option<Vec<[i8; 3]>>);
}

impl Entry for usize {
    const PERIODIC: bool = false;
    #[inline]
    fn new(b: usize, _: [i8; 3]) -> Self {
        b
    }
    #[inline]
    fn index(self) -> usize {
        self
    }
    fn unzip(entries: Vec<Self>) -> (Vec<usize>, Option<Vec<[i8; 3]>>) {
        (entries, None)
    }
}

/// An entry of a periodic list: box index and image shift packed in one
/// word, `index << 8 | code` with the shift's code
/// `9 (s_x + 1) + 3 (s_y + 1) + (s_z + 1)`, so that entries sort as fast as
/// plain indices, by box index, then shift (lexicographic).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Shifted(u64);

impl Shifted {
    /// The image shift.
    #[inline]
    pub(crate) fn shift(self) -> [i8; 3] {
        let c = (self.0 & 0xff) as i8;
        [c / 9 - 1, c / 3 % 3 - 1, c % 3 - 1]
    }
}

impl Entry for Shifted {
    const PERIODIC: bool = true;
    #[inline]
    fn new(b: usize, s: [i8; 3]) -> Self {
        debug_assert!(s.iter().all(|x| (-1..=1).contains(x)), "shift {s:?}");
        let code = 9 * (s[0] + 1) + 3 * (s[1] + 1) + (s[2] + 1);
        Shifted((b as u64) << 8 | code as u64)
    }
    #[inline]
    fn index(self) -> usize {
        (self.0 >> 8) as usize
    }
    fn unzip(entries: Vec<Self>) -> (Vec<usize>, Option<Vec<[i8; 3]>>) {
        let (indices, shifts) = entries.par_iter().map(|e| (e.index(), e.shift())).unzip();
        (indices, Some(shifts))
    }
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

    /// The image shifts of all entries, parallel to [`indices`](Self::indices),
    /// for the lists of a periodic tree; `None` otherwise. Entry `k` is box
    /// `indices()[k]` translated by `shifts()[k][a]` domain widths along
    /// axis `a` (see [`lists`](crate::lists)).
    pub fn shifts(&self) -> Option<&[[i8; 3]]> {
        self.shifts.as_deref()
    }

    /// The image shifts of row `b`, parallel to [`get`](Self::get)`(b)`, or
    /// `None` for lists without shifts (free space).
    #[inline]
    pub fn row_shifts(&self, b: usize) -> Option<&[[i8; 3]]> {
        self.shifts
            .as_deref()
            .map(|s| &s[self.offsets[b]..self.offsets[b + 1]])
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
        Csr {
            offsets,
            indices,
            shifts: None,
        }
    }

    /// Builds `n` rows in parallel; `row(b, out)` appends row `b` to `out`.
    pub(crate) fn build<E, F>(n: usize, row: F) -> Self
    where
        E: Entry,
        F: Fn(usize, &mut Vec<E>) + Sync,
    {
        let parts: Vec<(Vec<usize>, Vec<E>)> = (0..n.div_ceil(CHUNK))
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
        let mut entries = vec![E::default(); offsets[n]];
        let mut slices = Vec::with_capacity(parts.len());
        let mut rest: &mut [E] = &mut entries;
        for (_, idx) in &parts {
            let (head, tail) = rest.split_at_mut(idx.len());
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .zip(parts.par_iter())
            .for_each(|(dst, (_, src))| dst.copy_from_slice(src));
        let (indices, shifts) = E::unzip(entries);
        Csr {
            offsets,
            indices,
            shifts,
        }
    }

    /// Builds `n` rows in two passes: `count(b)` gives the length of row
    /// `b`, then `fill(scratch, b, row, shifts)` writes it in place (in
    /// parallel; `scratch` is per work chunk of consecutive boxes). With
    /// `periodic`, `shifts` is the row's shift slice, to be written too;
    /// otherwise it is empty and no shift array is kept.
    pub(crate) fn build_counted<S, C, F>(n: usize, periodic: bool, count: C, fill: F) -> Self
    where
        S: Default,
        C: Fn(usize) -> usize + Sync,
        F: Fn(&mut S, usize, &mut [usize], &mut [[i8; 3]]) + Sync,
    {
        let counts: Vec<usize> = (0..n).into_par_iter().map(&count).collect();
        let mut offsets = Vec::with_capacity(n + 1);
        offsets.push(0);
        for &c in &counts {
            offsets.push(offsets.last().copied().unwrap_or(0) + c);
        }
        let mut indices = vec![0usize; offsets[n]];
        let mut shifts = vec![[0i8; 3]; if periodic { offsets[n] } else { 0 }];
        let mut slices = Vec::with_capacity(n.div_ceil(CHUNK));
        let mut rest: &mut [usize] = &mut indices;
        let mut rest_s: &mut [[i8; 3]] = &mut shifts;
        for c in 0..n.div_ceil(CHUNK) {
            let (s, e) = (c * CHUNK, n.min((c + 1) * CHUNK));
            let len = offsets[e] - offsets[s];
            let (head, tail) = rest.split_at_mut(len);
            let (head_s, tail_s) = rest_s.split_at_mut(if periodic { len } else { 0 });
            slices.push((head, head_s));
            rest = tail;
            rest_s = tail_s;
        }
        slices
            .into_par_iter()
            .enumerate()
            .for_each(|(c, (slice, slice_s))| {
                let mut scratch = S::default();
                let mut pos = 0;
                let boxes = c * CHUNK..n.min((c + 1) * CHUNK);
                for (b, &len) in boxes.clone().zip(&counts[boxes]) {
                    let r = pos..pos + len;
                    let sr = if periodic { r.clone() } else { 0..0 };
                    fill(&mut scratch, b, &mut slice[r], &mut slice_s[sr]);
                    pos += len;
                }
            });
        Csr {
            offsets,
            indices,
            shifts: periodic.then_some(shifts),
        }
    }
}
