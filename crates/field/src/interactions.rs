//! Transfer vectors and the grouped V-list interactions of one level.

use std::ops::Range;
use std::sync::OnceLock;

use rayon::prelude::*;

use crate::FieldError;
use crate::siblings::{SiblingBlocks, block_vector};

/// Number of distinct M2L transfer vectors: `7^3 - 3^3 = 316`.
pub const N_TRANSFER_VECTORS: usize = 316;

/// The 316 transfer vectors `v` (integer, `|v_i| <= 3`, `max |v_i| >= 2`)
/// in their fixed index order (lexicographic, `x` slowest). A scheme's
/// per-vector operators are stored in this order.
///
/// ```
/// use ferrofmm_field::{transfer_vector_index, transfer_vectors};
/// let vs = transfer_vectors();
/// assert_eq!(vs.len(), 316);
/// for (i, v) in vs.iter().enumerate() {
///     assert_eq!(transfer_vector_index(*v), Some(i));
/// }
/// assert_eq!(transfer_vector_index([1, 1, 0]), None); // a neighbour, not a V-list vector
/// ```
pub fn transfer_vectors() -> Vec<[i32; 3]> {
    let mut out = Vec::with_capacity(N_TRANSFER_VECTORS);
    for x in -3..=3i32 {
        for y in -3..=3i32 {
            for z in -3..=3i32 {
                if x.abs().max(y.abs()).max(z.abs()) >= 2 {
                    out.push([x, y, z]);
                }
            }
        }
    }
    out
}

/// Index of `v` in [`transfer_vectors`], `None` when `v` is not a V-list
/// transfer vector.
pub fn transfer_vector_index(v: [i32; 3]) -> Option<usize> {
    if v.iter().any(|c| c.abs() > 3) || v.iter().all(|c| c.abs() <= 1) {
        return None;
    }
    let flat = |a: [i32; 3]| ((a[0] + 3) * 49 + (a[1] + 3) * 7 + (a[2] + 3)) as usize;
    let f = flat(v);
    // Number of excluded (|.| <= 1 everywhere) vectors before v in the
    // lexicographic order of the 7^3 cube.
    let mut excluded = 0usize;
    for x in -1..=1i32 {
        for y in -1..=1i32 {
            for z in -1..=1i32 {
                if flat([x, y, z]) < f {
                    excluded += 1;
                }
            }
        }
    }
    Some(f - excluded)
}

/// A block of consecutive target columns processed by one task.
#[derive(Clone, Debug)]
struct Chunk {
    target_start: usize,
    target_end: usize,
    group_start: usize,
    group_end: usize,
}

/// All pairs of one chunk sharing one transfer vector.
#[derive(Clone, Debug)]
struct Group {
    vector: u16,
    pair_start: usize,
    pair_end: usize,
}

/// The V-list (M2L) interactions of one tree level, grouped for batched
/// application.
///
/// Built from pairs `(t, s, v)`: target column `t` (its downward check
/// potential) receives `M2L_v * multipole[:, s]`, where `v = (center_s -
/// center_t) / box_width` is the integer transfer vector
/// (`|v_i| <= 3`, `max_i |v_i| >= 2`). The target columns are cut into
/// contiguous chunks (one rayon task each, so tasks never write the same
/// column), and inside a chunk the pairs are grouped by transfer vector so
/// that a scheme applies each vector's operator with one matrix-matrix
/// product over all of the chunk's pairs that share it.
///
/// ```
/// use ferrofmm_field::M2lInteractions;
/// let pairs = [(0, 1, [2, 0, 0]), (1, 0, [-2, 0, 0]), (0, 2, [0, 3, -1])];
/// let inter = M2lInteractions::new(2, 3, &pairs);
/// assert_eq!(inter.len(), 3);
/// assert!(!inter.is_empty());
/// ```
#[derive(Clone, Debug)]
pub struct M2lInteractions {
    n_target_cols: usize,
    n_source_cols: usize,
    /// Target columns per chunk (the last may have fewer).
    chunk_size: usize,
    /// Number of pairs (kept when the pair lists are released).
    n_pairs: usize,
    /// The grouped pairs; after [`M2lInteractions::release_pairs`] made
    /// again from the sibling blocks on first use.
    pairs: OnceLock<PairLists>,
    /// The pairs regrouped by parent, made on first use.
    siblings: OnceLock<SiblingBlocks>,
    /// Sibling slot (`8 group + octant`) of each target and source column,
    /// when given ([`M2lInteractions::with_sibling_slots`]).
    slots: Option<(Vec<u32>, Vec<u32>)>,
}

