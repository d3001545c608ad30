//! Which data travel between which ranks at each evaluation, worked out
//! once (with the ghost points' coordinates) when the FMM is built.
//!
//! A box `A` of rank `s` that appears in the lists of a box of rank `r`:
//!
//! * in a V list (M2L) or a W list (M2P): `r` needs `A`'s multipole, `n`
//!   values, each evaluation;
//! * in a U list (P2P) or an X list (P2L): `A` is a leaf and `r` needs its
//!   points: coordinates (with their Morton codes) once, here, and
//!   charges each evaluation.
//!
//! Setup: `r` asks each owner for the boxes it needs (a sparse exchange:
//! only the owners are asked); each owner answers with the points of the
//! leaves asked for and remembers what to send to whom. At each evaluation
//! each rank sends every requester one message, the multipoles of the
//! boxes it asked for followed by the charges of the points it asked for,
//! in an order both sides know: point to point, no counts, no collective.

use std::collections::BTreeMap;
use std::ops::Range;

use ferrofmm_kernels::Real;
use ferrofmm_tree::MortonKey;
use mpi::traits::*;

use super::local_tree::{Kind, range_of};
use crate::DistributedTree;
use crate::exchange::{planned_exchange, sparse_exchange};
use crate::partition::owners;

const TAG_ASK: i32 = 31;
const TAG_POINTS: i32 = 32;
const TAG_EVAL: i32 = 33;

/// What this rank sends one other rank at each evaluation.
#[derive(Debug)]
struct SendTo {
    rank: usize,
    /// Boxes (skeleton indices) whose multipoles go.
    boxes: Vec<usize>,
    /// Ranges of this rank's points whose charges go.
    points: Vec<Range<usize>>,
}

/// What this rank receives from one other rank at each evaluation.
#[derive(Debug)]
struct RecvFrom {
    rank: usize,
    /// Boxes (skeleton indices) whose multipoles come.
    boxes: Vec<usize>,
    /// The ghost points whose charges come.
    points: Range<usize>,
}

/// The exchange plan of one rank and the ghost points it received.
#[derive(Debug, Default)]
pub(crate) struct GhostPlan {
    send: Vec<SendTo>,
    recv: Vec<RecvFrom>,
    /// Morton codes of the ghost points.
    pub(crate) codes: Vec<u64>,
    /// Their coordinates, interleaved.
    pub(crate) coords: Vec<f64>,
    /// Bytes sent while making the plan.
    pub(crate) setup_bytes: u64,
}

/// Per requesting rank: boxes needing multipoles, leaves needing points.
type Needs = BTreeMap<usize, (Vec<usize>, Vec<usize>)>;

/// The foreign boxes this rank's lists reference, by owner.
fn needs(dtree: &DistributedTree, kinds: &[Kind], me: usize) -> Result<Needs, String> {
    let l = &dtree.ghosts.lists;
    let sk = &dtree.ghosts.skeleton;
    let mut mult = vec![false; kinds.len()];
    let mut pts = vec![false; kinds.len()];
    for (b, _) in kinds.iter().enumerate().filter(|(_, k)| **k == Kind::Own) {
        for (csr, flag) in [(&l.v, 0), (&l.w, 0), (&l.u, 1), (&l.x, 1)] {
            for &a in csr.get(b) {
                if kinds[a] == Kind::Foreign {
                    if flag == 0 {
                        mult[a] = true;
                    } else {
                        pts[a] = true;
                    }
                }
            }
        }
    }
    let mut out: Needs = BTreeMap::new();
    for a in 0..kinds.len() {
        if !(mult[a] || pts[a]) {
            continue;
        }
        let owner = owners(&dtree.cuts, sk[a].morton_range())
            .find(|&r| r != me)
            .ok_or_else(|| format!("no owner for ghost box {:?}", sk[a]))?;
        let entry = out.entry(owner).or_default();
        if mult[a] {
            entry.0.push(a);
        }
        if pts[a] {
            entry.1.push(a);
        }
    }
    Ok(out)
}

/// The skeleton index of `key` (sorted by level, then key).
fn index_of(sk: &[MortonKey], key: MortonKey) -> Option<usize> {
    sk.binary_search_by_key(&(key.level(), key), |k| (k.level(), *k))
        .ok()
}

