//! Parallel sort of the points along the Morton curve (sample sort).
//!
//! Each rank first sorts its own points with the tree crate's sort
//! ([`morton_order`]), keyed by `(finest Morton code, global id)` — the id
//! breaks ties between points in one finest cell, so the order is total and
//! every point has one place. Then:
//!
//! 1. every rank takes `S = 16 R` regular samples of its sorted keys (fewer
//!    if it holds fewer points) and all samples are gathered on every rank
//!    (`all_gather`, `16 R^2` keys in all);
//! 2. the sorted samples at positions `k * total / R` (`k = 1 .. R - 1`)
//!    are the splitters; rank `k` receives the keys in
//!    `[splitter_k, splitter_(k+1))`;
//! 3. one personalised all-to-all moves every point (code, coordinates, id,
//!    weight) to its bucket's rank, which merges the `R` sorted runs it
//!    receives (a heap merge, `O(n log R)`).
//!
//! With regular sampling a bucket holds at most about `n/R + n/S` points
//! (Shi & Schaeffer 1992), so the sort itself is balanced to a few percent;
//! the exact balance by weight, on box-aligned cuts, is
//! [`partition`](crate::partition)'s job.

use ferrofmm_tree::Domain;
use ferrofmm_tree::shape::morton_order;
use mpi::traits::*;

use crate::exchange::all_to_all;

/// Words per point in a message: code, x, y, z, id, weight.
const WORDS: usize = 6;

/// The points held by one rank, sorted by `(code, id)`.
#[derive(Clone, Debug, Default)]
pub struct LocalPoints {
    /// Finest-level Morton codes, ascending.
    pub codes: Vec<u64>,
    /// Interleaved `xyz`, in the order of `codes`.
    pub coords: Vec<f64>,
    /// Global ids: the position of the point in the concatenation of all
    /// ranks' inputs in rank order.
    pub ids: Vec<u64>,
    /// Weight of each point (1 unless given).
    pub weights: Vec<f64>,
}

impl LocalPoints {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.codes.len()
    }

    /// `true` if the rank holds no point.
    pub fn is_empty(&self) -> bool {
        self.codes.is_empty()
    }

    /// The points of `points` (validated, inside `domain`) sorted with the
    /// tree crate's sort; `first_id` is the global id of the first one.
    pub(crate) fn sorted_local(
        points: &[f64],
        weights: Option<&[f64]>,
        domain: &Domain,
        first_id: u64,
    ) -> Self {
        let (codes, perm) = morton_order(points, domain).expect("points validated before sorting");
        let mut coords = Vec::with_capacity(points.len());
        for &i in &perm {
            coords.extend_from_slice(&points[3 * i..3 * i + 3]);
        }
        let ids = perm.iter().map(|&i| first_id + i as u64).collect();
        let weights = match weights {
            Some(w) => perm.iter().map(|&i| w[i]).collect(),
            None => vec![1.0; perm.len()],
        };
        LocalPoints {
            codes,
            coords,
            ids,
            weights,
        }
    }

    fn key(&self, i: usize) -> (u64, u64) {
        (self.codes[i], self.ids[i])
    }

    /// Appends point `i` to a message.
    pub(crate) fn pack(&self, i: usize, out: &mut Vec<u64>) {
        let c = &self.coords[3 * i..3 * i + 3];
        out.extend_from_slice(&[
            self.codes[i],
            c[0].to_bits(),
            c[1].to_bits(),
            c[2].to_bits(),
            self.ids[i],
            self.weights[i].to_bits(),
        ]);
    }

    /// Merges, by `(code, id)`, the points `self[own]` (this rank's run,
    /// never copied through the exchange) with the received messages
    /// (`runs[r]` words from rank `r`, each run sorted): an `R`-way merge
    /// with a heap, `O(n log R)`.
    pub(crate) fn merge_runs(
        &self,
        own: std::ops::Range<usize>,
        me: usize,
        words: &[u64],
        runs: &[usize],
    ) -> Self {
        use std::cmp::Reverse;
        use std::collections::BinaryHeap;
        // Run `r`: `[next, end)`, in points of `self` for `r == me`, in
        // words of `words` otherwise.
        let mut pos: Vec<[usize; 2]> = Vec::with_capacity(runs.len());
        let mut start = 0;
        for (r, &len) in runs.iter().enumerate() {
            if r == me {
                pos.push([own.start, own.end]);
            } else {
                pos.push([start, start + len]);
            }
            start += len;
        }
        let key = |r: usize, i: usize| {
            if r == me {
                (self.codes[i], self.ids[i])
            } else {
                (words[i], words[i + 4])
            }
        };
        let mut heap: BinaryHeap<Reverse<((u64, u64), usize)>> = pos
            .iter()
            .enumerate()
            .filter(|(_, p)| p[0] < p[1])
            .map(|(r, p)| Reverse((key(r, p[0]), r)))
            .collect();
        let n = words.len() / WORDS + own.len();
        let mut p = LocalPoints {
            codes: Vec::with_capacity(n),
            coords: Vec::with_capacity(3 * n),
            ids: Vec::with_capacity(n),
            weights: Vec::with_capacity(n),
        };
        while let Some(Reverse((_, r))) = heap.pop() {
            let i = pos[r][0];
            if r == me {
                p.codes.push(self.codes[i]);
                p.coords.extend_from_slice(&self.coords[3 * i..3 * i + 3]);
                p.ids.push(self.ids[i]);
                p.weights.push(self.weights[i]);
                pos[r][0] += 1;
            } else {
                let w = &words[i..i + WORDS];
                p.codes.push(w[0]);
                p.coords.extend(w[1..4].iter().map(|&b| f64::from_bits(b)));
                p.ids.push(w[4]);
                p.weights.push(f64::from_bits(w[5]));
                pos[r][0] += WORDS;
            }
            if pos[r][0] < pos[r][1] {
                heap.push(Reverse((key(r, pos[r][0]), r)));
            }
        }
        p
    }

    /// Concatenates the points of `self` from `range` and of the messages
    /// `words` (unpacked in order) as `before ++ self[range] ++ after`:
    /// what a rank holds after exchanging points that were already in global
    /// order (lower ranks' points come first).
    pub(crate) fn splice(
        &self,
        before: &[u64],
        range: std::ops::Range<usize>,
        after: &[u64],
    ) -> Self {
        let n = (before.len() + after.len()) / WORDS + range.len();
        let mut p = LocalPoints {
            codes: Vec::with_capacity(n),
            coords: Vec::with_capacity(3 * n),
            ids: Vec::with_capacity(n),
            weights: Vec::with_capacity(n),
        };
        let unpack = |p: &mut LocalPoints, words: &[u64]| {
            for w in words.chunks_exact(WORDS) {
                p.codes.push(w[0]);
                p.coords.extend(w[1..4].iter().map(|&b| f64::from_bits(b)));
                p.ids.push(w[4]);
                p.weights.push(f64::from_bits(w[5]));
            }
        };
        unpack(&mut p, before);
        p.codes.extend_from_slice(&self.codes[range.clone()]);
        p.coords
            .extend_from_slice(&self.coords[3 * range.start..3 * range.end]);
        p.ids.extend_from_slice(&self.ids[range.clone()]);
        p.weights.extend_from_slice(&self.weights[range]);
        unpack(&mut p, after);
        p
    }

    /// Messages of the points `bounds[r] .. bounds[r + 1]` for each rank `r`
    /// (an empty one for rank `skip`).
    pub(crate) fn pack_ranges(&self, bounds: &[usize], skip: Option<usize>) -> Vec<Vec<u64>> {
        bounds
            .windows(2)
            .enumerate()
            .map(|(r, w)| {
                if skip == Some(r) {
                    return Vec::new();
                }
                let mut out = Vec::with_capacity(WORDS * (w[1] - w[0]));
                for i in w[0]..w[1] {
                    self.pack(i, &mut out);
                }
                out
            })
            .collect()
    }
}

