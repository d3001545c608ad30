//! Pre-pass: the occupancy of the adaptive tree for any leaf size,
//! simulated from the points' Morton codes.

// The parent's imports and the sibling modules' items (one namespace,
// split by job).
#[allow(unused_imports)]
use super::*;

/// A fast mixer for Morton keys (the std SipHash is several times slower,
/// and no attacker chooses these keys). SplitMix64's finaliser: every input
/// bit reaches the low bits the table indexes with.
#[derive(Default)]
pub(super) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(self.0 ^ b as u64);
        }
    }
    fn write_u64(&mut self, x: u64) {
        let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        self.0 = z ^ (z >> 31);
    }
}

pub(super) type KeyMap = HashMap<u64, u32, BuildHasherDefault<KeyHasher>>;

/// A box of a simulated tree: its level and integer coordinates on that
/// level's grid (cheaper to step to neighbours than Morton keys).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Cell {
    pub(super) level: u32,
    pub(super) c: [u32; 3],
}

impl Cell {
    const ROOT: Cell = Cell {
        level: 0,
        c: [0; 3],
    };

    pub(super) fn level(self) -> u32 {
        self.level
    }

    /// Key in the level's lookup table (21 bits per coordinate).
    pub(super) fn raw(self) -> u64 {
        self.c[0] as u64 | (self.c[1] as u64) << 21 | (self.c[2] as u64) << 42
    }

    /// The same-level box at `offset`, if inside the domain.
    pub(super) fn neighbour(self, offset: [i32; 3]) -> Option<Cell> {
        let n = 1i64 << self.level;
        let mut c = [0u32; 3];
        for a in 0..3 {
            let x = self.c[a] as i64 + offset[a] as i64;
            if x < 0 || x >= n {
                return None;
            }
            c[a] = x as u32;
        }
        Some(Cell {
            level: self.level,
            c,
        })
    }

    /// The 8 children in octant order (bit 0: upper half in `x`, bit 1 in
    /// `y`, bit 2 in `z`, as Morton digits and `MortonKey::octant`).
    pub(super) fn children(self) -> [Cell; 8] {
        std::array::from_fn(|d| Cell {
            level: self.level + 1,
            c: [
                2 * self.c[0] + (d & 1) as u32,
                2 * self.c[1] + ((d >> 1) & 1) as u32,
                2 * self.c[2] + ((d >> 2) & 1) as u32,
            ],
        })
    }

    pub(super) fn octant(self) -> usize {
        (self.c[0] & 1) as usize | ((self.c[1] & 1) as usize) << 1 | ((self.c[2] & 1) as usize) << 2
    }

    pub(super) fn ancestor(self, level: u32) -> Cell {
        let up = self.level - level;
        Cell {
            level,
            c: self.c.map(|x| x >> up),
        }
    }

    pub(super) fn parent(self) -> Cell {
        self.ancestor(self.level - 1)
    }

    /// Whether the closed boxes touch (or overlap).
    pub(super) fn is_adjacent(self, other: Cell) -> bool {
        let d = DEEPEST_LEVEL;
        (0..3).all(|a| {
            let (s0, s1) = (1u64 << (d - self.level), 1u64 << (d - other.level));
            let (lo0, lo1) = (self.c[a] as u64 * s0, other.c[a] as u64 * s1);
            lo0 <= lo1 + s1 && lo1 <= lo0 + s0
        })
    }

    pub(super) fn center_ratio(self, domain: &Domain) -> f64 {
        let h = domain.width / (1u64 << (self.level + 1)) as f64;
        let r2: f64 = (0..3)
            .map(|a| {
                let x = domain.origin[a] + (2 * self.c[a] + 1) as f64 * h;
                x * x
            })
            .sum();
        r2.sqrt() / h
    }
}

/// A box of a simulated tree: key and point ranges in the sorted codes.
pub(super) type SimNode = (Cell, [usize; 2], [usize; 2]);

