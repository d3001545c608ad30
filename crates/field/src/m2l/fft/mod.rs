//! [`FftM2l`]: M2L as a convolution on the surface lattice, applied with
//! FFTs.
//!
//! With equal upward equivalent and downward check radii `r`
//! (`r_ue = r_dc`, the default 1.05), the points of both surfaces of a box
//! of half-width `h` lie on the lattice `c - r h + delta (i, j, k)`,
//! `delta = 2 r h / (p - 1)`, `0 <= i, j, k < p`. For a source box at
//! `c_s = c_t + 2 h v`, target lattice point `j` minus source lattice point
//! `i` is `x_0 - y_0 + delta (j - i)`, so for each transfer vector `v`
//!
//! ```text
//! check[j] = sum_i T_v[j - i] phi[i],    T_v[m] = K(y_0, x_0 + delta m),  m in [-(p-1), p-1]^3,
//! ```
//!
//! a 3D convolution (with `phi = 0` at the lattice's interior nodes). On a
//! grid of `N >= 2p - 1` points per axis the circular convolution equals it
//! at the target nodes (the differences `j - i` take `2p - 1` values per
//! axis, so none wraps onto another). `N` is the smallest such size with
//! prime factors 2, 3, 5, 7 (`grid_size`: 11 -> 12 at `p = 6`, 15 at
//! `p = 8`, where ExaFMM-T and PVFMM use `2p = 16`), so with hats for 3D
//! real FFTs ([`crate::fft3d`]; `floor(N/2) + 1` values along the last
//! axis; the transforms skip the lines that are zero or not needed, as the
//! lattice fills only `[0, p)^3`)
//!
//! ```text
//! check_t = IFFT( sum_{(t, s, v)} That_v * phihat_s )   (pointwise products),
//! ```
//!
//! one forward FFT per source box, one inverse per target box, and
//! `N^2 (floor(N/2) + 1)` complex multiply-adds per pair in between, against
//! `n^2 = (6 (p-1)^2 + 2)^2` for [`DenseM2l`](crate::DenseM2l): fewer from
//! `p ~ 4` on. The precomputation is 316 kernel grids and FFTs (no SVD,
//! milliseconds). The kernel spectra are kept in `f64` (`317 N^2 (floor(N/2) + 1)`
//! complex values per set: 3.7 MB at `p = 6`, 18 MB at `p = 10`), and the
//! products run in `f64` whatever `T` is. It is exact up to rounding: the
//! same operator as dense M2L. With a cache directory
//! ([`OperatorParams::cache_dir`]) all 316 spectra of every set are
//! computed and kept in one checksummed `f64` file (kind `m2l-fft`, shared
//! by `f32` and `f64`); a damaged file is rebuilt.
//!
//! # Kernels with several components
//!
//! For a kernel with `c` [components](ferrofmm_kernels::Kernel::components)
//! (a complex kernel in its real `2 x 2` form, the `3 x 3` Stokeslet) the
//! densities and check potentials are `c` lattice functions per box, and
//!
//! ```text
//! check_a[j] = sum_b sum_i T_{v,ab}[j - i] phi_b[i],    a, b < c,
//! ```
//!
//! `c^2` convolutions per pair: `c` forward FFTs per source box, `c`
//! inverse FFTs per target box, `c^2` kernel spectra per vector and `c^2`
//! pointwise products per frequency, against `c^2 n^2` for the dense
//! scheme (the same ratio as for `c = 1`).
//!
//! # Complex kernels
//!
//! A complex kernel in real form ([`Kernel::is_complex`]: `c = 2`, blocks
//! `[[Re T, -Im T], [Im T, Re T]]`) would pay twice in that form: its four
//! real spectra hold `Re T` and `Im T` twice each. It is convolved as what
//! it is instead,
//!
//! ```text
//! check[j] = sum_i T_v[j - i] phi[i],    T_v, phi, check complex,
//! ```
//!
//! with complex 3D FFTs ([`Fft3d::forward_complex`]): one complex spectrum
//! per box each way and one complex kernel spectrum per vector, each of
//! all `N^3` frequencies (a complex grid's spectrum has no conjugate
//! half), so one pointwise product per frequency: `N^3` complex
//! multiply-adds per pair against `4 N^2 (floor(N/2) + 1)`, about half,
//! and half the kernel spectra's memory. The transforms cost what the two
//! real ones did. The pointwise products are the scalar path's, with
//! `N^3` frequencies.
//!
//! # Siblings together
//!
//! The products are organised by parent (as in PVFMM, ExaFMM-T and kifmm):
//! [`SiblingBlocks`](crate::siblings::SiblingBlocks) files the pairs of the
//! eight children of a target parent and a neighbouring source parent as
//! one `8 x 8` block per frequency, so each source spectrum value loaded
//! serves eight targets and each accumulator eight sources
//! ([`hadamard`] has the layout and the register blocking). The level's
//! target groups are taken in runs whose source spectra fit
//! [`SPECTRA_BUDGET_BYTES`] ([`chunks`]: `16 N^2 (floor(N/2) + 1)` bytes
//! per source box, which for a whole level would outweigh the rest of a
//! large run). For each run the spectra of its source boxes are made first
//! (in parallel over sibling groups); then each task takes a few of the
//! run's target groups, forms their spectra frequency block by frequency
//! block (the kernel slab of a block, `317 x 256` bytes, stays in cache
//! while all the task's groups use it), inverts them and adds the lattice
//! values to its own columns of the check potentials.

