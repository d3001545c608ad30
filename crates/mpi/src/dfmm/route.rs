//! Charges from where the user holds them to where the points live, and
//! values back: each rank passes its charges in its own input order and
//! gets its results in that order, while the FMM works on the points the
//! tree build moved along the Morton curve (each with its global id).
//!
//! Made once: each owner tells each origin rank which of its input points
//! it holds (one personalised all-to-all of ids). Each evaluation: one
//! all-to-all of charges (origin to owner) and one of values (owner to
//! origin), `8 nq` bytes a point's charges and `8 w` its result. This traffic grows with
//! the number of points a rank holds, not with the surface of its range:
//! a solver that keeps its vectors in the tree's order avoids it
//! ([`super::DistributedFmm::evaluate_sorted`]).
//!
//! With separate targets there are two routings: the sources' for the
//! charges and the targets' for the values.

use ferrofmm_kernels::Real;
use mpi::traits::*;

use crate::exchange::all_to_all;

/// The routing of one rank (see the [module docs](self)).
#[derive(Debug)]
pub(crate) struct Route {
    /// Per origin rank: this rank's points (tree order) that came from it,
    /// in the order they travel.
    by_origin: Vec<Vec<usize>>,
    /// Per owner rank: the input points of this rank it holds, in the
    /// order they travel.
    by_owner: Vec<Vec<usize>>,
    /// Points of this rank's input.
    pub(crate) n_input: usize,
    /// Bytes sent while making the routing.
    pub(crate) setup_bytes: u64,
}

impl Route {
    /// Makes the routing of the points whose global ids this rank holds in
    /// tree order (`ids`; `input_counts`: how many points each rank gave,
    /// which numbers the ids). A collective.
    pub(crate) fn make<C: Communicator>(comm: &C, ids: &[u64], input_counts: &[u64]) -> Self {
        let size = comm.size() as usize;
        let me = comm.rank() as usize;
        let mut first = Vec::with_capacity(size + 1);
        first.push(0u64);
        for &c in input_counts {
            first.push(first.last().copied().unwrap_or(0) + c);
        }
        let mut by_origin = vec![Vec::new(); size];
        let mut ask = vec![Vec::new(); size];
        for (k, &id) in ids.iter().enumerate() {
            let s = first
                .partition_point(|&f| f <= id)
                .saturating_sub(1)
                .min(size - 1);
            by_origin[s].push(k);
            ask[s].push(id - first[s]);
        }
        let (recv, counts, setup_bytes) = all_to_all(comm, &ask);
        let mut by_owner = Vec::with_capacity(size);
        let mut at = 0;
        for c in counts {
            by_owner.push(recv[at..at + c].iter().map(|&i| i as usize).collect());
            at += c;
        }
        Route {
            by_origin,
            by_owner,
            n_input: input_counts.get(me).copied().unwrap_or(0) as usize,
            setup_bytes,
        }
    }

    /// This rank's charges (input order, `nq` values per point) to the
    /// owners: returns the charges of this rank's points in tree order, and
    /// the bytes sent.
    pub(crate) fn charges_in<C: Communicator, T: Real>(
        &self,
        comm: &C,
        charges: &[T],
        nq: usize,
        n_owned: usize,
    ) -> (Vec<T>, u64) {
        move_values(comm, charges, nq, &self.by_owner, &self.by_origin, n_owned)
    }

    /// Values of this rank's points (tree order, `w` each) back to their
    /// origins: returns the values of this rank's input points (input
    /// order), and the bytes sent.
    pub(crate) fn values_out<C: Communicator, T: Real>(
        &self,
        comm: &C,
        values: &[T],
        w: usize,
    ) -> (Vec<T>, u64) {
        move_values(
            comm,
            values,
            w,
            &self.by_origin,
            &self.by_owner,
            self.n_input,
        )
    }
}

/// One all-to-all of `w` values per item: rank `r` gets the items
/// `send[r]` of `values` (in that order), and the items received from rank
/// `r` land at `place[r]` of a vector of `n_out` items. Returns it and the
/// bytes sent.
fn move_values<C: Communicator, T: Real>(
    comm: &C,
    values: &[T],
    w: usize,
    send: &[Vec<usize>],
    place: &[Vec<usize>],
    n_out: usize,
) -> (Vec<T>, u64) {
    let send: Vec<Vec<u64>> = send
        .iter()
        .map(|items| {
            items
                .iter()
                .flat_map(|&i| values[w * i..w * (i + 1)].iter())
                .map(|x| x.to_f64().to_bits())
                .collect()
        })
        .collect();
    let (recv, _, bytes) = all_to_all(comm, &send);
    let mut out = vec![T::ZERO; w * n_out];
    for (&k, chunk) in place.iter().flatten().zip(recv.chunks_exact(w)) {
        for (o, &x) in out[w * k..w * (k + 1)].iter_mut().zip(chunk) {
            *o = T::from_f64(f64::from_bits(x));
        }
    }
    (out, bytes)
}