/// One level of a simulated adaptive tree.
#[derive(Default)]
pub(super) struct SimLevel {
    pub(super) keys: Vec<Cell>,
    pub(super) sources: Vec<[usize; 2]>,
    pub(super) targets: Vec<[usize; 2]>,
    /// Octants of the existing children (0 for a leaf).
    pub(super) masks: Vec<u8>,
    pub(super) index: KeyMap,
}

impl SimLevel {
    pub(super) fn find(&self, key: Cell) -> Option<usize> {
        self.index.get(&key.raw()).map(|&i| i as usize)
    }

    pub(super) fn push(&mut self, node: SimNode) -> usize {
        let i = self.keys.len();
        self.index.insert(node.0.raw(), i as u32);
        self.keys.push(node.0);
        self.sources.push(node.1);
        self.targets.push(node.2);
        self.masks.push(0);
        i
    }

    pub(super) fn n_sources(&self, i: usize) -> usize {
        self.sources[i][1] - self.sources[i][0]
    }

    pub(super) fn n_targets(&self, i: usize) -> usize {
        self.targets[i][1] - self.targets[i][0]
    }
}

/// The box with `key` in simulated `levels`: `(level, index)`.
pub(super) fn sim_find(levels: &[SimLevel], key: Cell) -> Option<(usize, usize)> {
    let l = key.level() as usize;
    levels.get(l)?.find(key).map(|i| (l, i))
}

/// The 27 offsets of a box's neighbourhood (itself at index 13).
pub(super) fn offsets() -> impl Iterator<Item = [i32; 3]> {
    (0..27).map(|i| [i % 3 - 1, (i / 3) % 3 - 1, i / 9 - 1])
}

/// `NONADJ[o][i]`: mask of the children `j` of the neighbour at offset `o`
/// (index into [`offsets`]) of a parent that are not adjacent to its child
/// `i`, i.e. the V-list candidates. Octant bit 0 is `x`, 1 is `y`, 2 is `z`.
pub(super) fn non_adjacent_masks() -> [[u8; 8]; 27] {
    let mut out = [[0u8; 8]; 27];
    for (oi, o) in offsets().enumerate() {
        for (i, row) in out[oi].iter_mut().enumerate() {
            for j in 0..8usize {
                let far = (0..3).any(|a| {
                    let ci = ((i >> a) & 1) as i32;
                    let cj = ((j >> a) & 1) as i32;
                    (2 * o[a] + cj - ci).abs() >= 2
                });
                if far {
                    *row |= 1 << j;
                }
            }
        }
    }
    out
}

/// Leaves (and split parents) per level whose work is counted exactly; a
/// level with more is estimated from an evenly spaced sample of this many
/// (in Morton order, so every region is represented).
pub(super) const MAX_SAMPLED_LEAVES: usize = 2048;

/// Items per rayon task in the simulation (small levels run on one thread).
pub(super) const MIN_PARALLEL: usize = 512;

/// `ADJ[o]`: mask of the children of the same-level neighbour at offset `o`
/// (index into [`offsets`]) of a box that touch the box.
pub(super) fn adjacent_child_masks() -> [u8; 27] {
    let mut out = [0u8; 27];
    for (oi, o) in offsets().enumerate() {
        for j in 0..8usize {
            if (0..3).all(|a| {
                let cj = ((j >> a) & 1) as i32;
                (-1..=2).contains(&(2 * o[a] + cj))
            }) {
                out[oi] |= 1 << j;
            }
        }
    }
    out
}

