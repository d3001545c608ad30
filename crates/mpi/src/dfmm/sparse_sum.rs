//! A sum over ranks of some coarse boxes' columns, sent only between the
//! ranks that hold a share and the ranks that need the sum, through one
//! root per box (see `dfmm/coarse_plan.rs` for who is who).
//!
//! # Setup (two sparse exchanges)
//!
//! 1. Each rank tells the root of every box it has a share of, or needs,
//!    which (one word per box: its position in the coarse list and two
//!    flags).
//! 2. Each root answers each rank that registered: which of its shares to
//!    send (those of boxes someone needs: nobody reads the coarsest boxes'
//!    multipoles, so their many owners send nothing) and which sums will
//!    come (those of boxes someone has a share of: a sum nobody contributes
//!    to is zero, and the zeros the needing rank holds already are that
//!    sum).
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

/// Messages: (rank, words).
type Messages = Vec<(usize, Vec<u64>)>;

/// A root's part of the plan (step 2 of the setup).
#[derive(Debug, Default)]
pub(crate) struct Rooted {
    /// The shares it receives: (rank, boxes), rank order.
    shares_in: Lists,
    /// The sums it sends: (rank, boxes), rank order.
    sums_out: Lists,
    /// Its answers: the boxes each needing rank will get.
    answers: Messages,
}

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
/// of the boxes it has a share of or needs (one word `4 j + 2 need +
/// share` per box).
pub(crate) fn registrations(me: usize, roots: &[usize], roles: &[Role]) -> Messages {
    let mut words: BTreeMap<usize, Vec<u64>> = BTreeMap::new();
    for (j, (&root, role)) in roots.iter().zip(roles).enumerate() {
        if root != me && (role.share || role.need) {
            let word = 4 * j as u64 + 2 * u64::from(role.need) + u64::from(role.share);
            words.entry(root).or_default().push(word);
        }
    }
    words.into_iter().collect()
}

/// Step 2 of the setup, on a root: from the registrations received (rank
/// order) and this rank's own roles, the shares it receives (of boxes
/// someone needs), the sums it sends (of boxes someone has a share of) and
/// the answers telling each rank which (word `2 j` for "send your share of
/// box `j`", `2 j + 1` for "its sum comes").
pub(crate) fn as_root(
    me: usize,
    roots: &[usize],
    roles: &[Role],
    registered: &[(usize, Vec<u64>)],
) -> Result<Rooted, String> {
    let mine = |f: fn(&Role) -> bool| -> Vec<bool> {
        roots
            .iter()
            .zip(roles)
            .map(|(&r, role)| r == me && f(role))
            .collect()
    };
    let (mut has_share, mut has_need) = (mine(|r| r.share), mine(|r| r.need));
    let mut asked = Vec::with_capacity(registered.len());
    for (rank, words) in registered {
        let (mut s, mut n) = (Vec::new(), Vec::new());
        for &w in words {
            let j = (w / 4) as usize;
            if roots.get(j) != Some(&me) {
                return Err(format!(
                    "rank {rank} registered coarse box {j} with rank {me}, not its root"
                ));
            }
            if w & 1 == 1 {
                has_share[j] = true;
                s.push(j);
            }
            if w & 2 == 2 {
                has_need[j] = true;
                n.push(j);
            }
        }
        asked.push((*rank, s, n));
    }
    let mut rooted = Rooted::default();
    for (rank, s, n) in asked {
        let s: Vec<usize> = s.into_iter().filter(|&j| has_need[j]).collect();
        let n: Vec<usize> = n.into_iter().filter(|&j| has_share[j]).collect();
        let words: Vec<u64> = s
            .iter()
            .map(|&j| 2 * j as u64)
            .chain(n.iter().map(|&j| 2 * j as u64 + 1))
            .collect();
        if !s.is_empty() {
            rooted.shares_in.push((rank, s));
        }
        if !n.is_empty() {
            rooted.sums_out.push((rank, n));
        }
        if !words.is_empty() {
            rooted.answers.push((rank, words));
        }
    }
    Ok(rooted)
}

