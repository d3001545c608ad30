//! Distributed 2:1 balance, with the tree crate's balance on every rank.
//!
//! The balance of [`ferrofmm_tree::balance`] splits a leaf `L` of level `l`
//! when an **internal** box of level `l + 1` is adjacent to it, until no
//! leaf does; every split is forced, so the result is the least balanced
//! refinement, a unique tree. Across ranks the only missing information is
//! which boxes of *other* ranks are internal. So each round:
//!
//! 1. every rank sends each of its internal boxes `X` that it has not sent
//!    before to the ranks whose ranges meet one of `X`'s 26 same-level
//!    neighbours (a leaf adjacent to `X` overlaps one of them): counts by
//!    one all-to-all of integers, the boxes point to point;
//! 2. every rank inserts the boxes it received as internal boxes
//!    ([`TreeShape::insert_internal`]) and runs the tree crate's balance
//!    ([`TreeShape::balance`]), which splits its own leaves only;
//! 3. an `all_reduce` of "did my tree change" decides whether to go on.
//!
//! When no rank changes in a round, every rank has seen every internal box
//! adjacent to its leaves (all were sent at the start of the round) and
//! none of its leaves violates the condition: the union is balanced. Every
//! split was forced by an internal box that exists, so the union is the
//! least balanced refinement, the single-machine tree. Rounds are few: a
//! split propagates at most one rank boundary per round.

use ferrofmm_tree::{MortonCodes, MortonKey, TreeShape};
use mpi::collective::SystemOperation;
use mpi::traits::*;

use crate::exchange::sparse_exchange;
use crate::partition::owners;

const TAG: i32 = 11;

/// Internal boxes of `shape` lying in the codes `[lo, hi)`, sorted.
fn own_internal(shape: &TreeShape, lo: u64, hi: u64) -> Vec<MortonKey> {
    let mut out: Vec<MortonKey> = (0..shape.n_levels())
        .flat_map(|l| shape.level(l))
        .filter(|b| {
            let r = b.key.morton_range();
            !b.leaf && lo <= r.start && r.end <= hi
        })
        .map(|b| b.key)
        .collect();
    out.sort_unstable();
    out
}

/// Balances the rank's piece `shape` (refined from `codes`, the range
/// `cuts[rank] .. cuts[rank + 1]`) against all others (see the
/// [module docs](self)). Returns the rounds and the bytes sent.
pub fn balance_distributed<C: Communicator>(
    comm: &C,
    shape: &mut TreeShape,
    codes: &MortonCodes,
    cuts: &[u64],
) -> (usize, u64) {
    let me = comm.rank() as usize;
    let size = comm.size() as usize;
    let (lo, hi) = (cuts[me], cuts[me + 1]);
    let mut sent: Vec<MortonKey> = Vec::new();
    let mut bytes = 0;
    let mut rounds = 0;
    loop {
        rounds += 1;
        let internal = own_internal(shape, lo, hi);
        let mut out: Vec<Vec<u64>> = vec![Vec::new(); size];
        for &x in internal.iter().filter(|x| sent.binary_search(x).is_err()) {
            let mut dest: Vec<usize> = x
                .colleagues()
                .into_iter()
                .flat_map(|n| owners(cuts, n.morton_range()))
                .filter(|&r| r != me)
                .collect();
            dest.sort_unstable();
            dest.dedup();
            for r in dest {
                out[r].push(x.raw());
            }
        }
        let send: Vec<(usize, Vec<u64>)> = out
            .into_iter()
            .enumerate()
            .filter(|(_, w)| !w.is_empty())
            .collect();
        let (received, b) = sparse_exchange(comm, &send, TAG);
        bytes += b;
        let foreign: Vec<MortonKey> = received
            .iter()
            .flat_map(|(_, w)| w.iter().filter_map(|&r| MortonKey::from_raw(r)))
            .collect();
        shape.insert_internal(codes, &foreign);
        let before = shape.n_boxes();
        shape.balance(codes);
        let changed = u8::from(shape.n_boxes() != before);
        let mut any = 0u8;
        comm.all_reduce_into(&changed, &mut any, SystemOperation::max());
        sent = internal;
        if any == 0 {
            return (rounds, bytes);
        }
    }
}