/// The pairs of an [`M2lInteractions`] in chunks of target columns,
/// grouped by transfer vector within each chunk.
#[derive(Clone, Debug)]
struct PairLists {
    chunks: Vec<Chunk>,
    groups: Vec<Group>,
    sources: Vec<u32>,
    /// Target column relative to its chunk's first column.
    local_targets: Vec<u32>,
}

impl PairLists {
    fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(&self.chunks[..])
            + size_of_val(&self.groups[..])
            + size_of_val(&self.sources[..])
            + size_of_val(&self.local_targets[..])
    }
}

impl M2lInteractions {
    /// Group `pairs` with an automatic chunk size (about four chunks per
    /// rayon thread, 32 to 256 target columns each).
    ///
    /// # Panics
    /// When a pair is invalid (see [`M2lInteractions::try_new`]).
    pub fn new(
        n_target_cols: usize,
        n_source_cols: usize,
        pairs: &[(usize, usize, [i32; 3])],
    ) -> Self {
        Self::try_new(n_target_cols, n_source_cols, pairs).unwrap_or_else(|e| panic!("{e}"))
    }

    /// Like [`M2lInteractions::new`], returning an error for a target or
    /// source column out of range or a vector that is not one of the 316
    /// V-list transfer vectors.
    pub fn try_new(
        n_target_cols: usize,
        n_source_cols: usize,
        pairs: &[(usize, usize, [i32; 3])],
    ) -> Result<Self, FieldError> {
        let chunk = Self::default_chunk_size(n_target_cols);
        Self::with_chunk_size(n_target_cols, n_source_cols, pairs, chunk)
    }

    /// Group `pairs` into chunks of `chunk_size` target columns (a tuning
    /// knob: larger chunks give larger matrix products, smaller ones more
    /// parallelism).
    pub fn with_chunk_size(
        n_target_cols: usize,
        n_source_cols: usize,
        pairs: &[(usize, usize, [i32; 3])],
        chunk_size: usize,
    ) -> Result<Self, FieldError> {
        if let Some((i, &(t, s, v))) = pairs.iter().enumerate().find(|(_, p)| p.0 >= n_target_cols)
        {
            return Err(out_of_range(i, t, s, v, n_target_cols, n_source_cols));
        }
        // Pair indices bucketed by target column (CSR, input order kept).
        let mut offsets = vec![0usize; n_target_cols + 1];
        for &(t, _, _) in pairs {
            offsets[t + 1] += 1;
        }
        for t in 0..n_target_cols {
            offsets[t + 1] += offsets[t];
        }
        let mut next = offsets.clone();
        let mut order = vec![0u32; pairs.len()];
        for (i, &(t, _, _)) in pairs.iter().enumerate() {
            order[next[t]] = i as u32;
            next[t] += 1;
        }
        Self::from_targets(n_target_cols, n_source_cols, chunk_size, |t| {
            order[offsets[t]..offsets[t + 1]].iter().map(|&i| {
                let (_, s, v) = pairs[i as usize];
                (s, v)
            })
        })
    }

    /// Build from the V list of each target column: `list(t)` yields the
    /// `(source column, transfer vector)` pairs of target column `t`. The
    /// lists are read chunk by chunk in parallel and grouped by a counting
    /// sort on the transfer vector, so no list of all pairs is ever held
    /// (the fast path of the FMM setup: 6M pairs at N = 1e6).
    ///
    /// ```
    /// use ferrofmm_field::M2lInteractions;
    /// // Target 0 hears sources 1 and 2, target 1 hears source 0.
    /// let lists = [vec![(1, [2, 0, 0]), (2, [0, 3, -1])], vec![(0, [-2, 0, 0])]];
    /// let inter = M2lInteractions::from_targets(2, 3, 64, |t| lists[t].iter().copied()).unwrap();
    /// assert_eq!(inter.len(), 3);
    /// ```
    ///
    /// # Errors
    /// [`FieldError::InvalidInteractions`] for a zero chunk size, a column
    /// out of range or a vector that is not a V-list transfer vector.
    pub fn from_targets<F, I>(
        n_target_cols: usize,
        n_source_cols: usize,
        chunk_size: usize,
        list: F,
    ) -> Result<Self, FieldError>
    where
        F: Fn(usize) -> I + Sync,
        I: IntoIterator<Item = (usize, [i32; 3])>,
    {
        if chunk_size == 0 {
            return Err(FieldError::InvalidInteractions(
                "chunk size must be positive".into(),
            ));
        }
        if n_target_cols > u32::MAX as usize || n_source_cols > u32::MAX as usize {
            return Err(FieldError::InvalidInteractions(
                "more than 2^32 columns".into(),
            ));
        }
        let lists = group_pairs(n_target_cols, n_source_cols, chunk_size, list)?;
        Ok(M2lInteractions {
            n_target_cols,
            n_source_cols,
            chunk_size,
            n_pairs: lists.sources.len(),
            pairs: OnceLock::from(lists),
            siblings: OnceLock::new(),
            slots: None,
        })
    }