/// Step 3 of the setup: from the roots' answers, the shares this rank
/// sends and the sums it receives (in the roots' order of boxes).
pub(crate) fn from_answers(answers: Messages) -> (Lists, Lists) {
    let (mut shares_out, mut sums_in) = (Lists::new(), Lists::new());
    for (root, words) in answers {
        let pick = |bit: u64| -> Vec<usize> {
            words
                .iter()
                .filter(|&&w| w % 2 == bit)
                .map(|&w| (w / 2) as usize)
                .collect()
        };
        let (s, n) = (pick(0), pick(1));
        if !s.is_empty() {
            shares_out.push((root, s));
        }
        if !n.is_empty() {
            sums_in.push((root, n));
        }
    }
    (shares_out, sums_in)
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
        let register = registrations(me, roots, roles);
        let (registered, mut bytes) = sparse_exchange(comm, &register, TAG_REGISTER);
        // Errors are carried to the end: every rank must reach both exchanges.
        let (rooted, error) = match as_root(me, roots, roles, &registered) {
            Ok(r) => (r, None),
            Err(e) => (Rooted::default(), Some(e)),
        };
        let (got, b) = sparse_exchange(comm, &rooted.answers, TAG_REPLY);
        bytes += b;
        let (shares_out, sums_in) = from_answers(got);
        let plan = SparseSum {
            shares_out,
            shares_in: rooted.shares_in,
            sums_out: rooted.sums_out,
            sums_in,
        };
        (error.map_or(Ok(plan), Err), bytes)
    }

    /// The part of the plan for the boxes `keep` selects (both sides of
    /// every pair select the same boxes, so the parts still match).
    pub(crate) fn restrict(&self, keep: impl Fn(usize) -> bool) -> Self {
        let part = |lists: &Lists| -> Lists {
            lists
                .iter()
                .map(|(r, js)| {
                    (
                        *r,
                        js.iter().copied().filter(|&j| keep(j)).collect::<Vec<_>>(),
                    )
                })
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

    /// Boxes this rank sends as shares, receives as shares (a root), sends
    /// as sums (a root) and receives as sums, counted once per message.
    #[cfg(test)]
    pub(crate) fn box_counts(&self) -> [usize; 4] {
        let count = |l: &Lists| l.iter().map(|(_, js)| js.len()).sum();
        [
            count(&self.shares_out),
            count(&self.shares_in),
            count(&self.sums_out),
            count(&self.sums_in),
        ]
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
                let sum = sums.entry(j).or_insert_with(|| {
                    data[n * c..n * (c + 1)]
                        .iter()
                        .map(|x| x.to_f64())
                        .collect()
                });
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
                    data[n * c..n * (c + 1)]
                        .iter()
                        .map(|x| x.to_f64().to_bits())
                })
                .collect();
            (*r, words)
        })
        .collect()
}

