//! Moving `u64` words between ranks: a personalised all-to-all (for the
//! sort, where every rank may send to every other) and a sparse exchange
//! (for balance and ghosts, where each rank talks to a few neighbours).
//!
//! The sparse exchange sends data point to point: each rank first learns
//! how many words every rank will send it (an all-to-all of one integer per
//! pair, `R` integers per rank), then posts non-blocking sends to its
//! destinations and blocking receives from exactly the ranks that announced
//! data. No payload goes to a rank that does not need it.

use mpi::datatype::{Partition, PartitionMut};
use mpi::request::scope;
use mpi::traits::*;

/// Counts and displacements (in words) of `buckets`.
pub(crate) fn layout(counts: &[usize]) -> (Vec<i32>, Vec<i32>) {
    let c: Vec<i32> = counts.iter().map(|&n| n as i32).collect();
    let d: Vec<i32> = c
        .iter()
        .scan(0i32, |s, &n| {
            let d = *s;
            *s += n;
            Some(d)
        })
        .collect();
    (c, d)
}

/// Personalised all-to-all: `send[r]` goes to rank `r`; returns what every
/// rank sent to this one, concatenated in rank order, the number of words
/// from each rank, and the bytes sent to other ranks.
pub(crate) fn all_to_all<C: Communicator>(
    comm: &C,
    send: &[Vec<u64>],
) -> (Vec<u64>, Vec<usize>, u64) {
    let me = comm.rank() as usize;
    let counts: Vec<usize> = send.iter().map(Vec::len).collect();
    let mut recv_counts = vec![0usize; counts.len()];
    let c64: Vec<u64> = counts.iter().map(|&n| n as u64).collect();
    let mut r64 = vec![0u64; counts.len()];
    comm.all_to_all_into(&c64[..], &mut r64[..]);
    for (r, &n) in recv_counts.iter_mut().zip(&r64) {
        *r = n as usize;
    }
    let flat: Vec<u64> = send.concat();
    let (sc, sd) = layout(&counts);
    let (rc, rd) = layout(&recv_counts);
    let mut recv = vec![0u64; recv_counts.iter().sum()];
    {
        let sp = Partition::new(&flat[..], sc, sd);
        let mut rp = PartitionMut::new(&mut recv[..], rc, rd);
        comm.all_to_all_varcount_into(&sp, &mut rp);
    }
    let bytes = counts
        .iter()
        .enumerate()
        .filter(|&(r, _)| r != me)
        .map(|(_, &n)| 8 * n as u64)
        .sum();
    (recv, recv_counts, bytes)
}

/// Sparse point-to-point exchange: `send` holds `(rank, words)` for the
/// ranks this one sends to (at most one entry per rank; none to itself).
/// Returns `(rank, words)` for every rank that sent here, in rank order,
/// and the bytes sent. A collective: every rank must call it.
pub(crate) fn sparse_exchange<C: Communicator>(
    comm: &C,
    send: &[(usize, Vec<u64>)],
    tag: i32,
) -> (Vec<(usize, Vec<u64>)>, u64) {
    let size = comm.size() as usize;
    let mut counts = vec![0u64; size];
    for (r, w) in send {
        counts[*r] = w.len() as u64 + 1;
    }
    let mut incoming = vec![0u64; size];
    comm.all_to_all_into(&counts[..], &mut incoming[..]);
    let from: Vec<usize> = (0..size).filter(|&r| incoming[r] > 0).collect();
    planned_exchange(comm, send, &from, tag)
}

/// Point-to-point exchange whose pattern both sides already know (a plan
/// made once): `send` holds `(rank, words)` for the ranks this one sends
/// to, `from` the ranks that send here. Returns `(rank, words)` in the
/// order of `from`, and the bytes sent. Not a collective: only the ranks
/// in the plan talk, and no counts are exchanged.
pub(crate) fn planned_exchange<C: Communicator>(
    comm: &C,
    send: &[(usize, Vec<u64>)],
    from: &[usize],
    tag: i32,
) -> (Vec<(usize, Vec<u64>)>, u64) {
    let mut received = Vec::with_capacity(from.len());
    scope(|sc| {
        let requests: Vec<_> = send
            .iter()
            .map(|(r, w)| {
                comm.process_at_rank(*r as i32)
                    .immediate_send_with_tag(sc, &w[..], tag)
            })
            .collect();
        for &r in from {
            let (words, _) = comm
                .process_at_rank(r as i32)
                .receive_vec_with_tag::<u64>(tag);
            received.push((r, words));
        }
        for q in requests {
            q.wait();
        }
    });
    let bytes = send.iter().map(|(_, w)| 8 * w.len() as u64).sum();
    (received, bytes)
}