/// The point distribution as sorted Morton codes: enough to simulate the
/// adaptive, 2:1-balanced refinement for any leaf size and count its work
/// ([`Occupancy::work`]) without building a tree, at a fraction of the
/// cost of building one.
///
/// ```
/// use ferrofmm_fmm::Geometry;
/// use ferrofmm_fmm::tuning::Occupancy;
/// let points: Vec<f64> = Geometry::Cube.points(20_000, 1);
/// let occ = Occupancy::new(&points, None, None, 19).unwrap();
/// let coarse = occ.work(400);
/// let fine = occ.work(32);
/// assert!(fine.n_boxes > coarse.n_boxes);
/// assert!(fine.p2p_pairs < coarse.p2p_pairs);
/// ```
pub struct Occupancy {
    domain: Domain,
    sources: Vec<u64>,
    targets: Option<Vec<u64>>,
    max_level: u32,
}

impl Occupancy {
    /// Morton codes (deepest level) of the sources and, when different, the
    /// targets, in the bounding cube of both (or `domain`), sorted.
    /// `max_level` is the deepest level a box may have.
    pub fn new(
        sources: &[f64],
        targets: Option<&[f64]>,
        domain: Option<Domain>,
        max_level: u32,
    ) -> Result<Self, FmmError> {
        let domain = match domain {
            Some(d) => d,
            None => match targets {
                Some(t) => Domain::from_points(&[sources, t])?,
                None => Domain::from_points(&[sources])?,
            },
        };
        let codes = |p: &[f64]| {
            let mut c: Vec<u64> = p
                .par_chunks_exact(3)
                .map(|x| MortonKey::from_point([x[0], x[1], x[2]], &domain, DEEPEST_LEVEL).morton())
                .collect();
            c.par_sort_unstable();
            c
        };
        Ok(Occupancy {
            domain,
            sources: codes(sources),
            targets: targets.map(codes),
            max_level: max_level.min(DEEPEST_LEVEL),
        })
    }

    /// Number of sources.
    pub fn n_sources(&self) -> usize {
        self.sources.len()
    }

    /// Number of targets.
    pub fn n_targets(&self) -> usize {
        self.targets.as_ref().map_or(self.sources.len(), Vec::len)
    }

    /// Size of a box for the refinement rule: `max(#sources, #targets)`.
    pub(super) fn count(&self, n: &SimNode) -> usize {
        let s = n.1[1] - n.1[0];
        if self.targets.is_some() {
            s.max(n.2[1] - n.2[0])
        } else {
            s
        }
    }

    /// The non-empty children of a box.
    pub(super) fn split(&self, n: &SimNode) -> impl Iterator<Item = SimNode> + use<> {
        let level = n.0.level();
        let shift = 3 * (DEEPEST_LEVEL - level - 1);
        let digit = |c: u64| ((c >> shift) & 7) as usize;
        let bounds = |codes: &[u64], r: [usize; 2]| {
            let s = &codes[r[0]..r[1]];
            let mut b = [r[0]; 9];
            for (d, slot) in b.iter_mut().enumerate().skip(1) {
                *slot = r[0] + s.partition_point(|&c| digit(c) < d);
            }
            b[8] = r[1];
            b
        };
        let bs = bounds(&self.sources, n.1);
        let bt = match &self.targets {
            Some(t) => bounds(t, n.2),
            None => bs,
        };
        n.0.children()
            .into_iter()
            .enumerate()
            .filter(move |&(d, _)| bs[d] < bs[d + 1] || bt[d] < bt[d + 1])
            .map(move |(d, k)| (k, [bs[d], bs[d + 1]], [bt[d], bt[d + 1]]))
    }

    /// The adaptive refinement for `leaf_size` (before balancing), level by
    /// level, without the lookup tables.
    pub(super) fn refine(&self, leaf_size: usize) -> Vec<SimLevel> {
        let mut levels: Vec<SimLevel> = Vec::new();
        let mut current: Vec<SimNode> =
            vec![(Cell::ROOT, [0, self.sources.len()], [0, self.n_targets()])];
        loop {
            let level = levels.len() as u32;
            let children: Vec<(u32, SimNode)> = current
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .enumerate()
                .filter(|(_, n)| self.count(n) > leaf_size && level < self.max_level)
                .flat_map_iter(|(i, n)| self.split(n).map(move |c| (i as u32, c)))
                .collect();
            let mut lv = SimLevel {
                masks: vec![0; current.len()],
                ..Default::default()
            };
            for &(i, c) in &children {
                lv.masks[i as usize] |= 1 << c.0.octant();
            }
            lv.keys = current.iter().map(|n| n.0).collect();
            lv.sources = current.iter().map(|n| n.1).collect();
            lv.targets = current.iter().map(|n| n.2).collect();
            levels.push(lv);
            if children.is_empty() {
                break;
            }
            current = children.into_iter().map(|(_, c)| c).collect();
        }
        levels
    }

