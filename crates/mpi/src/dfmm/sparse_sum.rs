//! A sum over ranks of some coarse boxes' columns, sent only between the
//! ranks that hold a share and the ranks that need the sum, through one
//! root per box (see `dfmm/coarse_plan.rs` for who is who).
//!
//! # Setup (two sparse exchanges)
//!
//! 1. Each rank tells the root of every box it has a share of, or needs,
//!    which (one word per box: its position in the coarse list and two
//!    flags).
//! 2. Each root answers each rank that needs some of its boxes with the
//!    boxes it will send: those with at least one share (a sum nobody
//!    contributes to is zero, and the zeros the needing rank holds already
//!    are that sum).
//!
//! # Each evaluation (two point-to-point rounds, no collective)
//!
//! Shares go to the roots; each root adds them to its own (in `f64`, as the
//! `all_reduce` did) and sends the sums to the ranks that need them. Both
//! sides of every message know its boxes and their order from the plan:
//! no counts, and only the ranks in the plan talk.

use std::collections::BTreeMap;

use ferrofmm_kernels::Real;
use mpi::traits::*;

use crate::exchange::{planned_exchange, sparse_exchange};

const TAG_REGISTER: i32 = 41;
const TAG_REPLY: i32 = 42;
const TAG_SHARES: i32 = 43;
const TAG_SUMS: i32 = 44;

/// What one rank has to do with one coarse box in one sum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Role {
    /// It holds a share that may be nonzero.
    pub(crate) share: bool,
    /// It needs the whole sum.
    pub(crate) need: bool,
}

/// Boxes (positions in the coarse list) exchanged with each partner rank.
type Lists = Vec<(usize, Vec<usize>)>;

/// One rank's plan of a sparse sum over some coarse boxes (positions `j`
/// in the coarse list, the same on every rank).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct SparseSum {
    /// Shares this rank sends: (root, boxes).
    shares_out: Lists,
    /// Shares this rank receives as a root: (rank, boxes), rank order.
    shares_in: Lists,
    /// Sums this rank sends as a root: (rank, boxes), rank order.
    sums_out: Lists,
    /// Sums this rank receives: (root, boxes), rank order.
    sums_in: Lists,
}

/// Step 1 of the setup: the registrations this rank sends to the roots
/// (one word `4 j + 2 need + share` per box), and the shares it will send.
pub(crate) fn registrations(me: usize, roots: &[usize], roles: &[Role]) -> (Vec<(usize, Vec<u64>)>, Lists) {
    let mut words: BTreeMap<usize, Vec<u64>> = BTreeMap::new();
    let mut shares: BTreeMap<usize, Vec<usize>> = BTreeMap::new();
    for (j, (&root, role)) in roots.iter().zip(roles).enumerate() {
        if root == me || !(role.share || role.need) {
            continue;
        }
        let word = 4 * j as u64 + 2 * u64::from(role.need) + u64::from(role.share);
        words.entry(root).or_default().push(word);
        if role.share {
            shares.entry(root).or_default().push(j);
        }
    }
    (words.into_iter().collect(), shares.into_iter().collect())
}