mod chunks;
mod hadamard;

pub use self::chunks::SPECTRA_BUDGET_BYTES;

use std::marker::PhantomData;

use ferrofmm_kernels::lanes::run_task;
use ferrofmm_kernels::{Kernel, Real, SimdLevel};
use rayon::prelude::*;
use rustfft::num_complex::Complex;

use self::chunks::plan_chunks;
use self::hadamard::{FREQ_BLOCK, Many, One, Products, SLAB_VECTORS, W, block_tables};
use super::{M2lProgress, M2lScheme, Plan, check_lengths, planned_sets};
use crate::cache::{CacheKey, CachePayload, CacheStatus, StoreLayout, ValueReader};
use crate::estimate::seconds_for;
use crate::fft3d::{Fft3d, FftWorkspace};
use crate::levels::LevelMap;
use crate::siblings::SiblingBlocks;
use crate::surface::unit_surface;
use crate::{
    FieldError, M2lInteractions, M2lUsage, OperatorParams, PrecomputeEstimate, n_surface_points,
    transfer_vectors,
};

/// Target sibling groups per task of [`FftM2l::apply`] at most (their
/// spectra, `8 x 16 N^2 (floor(N/2) + 1)` bytes per group, are the task's
/// scratch).
const GROUPS_PER_TASK: usize = 16;

/// Progress weight of one source group's forward transforms (see
/// [`M2lScheme::apply_with_progress`]): about a quarter of a level's time
/// goes to them when each is done once (see [`chunks`]).
const SOURCE_GROUP_WEIGHT: u64 = 1;

/// Progress weight of one target group's products and inverse transforms.
const TARGET_GROUP_WEIGHT: u64 = 3;

/// Configuration of [`FftM2l`] (nothing to configure).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FftConfig;

/// FFT-accelerated M2L: for each transfer vector `v`, `check[j] = sum_i
/// T_v[j - i] phi[i]` on the surface lattice, a 3D convolution computed as
/// a circular one on an `N^3` grid (`N >= 2p - 1`, prime factors 2, 3, 5,
/// 7) with real FFTs, siblings together (the derivation is in the source
/// module `m2l::fft`).
///
/// ```
/// use ferrofmm_field::{FftConfig, FftM2l, M2lInteractions, M2lScheme, OperatorParams};
/// use ferrofmm_kernels::Laplace3d;
/// let m2l = FftM2l::<f64>::precompute(&Laplace3d, &OperatorParams::new(4), &FftConfig, 1.0, 3).unwrap();
/// let n = ferrofmm_field::n_surface_points(4);
/// let inter = M2lInteractions::new(1, 1, &[(0, 0, [2, 0, 0])]);
/// let mut check = vec![0.0; n];
/// m2l.apply(3, &inter, &vec![1.0; n], &mut check);
/// assert!(check.iter().all(|&x| x > 0.0));
/// ```
pub struct FftM2l<T: Real> {
    /// Surface points `n` (an expansion is `c n` values).
    n: usize,
    /// Components `c` of the kernel.
    components: usize,
    /// Whether the kernel is convolved as a complex scalar (see the module
    /// docs): then each box has one complex spectrum of `N^3` frequencies,
    /// otherwise `c` real-grid spectra of `N^2 (floor(N/2) + 1)`.
    complex: bool,
    /// Expansion order `p`: lattice points per axis.
    order: usize,
    levels: LevelMap,
    fft: Fft3d,
    /// Flat grid index of each surface point.
    lattice: Vec<usize>,
    /// Frequency blocks of a spectrum.
    blocks: usize,
    /// `slabs[set]`: the kernel spectra `That_v` of the set, frequency
    /// block by frequency block (`[block][SLAB_VECTORS][s][s][W]` with `s`
    /// spectra per box, [`FftM2l::spectra_per_box`]; see [`hadamard`]).
    slabs: Vec<Vec<f64>>,
    /// `present[set][v]`: whether `That_v` was computed.
    present: Vec<Vec<bool>>,
    cache_status: CacheStatus,
    /// Bytes of source spectra [`M2lScheme::apply`] holds at once.
    spectra_budget: usize,
    _values: PhantomData<T>,
}