    /// The refinement for `leaf_size`, 2:1 balanced with the rule of
    /// `ferrofmm_tree::balance` (a leaf adjacent to an internal box one
    /// level deeper is split), with lookup tables.
    pub(super) fn balanced(&self, mut levels: Vec<SimLevel>) -> Vec<SimLevel> {
        levels.par_iter_mut().for_each(|lv| {
            lv.index.reserve(lv.keys.len());
            for (i, k) in lv.keys.iter().enumerate() {
                lv.index.insert(k.raw(), i as u32);
            }
        });
        self.balance(&mut levels);
        levels
    }

    /// Ripple the 2:1 balance to a fixed point.
    pub(super) fn balance(&self, levels: &mut Vec<SimLevel>) {
        let adj = adjacent_child_masks();
        let depth = levels.len();
        let mut candidates: Vec<(usize, usize)> = levels
            .iter()
            .enumerate()
            .take(depth.saturating_sub(2))
            .flat_map(|(l, lv)| {
                (0..lv.keys.len())
                    .filter(|&i| lv.masks[i] == 0)
                    .map(move |i| (l, i))
            })
            .collect();
        while !candidates.is_empty() {
            let lv: &[SimLevel] = levels;
            let mut violators: Vec<(usize, usize)> = candidates
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .copied()
                .filter(|&(l, i)| lv[l].masks[i] == 0 && violates(lv, l, i, &adj))
                .collect();
            violators.sort_unstable();
            violators.dedup();
            let mut next = Vec::new();
            for &(l, i) in &violators {
                let node = (
                    levels[l].keys[i],
                    levels[l].sources[i],
                    levels[l].targets[i],
                );
                let children: Vec<SimNode> = self.split(&node).collect();
                if levels.len() == l + 1 {
                    levels.push(SimLevel::default());
                }
                let mut mask = 0u8;
                for c in children {
                    mask |= 1 << c.0.octant();
                    let j = levels[l + 1].push(c);
                    next.push((l + 1, j));
                }
                levels[l].masks[i] = mask;
                // Leaves one level coarser and adjacent to the new internal box.
                if l >= 1 {
                    for o in offsets() {
                        if let Some(nk) = node.0.neighbour(o)
                            && let Some(j) = levels[l - 1].find(nk.parent())
                            && levels[l - 1].masks[j] == 0
                        {
                            next.push((l - 1, j));
                        }
                    }
                }
            }
            next.sort_unstable();
            next.dedup();
            candidates = next;
        }
    }

    /// Estimated [`WorkCounts`] of the tree built with `leaf_size`, counted
    /// on the simulated 2:1-balanced tree: U-, W- and X-list work by walking
    /// each leaf's neighbourhood as the interaction lists do, V-list pairs
    /// from the child masks of adjacent parents. Close to the real tree's
    /// counts (within a few percent for uniform points, within about 20% for
    /// strongly clustered ones; the differences come from boxes holding
    /// only sources or only targets and from balancing details).
    pub fn work(&self, leaf_size: usize) -> WorkCounts {
        self.work_of(self.refine(leaf_size.max(1)))
    }