/// Step 2 of the setup, on a root: from the registrations received (rank
/// order) and this rank's own roles, the shares it receives, the sums it
/// sends and the answers (the boxes each needing rank will get).
pub(crate) fn as_root(
    me: usize,
    roots: &[usize],
    roles: &[Role],
    registered: &[(usize, Vec<u64>)],
) -> Result<(Lists, Lists, Vec<(usize, Vec<u64>)>), String> {
    let mut has_share: Vec<bool> = roots
        .iter()
        .zip(roles)
        .map(|(&r, role)| r == me && role.share)
        .collect();
    let mut shares_in = Lists::new();
    let mut needs = Lists::new();
    for (rank, words) in registered {
        let (mut s, mut n) = (Vec::new(), Vec::new());
        for &w in words {
            let j = (w / 4) as usize;
            if roots.get(j) != Some(&me) {
                return Err(format!("rank {rank} sent a share of coarse box {j} to rank {me}, not its root"));
            }
            if w & 1 == 1 {
                has_share[j] = true;
                s.push(j);
            }
            if w & 2 == 2 {
                n.push(j);
            }
        }
        if !s.is_empty() {
            shares_in.push((*rank, s));
        }
        needs.push((*rank, n));
    }
    let sums_out: Lists = needs
        .into_iter()
        .map(|(r, n)| (r, n.into_iter().filter(|&j| has_share[j]).collect::<Vec<_>>()))
        .filter(|(_, n)| !n.is_empty())
        .collect();
    let answers = sums_out
        .iter()
        .map(|(r, n)| (*r, n.iter().map(|&j| j as u64).collect()))
        .collect();
    Ok((shares_in, sums_out, answers))
}

/// Step 3 of the setup: the sums this rank receives, from the answers.
pub(crate) fn sums_in(answers: Vec<(usize, Vec<u64>)>) -> Lists {
    answers
        .into_iter()
        .map(|(r, w)| (r, w.into_iter().map(|j| j as usize).collect()))
        .collect()
}

impl SparseSum {
    /// Makes the plan (a collective: two sparse exchanges). `roots[j]` and
    /// `roles[j]`: the root of coarse box `j` and this rank's role in it;
    /// returns the plan and the bytes sent.
    pub(crate) fn make<C: Communicator>(
        comm: &C,
        roots: &[usize],
        roles: &[Role],
    ) -> (Result<Self, String>, u64) {
        let me = comm.rank() as usize;
        let (register, shares_out) = registrations(me, roots, roles);
        let (registered, mut bytes) = sparse_exchange(comm, &register, TAG_REGISTER);
        // Errors are carried to the end: every rank must reach both exchanges.
        let (shares_in, sums_out, answers, error) = match as_root(me, roots, roles, &registered) {
            Ok((i, o, a)) => (i, o, a, None),
            Err(e) => (Lists::new(), Lists::new(), Vec::new(), Some(e)),
        };
        let (got, b) = sparse_exchange(comm, &answers, TAG_REPLY);
        bytes += b;
        let plan = SparseSum {
            shares_out,
            shares_in,
            sums_out,
            sums_in: sums_in(got),
        };
        (error.map_or(Ok(plan), Err), bytes)
    }

    /// The part of the plan for the boxes `keep` selects (both sides of
    /// every pair select the same boxes, so the parts still match).
    pub(crate) fn restrict(&self, keep: impl Fn(usize) -> bool) -> Self {
        let part = |lists: &Lists| -> Lists {
            lists
                .iter()
                .map(|(r, js)| (*r, js.iter().copied().filter(|&j| keep(j)).collect::<Vec<_>>()))
                .filter(|(_, js)| !js.is_empty())
                .collect()
        };
        SparseSum {
            shares_out: part(&self.shares_out),
            shares_in: part(&self.shares_in),
            sums_out: part(&self.sums_out),
            sums_in: part(&self.sums_in),
        }
    }

    /// Whether this rank sends or receives nothing.
    pub(crate) fn is_empty(&self) -> bool {
        self.shares_out.is_empty()
            && self.shares_in.is_empty()
            && self.sums_out.is_empty()
            && self.sums_in.is_empty()
    }

    /// Distinct ranks this one sends to and receives from.
    pub(crate) fn partners(&self) -> (Vec<usize>, Vec<usize>) {
        let ranks = |a: &Lists, b: &Lists| {
            let mut r: Vec<usize> = a.iter().chain(b).map(|(r, _)| *r).collect();
            r.sort_unstable();
            r.dedup();
            r
        };
        (
            ranks(&self.shares_out, &self.sums_out),
            ranks(&self.shares_in, &self.sums_in),
        )
    }