    /// The automatic chunk size of [`M2lInteractions::new`] for
    /// `n_target_cols` columns: about four chunks per rayon thread, 32 to
    /// 256 columns each.
    pub fn default_chunk_size(n_target_cols: usize) -> usize {
        let threads = rayon::current_num_threads().max(1);
        n_target_cols.div_ceil(4 * threads).clamp(32, 256)
    }

    /// Number of `(target, source)` pairs.
    pub fn len(&self) -> usize {
        self.n_pairs
    }

    /// True when there are no pairs.
    pub fn is_empty(&self) -> bool {
        self.n_pairs == 0
    }

    /// Number of target columns (boxes receiving M2L).
    pub fn n_target_cols(&self) -> usize {
        self.n_target_cols
    }

    /// Number of source columns (boxes whose multipoles are read).
    pub fn n_source_cols(&self) -> usize {
        self.n_source_cols
    }

    /// Number of (chunk, transfer vector) groups, i.e. matrix products per
    /// application.
    pub fn n_groups(&self) -> usize {
        (0..self.n_chunks())
            .map(|c| self.with_chunk(c, |v| v.groups().count()))
            .sum()
    }

    /// Number of target chunks (parallel tasks).
    pub fn n_chunks(&self) -> usize {
        self.n_target_cols.div_ceil(self.chunk_size)
    }

    /// Target columns per chunk (the last chunk may have fewer).
    pub fn chunk_size(&self) -> usize {
        self.chunk_size
    }

    /// The target columns of chunk `c`: `c * chunk_size` up to the next
    /// chunk's first column (or the last column).
    pub fn chunk_targets(&self, c: usize) -> Range<usize> {
        let start = (c * self.chunk_size).min(self.n_target_cols);
        start..(start + self.chunk_size).min(self.n_target_cols)
    }

