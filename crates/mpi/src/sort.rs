//! Parallel sort of the points along the Morton curve (sample sort).
//!
//! Each rank first sorts its own points with the tree crate's sort
//! ([`morton_order`]), keyed by `(finest Morton code, global id)` — the id
//! breaks ties between points in one finest cell, so the order is total and
//! every point has one place. Then:
//!
//! 1. every rank takes `S` regular samples of its sorted keys (fewer if it
//!    holds fewer points), `S = 16 R` up to `R = 256` and `SAMPLE_CAP / R`
//!    beyond ([`samples_per_rank`]), and rank 0 gathers them (at most
//!    [`SAMPLE_CAP`] keys, 16 MB; the other ranks hold only their own);
//! 2. rank 0 sorts them and broadcasts the samples at positions `k * total
//!    / R` (`k = 1 .. R - 1`), the splitters; rank `k` receives the keys in
//!    `[splitter_k, splitter_(k+1))`;
//! 3. one personalised all-to-all moves every point (code, coordinates, id,
//!    weight) to its bucket's rank, which merges the `R` sorted runs it
//!    receives (a heap merge, `O(n log R)`).
//!
//! With regular sampling a bucket holds at most about `N/R + N/S` points
//! of `N` (Shi & Schaeffer 1992): within `1/16` of even up to `R = 256`;
//! beyond, where the cap keeps the gather at `O(1)` per rank instead of
//! `O(R^2)` on every rank, the worst-case bound loosens to `R / S` times
//! the share (inputs in random-like order stay much closer). The sort only
//! has to be roughly even (it sets the transient memory); the exact
//! balance by weight, on box-aligned cuts, is
//! [`partition`](crate::partition)'s job, right after it.

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
    /// tree crate's sort; `id_of(i)` is the global id of point `i`.
    pub(crate) fn sorted_local(
        points: &[f64],
        weights: Option<&[f64]>,
        domain: &Domain,
        id_of: impl Fn(usize) -> u64,
    ) -> Self {
        let (codes, perm) = morton_order(points, domain).expect("points validated before sorting");
        let mut coords = Vec::with_capacity(points.len());
        for &i in &perm {
            coords.extend_from_slice(&points[3 * i..3 * i + 3]);
        }
        let ids = perm.iter().map(|&i| id_of(i)).collect();
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

    /// Splits points whose ids number sources `0 .. first_target` and
    /// targets from `first_target` on (a build with separate targets) into
    /// the sources and the targets, each still sorted, the targets' ids
    /// made positions among the targets (`id - first_target`).
    pub(crate) fn split_targets(self, first_target: u64) -> (Self, Self) {
        let mut sets = [LocalPoints::default(), LocalPoints::default()];
        for i in 0..self.len() {
            let target = self.ids[i] >= first_target;
            let p = &mut sets[usize::from(target)];
            p.codes.push(self.codes[i]);
            p.coords.extend_from_slice(&self.coords[3 * i..3 * i + 3]);
            p.ids
                .push(self.ids[i] - if target { first_target } else { 0 });
            p.weights.push(self.weights[i]);
        }
        let [sources, targets] = sets;
        (sources, targets)
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

/// Most sample keys rank 0 gathers: `16 R` per rank up to `R = 256`,
/// fewer per rank beyond (`2^20` keys, 16 MB).
pub const SAMPLE_CAP: usize = 1 << 20;

/// Samples each of `size` ranks takes: `16 R`, or `SAMPLE_CAP / R` when
/// that is fewer (at least 4).
pub fn samples_per_rank(size: usize) -> usize {
    (16 * size).min((SAMPLE_CAP / size.max(1)).max(4))
}

/// Sample sort (see the [module docs](self)): returns this rank's share of
/// the globally sorted points and the bytes it sent.
pub fn sample_sort<C: Communicator>(comm: &C, local: LocalPoints) -> (LocalPoints, u64) {
    let size = comm.size() as usize;
    if size == 1 {
        return (local, 0);
    }
    let n = local.len();
    let s = n.min(samples_per_rank(size));
    let mut samples: Vec<u64> = Vec::with_capacity(2 * s);
    for j in 0..s {
        let (c, id) = local.key((j * n + n / 2) / s.max(1));
        samples.extend_from_slice(&[c, id]);
    }
    // Samples to rank 0, which picks the splitters and broadcasts them.
    let root = comm.process_at_rank(0);
    let count = samples.len() as i32;
    let mut flat = vec![0u64; 2 * (size - 1)];
    if comm.rank() == 0 {
        let mut counts = vec![0i32; size];
        root.gather_into_root(&count, &mut counts[..]);
        let sizes: Vec<usize> = counts.iter().map(|&c| c as usize).collect();
        let (c, displs) = crate::exchange::layout(&sizes);
        let mut all = vec![0u64; sizes.iter().sum()];
        let mut part = mpi::datatype::PartitionMut::new(&mut all[..], c, displs);
        root.gather_varcount_into_root(&samples[..], &mut part);
        let mut keys: Vec<(u64, u64)> = all.chunks_exact(2).map(|p| (p[0], p[1])).collect();
        keys.sort_unstable();
        if !keys.is_empty() {
            for k in 1..size {
                let (c, id) = keys[k * keys.len() / size];
                flat[2 * (k - 1)] = c;
                flat[2 * (k - 1) + 1] = id;
            }
        }
    } else {
        root.gather_into(&count);
        root.gather_varcount_into(&samples[..]);
    }
    root.broadcast_into(&mut flat[..]);
    let splitters: Vec<(u64, u64)> = flat.chunks_exact(2).map(|p| (p[0], p[1])).collect();
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

#[cfg(test)]
mod sample_tests {
    use super::*;

    #[test]
    fn samples_per_rank_is_16_r_then_capped() {
        assert_eq!(samples_per_rank(1), 16);
        assert_eq!(samples_per_rank(256), 16 * 256);
        assert_eq!(samples_per_rank(4096), SAMPLE_CAP / 4096);
        assert!(samples_per_rank(4096) * 4096 <= SAMPLE_CAP);
        assert_eq!(samples_per_rank(1 << 20), 4);
        for r in [2, 3, 100, 300, 5000, 70_000] {
            let s = samples_per_rank(r);
            assert!(s >= 4 && (s * r <= SAMPLE_CAP || s == 4), "R = {r}: {s}");
        }
    }
}
