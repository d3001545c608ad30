//! A conformance check for [`M2lScheme`] implementations, reusable from
//! any crate's tests.
//!
//! [`check_scheme`] builds the V lists of two complete levels (2 and 3, all
//! `4^3` and `8^3` boxes of a domain of width 2, so every one of the 316
//! transfer vectors occurs), fills the multipoles and the check potentials
//! with deterministic values in `[-0.5, 0.5)`, and compares
//! `apply` with the reference
//!
//! ```text
//! ref[:, t] = check0[:, t] + sum_{(t, s, v)} K_v(h_level) multipoles[:, s]
//! ```
//!
//! computed in `f64` from [`m2l_matrix`] for every vector, as
//! `||apply - ref||_2 / ||ref - check0||_2` over all values. It checks the
//! scheme built by [`M2lScheme::precompute`] and by
//! [`M2lScheme::precompute_for`] with the levels' usage, with the default
//! chunking and with chunks of 7 target columns (so a chunk boundary falls
//! inside many V lists) and with those chunks' pair lists released (made
//! again from the sibling blocks, [`M2lInteractions::release_pairs`]),
//! with the boxes in lexicographic and in Morton
//! column order (siblings in eight consecutive columns, as in a tree level:
//! the layout [`SiblingBlocks`](super::SiblingBlocks) files into full
//! `8 x 8` blocks), with one Morton pair in five left out (partial
//! blocks) and without every third box (compacted columns with their
//! sibling slots, as a tree that leaves out empty boxes), that a scheme
//! that says it reads no pair lists ([`M2lScheme::reads_pair_lists`]) does
//! not make them again, that `apply`
//! accumulates (the initial `check0` is kept), and
//! that an empty interaction set changes nothing.
//!
//! ```
//! use ferrofmm_field::plumbing::conformance::check_scheme;
//! use ferrofmm_field::{DenseConfig, DenseM2l, OperatorParams};
//! use ferrofmm_kernels::Laplace3d;
//! let report =
//!     check_scheme::<f64, DenseM2l<f64>, _>(&Laplace3d, &OperatorParams::new(3), &DenseConfig, 1e-12)
//!         .unwrap();
//! assert!(report.relative_error < 1e-12);
//! ```

use ferrofmm_kernels::{Kernel, Real};

use super::{LevelMap, m2l_matrix};
use crate::{
    M2lInteractions, M2lScheme, M2lUsage, OperatorParams, Update, gemm_scaled,
    transfer_vector_index, transfer_vectors,
};

/// One V-list pair: (target column, source column, transfer vector).
pub type Pair = (usize, usize, [i32; 3]);