/// Sample sort (see the [module docs](self)): returns this rank's share of
/// the globally sorted points and the bytes it sent.
pub fn sample_sort<C: Communicator>(comm: &C, local: LocalPoints) -> (LocalPoints, u64) {
    let size = comm.size() as usize;
    if size == 1 {
        return (local, 0);
    }
    let n = local.len();
    let s = n.min(16 * size);
    let mut samples: Vec<u64> = Vec::with_capacity(2 * s);
    for j in 0..s {
        let (c, id) = local.key((j * n + n / 2) / s.max(1));
        samples.extend_from_slice(&[c, id]);
    }
    let mut counts = vec![0u64; size];
    comm.all_gather_into(&(samples.len() as u64), &mut counts[..]);
    let total: usize = counts.iter().map(|&c| c as usize).sum();
    let mut all = vec![0u64; total];
    {
        let c: Vec<i32> = counts.iter().map(|&c| c as i32).collect();
        let d: Vec<i32> = c
            .iter()
            .scan(0, |acc, &x| {
                let v = *acc;
                *acc += x;
                Some(v)
            })
            .collect();
        let mut part = mpi::datatype::PartitionMut::new(&mut all[..], c, d);
        comm.all_gather_varcount_into(&samples[..], &mut part);
    }
    let mut keys: Vec<(u64, u64)> = all.chunks_exact(2).map(|p| (p[0], p[1])).collect();
    keys.sort_unstable();
    let splitters: Vec<(u64, u64)> = (1..size).map(|k| keys[k * keys.len() / size]).collect();
    let mut bounds = Vec::with_capacity(size + 1);
    bounds.push(0);
    for sp in &splitters {
        // First local point not below the splitter (binary search).
        let (mut a, mut b) = (0, n);
        while a < b {
            let m = (a + b) / 2;
            if local.key(m) < *sp {
                a = m + 1;
            } else {
                b = m;
            }
        }
        bounds.push(a);
    }
    bounds.push(n);
    let me = comm.rank() as usize;
    let (recv, runs, bytes) = all_to_all(comm, &local.pack_ranges(&bounds, Some(me)));
    let own = bounds[me]..bounds[me + 1];
    (local.merge_runs(own, me, &recv, &runs), bytes)
}