    /// The shares this rank sends (`n` values of column `col(j)` of `data`
    /// per box, as `f64` bits).
    pub(crate) fn share_messages<T: Real>(
        &self,
        n: usize,
        col: &impl Fn(usize) -> usize,
        data: &[T],
    ) -> Vec<(usize, Vec<u64>)> {
        pack(&self.shares_out, n, col, data)
    }

    /// Adds the shares received (in the order of `shares_in`) to this
    /// root's own, in `f64`.
    pub(crate) fn add_shares<T: Real>(
        &self,
        n: usize,
        col: &impl Fn(usize) -> usize,
        got: &[(usize, Vec<u64>)],
        data: &mut [T],
    ) {
        let mut sums: BTreeMap<usize, Vec<f64>> = BTreeMap::new();
        for ((_, js), (_, words)) in self.shares_in.iter().zip(got) {
            for (&j, share) in js.iter().zip(words.chunks_exact(n)) {
                let c = col(j);
                let sum = sums
                    .entry(j)
                    .or_insert_with(|| data[n * c..n * (c + 1)].iter().map(|x| x.to_f64()).collect());
                for (s, &w) in sum.iter_mut().zip(share) {
                    *s += f64::from_bits(w);
                }
            }
        }
        for (j, sum) in sums {
            let c = col(j);
            for (x, s) in data[n * c..n * (c + 1)].iter_mut().zip(sum) {
                *x = T::from_f64(s);
            }
        }
    }

    /// The sums this root sends.
    pub(crate) fn sum_messages<T: Real>(
        &self,
        n: usize,
        col: &impl Fn(usize) -> usize,
        data: &[T],
    ) -> Vec<(usize, Vec<u64>)> {
        pack(&self.sums_out, n, col, data)
    }

    /// Writes the sums received (in the order of `sums_in`) into `data`.
    pub(crate) fn set_sums<T: Real>(
        &self,
        n: usize,
        col: &impl Fn(usize) -> usize,
        got: &[(usize, Vec<u64>)],
        data: &mut [T],
    ) {
        for ((_, js), (_, words)) in self.sums_in.iter().zip(got) {
            for (&j, sum) in js.iter().zip(words.chunks_exact(n)) {
                let c = col(j);
                for (x, &w) in data[n * c..n * (c + 1)].iter_mut().zip(sum) {
                    *x = T::from_f64(f64::from_bits(w));
                }
            }
        }
    }

    /// One evaluation's sum: box `j`'s column is `col(j)` of `data` (`n`
    /// values each); on return the ranks that need a box hold its sum.
    /// Returns the bytes sent. Only the ranks in the plan talk.
    pub(crate) fn sum<C: Communicator, T: Real>(
        &self,
        comm: &C,
        n: usize,
        col: impl Fn(usize) -> usize,
        data: &mut [T],
    ) -> u64 {
        if self.is_empty() {
            return 0;
        }
        let from: Vec<usize> = self.shares_in.iter().map(|(r, _)| *r).collect();
        let send = self.share_messages(n, &col, data);
        let (got, mut bytes) = planned_exchange(comm, &send, &from, TAG_SHARES);
        self.add_shares(n, &col, &got, data);
        let from: Vec<usize> = self.sums_in.iter().map(|(r, _)| *r).collect();
        let send = self.sum_messages(n, &col, data);
        let (got, b) = planned_exchange(comm, &send, &from, TAG_SUMS);
        bytes += b;
        self.set_sums(n, &col, &got, data);
        bytes
    }
}

/// The columns of `lists`' boxes, one message per rank.
fn pack<T: Real>(
    lists: &Lists,
    n: usize,
    col: &impl Fn(usize) -> usize,
    data: &[T],
) -> Vec<(usize, Vec<u64>)> {
    lists
        .iter()
        .map(|(r, js)| {
            let words = js
                .iter()
                .flat_map(|&j| {
                    let c = col(j);
                    data[n * c..n * (c + 1)].iter().map(|x| x.to_f64().to_bits())
                })
                .collect();
            (*r, words)
        })
        .collect()
}
