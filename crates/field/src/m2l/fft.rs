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
//! grid of `N = 2p` points per axis the circular convolution equals it at
//! the target nodes, so with hats for 3D real FFTs ([`crate::fft3d`])
//!
//! ```text
//! check_t = IFFT( sum_{(t, s, v)} That_v * phihat_s )   (pointwise products),
//! ```
//!
//! one forward FFT per source box, one inverse per target box, and
//! (in frequency blocks of 8, real and imaginary parts apart, so that one
//! block of every source's spectrum stays in cache and the products
//! vectorise)
//! `N^2 (N/2 + 1)` complex multiply-adds per pair, against
//! `n^2 = (6 (p-1)^2 + 2)^2` for [`DenseM2l`](crate::DenseM2l): fewer from
//! `p ~ 4` on, and
//! the precomputation is 316 kernel grids and FFTs (no SVD). The kernel
//! spectra are kept in `f64` (`316 N^2 (N/2 + 1)` complex values per set:
//! 5 MB at `p = 6`, 31 MB at `p = 10`), and the products run in `f64`
//! whatever `T` is. It is exact up to rounding: the same operator as dense
//! M2L.
//!
//! Not yet done (issue 13): grouping the eight children of a parent so
//! that the Hadamard products become 8x8 blocks, SIMD for them, and the
//! operator cache (an FFT scheme's precomputation takes milliseconds).

use std::marker::PhantomData;

use ferrofmm_kernels::{Kernel, Real};
use rayon::prelude::*;
use rustfft::num_complex::Complex;

use super::{FIRST_M2L_LEVEL, M2lScheme, check_lengths, for_each_chunk, planned_sets};
use crate::fft3d::Fft3d;
use crate::levels::LevelMap;
use crate::precompute::effective_threads;
use crate::surface::unit_surface;
use crate::{
    FieldError, M2lInteractions, M2lUsage, OperatorParams, PrecomputeEstimate, n_surface_points,
    transfer_vectors,
};

/// Frequencies handled together in the pointwise products: one block of
/// every source column's spectrum (`16 B` bytes each) stays in cache while
/// all pairs use it.
const FREQUENCY_BLOCK: usize = 8;

/// Configuration of [`FftM2l`] (nothing to configure).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FftConfig;

/// FFT-accelerated M2L (see the [module documentation](self)).
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
    n: usize,
    levels: LevelMap,
    fft: Fft3d,
    /// Flat grid index of each surface point.
    lattice: Vec<usize>,
    /// `spectra[set][vector]`: `That_v` in frequency blocks (see
    /// [`to_blocks`]), `None` when not precomputed.
    spectra: Vec<Vec<Option<Vec<f64>>>>,
    _values: PhantomData<T>,
}

impl<T: Real> FftM2l<T> {
    /// The kernel grid `T_v` at half-width `h`, transformed.
    fn kernel_spectrum<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        fft: &Fft3d,
        h: f64,
        v: [i32; 3],
    ) -> Result<Vec<Complex<f64>>, FieldError> {
        let p = params.order as i32;
        let grid = 2 * params.order;
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
        let mut values = vec![0.0f64; offsets.len()];
        kernel.assemble::<f64>(&source, &targets, &mut values);
        if values.iter().any(|x| !x.is_finite()) {
            return Err(FieldError::NonFiniteKernel {
                kernel: kernel.name(),
                what: format!("an FFT M2L kernel grid (vector {v:?})"),
            });
        }
        let wrap = |m: i32| m.rem_euclid(grid as i32) as usize;
        let mut real = vec![0.0f64; fft.real_len()];
        for (m, value) in offsets.iter().zip(values) {
            real[(wrap(m[0]) * grid + wrap(m[1])) * grid + wrap(m[2])] = value;
        }
        let mut spectrum = vec![Complex::new(0.0, 0.0); fft.spectrum_len()];
        fft.forward(&mut real, &mut spectrum);
        Ok(spectrum)
    }
}