    /// Call `f` with chunk `c` (`c < n_chunks()`). When the pair lists are
    /// held, the chunk is a view of them; after
    /// [`M2lInteractions::release_pairs`] only this chunk's pairs are made
    /// from the sibling blocks, exactly as the whole lists would group them
    /// (the same groups, pairs in target order within a group), and are
    /// dropped when `f` returns: a scheme that reads its chunks this way
    /// (the SVD scheme) never holds more than one chunk's pairs per thread.
    ///
    /// ```
    /// use ferrofmm_field::M2lInteractions;
    /// let pairs = [(0, 1, [2, 0, 0]), (1, 0, [-2, 0, 0]), (0, 2, [0, 3, -1])];
    /// let mut inter = M2lInteractions::with_chunk_size(2, 3, &pairs, 1).unwrap();
    /// let held: Vec<usize> = (0..2).map(|c| inter.with_chunk(c, |v| v.groups().count())).collect();
    /// inter.release_pairs();
    /// let made: Vec<usize> = (0..2).map(|c| inter.with_chunk(c, |v| v.groups().count())).collect();
    /// assert_eq!(held, made);
    /// assert!(!inter.holds_pair_lists());
    /// ```
    ///
    /// # Panics
    /// When `c` is not a chunk.
    pub fn with_chunk<R>(&self, c: usize, f: impl FnOnce(ChunkView<'_>) -> R) -> R {
        assert!(c < self.n_chunks(), "chunk {c} of {}", self.n_chunks());
        if let Some(lists) = self.pairs.get() {
            return f(ChunkView {
                lists,
                chunk: &lists.chunks[c],
            });
        }
        let siblings = self.released_blocks();
        let vectors = transfer_vectors();
        let list = |t: usize| self.pairs_from_blocks(siblings, &vectors, t);
        let targets = self.chunk_targets(c);
        let count = targets.clone().map(|t| list(t).count()).sum();
        let mut sources = vec![0u32; count];
        let mut local_targets = vec![0u32; count];
        let groups = fill_chunk(
            targets.clone(),
            (self.n_target_cols, self.n_source_cols),
            &list,
            &mut sources,
            &mut local_targets,
        )
        .expect("the sibling blocks hold valid pairs");
        let lists = PairLists {
            chunks: vec![Chunk {
                target_start: targets.start,
                target_end: targets.end,
                group_start: 0,
                group_end: groups.len(),
            }],
            groups,
            sources,
            local_targets,
        };
        f(ChunkView {
            lists: &lists,
            chunk: &lists.chunks[0],
        })
    }

    /// Say which columns are siblings: column `c` is child `slot[c] % 8` of
    /// sibling group `slot[c] / 8` (octant order of
    /// [`octant_bits`](crate::plumbing::octant_bits)). Slots must increase
    /// strictly with the column, as the boxes of a tree level in Morton
    /// order do with `slot = 8 (index of the parent on its level) +
    /// octant`. Without slots, column `c` is taken as slot `c`, which is
    /// right only for a level where every box has all seven siblings; an
    /// adaptive tree that leaves out empty boxes needs the slots for
    /// [`M2lInteractions::sibling_blocks`] to find its full blocks (the
    /// result of a scheme is exact either way).
    ///
    /// # Errors
    /// [`FieldError::InvalidInteractions`] when a slot list has the wrong
    /// length or does not increase strictly.
    pub fn with_sibling_slots(
        mut self,
        target_slots: Vec<u32>,
        source_slots: Vec<u32>,
    ) -> Result<Self, FieldError> {
        for (what, slots, cols) in [
            ("target", &target_slots, self.n_target_cols),
            ("source", &source_slots, self.n_source_cols),
        ] {
            if slots.len() != cols {
                return Err(FieldError::InvalidInteractions(format!(
                    "{} {what} slots for {cols} {what} columns",
                    slots.len()
                )));
            }
            if let Some(i) = slots.windows(2).position(|w| w[0] >= w[1]) {
                return Err(FieldError::InvalidInteractions(format!(
                    "{what} slots must increase: column {} has slot {}, column {} slot {}",
                    i,
                    slots[i],
                    i + 1,
                    slots[i + 1]
                )));
            }
        }
        // Pairs released to the sibling blocks are made again first: the
        // blocks made under the old slots go.
        self.lists();
        self.slots = Some((target_slots, source_slots));
        self.siblings = OnceLock::new();
        Ok(self)
    }

    /// Sibling slot of target column `t` (`t` itself without
    /// [`M2lInteractions::with_sibling_slots`]).
    pub fn target_slot(&self, t: usize) -> usize {
        self.slots.as_ref().map_or(t, |(ts, _)| ts[t] as usize)
    }

    /// Sibling slot of source column `s`.
    pub fn source_slot(&self, s: usize) -> usize {
        self.slots.as_ref().map_or(s, |(_, ss)| ss[s] as usize)
    }

    /// The pairs regrouped into `8 x 8` sibling blocks
    /// ([`SiblingBlocks`](crate::plumbing::SiblingBlocks)), computed on the
    /// first call and kept (later calls, e.g. every evaluation of an FMM,
    /// cost nothing).
    pub fn sibling_blocks(&self) -> &SiblingBlocks {
        self.siblings.get_or_init(|| SiblingBlocks::new(self))
    }

    /// Release the grouped pairs and keep the sibling blocks (made now if
    /// they are not yet), which hold the same pairs in about 1/30 of the
    /// memory on a tree level (a 16-byte block for up to 63 pairs of 8
    /// bytes): for schemes that read only the blocks
    /// ([`M2lScheme::reads_pair_lists`](crate::M2lScheme::reads_pair_lists),
    /// the FFT scheme). Nothing is lost: the pair lists are made again from
    /// the blocks, exactly as they were grouped (the same pairs in the same
    /// chunks and groups, in target order within a group), the first time
    /// anything reads them ([`M2lInteractions::chunk_views`]).
    ///
    /// ```
    /// use ferrofmm_field::M2lInteractions;
    /// let pairs = [(0, 1, [2, 0, 0]), (1, 0, [-2, 0, 0]), (0, 2, [0, 3, -1])];
    /// let mut inter = M2lInteractions::new(2, 3, &pairs);
    /// inter.release_pairs();
    /// assert!(!inter.holds_pair_lists());
    /// assert_eq!(inter.len(), 3);
    /// assert_eq!(inter.chunk_views().flat_map(|c| c.groups()).count(), 3);
    /// assert!(inter.holds_pair_lists());
    /// ```
    pub fn release_pairs(&mut self) {
        self.sibling_blocks();
        self.pairs.take();
    }

    /// Whether the grouped pairs are held (false after
    /// [`M2lInteractions::release_pairs`] until something reads them).
    pub fn holds_pair_lists(&self) -> bool {
        self.pairs.get().is_some()
    }

    /// The grouped pairs, made again from the sibling blocks after
    /// [`M2lInteractions::release_pairs`].
    fn lists(&self) -> &PairLists {
        self.pairs.get_or_init(|| {
            let siblings = self.released_blocks();
            let vectors = transfer_vectors();
            let list = |t: usize| self.pairs_from_blocks(siblings, &vectors, t);
            let lists = group_pairs(
                self.n_target_cols,
                self.n_source_cols,
                self.chunk_size,
                list,
            )
            .expect("the sibling blocks hold valid pairs");
            debug_assert_eq!(lists.sources.len(), self.n_pairs);
            lists
        })
    }

    /// The sibling blocks of released pair lists.
    fn released_blocks(&self) -> &SiblingBlocks {
        self.siblings
            .get()
            .expect("pair lists are released only once the sibling blocks are made")
    }

    /// The V list of target column `t` (`(source column, vector)`), read
    /// from the sibling blocks: the block pairs in block order, then the
    /// loose ones.
    fn pairs_from_blocks<'s>(
        &'s self,
        siblings: &'s SiblingBlocks,
        vectors: &'s [[i32; 3]],
        t: usize,
    ) -> impl Iterator<Item = (usize, [i32; 3])> + 's {
        let slot = self.target_slot(t);
        let (g, ct) = (slot / 8, slot % 8);
        let from_blocks = siblings.blocks(g).iter().flat_map(move |b| {
            let row = (b.mask >> (8 * ct)) & 0xff;
            (0..8).filter(move |cs| row >> cs & 1 == 1).map(move |cs| {
                let s = 8 * b.source_group as usize + cs;
                let v = block_vector(b.offset as usize, ct, cs)
                    .expect("a block holds V-list pairs only");
                (column(siblings.source_column(s)), vectors[v])
            })
        });
        let loose = siblings
            .loose(g)
            .iter()
            .filter(move |p| p.target as usize == slot)
            .map(move |p| {
                let s = siblings.source_column(p.source as usize);
                (column(s), vectors[p.vector as usize])
            });
        from_blocks.chain(loose)
    }

    /// Bytes held: the grouped pairs (unless released), the sibling slots,
    /// and the sibling blocks once made
    /// ([`M2lInteractions::sibling_blocks`]).
    pub fn memory_bytes(&self) -> usize {
        use std::mem::size_of_val;
        self.pairs.get().map_or(0, PairLists::memory_bytes)
            + self
                .slots
                .as_ref()
                .map_or(0, |(t, s)| size_of_val(&t[..]) + size_of_val(&s[..]))
            + self.siblings.get().map_or(0, SiblingBlocks::memory_bytes)
    }

    /// The chunks in target order: chunk `c` owns a contiguous range of
    /// target columns, the next chunk starts where it ends, and together
    /// they cover `0..n_target_cols`. See
    /// [`plumbing::for_each_chunk`](crate::plumbing::for_each_chunk).
    pub fn chunk_views(&self) -> impl Iterator<Item = ChunkView<'_>> + '_ {
        let lists = self.lists();
        lists
            .chunks
            .iter()
            .map(move |c| ChunkView { lists, chunk: c })
    }
}