/// A column layout of a level: name, pairs, columns and sibling slots.
type Layout = (&'static str, Vec<Pair>, usize, Option<Vec<u32>>);

/// Levels [`check_scheme`] exercises (both complete grids).
pub const LEVELS: [u32; 2] = [2, 3];

/// Width of the domain [`check_scheme`] uses (not 1, so that the scaling
/// of a homogeneous kernel's operators is exercised).
pub const DOMAIN_WIDTH: f64 = 2.0;

/// What [`check_scheme`] measured.
#[derive(Clone, Debug, PartialEq)]
pub struct ConformanceReport {
    /// Largest relative L2 error over the levels and variants.
    pub relative_error: f64,
    /// V-list pairs applied per variant (both levels).
    pub pairs: usize,
    /// Bytes the scheme reported for the full precomputation.
    pub memory_bytes: usize,
}

/// Check `S` for `kernel` at `params` against per-vector dense products
/// (see the [module documentation](self)); `Err` describes the first
/// failure: a precomputation error, a relative error above `tolerance`, a
/// lost initial value or a change from an empty interaction set.
pub fn check_scheme<T: Real, S: M2lScheme<T>, K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    config: &S::Config,
    tolerance: f64,
) -> Result<ConformanceReport, String> {
    let depth = *LEVELS.last().expect("levels");
    let n = crate::expansion_len(kernel, params.order);
    let full = S::precompute(kernel, params, config, DOMAIN_WIDTH, depth)
        .map_err(|e| format!("precompute: {e}"))?;
    let mut usage = M2lUsage::none();
    let levels: Vec<(u32, Vec<Pair>)> = LEVELS
        .iter()
        .map(|&l| {
            let pairs = full_level_pairs(l);
            for &(_, _, v) in &pairs {
                usage.mark(l, transfer_vector_index(v).expect("a V-list vector"));
            }
            (l, pairs)
        })
        .collect();
    let restricted = S::precompute_for(kernel, params, config, DOMAIN_WIDTH, depth, &usage)
        .map_err(|e| format!("precompute_for: {e}"))?;
    let map = LevelMap::new(kernel.homogeneity(), DOMAIN_WIDTH, depth, LEVELS[0])
        .map_err(|e| e.to_string())?;
    let mut rng = Lcg(0x5eed);
    let mut worst = 0.0f64;
    let mut total_pairs = 0;
    for (level, lex_pairs) in &levels {
        let all = 1usize << (3 * level);
        // Four layouts of the same level: lexicographic columns, Morton
        // columns (siblings in consecutive columns, as in a tree), Morton
        // columns with one pair in five left out (partial sibling blocks),
        // and Morton columns without every third box, compacted, with
        // their sibling slots (a tree that leaves out empty boxes).
        let morton = morton_columns(*level);
        let morton_pairs = |keep: &dyn Fn(usize) -> bool| -> Vec<Pair> {
            lex_pairs
                .iter()
                .enumerate()
                .filter(|&(i, _)| keep(i))
                .map(|(_, &(t, s, v))| (morton[t], morton[s], v))
                .collect()
        };
        let kept_slots: Vec<u32> = (0..all as u32).filter(|m| m % 3 != 1).collect();
        let mut compact = vec![usize::MAX; all];
        for (c, &m) in kept_slots.iter().enumerate() {
            compact[m as usize] = c;
        }
        let sparse_pairs: Vec<Pair> = morton_pairs(&|_| true)
            .into_iter()
            .filter(|&(t, s, _)| compact[t] != usize::MAX && compact[s] != usize::MAX)
            .map(|(t, s, v)| (compact[t], compact[s], v))
            .collect();
        let layouts: [Layout; 4] = [
            ("lexicographic columns", lex_pairs.clone(), all, None),
            ("Morton columns", morton_pairs(&|_| true), all, None),
            (
                "Morton columns, 1 pair in 5 left out",
                morton_pairs(&|i| i % 5 != 2),
                all,
                None,
            ),
            (
                "Morton columns without every third box, with sibling slots",
                sparse_pairs,
                kept_slots.len(),
                Some(kept_slots.clone()),
            ),
        ];
        for (layout, pairs, cols, slots) in &layouts {
            let (pairs, cols) = (pairs.as_slice(), *cols);
            let multipoles: Vec<T> = (0..n * cols).map(|_| T::from_f64(rng.next())).collect();
            let check0: Vec<T> = (0..n * cols).map(|_| T::from_f64(rng.next())).collect();
            let reference = reference(kernel, params, &map, *level, pairs, &multipoles, &check0)?;
            let contribution: f64 = reference
                .iter()
                .zip(&check0)
                .map(|(r, c)| (r - c.to_f64()).powi(2))
                .sum::<f64>()
                .sqrt();
            if contribution == 0.0 {
                return Err(format!("level {level}: the reference contribution is zero"));
            }
            let with_slots = |inter: M2lInteractions| match slots {
                Some(sl) => inter.with_sibling_slots(sl.clone(), sl.clone()),
                None => Ok(inter),
            };
            let default_chunks = M2lInteractions::try_new(cols, cols, pairs)
                .and_then(with_slots)
                .map_err(|e| e.to_string())?;
            let small_chunks = M2lInteractions::with_chunk_size(cols, cols, pairs, 7)
                .and_then(with_slots)
                .map_err(|e| e.to_string())?;
            let mut released = small_chunks.clone();
            released.release_pairs();
            for (scheme, which) in [(&full, "precompute"), (&restricted, "precompute_for")] {
                for (inter, chunks) in [
                    (&default_chunks, "default chunks"),
                    (&small_chunks, "chunks of 7"),
                    (&released, "chunks of 7, pair lists released"),
                ] {
                    let mut check = check0.clone();
                    scheme.apply(*level, inter, &multipoles, &mut check);
                    let error = check
                        .iter()
                        .zip(&reference)
                        .map(|(c, r)| (c.to_f64() - r).powi(2))
                        .sum::<f64>()
                        .sqrt()
                        / contribution;
                    if error.is_nan() || error > tolerance {
                        return Err(format!(
                            "{} ({which}, {chunks}, {layout}), level {level}: relative error \
                         {error:.3e} above {tolerance:.1e}",
                            scheme.name()
                        ));
                    }
                    worst = worst.max(error);
                }
            }
            if !full.reads_pair_lists() && released.holds_pair_lists() {
                return Err(format!(
                    "{} says it reads no pair lists, but its apply made them again ({layout}, \
                     level {level})",
                    full.name()
                ));
            }
        }
        let (pairs, cols) = (lex_pairs, all);
        let multipoles: Vec<T> = (0..n * cols).map(|_| T::from_f64(rng.next())).collect();
        let check0: Vec<T> = (0..n * cols).map(|_| T::from_f64(rng.next())).collect();
        total_pairs += pairs.len();
        let mut check = check0.clone();
        full.apply(
            *level,
            &M2lInteractions::new(cols, cols, &[]),
            &multipoles,
            &mut check,
        );
        if check != check0 {
            return Err(format!(
                "{}: level {level}: an empty interaction set changed the check potentials",
                full.name()
            ));
        }
    }
    Ok(ConformanceReport {
        relative_error: worst,
        pairs: total_pairs,
        memory_bytes: full.memory_bytes(),
    })
}