/// The plans of `roles.len()` ranks made in memory, with the messages of
/// [`SparseSum::make`] delivered by hand (for tests).
#[cfg(test)]
pub(crate) fn simulate_plans(roots: &[usize], roles: &[Vec<Role>]) -> Vec<SparseSum> {
    let ranks = roles.len();
    let deliver = |out: Vec<Vec<(usize, Vec<u64>)>>| {
        let mut inbox: Vec<Vec<(usize, Vec<u64>)>> = vec![Vec::new(); ranks];
        for (from, msgs) in out.into_iter().enumerate() {
            for (to, words) in msgs {
                inbox[to].push((from, words));
            }
        }
        inbox
    };
    let registered = deliver(
        (0..ranks)
            .map(|me| registrations(me, roots, &roles[me]))
            .collect(),
    );
    let rooted: Vec<_> = (0..ranks)
        .map(|me| as_root(me, roots, &roles[me], &registered[me]).expect("valid registrations"))
        .collect();
    let answers = deliver(rooted.iter().map(|r| r.answers.clone()).collect());
    rooted
        .into_iter()
        .zip(answers)
        .map(|(rooted, got)| {
            let (shares_out, sums_in) = from_answers(got);
            SparseSum {
                shares_out,
                shares_in: rooted.shares_in,
                sums_out: rooted.sums_out,
                sums_in,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One evaluation's two rounds, in memory; returns the bytes each rank sent.
    fn run(plans: &[SparseSum], n: usize, data: &mut [Vec<f64>]) -> Vec<u64> {
        let col = |j: usize| j;
        let ranks = plans.len();
        let mut bytes = vec![0u64; ranks];
        for round in 0..2 {
            let mut inbox: Vec<Vec<(usize, Vec<u64>)>> = vec![Vec::new(); ranks];
            for (r, plan) in plans.iter().enumerate() {
                let out = if round == 0 {
                    plan.share_messages(n, &col, &data[r])
                } else {
                    plan.sum_messages(n, &col, &data[r])
                };
                for (to, words) in out {
                    bytes[r] += 8 * words.len() as u64;
                    inbox[to].push((r, words));
                }
            }
            for (r, plan) in plans.iter().enumerate() {
                // Delivered in the order the plan expects.
                let order = if round == 0 {
                    &plan.shares_in
                } else {
                    &plan.sums_in
                };
                let got: Vec<(usize, Vec<u64>)> = order
                    .iter()
                    .map(|(s, _)| {
                        let i = inbox[r]
                            .iter()
                            .position(|(f, _)| f == s)
                            .expect("a message");
                        inbox[r].swap_remove(i)
                    })
                    .collect();
                assert!(inbox[r].is_empty(), "rank {r} got an unplanned message");
                if round == 0 {
                    plan.add_shares(n, &col, &got, &mut data[r]);
                } else {
                    plan.set_sums(n, &col, &got, &mut data[r]);
                }
            }
        }
        bytes
    }

    /// Roles from a small hash: about a third of the ranks hold a share of
    /// a box, a third need it, the root may do either.
    fn layout(ranks: usize, boxes: usize) -> (Vec<usize>, Vec<Vec<Role>>) {
        let h = |r: usize, j: usize, s: usize| (r * 7919 + j * 104_729 + s * 31).is_multiple_of(3);
        let roots = (0..boxes).map(|j| (5 * j) % ranks).collect();
        let roles = (0..ranks)
            .map(|r| {
                (0..boxes)
                    .map(|j| Role {
                        share: h(r, j, 1),
                        need: h(r, j, 2),
                    })
                    .collect()
            })
            .collect();
        (roots, roles)
    }

    #[test]
    fn every_rank_that_needs_a_box_gets_the_sum_of_all_shares() {
        let (ranks, boxes, n) = (7, 23, 3);
        let (roots, roles) = layout(ranks, boxes);
        let plans = simulate_plans(&roots, &roles);
        // A share is (rank + 1) * 10^j-ish; where there is no share, zero.
        let value = |r: usize, j: usize, k: usize| ((r + 1) * 1000 + j * 10 + k) as f64;
        let mut data: Vec<Vec<f64>> = (0..ranks)
            .map(|r| {
                (0..boxes * n)
                    .map(|i| {
                        if roles[r][i / n].share {
                            value(r, i / n, i % n)
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let bytes = run(&plans, n, &mut data);
        for j in 0..boxes {
            for k in 0..n {
                let sum: f64 = (0..ranks)
                    .filter(|&r| roles[r][j].share)
                    .map(|r| value(r, j, k))
                    .sum();
                for r in (0..ranks).filter(|&r| roles[r][j].need) {
                    assert_eq!(data[r][n * j + k], sum, "rank {r}, box {j}");
                }
            }
        }
        // Each rank sends its shares of boxes rooted elsewhere and, as a
        // root, one sum per needing rank of a box with a share.
        for r in 0..ranks {
            let shares = (0..boxes)
                .filter(|&j| roles[r][j].share && roots[j] != r)
                .count();
            let sums: usize = (0..boxes)
                .filter(|&j| roots[j] == r && (0..ranks).any(|s| roles[s][j].share))
                .map(|j| (0..ranks).filter(|&s| s != r && roles[s][j].need).count())
                .sum();
            assert_eq!(bytes[r], 8 * (n * (shares + sums)) as u64, "rank {r}");
        }
    }

    #[test]
    fn no_share_means_no_message() {
        let (ranks, boxes) = (4, 5);
        let roots = vec![0, 1, 2, 3, 0];
        let mut roles = vec![vec![Role::default(); boxes]; ranks];
        for role in &mut roles {
            role[2].need = true; // nobody holds a share of box 2
        }
        roles[3][4] = Role {
            share: true,
            need: false,
        };
        roles[1][4].need = true;
        roles[2][3].share = true; // nobody needs box 3
        let plans = simulate_plans(&roots, &roles);
        assert_eq!(plans[3].shares_out, vec![(0, vec![4])]);
        assert_eq!(plans[0].shares_in, vec![(3, vec![4])]);
        assert_eq!(plans[0].sums_out, vec![(1, vec![4])]);
        assert_eq!(plans[1].sums_in, vec![(0, vec![4])]);
        assert!(plans[2].is_empty());
        // Boxes 2 and 3 travel nowhere: box 2's sum is the zeros every rank
        // holds, and nobody reads box 3's.
        assert!(
            plans
                .iter()
                .all(|p| p.restrict(|j| j == 2 || j == 3).is_empty())
        );
    }

    #[test]
    fn a_registration_sent_to_the_wrong_root_is_an_error() {
        let roots = vec![1, 0];
        let registered = vec![(1, vec![4 + 1])];
        assert!(as_root(1, &roots, &[Role::default(); 2], &registered).is_err());
    }
}