/// What a cached FFT scheme holds: one kernel slab per set, each
/// `blocks x SLAB_VECTORS x c^2 x W` values (always `f64`, whatever `T`;
/// every vector of every set).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
struct FftLayout {
    /// Frequency blocks of a spectrum.
    blocks: usize,
    /// Operator sets.
    sets: usize,
    /// Components `c` of the kernel.
    components: usize,
}

impl FftLayout {
    fn slab_len(&self) -> usize {
        self.blocks * SLAB_VECTORS * self.components * self.components * W
    }
}

impl StoreLayout for FftLayout {
    fn n_values(&self) -> Result<usize, String> {
        Ok(self.sets * self.slab_len())
    }
}

/// The kernel slabs of every set, as the operator cache stores them.
struct FftSlabs {
    layout: FftLayout,
    slabs: Vec<Vec<f64>>,
}

impl CachePayload<f64> for FftSlabs {
    type Layout = FftLayout;

    fn layout(&self) -> FftLayout {
        self.layout
    }

    fn arrays(&self) -> Vec<&[f64]> {
        self.slabs.iter().map(Vec::as_slice).collect()
    }

    fn from_values(layout: FftLayout, values: Vec<f64>) -> Result<Self, String> {
        let mut reader = ValueReader::new(values);
        let slabs = (0..layout.sets)
            .map(|_| reader.take(layout.slab_len()))
            .collect::<Result<_, _>>()?;
        reader.finish()?;
        Ok(FftSlabs { layout, slabs })
    }
}

impl<T: Real> FftM2l<T> {
    /// Whether `kernel` takes the complex path (see the module docs).
    fn convolves_complex<K: Kernel>(kernel: &K) -> bool {
        kernel.is_complex() && kernel.components() == 2
    }

    /// Spectra per box: 1 on the complex path, else `c`.
    fn spectra_per_box(&self) -> usize {
        if self.complex { 1 } else { self.components }
    }

    /// Frequencies of one spectrum: `N^3` on the complex path, else
    /// `N^2 (floor(N/2) + 1)`.
    fn spectrum_len(&self) -> usize {
        spectrum_len(&self.fft, self.complex)
    }