/// Read the lists of every target column, chunk by chunk in parallel, and
/// group each chunk's pairs by transfer vector (a counting sort), filling
/// the final arrays in place: no list of all pairs is ever held beside
/// them. `chunk_size` is positive.
fn group_pairs<F, I>(
    n_target_cols: usize,
    n_source_cols: usize,
    chunk_size: usize,
    list: F,
) -> Result<PairLists, FieldError>
where
    F: Fn(usize) -> I + Sync,
    I: IntoIterator<Item = (usize, [i32; 3])>,
{
    let n_chunks = n_target_cols.div_ceil(chunk_size);
    let targets_of = |c: usize| c * chunk_size..((c + 1) * chunk_size).min(n_target_cols);
    // Two passes: count each chunk's pairs, then fill each chunk's
    // slice of the final arrays in place (no second copy of the pairs).
    let counts: Vec<usize> = (0..n_chunks)
        .into_par_iter()
        .map(|c| targets_of(c).map(|t| list(t).into_iter().count()).sum())
        .collect();
    let total: usize = counts.iter().sum();
    let mut sources = vec![0u32; total];
    let mut local_targets = vec![0u32; total];
    let mut slices = Vec::with_capacity(n_chunks);
    let (mut s_rest, mut t_rest) = (&mut sources[..], &mut local_targets[..]);
    for &len in &counts {
        let (s, s_next) = s_rest.split_at_mut(len);
        let (t, t_next) = t_rest.split_at_mut(len);
        slices.push((s, t));
        (s_rest, t_rest) = (s_next, t_next);
    }
    let chunk_groups: Vec<Vec<Group>> = slices
        .into_par_iter()
        .enumerate()
        .map(|(c, (s, t))| fill_chunk(targets_of(c), (n_target_cols, n_source_cols), &list, s, t))
        .collect::<Result<_, _>>()?;
    let mut chunks = Vec::with_capacity(n_chunks);
    let mut groups = Vec::new();
    let mut base = 0;
    for (c, (g, len)) in chunk_groups.into_iter().zip(counts).enumerate() {
        let group_start = groups.len();
        groups.extend(g.into_iter().map(|g| Group {
            vector: g.vector,
            pair_start: base + g.pair_start,
            pair_end: base + g.pair_end,
        }));
        base += len;
        let r = targets_of(c);
        chunks.push(Chunk {
            target_start: r.start,
            target_end: r.end,
            group_start,
            group_end: groups.len(),
        });
    }
    Ok(PairLists {
        chunks,
        groups,
        sources,
        local_targets,
    })
}