    /// [`Occupancy::work`] of a refinement.
    pub(super) fn work_of(&self, refined: Vec<SimLevel>) -> WorkCounts {
        let levels = self.balanced(refined);
        let nonadj = non_adjacent_masks();
        let adj = adjacent_child_masks();
        let depth = (levels.len() - 1) as u32;
        let n_boxes: usize = levels.iter().map(|l| l.keys.len()).sum();
        let n_leaves: usize = levels
            .iter()
            .map(|l| l.masks.iter().filter(|&&m| m == 0).count())
            .sum();
        let m2l_boxes: usize = levels.iter().skip(2).map(|l| l.keys.len()).sum();

        // V-list pairs, counted from the parents' level.
        let mut m2l_pairs = 0.0;
        for parents in levels.iter().skip(1) {
            let split: Vec<usize> = (0..parents.keys.len())
                .filter(|&i| parents.masks[i] != 0)
                .collect();
            let stride = split.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = split.iter().step_by(stride).copied().collect();
            let scale = split.len() as f64 / sampled.len().max(1) as f64;
            m2l_pairs += scale
                * sampled
                    .par_iter()
                    .with_min_len(MIN_PARALLEL)
                    .map(|&i| {
                        let mp = parents.masks[i];
                        let mut pairs = 0u32;
                        for (oi, o) in offsets().enumerate() {
                            let Some(q) = parents.keys[i].neighbour(o) else {
                                continue;
                            };
                            let Some(j) = parents.find(q) else {
                                continue;
                            };
                            let mq = parents.masks[j];
                            if mq == 0 {
                                continue;
                            }
                            for (c, &far) in nonadj[oi].iter().enumerate() {
                                if mp & (1 << c) != 0 {
                                    pairs += (far & mq).count_ones();
                                }
                            }
                        }
                        pairs as f64
                    })
                    .sum::<f64>();
        }

        // U (P2P) and W/X (M2P/P2L) work, per leaf.
        let (mut p2p_pairs, mut far_points, mut u_entries) = (0.0, 0.0, 0.0);
        for (l, lv) in levels.iter().enumerate() {
            let leaves: Vec<usize> = (0..lv.keys.len()).filter(|&i| lv.masks[i] == 0).collect();
            // A level with many leaves is estimated from an evenly spaced
            // sample of them (Morton order, so all regions are represented).
            let stride = leaves.len().div_ceil(MAX_SAMPLED_LEAVES).max(1);
            let sampled: Vec<usize> = leaves.iter().step_by(stride).copied().collect();
            if sampled.is_empty() {
                continue;
            }
            let scale = leaves.len() as f64 / sampled.len() as f64;
            let (p, f, u) = sampled
                .par_iter()
                .with_min_len(MIN_PARALLEL)
                .map_init(Vec::new, |stack, &i| leaf_work(&levels, l, i, &adj, stack))
                .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
            p2p_pairs += scale * p;
            far_points += scale * f;
            u_entries += scale * u;
        }

        WorkCounts {
            n_sources: self.n_sources(),
            n_targets: self.n_targets(),
            depth,
            n_boxes,
            n_leaves,
            m2l_boxes,
            p2p_pairs,
            m2l_pairs,
            far_points,
            u_entries,
            rounding_ratio: levels
                .iter()
                .flat_map(|lv| lv.keys.iter().zip(&lv.masks))
                .filter(|&(_, &m)| m == 0)
                .map(|(&k, _)| k.center_ratio(&self.domain))
                .fold(0.0, f64::max),
        }
    }
}