    /// The kernel grids `T_v` at half-width `h`, transformed: `c^2`
    /// spectra, entry `(a, b)` of the `c x c` block at `a c + b`; on the
    /// complex path one spectrum, of `Re T + i Im T` (entries `(0, 0)` and
    /// `(1, 0)`).
    fn kernel_spectra<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        fft: &Fft3d,
        h: f64,
        v: [i32; 3],
    ) -> Result<Vec<Vec<Complex<f64>>>, FieldError> {
        let c = kernel.components();
        let p = params.order as i32;
        let grid = grid_size(params.order);
        let r = params.radii.upward_equivalent;
        let delta = 2.0 * r * h / (p - 1) as f64;
        let source: [f64; 3] = std::array::from_fn(|d| 2.0 * h * v[d] as f64 - r * h);
        let offsets: Vec<[i32; 3]> = (-(p - 1)..p)
            .flat_map(|a| (-(p - 1)..p).flat_map(move |b| (-(p - 1)..p).map(move |c| [a, b, c])))
            .collect();
        let targets: Vec<f64> = offsets
            .iter()
            .flat_map(|m| (0..3).map(move |d| -r * h + delta * m[d] as f64))
            .collect();
        // One source: row `c m + a`, column `b` at `(c m + a) c + b`.
        let mut values = vec![0.0f64; offsets.len() * c * c];
        kernel.assemble::<f64>(&source, &targets, &mut values);
        if values.iter().any(|x| !x.is_finite()) {
            return Err(FieldError::NonFiniteKernel {
                kernel: kernel.name(),
                what: format!("an FFT M2L kernel grid (vector {v:?})"),
            });
        }
        let wrap = |m: i32| m.rem_euclid(grid as i32) as usize;
        let mut work = fft.workspace();
        if Self::convolves_complex(kernel) {
            let mut spectrum = vec![Complex::new(0.0, 0.0); fft.complex_len()];
            for (m, block) in offsets.iter().zip(values.chunks_exact(4)) {
                spectrum[(wrap(m[0]) * grid + wrap(m[1])) * grid + wrap(m[2])] =
                    Complex::new(block[0], block[2]);
            }
            fft.forward_complex(&mut spectrum, grid, &mut work);
            return Ok(vec![spectrum]);
        }
        let mut real = vec![0.0f64; fft.real_len()];
        let spectra = (0..c * c)
            .map(|ab| {
                for (m, block) in offsets.iter().zip(values.chunks_exact(c * c)) {
                    real[(wrap(m[0]) * grid + wrap(m[1])) * grid + wrap(m[2])] = block[ab];
                }
                let mut spectrum = vec![Complex::new(0.0, 0.0); fft.spectrum_len()];
                fft.forward(&real, &mut spectrum, grid, &mut work);
                spectrum
            })
            .collect();
        Ok(spectra)
    }

    /// The spectra of the source boxes of sibling group `g` (missing
    /// children zero) into `out` (`[block][8][c][W]`). `scratch.grid` must be
    /// zero off the lattice: a scratch used only here is (only lattice
    /// points are ever written to it; the inverse transforms use their own).
    fn source_group(
        &self,
        multipoles: &[T],
        siblings: &SiblingBlocks,
        g: usize,
        scratch: &mut Scratch,
        out: &mut [f64],
    ) {
        let c = self.components;
        let len = c * self.n;
        for cs in 0..8 {
            let Some(col) = siblings.source_column(8 * g + cs) else {
                continue;
            };
            let phi = &multipoles[col * len..(col + 1) * len];
            if self.complex {
                let spectrum = &mut scratch.spectrum;
                spectrum.fill(Complex::new(0.0, 0.0));
                for (&at, z) in self.lattice.iter().zip(phi.chunks_exact(2)) {
                    spectrum[at] = Complex::new(z[0].to_f64(), z[1].to_f64());
                }
                self.fft
                    .forward_complex(spectrum, self.order, &mut scratch.work);
                for (f, z) in spectrum.iter().enumerate() {
                    let at = ((f / FREQ_BLOCK) * 8 + cs) * W + f % FREQ_BLOCK;
                    out[at] = z.re;
                    out[at + FREQ_BLOCK] = z.im;
                }
                continue;
            }
            for b in 0..c {
                for (&at, x) in self.lattice.iter().zip(phi[b..].iter().step_by(c)) {
                    scratch.grid[at] = x.to_f64();
                }
                let spectrum = &mut scratch.spectrum;
                self.fft
                    .forward(&scratch.grid, spectrum, self.order, &mut scratch.work);
                for (f, z) in spectrum.iter().enumerate() {
                    let at = (((f / FREQ_BLOCK) * 8 + cs) * c + b) * W + f % FREQ_BLOCK;
                    out[at] = z.re;
                    out[at + FREQ_BLOCK] = z.im;
                }
            }
        }
    }

    /// Invert the target spectra `targets` of target groups `groups` and
    /// add `scale` times their lattice values to the check columns `out`
    /// (the first of them column `col0`).
    #[allow(clippy::too_many_arguments)]
    fn add_lattice_values(
        &self,
        siblings: &SiblingBlocks,
        groups: std::ops::Range<usize>,
        targets: &[f64],
        scale: f64,
        scratch: &mut Scratch,
        col0: usize,
        out: &mut [T],
    ) {
        let c = self.components;
        let n = c * self.n;
        let group_len = self.group_values();
        for (i, g) in groups.enumerate() {
            let hit = siblings.targets_hit(g);
            for ct in (0..8).filter(|ct| hit >> ct & 1 == 1) {
                let col = siblings
                    .target_column(8 * g + ct)
                    .expect("a target slot with pairs has a column");
                let y = &targets[i * group_len..(i + 1) * group_len];
                let column = &mut out[(col - col0) * n..(col - col0 + 1) * n];
                if self.complex {
                    let spectrum = &mut scratch.spectrum;
                    for (f, z) in spectrum.iter_mut().enumerate() {
                        let at = ((f / FREQ_BLOCK) * 8 + ct) * W + f % FREQ_BLOCK;
                        *z = Complex::new(y[at], y[at + FREQ_BLOCK]);
                    }
                    self.fft
                        .inverse_complex(spectrum, self.order, &mut scratch.work);
                    for (o, &at) in column.chunks_exact_mut(2).zip(&self.lattice) {
                        o[0] += T::from_f64(scale * spectrum[at].re);
                        o[1] += T::from_f64(scale * spectrum[at].im);
                    }
                    continue;
                }
                for a in 0..c {
                    for (f, z) in scratch.spectrum.iter_mut().enumerate() {
                        let at = (((f / FREQ_BLOCK) * 8 + ct) * c + a) * W + f % FREQ_BLOCK;
                        *z = Complex::new(y[at], y[at + FREQ_BLOCK]);
                    }
                    let Scratch {
                        grid,
                        spectrum,
                        work,
                    } = scratch;
                    self.fft.inverse(spectrum, grid, self.order, work);
                    for (o, &at) in column[a..].iter_mut().step_by(c).zip(&self.lattice) {
                        *o += T::from_f64(scale * grid[at]);
                    }
                }
            }
        }
    }

    /// Values of the spectra of one sibling group (`8` boxes'
    /// [`FftM2l::spectra_per_box`] spectra).
    fn group_values(&self) -> usize {
        self.blocks * 8 * self.spectra_per_box() * W
    }

    /// Bytes of the spectra of one sibling group.
    fn group_bytes(&self) -> usize {
        self.group_values() * std::mem::size_of::<f64>()
    }

    /// One thread's buffers: a real grid (unused on the complex path) and
    /// a spectrum (the complex path's grid too).
    fn scratch(&self) -> Scratch {
        Scratch {
            grid: if self.complex {
                Vec::new()
            } else {
                vec![0.0f64; self.fft.real_len()]
            },
            spectrum: vec![Complex::new(0.0, 0.0); self.spectrum_len()],
            work: self.fft.workspace(),
        }
    }

    /// Source groups whose spectra fit the budget (at least one).
    fn groups_per_run(&self) -> usize {
        (self.spectra_budget / self.group_bytes()).max(1)
    }

    /// Hold at most `bytes` of source spectra at once in
    /// [`M2lScheme::apply`] (default [`SPECTRA_BUDGET_BYTES`]; at least one
    /// target group's sources are held whatever the budget). A smaller
    /// budget repeats more forward transforms; the results do not change.
    pub fn set_spectra_budget(&mut self, bytes: usize) {
        self.spectra_budget = bytes;
    }

    /// Panic unless every vector of `interactions` is in operator set
    /// `set` (the contract of [`M2lScheme::apply`]).
    fn assert_present(&self, set: usize, interactions: &M2lInteractions) {
        // From the sibling blocks: the pair lists may have been released
        // ([`M2lScheme::reads_pair_lists`]).
        let siblings = interactions.sibling_blocks();
        for (v, &present) in self.present[set].iter().enumerate() {
            assert!(
                present || !siblings.uses_vector(v),
                "apply called with a transfer vector the scheme was not built for"
            );
        }
    }
}