/// Read the lists of `targets` and counting-sort them by transfer vector
/// into `sources` and `local_targets` (exactly the chunk's pair count
/// long). Returns the chunk's groups, with pair indices local to the chunk.
/// Stable: within a group, pairs stay in target order.
fn fill_chunk<F, I>(
    targets: Range<usize>,
    (n_target_cols, n_source_cols): (usize, usize),
    list: &F,
    sources: &mut [u32],
    local_targets: &mut [u32],
) -> Result<Vec<Group>, FieldError>
where
    F: Fn(usize) -> I,
    I: IntoIterator<Item = (usize, [i32; 3])>,
{
    let mut raw: Vec<(u16, u32, u32)> = Vec::with_capacity(sources.len());
    let mut counts = [0usize; N_TRANSFER_VECTORS + 1];
    for t in targets.clone() {
        for (i, (s, v)) in list(t).into_iter().enumerate() {
            if s >= n_source_cols {
                return Err(out_of_range(i, t, s, v, n_target_cols, n_source_cols));
            }
            let Some(vi) = transfer_vector_index(v) else {
                return Err(FieldError::InvalidInteractions(format!(
                    "target {t}, pair {i}: {v:?} is not a V-list transfer vector"
                )));
            };
            counts[vi + 1] += 1;
            raw.push((vi as u16, (t - targets.start) as u32, s as u32));
        }
    }
    if raw.len() != sources.len() {
        return Err(FieldError::InvalidInteractions(format!(
            "the lists of targets {targets:?} gave {} pairs, then {}",
            sources.len(),
            raw.len()
        )));
    }
    for v in 0..N_TRANSFER_VECTORS {
        counts[v + 1] += counts[v];
    }
    let groups = (0..N_TRANSFER_VECTORS)
        .filter(|&v| counts[v + 1] > counts[v])
        .map(|v| Group {
            vector: v as u16,
            pair_start: counts[v],
            pair_end: counts[v + 1],
        })
        .collect();
    for (vi, t, s) in raw {
        let at = &mut counts[vi as usize];
        sources[*at] = s;
        local_targets[*at] = t;
        *at += 1;
    }
    Ok(groups)
}