impl GhostPlan {
    /// Makes the plan (a collective). `kinds` classifies the skeleton boxes.
    pub(crate) fn make<C: Communicator>(
        comm: &C,
        dtree: &DistributedTree,
        kinds: &[Kind],
    ) -> Result<Self, String> {
        let me = comm.rank() as usize;
        let sk = &dtree.ghosts.skeleton;
        // Errors are carried to the end: every rank must reach both exchanges.
        let (needs, mut error) = match needs(dtree, kinds, me) {
            Ok(n) => (n, None),
            Err(e) => (Needs::new(), Some(e)),
        };
        let ask: Vec<(usize, Vec<u64>)> = needs
            .iter()
            .map(|(&r, (m, p))| {
                let mut w = vec![m.len() as u64];
                w.extend(m.iter().chain(p).map(|&a| sk[a].raw()));
                (r, w)
            })
            .collect();
        let (asked, mut bytes) = sparse_exchange(comm, &ask, TAG_ASK);

        let codes = &dtree.points.codes;
        let coords = &dtree.points.coords;
        let mut send = Vec::with_capacity(asked.len());
        let mut answers = Vec::with_capacity(asked.len());
        for (r, words) in asked {
            let m = words.first().copied().unwrap_or(0) as usize;
            let keys = words.get(1..).unwrap_or(&[]);
            let mut to = SendTo {
                rank: r,
                boxes: Vec::new(),
                points: Vec::new(),
            };
            let mut answer = Vec::new();
            for (i, &raw) in keys.iter().enumerate() {
                let found = MortonKey::from_raw(raw).and_then(|k| Some((k, index_of(sk, k)?)));
                let Some((key, b)) = found.filter(|&(_, b)| kinds[b] == Kind::Own) else {
                    error.get_or_insert_with(|| format!("rank {r} asked for a box not here"));
                    continue;
                };
                if i < m {
                    to.boxes.push(b);
                } else {
                    let range = range_of(codes, key);
                    answer.push(range.len() as u64);
                    for k in range.clone() {
                        answer.push(codes[k]);
                        answer.extend(coords[3 * k..3 * k + 3].iter().map(|x| x.to_bits()));
                    }
                    to.points.push(range);
                }
            }
            send.push(to);
            answers.push((r, answer));
        }
        let (got, b) = sparse_exchange(comm, &answers, TAG_POINTS);
        bytes += b;

        let mut plan = GhostPlan {
            send,
            setup_bytes: bytes,
            ..GhostPlan::default()
        };
        for (s, words) in got {
            let Some((m, p)) = needs.get(&s) else {
                error.get_or_insert_with(|| format!("unexpected answer from rank {s}"));
                continue;
            };
            let first = plan.codes.len();
            let mut w = words.iter().copied();
            for _ in p {
                let count = w.next().unwrap_or(0) as usize;
                for _ in 0..count {
                    let mut take = || w.next().unwrap_or(0);
                    plan.codes.push(take());
                    for _ in 0..3 {
                        plan.coords.push(f64::from_bits(take()));
                    }
                }
            }
            plan.recv.push(RecvFrom {
                rank: s,
                boxes: m.clone(),
                points: first..plan.codes.len(),
            });
        }
        match error {
            Some(e) => Err(e),
            None => Ok(plan),
        }
    }

    /// Number of ghost points.
    pub(crate) fn n_points(&self) -> usize {
        self.codes.len()
    }

    /// Ranks this one sends to and receives from at each evaluation.
    pub(crate) fn partners(&self) -> (usize, usize) {
        (self.send.len(), self.recv.len())
    }

    /// One evaluation's exchange: sends the multipoles (`n` per box, in
    /// `multipoles`) and this rank's charges (`own_charges`, `nq` values
    /// per point) that others asked for; writes the multipoles received
    /// into `multipoles` and the ghost points' charges into
    /// `ghost_charges` (`nq` per ghost point). Returns the bytes sent.
    pub(crate) fn exchange<C: Communicator, T: Real>(
        &self,
        comm: &C,
        n: usize,
        nq: usize,
        multipoles: &mut [T],
        own_charges: &[T],
        ghost_charges: &mut [T],
    ) -> u64 {
        let bits = |x: &T| x.to_f64().to_bits();
        let send: Vec<(usize, Vec<u64>)> = self
            .send
            .iter()
            .map(|to| {
                let mut w = Vec::new();
                for &b in &to.boxes {
                    w.extend(multipoles[n * b..n * (b + 1)].iter().map(bits));
                }
                for r in &to.points {
                    w.extend(own_charges[nq * r.start..nq * r.end].iter().map(bits));
                }
                (to.rank, w)
            })
            .collect();
        let from: Vec<usize> = self.recv.iter().map(|r| r.rank).collect();
        let (got, bytes) = planned_exchange(comm, &send, &from, TAG_EVAL);
        for (rf, (_, words)) in self.recv.iter().zip(got) {
            let mut w = words.into_iter().map(|x| T::from_f64(f64::from_bits(x)));
            for &b in &rf.boxes {
                for x in &mut multipoles[n * b..n * (b + 1)] {
                    *x = w.next().unwrap_or(T::ZERO);
                }
            }
            for q in &mut ghost_charges[nq * rf.points.start..nq * rf.points.end] {
                *q = w.next().unwrap_or(T::ZERO);
            }
        }
        bytes
    }
}