/// The convolution grid size for order `p`: the smallest `N >= 2p - 1`
/// whose prime factors are 2, 3, 5 and 7 (prime sizes such as 19 run
/// several times slower in the FFT library than the 20 next to them).
pub(crate) fn grid_size(p: usize) -> usize {
    let smooth = |mut m: usize| {
        for f in [2, 3, 5, 7] {
            while m.is_multiple_of(f) {
                m /= f;
            }
        }
        m == 1
    };
    (2 * p - 1..)
        .find(|&m| smooth(m))
        .expect("smooth numbers are unbounded")
}

/// Frequencies of one spectrum: `N^3` for complex grids, else
/// `N^2 (floor(N/2) + 1)`.
fn spectrum_len(fft: &Fft3d, complex: bool) -> usize {
    if complex {
        fft.complex_len()
    } else {
        fft.spectrum_len()
    }
}

/// One thread's buffers in [`FftM2l::apply`].
struct Scratch {
    /// A real grid (`N^3`; empty on the complex path).
    grid: Vec<f64>,
    /// A spectrum (on the complex path also the grid transformed in place).
    spectrum: Vec<Complex<f64>>,
    /// The transforms' scratch.
    work: FftWorkspace,
}

/// Check that the surfaces lie on one lattice.
fn check_radii(params: &OperatorParams) -> Result<(), FieldError> {
    let r = &params.radii;
    if r.upward_equivalent != r.downward_check {
        return Err(FieldError::InvalidParams(format!(
            "FFT M2L needs equal upward equivalent and downward check radii \
             (got {} and {})",
            r.upward_equivalent, r.downward_check
        )));
    }
    Ok(())
}