/// `|center| / half-width` of a box.
pub(super) fn center_ratio(key: MortonKey, domain: &Domain) -> f64 {
    let c = key.center(domain);
    (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / key.half_width(domain)
}

/// Whether leaf `(l, i)` is adjacent to an internal box one level deeper.
pub(super) fn violates(levels: &[SimLevel], l: usize, i: usize, adj: &[u8; 27]) -> bool {
    if l + 2 >= levels.len() {
        return false;
    }
    let key = levels[l].keys[i];
    offsets().enumerate().any(|(oi, o)| {
        if oi == 13 {
            return false;
        }
        let Some(nk) = key.neighbour(o) else {
            return false;
        };
        let Some(j) = levels[l].find(nk) else {
            return false;
        };
        let touching = levels[l].masks[j] & adj[oi];
        touching != 0
            && nk.children().into_iter().enumerate().any(|(c, ck)| {
                touching & (1 << c) != 0
                    && levels[l + 1]
                        .find(ck)
                        .is_some_and(|m| levels[l + 1].masks[m] != 0)
            })
    })
}

/// `(P2P pairs, far points, U-list entries)` of leaf `(l, i)`: its
/// targets times the sources of its U list, for every W-list box `a` its
/// targets (M2P) plus, for the matching X-list entry of `a`, its sources
/// (P2L), and the length of its U list.
///
/// The children of an internal colleague that touch the leaf are U-list
/// leaves (2:1 balance: a box one level deeper touching a leaf is a leaf;
/// deeper ones are still walked), the others are its W list.
pub(super) fn leaf_work(
    levels: &[SimLevel],
    l: usize,
    i: usize,
    adj: &[u8; 27],
    stack: &mut Vec<(usize, usize)>,
) -> (f64, f64, f64) {
    let lv = &levels[l];
    let key = lv.keys[i];
    let nt = lv.n_targets(i) as f64;
    let ns_self = lv.n_sources(i) as f64;
    let mut u_sources = 0.0;
    let mut u_entries = 0u32;
    let mut w_boxes = 0u32;
    let mut coarse: [(usize, usize); 8] = [(usize::MAX, 0); 8];
    let mut n_coarse = 0;
    for (oi, o) in offsets().enumerate() {
        let Some(nk) = key.neighbour(o) else {
            continue;
        };
        if let Some(j) = lv.find(nk) {
            let mask = lv.masks[j];
            if mask == 0 {
                u_sources += lv.n_sources(j) as f64;
                u_entries += 1;
                continue;
            }
            w_boxes += (mask & !adj[oi]).count_ones();
            let touching = mask & adj[oi];
            for (c, ck) in nk.children().into_iter().enumerate() {
                if touching & (1 << c) == 0 {
                    continue;
                }
                let Some(b) = levels[l + 1].find(ck) else {
                    continue;
                };
                if levels[l + 1].masks[b] == 0 {
                    u_sources += levels[l + 1].n_sources(b) as f64;
                    u_entries += 1;
                    continue;
                }
                // Not balanced here (never after `balance`): walk deeper.
                stack.clear();
                stack.push((l + 1, b));
                while let Some((m, a)) = stack.pop() {
                    let mask = levels[m].masks[a];
                    for (c, ck) in levels[m].keys[a].children().into_iter().enumerate() {
                        if mask & (1 << c) == 0 {
                            continue;
                        }
                        let Some(b) = levels[m + 1].find(ck) else {
                            continue;
                        };
                        if !ck.is_adjacent(key) {
                            w_boxes += 1;
                        } else if levels[m + 1].masks[b] == 0 {
                            u_sources += levels[m + 1].n_sources(b) as f64;
                            u_entries += 1;
                        } else {
                            stack.push((m + 1, b));
                        }
                    }
                }
            }
            continue;
        }
        // Covered by a coarser leaf (U), or empty.
        for up in (0..l).rev() {
            let Some((m, a)) = sim_find(levels, nk.ancestor(up as u32)) else {
                continue;
            };
            if levels[m].masks[a] == 0 && !coarse[..n_coarse].contains(&(m, a)) {
                if n_coarse < coarse.len() {
                    coarse[n_coarse] = (m, a);
                    n_coarse += 1;
                }
                u_sources += levels[m].n_sources(a) as f64;
                u_entries += 1;
            }
            break;
        }
    }
    (
        nt * u_sources,
        w_boxes as f64 * (nt + ns_self),
        u_entries as f64,
    )
}
