//! The FFT scheme's level in pieces whose source spectra fit a budget.
//!
//! A level's products need the spectrum of every source group its target
//! groups read. Held for the whole level at once they take
//! `16 N^2 (floor(N/2) + 1)` bytes per source box: about 230 KB per
//! sibling group at `p = 8`, 7.5 GB for the 32,768 groups of a uniform
//! level 6 (1e8 points), more than everything else of the run together.
//! So [`plan_chunks`] cuts the level's target groups, in their (Morton)
//! order, into runs whose source groups together number at most
//! `max_groups`, and [`FftM2l::apply`](super::FftM2l) transforms the source
//! groups of one run, applies the run's products and moves on.
//!
//! A run of `C` target groups in Morton order is close to a cube of
//! `C` parents, and reads the parents' neighbours as well: about
//! `(C^(1/3) + 2)^3` source groups, so a source group on a run's border is
//! transformed once for each run that reads it. With the default budget
//! ([`SPECTRA_BUDGET_BYTES`], about a thousand groups at `p = 8`) a run
//! holds some 600 target groups and the forward transforms are done about
//! 1.8 times where one pass would do. Measured (uniform cube, p = 8, 2
//! threads): one pass of forward transforms is about 28% of the M2L at 1e6
//! points (0.35 s with the whole level, 2.9 s when every target group
//! transforms its own sources), yet at 1e8, where the level is cut into
//! runs, the M2L took 8.4x the time of 1e7 for 10x the points: the repeats
//! do not show, and the memory no longer grows with the level. The
//! products of each target group are the same whichever run it is in, so
//! the result does not depend on the budget (bit for bit).

use std::ops::Range;

use crate::siblings::SiblingBlocks;

/// Bytes of source spectra [`FftM2l::apply`](super::FftM2l) holds at once
/// (at least one target group's sources, whatever the budget).
pub const SPECTRA_BUDGET_BYTES: usize = 256 << 20;

/// A run of target groups and the source groups it reads.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(super) struct Chunk {
    /// Consecutive target groups.
    pub targets: Range<usize>,
    /// The distinct source groups they read, ascending.
    pub sources: Vec<u32>,
}

/// The level's target groups cut into runs, in order, each reading at most
/// `max_groups` source groups (a run of one target group may read more).
/// Target groups that read nothing join the run they fall in.
pub(super) fn plan_chunks(siblings: &SiblingBlocks, max_groups: usize) -> Vec<Chunk> {
    let n = siblings.n_target_groups();
    // `seen[s]`: one more than the index of the last run that took source
    // group `s` (0: none yet).
    let mut seen = vec![0u32; siblings.n_source_groups()];
    let mut chunks = Vec::new();
    let mut sources: Vec<u32> = Vec::new();
    let mut start = 0;
    let mut g = 0;
    while g < n {
        let mark = chunks.len() as u32 + 1;
        let new: Vec<u32> = {
            let mut new = Vec::new();
            for s in siblings.source_groups(g) {
                if seen[s] != mark {
                    seen[s] = mark;
                    new.push(s as u32);
                }
            }
            new
        };
        if g > start && sources.len() + new.len() > max_groups {
            // Close the run before `g`; `g` opens the next one (its marks
            // belong to the closed run, so they are recounted).
            for &s in &new {
                seen[s as usize] = 0;
            }
            sources.sort_unstable();
            chunks.push(Chunk {
                targets: start..g,
                sources: std::mem::take(&mut sources),
            });
            start = g;
            continue;
        }
        sources.extend(new);
        g += 1;
    }
    if start < n {
        sources.sort_unstable();
        chunks.push(Chunk {
            targets: start..n,
            sources,
        });
    }
    chunks
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{M2lInteractions, transfer_vector_index};

    /// V-list pairs of every box of a uniform level of `side^3` boxes,
    /// columns in Morton order (sibling slots are the columns).
    fn uniform_level(side: i32) -> M2lInteractions {
        let morton = |p: [i32; 3]| {
            let mut k = 0usize;
            for bit in 0..8 {
                for (d, &c) in p.iter().enumerate() {
                    k |= (((c >> bit) & 1) as usize) << (3 * bit + d);
                }
            }
            k
        };
        let mut pairs = Vec::new();
        let boxes =
            (0..side).flat_map(|x| (0..side).flat_map(move |y| (0..side).map(move |z| [x, y, z])));
        for t in boxes.clone() {
            for s in boxes.clone() {
                let v = [s[0] - t[0], s[1] - t[1], s[2] - t[2]];
                let parents_near = (0..3).all(|d| (s[d] / 2 - t[d] / 2).abs() <= 1);
                if parents_near && transfer_vector_index(v).is_some() {
                    pairs.push((morton(t), morton(s), v));
                }
            }
        }
        let n = (side * side * side) as usize;
        M2lInteractions::new(n, n, &pairs)
    }

    #[test]
    fn runs_cover_the_level_once_and_keep_to_the_budget() {
        let inter = uniform_level(8);
        let sib = inter.sibling_blocks();
        for max in [1, 27, 30, 64, 1000] {
            let chunks = plan_chunks(sib, max);
            // Consecutive and complete.
            let mut next = 0;
            for c in &chunks {
                assert_eq!(c.targets.start, next);
                assert!(!c.targets.is_empty());
                next = c.targets.end;
                let mut want: Vec<u32> = c
                    .targets
                    .clone()
                    .flat_map(|g| sib.source_groups(g))
                    .map(|s| s as u32)
                    .collect();
                want.sort_unstable();
                want.dedup();
                assert_eq!(c.sources, want, "budget {max}");
                assert!(
                    c.sources.len() <= max || c.targets.len() == 1,
                    "budget {max}"
                );
            }
            assert_eq!(next, sib.n_target_groups());
        }
        // A budget of the whole level is one run; a tight one is several.
        assert_eq!(plan_chunks(sib, usize::MAX).len(), 1);
        assert!(plan_chunks(sib, 27).len() > 4);
    }
}