impl<T: Real> M2lScheme<T> for FftM2l<T> {
    type Config = FftConfig;
    const COST_SHAPE: super::M2lCostShape = super::M2lCostShape::Fft;

    fn name(&self) -> &'static str {
        "fft"
    }

    fn precompute_for<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        _config: &Self::Config,
        domain_width: f64,
        depth: u32,
        usage: &M2lUsage,
    ) -> Result<Self, FieldError> {
        params.validate()?;
        check_radii(params)?;
        params.monitor.check()?;
        let c = kernel.components();
        let complex = Self::convolves_complex(kernel);
        // Spectra per box.
        let s = if complex { 1 } else { c };
        let plan = Plan::new(kernel, params, domain_width, depth, usage)?;
        let (levels, sets) = (&plan.levels, &plan.sets);
        let grid = grid_size(params.order);
        let fft = Fft3d::new(grid);
        let blocks = spectrum_len(&fft, complex).div_ceil(FREQ_BLOCK);
        let lattice = unit_surface(params.order)
            .iter()
            .map(|u| {
                let i =
                    |d: usize| ((u[d] + 1.0) * 0.5 * (params.order - 1) as f64).round() as usize;
                (i(0) * grid + i(1)) * grid + i(2)
            })
            .collect();
        let vectors = transfer_vectors();
        // Without a cache file there is nothing to keep complete: the plan
        // has only the used vectors (with one, `planned_sets` gives all 316).
        let n_sets = sets.len();
        let cc = s * s;
        let slab_len = blocks * SLAB_VECTORS * cc * W;
        let compute_set = |set: usize, wanted: &[usize]| -> Result<Vec<f64>, FieldError> {
            if wanted.is_empty() {
                // A level (or a tree) without V pairs holds no slab.
                return Ok(Vec::new());
            }
            let h = levels.set_half_width(set);
            let computed: Vec<(usize, Vec<Vec<Complex<f64>>>)> = wanted
                .par_iter()
                .map(|&vi| {
                    params.monitor.check()?;
                    Ok((
                        vi,
                        Self::kernel_spectra(kernel, params, &fft, h, vectors[vi])?,
                    ))
                })
                .collect::<Result<_, FieldError>>()?;
            let mut slab = vec![0.0f64; slab_len];
            for (vi, spectra) in computed {
                for (ab, spectrum) in spectra.iter().enumerate() {
                    for (f, z) in spectrum.iter().enumerate() {
                        let at =
                            (((f / FREQ_BLOCK) * SLAB_VECTORS + vi) * cc + ab) * W + f % FREQ_BLOCK;
                        slab[at] = z.re;
                        slab[at + FREQ_BLOCK] = z.im;
                    }
                }
            }
            Ok(slab)
        };
        let key = || {
            let mut key =
                CacheKey::new::<K, f64>("m2l-fft", kernel, params.order, params.radii.to_array())
                    .for_domain(domain_width, depth);
            key.scheme_config = if complex {
                format!("grid {grid}, complex")
            } else {
                format!("grid {grid}")
            };
            key
        };
        let layout = FftLayout {
            blocks,
            sets: n_sets,
            components: s,
        };
        let compute = || -> Result<FftSlabs, FieldError> {
            let slabs = sets
                .iter()
                .enumerate()
                .map(|(set, wanted)| compute_set(set, wanted))
                .collect::<Result<_, _>>()?;
            Ok(FftSlabs { layout, slabs })
        };
        let (store, cache_status) = plan.load_or_compute(params, key, layout.accept(), compute)?;
        let slabs = store.slabs;
        let present = sets
            .iter()
            .map(|wanted| {
                let mut has = vec![false; vectors.len()];
                for &vi in wanted {
                    has[vi] = true;
                }
                has
            })
            .collect();
        Ok(FftM2l {
            n: n_surface_points(params.order),
            components: c,
            complex,
            order: params.order,
            levels: plan.levels,
            fft,
            lattice,
            blocks,
            slabs,
            present,
            cache_status,
            spectra_budget: SPECTRA_BUDGET_BYTES,
            _values: PhantomData,
        })
    }

    fn estimate<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        _config: &Self::Config,
        depth: u32,
        usage: &M2lUsage,
    ) -> PrecomputeEstimate {
        let sets = planned_sets(kernel.homogeneity().is_some(), params, depth, usage);
        // `c^2` kernel spectra per vector (one of `N^3` values complex).
        let complex = Self::convolves_complex(kernel);
        let c = kernel.components() as f64;
        let cc = if complex { 1.0 } else { c * c };
        let m: usize = sets.iter().map(Vec::len).sum();
        let grid = grid_size(params.order) as f64;
        let spectrum = if complex {
            grid.powi(3)
        } else {
            grid * grid * (grid / 2.0 + 1.0)
        };
        // Kernel grid (~20 flops per value) and a 3D FFT (~5 N^3 log2 N^3;
        // the complex one twice that, for one transform instead of four).
        let transforms = if complex { 2.0 } else { cc };
        let flops = m as f64
            * (20.0 * c * c * grid.powi(3) + transforms * 15.0 * grid.powi(3) * grid.log2());
        // The slabs hold every vector of a used set; each computed spectrum
        // is held once more until it is filed.
        let used_sets = sets.iter().filter(|w| !w.is_empty()).count() as f64;
        PrecomputeEstimate {
            matrices: m,
            peak_bytes: ((used_sets * SLAB_VECTORS as f64 + m as f64) * cc * spectrum * 16.0)
                as u64,
            flops,
            seconds: seconds_for(flops),
        }
    }

    fn apply(&self, level: u32, interactions: &M2lInteractions, multipoles: &[T], check: &mut [T]) {
        self.apply_with_progress(level, interactions, multipoles, check, M2lProgress::none());
    }

    /// Reports each source group transformed and each task of target
    /// groups done, weighted by their rough cost (a target group's
    /// products and inverse transforms count `TARGET_GROUP_WEIGHT`, a
    /// source group's forward transform `SOURCE_GROUP_WEIGHT`).
    fn apply_with_progress(
        &self,
        level: u32,
        interactions: &M2lInteractions,
        multipoles: &[T],
        check: &mut [T],
        progress: M2lProgress<'_>,
    ) {
        let c = self.components;
        let n = c * self.n;
        check_lengths(n, interactions, multipoles, check);
        if interactions.is_empty() {
            return;
        }
        let (set, scale) = self.levels.lookup(level, 1.0);
        self.assert_present(set, interactions);
        let siblings = interactions.sibling_blocks();
        let group_len = self.group_values();
        let s = self.spectra_per_box();
        let scratch = || self.scratch();
        let kernels = &self.slabs[set];
        let level_simd = SimdLevel::active();
        let threads = rayon::current_num_threads().max(1);
        // Runs of target groups whose source spectra fit the budget
        // ([`chunks`]); the slot of each source group in the run's spectra.
        let max_groups = self.groups_per_run();
        let mut slots = vec![0u32; siblings.n_source_groups()];
        let mut sources: Vec<f64> = Vec::new();
        let mut rest = check;
        let chunks = plan_chunks(siblings, max_groups);
        let total: u64 = if progress.is_active() {
            chunks
                .iter()
                .map(|c| {
                    SOURCE_GROUP_WEIGHT * c.sources.len() as u64
                        + TARGET_GROUP_WEIGHT * c.targets.len() as u64
                })
                .sum()
        } else {
            0
        };
        for chunk in chunks {
            for (slot, &g) in chunk.sources.iter().enumerate() {
                slots[g as usize] = slot as u32;
            }
            // Spectra of the run's source groups.
            sources.clear();
            sources.resize(chunk.sources.len() * group_len, 0.0);
            sources
                .par_chunks_mut(group_len)
                .zip(&chunk.sources)
                .for_each_init(scratch, |scratch, (out, &g)| {
                    self.source_group(multipoles, siblings, g as usize, scratch, out);
                    progress.advance(SOURCE_GROUP_WEIGHT, total);
                });
            // Tasks of consecutive target groups: products, inverse FFTs,
            // lattice values into the task's own check columns
            // (consecutive: the slots increase with the column).
            let n_groups = chunk.targets.len();
            let per_task = n_groups.div_ceil(4 * threads).clamp(1, GROUPS_PER_TASK);
            let mut tasks = Vec::with_capacity(n_groups.div_ceil(per_task));
            for first in chunk.targets.clone().step_by(per_task) {
                let groups = first..(first + per_task).min(chunk.targets.end);
                let columns = siblings.group_columns(groups.clone());
                let (mine, next) = std::mem::take(&mut rest).split_at_mut(columns.len() * n);
                tasks.push((groups, columns.start, mine));
                rest = next;
            }
            let (sources, slots) = (&sources, &slots);
            tasks.into_par_iter().for_each_init(
                || (scratch(), Vec::new(), Vec::new()),
                |(scratch, targets, tables), (groups, col0, out)| {
                    targets.clear();
                    targets.resize(groups.len() * group_len, 0.0);
                    block_tables(siblings, groups.clone(), tables);
                    let products = Products {
                        components: One,
                        kernels,
                        sources,
                        source_slots: slots,
                        siblings,
                        tables,
                        first: groups.start,
                        targets,
                        blocks: self.blocks,
                    };
                    if s == 1 {
                        run_task(level_simd, products);
                    } else {
                        run_task(level_simd, products.with_components(Many(s)));
                    }
                    let done = TARGET_GROUP_WEIGHT * groups.len() as u64;
                    self.add_lattice_values(siblings, groups, targets, scale, scratch, col0, out);
                    progress.advance(done, total);
                },
            );
        }
    }

    fn cache_status(&self) -> CacheStatus {
        self.cache_status.clone()
    }

    /// `false`: the products read the sibling blocks only.
    fn reads_pair_lists(&self) -> bool {
        false
    }

    fn memory_bytes(&self) -> usize {
        let values: usize = self.slabs.iter().map(Vec::len).sum();
        values * std::mem::size_of::<f64>()
    }

    /// The source spectra held at once: those of the largest run
    /// (the `chunks` module), at most the budget (or one target group's sources);
    /// and per thread the target spectra and the blocks' slab tables of a
    /// task and the transforms' grids.
    fn apply_scratch_bytes(&self, interactions: &M2lInteractions) -> usize {
        let group = self.group_bytes();
        let siblings = interactions.sibling_blocks();
        let largest = plan_chunks(siblings, self.groups_per_run())
            .iter()
            .map(|c| c.sources.len())
            .max()
            .unwrap_or(0);
        // A target group has at most one block per parent offset (26).
        let tables = GROUPS_PER_TASK
            * (crate::siblings::N_PARENT_OFFSETS - 1)
            * std::mem::size_of::<hadamard::BlockTable>();
        let grid = if self.complex {
            0
        } else {
            self.fft.real_len() * 8
        };
        let per_thread = GROUPS_PER_TASK * group + tables + 2 * (grid + self.spectrum_len() * 16);
        largest * group + rayon::current_num_threads() * per_thread
    }

    fn flops(&self, interactions: &M2lInteractions) -> f64 {
        let s = self.spectra_per_box() as f64;
        8.0 * s * s * self.spectrum_len() as f64 * interactions.len() as f64
    }
}
