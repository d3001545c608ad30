//! A model of the coarse sums' traffic on many ranks (not a test of the
//! code's behaviour; run by hand):
//!
//! ```sh
//! cargo test -p ferrofmm-mpi --lib coarse_sums_model -- --ignored --nocapture
//! ```
//!
//! A uniform tree of depth `D` (every box of levels `0..=D`, leaves at `D`)
//! cut into `R` about equal ranges at leaf boundaries; the roles of
//! `dfmm/coarse_plan.rs` on it (no X or W lists in a uniform tree):
//!
//! * check of coarse `C`: shares from the owner of every non-coarse box in
//!   `V(C)` and from `C`'s root if `V(C)` holds coarse boxes; the sum to
//!   `C`'s other owners;
//! * multipole of coarse `C`: needed by the owner of every non-coarse box
//!   in `V(C)` and the root of every coarse box in `V(C)` (V is symmetric
//!   on one level); if anyone needs it, shares from `C`'s other owners to
//!   its root and the sum to the ranks that need it.
//!
//! Prints, per rank, the boxes and messages sent and received (max and
//! mean over ranks) against the `all_reduce`'s vector (every coarse box).

use ferrofmm_tree::{DEEPEST_LEVEL, MortonKey};

use crate::partition::straddling;

/// The first and last rank whose range meets `key`.
fn span(cuts: &[u64], key: MortonKey) -> (u32, u32) {
    let r = key.morton_range();
    let first = cuts.partition_point(|&c| c <= r.start) - 1;
    let last = cuts.partition_point(|&c| c < r.end) - 1;
    (first as u32, last as u32)
}

/// V list of `key` in a uniform tree.
fn v_list(key: MortonKey) -> Vec<MortonKey> {
    if key.level() < 2 {
        return Vec::new();
    }
    key.parent()
        .colleagues()
        .into_iter()
        .flat_map(|p| p.children())
        .filter(|a| !key.is_adjacent(*a))
        .collect()
}

/// Per rank: boxes and messages (distinct partners per round) out and in.
#[derive(Default)]
struct Tally {
    boxes_out: Vec<u64>,
    boxes_in: Vec<u64>,
    msgs_out: Vec<u64>,
    msgs_in: Vec<u64>,
}

impl Tally {
    fn new(ranks: usize) -> Self {
        Tally {
            boxes_out: vec![0; ranks],
            boxes_in: vec![0; ranks],
            msgs_out: vec![0; ranks],
            msgs_in: vec![0; ranks],
        }
    }

    /// One round: `pairs` holds `(from, to)` once per box sent.
    fn round(&mut self, mut pairs: Vec<(u32, u32)>) {
        for &(f, t) in &pairs {
            self.boxes_out[f as usize] += 1;
            self.boxes_in[t as usize] += 1;
        }
        pairs.sort_unstable();
        pairs.dedup();
        for &(f, t) in &pairs {
            self.msgs_out[f as usize] += 1;
            self.msgs_in[t as usize] += 1;
        }
    }

    fn line(&self, what: &str, box_bytes: f64) -> String {
        let stat = |v: &[u64]| {
            let max = v.iter().copied().max().unwrap_or(0) as f64;
            let mean = v.iter().sum::<u64>() as f64 / v.len() as f64;
            (max, mean)
        };
        let (bo, bom) = stat(&self.boxes_out);
        let (bi, bim) = stat(&self.boxes_in);
        let (mo, mom) = stat(&self.msgs_out);
        let (mi, mim) = stat(&self.msgs_in);
        let kb = |b: f64| b * box_bytes / 1e3;
        format!(
            "  {what}: KB out max {:.1} mean {:.1}, in max {:.1} mean {:.1}; \
             messages out max {mo} mean {mom:.1}, in max {mi} mean {mim:.1}",
            kb(bo),
            kb(bom),
            kb(bi),
            kb(bim)
        )
    }
}

fn model(ranks: usize, depth: u32, box_bytes: f64) {
    let leaves = 1u64 << (3 * depth);
    let unit = 1u64 << (3 * (DEEPEST_LEVEL - depth));
    // Equal ranges moved by up to half a range (a hash of the rank): cuts
    // off the boundaries of coarse boxes, as cuts at leaf quantiles are.
    let share = leaves / ranks as u64;
    let cuts: Vec<u64> = (0..=ranks as u64)
        .map(|r| {
            let shift = if r == 0 || r == ranks as u64 {
                0
            } else {
                (r * 2_654_435_761) % (share / 2).max(1)
            };
            (r * share + shift) * unit
        })
        .collect();
    let mut coarse: Vec<MortonKey> = cuts.iter().flat_map(|&c| straddling(c)).collect();
    coarse.sort_unstable_by_key(|k| (k.level(), *k));
    coarse.dedup();
    let (mut checks, mut multipoles) = (Tally::new(ranks), Tally::new(ranks));
    let (mut m_shares, mut m_sums) = (Vec::new(), Vec::new());
    let mut levels = 0;
    for level in 0..depth {
        let (mut c_shares, mut c_sums) = (Vec::new(), Vec::new());
        for &c in coarse.iter().filter(|k| k.level() == level) {
            let (root, last) = span(&cuts, c);
            let (mut sharing, mut needing) = (Vec::new(), Vec::new());
            let mut coarse_in_v = false;
            for a in v_list(c) {
                let (f, l) = span(&cuts, a);
                if f == l {
                    sharing.push(f);
                    needing.push(f);
                } else {
                    coarse_in_v = true;
                    needing.push(f);
                }
            }
            if coarse_in_v {
                sharing.push(root);
            }
            for v in [&mut sharing, &mut needing] {
                v.sort_unstable();
                v.dedup();
            }
            c_shares.extend(sharing.iter().filter(|&&s| s != root).map(|&s| (s, root)));
            if !sharing.is_empty() {
                c_sums.extend((root + 1..=last).map(|o| (root, o)));
            }
            if !needing.is_empty() {
                m_shares.extend((root + 1..=last).map(|o| (o, root)));
                m_sums.extend(needing.iter().filter(|&&n| n != root).map(|&n| (root, n)));
            }
        }
        if !c_shares.is_empty() || !c_sums.is_empty() {
            levels += 1;
        }
        checks.round(c_shares);
        checks.round(c_sums);
    }
    multipoles.round(m_shares);
    multipoles.round(m_sums);
    println!(
        "R = {ranks}, depth {depth}: {} coarse boxes (all_reduce vector {:.1} MB per sum), \
         check rounds {} (2 per level with checks)",
        coarse.len(),
        coarse.len() as f64 * box_bytes / 1e6,
        2 * levels
    );
    println!("{}", multipoles.line("multipoles", box_bytes));
    println!("{}", checks.line("checks", box_bytes));
}

#[test]
#[ignore = "a model, run by hand with --nocapture"]
fn coarse_sums_model() {
    // 8 n bytes a box: n = 6 (p - 1)^2 + 2 = 152 at order 6.
    let box_bytes = 8.0 * 152.0;
    for (ranks, depth) in [(4, 5), (16, 4), (256, 8), (4096, 8), (65_536, 9)] {
        model(ranks, depth, box_bytes);
    }
}