/// The column of a slot that holds a pair (present by construction).
fn column(c: Option<usize>) -> usize {
    c.expect("a slot with a pair has a column")
}

fn out_of_range(
    i: usize,
    t: usize,
    s: usize,
    v: [i32; 3],
    n_target_cols: usize,
    n_source_cols: usize,
) -> FieldError {
    FieldError::InvalidInteractions(format!(
        "pair {i} = ({t}, {s}, {v:?}): column out of range ({n_target_cols} targets, \
         {n_source_cols} sources)"
    ))
}

/// One chunk of an [`M2lInteractions`] as a scheme's apply sees it: a
/// contiguous range of target columns and its pairs, grouped by transfer
/// vector (ascending vector index; within a group, pairs in target order).
#[derive(Clone, Copy, Debug)]
pub struct ChunkView<'a> {
    lists: &'a PairLists,
    chunk: &'a Chunk,
}

/// The pairs of one chunk that share a transfer vector: pair `k` adds
/// `K_v multipoles[:, sources[k]]` to the chunk's target column
/// `targets[k]` (relative to the chunk's first column).
#[derive(Clone, Copy, Debug)]
pub struct GroupView<'a> {
    /// Index of the transfer vector `v` in
    /// [`transfer_vectors`](crate::transfer_vectors).
    pub vector: usize,
    /// Source columns (boxes whose multipoles are read).
    pub sources: &'a [u32],
    /// Target columns, relative to the chunk's first target column.
    pub targets: &'a [u32],
}

impl<'a> ChunkView<'a> {
    /// Number of target columns in the chunk.
    pub fn n_targets(&self) -> usize {
        self.chunk.target_end - self.chunk.target_start
    }

    /// Largest group (number of pairs) of the chunk.
    pub fn max_group_len(&self) -> usize {
        self.groups().map(|g| g.sources.len()).max().unwrap_or(0)
    }

    /// True when the chunk has no pairs.
    pub fn is_empty(&self) -> bool {
        self.chunk.group_start == self.chunk.group_end
    }

    /// First target column of the chunk (in the level's numbering).
    pub fn first_target(&self) -> usize {
        self.chunk.target_start
    }

    /// The chunk's groups, one per transfer vector present, in ascending
    /// vector index.
    pub fn groups(&self) -> impl Iterator<Item = GroupView<'a>> + use<'a> {
        let lists = self.lists;
        lists.groups[self.chunk.group_start..self.chunk.group_end]
            .iter()
            .map(move |g| GroupView {
                vector: g.vector as usize,
                sources: &lists.sources[g.pair_start..g.pair_end],
                targets: &lists.local_targets[g.pair_start..g.pair_end],
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grouping_preserves_pairs() {
        let vs = transfer_vectors();
        let mut pairs = Vec::new();
        for t in 0..300 {
            for k in 0..7 {
                let s = (t * 13 + k * 101) % 250;
                pairs.push((t, s, vs[(t * 7 + k * 31) % 316]));
            }
        }
        let inter = M2lInteractions::with_chunk_size(300, 250, &pairs, 64).unwrap();
        assert_eq!(inter.len(), pairs.len());
        assert_eq!(inter.n_chunks(), 5);
        let mut got = Vec::new();
        for c in inter.chunk_views() {
            let start = c.chunk.target_start;
            let mut last = None;
            for g in c.groups() {
                assert!(last < Some(g.vector));
                last = Some(g.vector);
                for (&s, &t) in g.sources.iter().zip(g.targets) {
                    assert!((t as usize) < c.n_targets());
                    got.push((start + t as usize, s as usize, vs[g.vector]));
                }
            }
        }
        got.sort();
        let mut want = pairs.clone();
        want.sort();
        assert_eq!(got, want);
    }

    #[test]
    fn rejects_bad_pairs() {
        assert!(M2lInteractions::try_new(2, 2, &[(2, 0, [2, 0, 0])]).is_err());
        assert!(M2lInteractions::try_new(2, 2, &[(0, 2, [2, 0, 0])]).is_err());
        assert!(M2lInteractions::try_new(2, 2, &[(0, 1, [1, 1, 1])]).is_err());
        assert!(M2lInteractions::try_new(2, 2, &[(0, 1, [4, 0, 0])]).is_err());
        let empty = M2lInteractions::new(0, 0, &[]);
        assert!(empty.is_empty());
    }
}