/// Every V-list pair `(t, s, v)` of the complete grid of `level`: boxes
/// whose parents are neighbours (or the same) but which are not
/// neighbours themselves. Column of box `(x, y, z)`: `(x side + y) side +
/// z`.
pub fn full_level_pairs(level: u32) -> Vec<Pair> {
    let side = 1i32 << level;
    let column = |b: [i32; 3]| ((b[0] * side + b[1]) * side + b[2]) as usize;
    let boxes: Vec<[i32; 3]> = (0..side)
        .flat_map(|x| (0..side).flat_map(move |y| (0..side).map(move |z| [x, y, z])))
        .collect();
    let mut pairs = Vec::new();
    for &t in &boxes {
        for v in transfer_vectors() {
            let s = [t[0] + v[0], t[1] + v[1], t[2] + v[2]];
            let inside = s.iter().all(|&c| (0..side).contains(&c));
            let parents_adjacent = (0..3).all(|i| ((s[i] >> 1) - (t[i] >> 1)).abs() <= 1);
            if inside && parents_adjacent {
                pairs.push((column(t), column(s), v));
            }
        }
    }
    pairs
}

/// The Morton column of each lexicographic column of the complete grid of
/// `level`: bit `i` of `x`, `y`, `z` at bits `3 i`, `3 i + 1`, `3 i + 2`
/// (so the children of a parent take eight consecutive columns, child `o`
/// with [`octant_bits`](super::octant_bits)`(o)` at `8 g + o`).
pub fn morton_columns(level: u32) -> Vec<usize> {
    let side = 1usize << level;
    let mut out = vec![0; side * side * side];
    for x in 0..side {
        for y in 0..side {
            for z in 0..side {
                let mut m = 0;
                for i in 0..level as usize {
                    m |= ((x >> i) & 1) << (3 * i)
                        | ((y >> i) & 1) << (3 * i + 1)
                        | ((z >> i) & 1) << (3 * i + 2);
                }
                out[(x * side + y) * side + z] = m;
            }
        }
    }
    out
}

/// `check0 + sum K_v(h) multipoles[:, s]` in `f64`, one product per vector.
fn reference<T: Real, K: Kernel>(
    kernel: &K,
    params: &OperatorParams,
    map: &LevelMap,
    level: u32,
    pairs: &[Pair],
    multipoles: &[T],
    check0: &[T],
) -> Result<Vec<f64>, String> {
    let n = crate::expansion_len(kernel, params.order);
    let h = map.half_width(level);
    let mut out: Vec<f64> = check0.iter().map(|x| x.to_f64()).collect();
    let vectors = transfer_vectors();
    let mut by_vector: Vec<Vec<(usize, usize)>> = vec![Vec::new(); vectors.len()];
    for &(t, s, v) in pairs {
        by_vector[transfer_vector_index(v).expect("a V-list vector")].push((t, s));
    }
    for (vi, list) in by_vector.iter().enumerate().filter(|(_, l)| !l.is_empty()) {
        let k = m2l_matrix(kernel, params.order, &params.radii, h, vectors[vi])
            .map_err(|e| e.to_string())?;
        let k: Vec<f64> = (0..n)
            .flat_map(|i| (0..n).map(move |j| (i, j)))
            .map(|(i, j)| k[(j, i)])
            .collect();
        let block: Vec<f64> = list
            .iter()
            .flat_map(|&(_, s)| multipoles[s * n..(s + 1) * n].iter().map(|x| x.to_f64()))
            .collect();
        let mut product = vec![0.0; n * list.len()];
        gemm_scaled(
            n,
            list.len(),
            n,
            1.0,
            &k,
            &block,
            &mut product,
            Update::Overwrite,
        );
        for (j, &(t, _)) in list.iter().enumerate() {
            for (o, p) in out[t * n..(t + 1) * n]
                .iter_mut()
                .zip(&product[j * n..(j + 1) * n])
            {
                *o += p;
            }
        }
    }
    Ok(out)
}

/// A small deterministic generator of values in `[-0.5, 0.5)`.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}