/// Block `b` of a spectrum as `B` real parts then `B` imaginary parts
/// (zeros past the end), the layout of the pointwise products.
fn write_block(spectrum: &[Complex<f64>], b: usize, out: &mut [f64]) {
    let f0 = b * FREQUENCY_BLOCK;
    for i in 0..FREQUENCY_BLOCK {
        let c = spectrum.get(f0 + i).copied().unwrap_or_default();
        out[i] = c.re;
        out[FREQUENCY_BLOCK + i] = c.im;
    }
}

/// A whole spectrum in frequency blocks ([`write_block`]).
fn to_blocks(spectrum: &[Complex<f64>]) -> Vec<f64> {
    let blocks = spectrum.len().div_ceil(FREQUENCY_BLOCK);
    let mut out = vec![0.0; 2 * FREQUENCY_BLOCK * blocks];
    for (b, block) in out.chunks_exact_mut(2 * FREQUENCY_BLOCK).enumerate() {
        write_block(spectrum, b, block);
    }
    out
}

/// `acc += k * x` for one frequency block of complex values (real parts
/// first, then imaginary parts; fixed length, so the loop vectorises).
#[inline(always)]
fn multiply_add(
    acc: &mut [f64; 2 * FREQUENCY_BLOCK],
    k: &[f64; 2 * FREQUENCY_BLOCK],
    x: &[f64; 2 * FREQUENCY_BLOCK],
) {
    const B: usize = FREQUENCY_BLOCK;
    for i in 0..B {
        let (kr, ki, xr, xi) = (k[i], k[B + i], x[i], x[B + i]);
        acc[i] += kr * xr - ki * xi;
        acc[B + i] += kr * xi + ki * xr;
    }
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

    fn name(&self) -> &'static str {
        "fft"
    }

    fn precompute<K: Kernel>(
        kernel: &K,
        params: &OperatorParams,
        config: &Self::Config,
        domain_width: f64,
        depth: u32,
    ) -> Result<Self, FieldError> {
        Self::precompute_for(
            kernel,
            params,
            config,
            domain_width,
            depth,
            &M2lUsage::all(depth),
        )
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
        let levels = LevelMap::new(kernel.homogeneity(), domain_width, depth, FIRST_M2L_LEVEL)?;
        let grid = 2 * params.order;
        let fft = Fft3d::new(grid);
        let lattice = unit_surface(params.order)
            .iter()
            .map(|u| {
                let i =
                    |d: usize| ((u[d] + 1.0) * 0.5 * (params.order - 1) as f64).round() as usize;
                (i(0) * grid + i(1)) * grid + i(2)
            })
            .collect();
        let vectors = transfer_vectors();
        // Without a cache file there is nothing to keep complete: compute
        // only the used vectors.
        let mut plain = params.clone();
        plain.cache_dir = None;
        let sets = planned_sets(kernel.homogeneity().is_some(), &plain, depth, usage);
        let mut spectra = Vec::with_capacity(sets.len());
        for (set, wanted) in sets.into_iter().enumerate() {
            let h = levels.set_half_width(set);
            let computed: Vec<(usize, Vec<f64>)> = wanted
                .par_iter()
                .map(|&vi| {
                    params.monitor.check()?;
                    let spectrum = Self::kernel_spectrum(kernel, params, &fft, h, vectors[vi])?;
                    Ok((vi, to_blocks(&spectrum)))
                })
                .collect::<Result<_, FieldError>>()?;
            let mut row: Vec<Option<Vec<f64>>> = vec![None; vectors.len()];
            for (vi, s) in computed {
                row[vi] = Some(s);
            }
            spectra.push(row);
        }
        Ok(FftM2l {
            n: n_surface_points(params.order),
            levels,
            fft,
            lattice,
            spectra,
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
        let mut plain = params.clone();
        plain.cache_dir = None;
        let m: usize = planned_sets(kernel.homogeneity().is_some(), &plain, depth, usage)
            .iter()
            .map(Vec::len)
            .sum();
        let grid = (2 * params.order) as f64;
        let spectrum = grid * grid * (grid / 2.0 + 1.0);
        let threads = effective_threads() as f64;
        // Kernel grid (~20 flops per value) and a 3D FFT (~5 N^3 log2 N^3).
        let flops = m as f64 * (20.0 * grid.powi(3) + 15.0 * grid.powi(3) * grid.log2());
        PrecomputeEstimate {
            matrices: m,
            peak_bytes: (m as f64 * spectrum * 16.0) as u64,
            flops,
            seconds: flops / (crate::precompute::FLOPS_PER_THREAD * threads),
        }
    }

    fn apply(&self, level: u32, interactions: &M2lInteractions, multipoles: &[T], check: &mut [T]) {
        let n = self.n;
        check_lengths(n, interactions, multipoles, check);
        if interactions.is_empty() {
            return;
        }
        let (set, scale) = self.levels.lookup(level, 1.0);
        let len = self.fft.spectrum_len();
        let blocks = len.div_ceil(FREQUENCY_BLOCK);
        let cols = interactions.n_source_cols();
        // Spectra of every source column's density on the lattice, then
        // frequency-blocked: block b of column s at (b cols + s) B, so that
        // one block of all columns (cols B values) stays in cache while
        // every pair of a chunk uses it.
        let mut by_column = vec![Complex::new(0.0, 0.0); cols * len];
        by_column
            .par_chunks_mut(len)
            .zip(multipoles.par_chunks(n))
            .for_each_init(
                || vec![0.0f64; self.fft.real_len()],
                |grid, (spectrum, phi)| {
                    grid.fill(0.0);
                    for (&at, &x) in self.lattice.iter().zip(phi) {
                        grid[at] = x.to_f64();
                    }
                    self.fft.forward(grid, spectrum);
                },
            );
        const W: usize = 2 * FREQUENCY_BLOCK;
        let mut sources = vec![0.0f64; blocks * cols * W];
        sources
            .par_chunks_mut(cols * W)
            .enumerate()
            .for_each(|(b, block)| {
                for (s, out) in block.chunks_exact_mut(W).enumerate() {
                    write_block(&by_column[s * len..(s + 1) * len], b, out);
                }
            });
        drop(by_column);
        let kernels = &self.spectra[set];
        for_each_chunk(interactions, n, check, |chunk, out| {
            let targets = chunk.n_targets();
            let mut sums = vec![0.0f64; blocks * targets * W];
            let mut touched = vec![false; targets];
            for g in chunk.groups() {
                for &t in g.targets {
                    touched[t as usize] = true;
                }
            }
            for (b, sum_block) in sums.chunks_exact_mut(targets * W).enumerate() {
                let source_block = &sources[b * cols * W..(b + 1) * cols * W];
                for g in chunk.groups() {
                    let kernel = kernels[g.vector]
                        .as_deref()
                        .expect("apply called with a transfer vector the scheme was not built for");
                    let k: &[f64; W] = kernel[b * W..(b + 1) * W].try_into().expect("W values");
                    for (&s, &t) in g.sources.iter().zip(g.targets) {
                        let x: &[f64; W] = source_block[s as usize * W..][..W]
                            .try_into()
                            .expect("W values");
                        let acc: &mut [f64; W] = (&mut sum_block[t as usize * W..][..W])
                            .try_into()
                            .expect("W values");
                        multiply_add(acc, k, x);
                    }
                }
            }
            let mut spectrum = vec![Complex::new(0.0, 0.0); len];
            let mut grid = vec![0.0f64; self.fft.real_len()];
            for t in (0..targets).filter(|&t| touched[t]) {
                for (b, part) in spectrum.chunks_mut(FREQUENCY_BLOCK).enumerate() {
                    let at = (b * targets + t) * W;
                    for (i, c) in part.iter_mut().enumerate() {
                        *c = Complex::new(sums[at + i], sums[at + FREQUENCY_BLOCK + i]);
                    }
                }
                self.fft.inverse(&mut spectrum, &mut grid);
                for (o, &at) in out[t * n..(t + 1) * n].iter_mut().zip(&self.lattice) {
                    *o += T::from_f64(scale * grid[at]);
                }
            }
        });
    }

    fn memory_bytes(&self) -> usize {
        let values: usize = self.spectra.iter().flatten().flatten().map(Vec::len).sum();
        values * std::mem::size_of::<f64>()
    }

    fn flops(&self, interactions: &M2lInteractions) -> f64 {
        8.0 * self.fft.spectrum_len() as f64 * interactions.len() as f64
    }
}
