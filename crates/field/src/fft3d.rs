//! Three-dimensional real FFTs on an `N x N x N` grid (pure Rust: realfft
//! on rustfft), for the FFT M2L scheme.
//!
//! The forward transform of a real grid `g[x][y][z]` (flat index
//! `(x N + y) N + z`) is
//!
//! ```text
//! G[a][b][c] = sum_{x,y,z} g[x][y][z] e^{-2 pi i (a x + b y + c z) / N},  c = 0..=floor(N/2),
//! ```
//!
//! stored at `(a N + b) H + c` with `H = floor(N/2) + 1` (the other half follows
//! from `G[-a][-b][-c] = conj(G[a][b][c])`). It runs as real-to-complex
//! transforms along `z`, then complex transforms along `y` and `x`; the
//! inverse undoes them in reverse order and divides by `N^3`, so that
//! `inverse(forward(g)) = g` and a pointwise product of two spectra is the
//! spectrum of the circular convolution of the grids.
//!
//! A complex grid (a complex kernel's densities, [`Fft3d::forward_complex`])
//! has no such symmetry: its spectrum is all `N^3` values `G[a][b][c]`,
//! stored at `(a N + b) N + c`, computed in place by complex transforms
//! along `z`, `y` and `x`. One complex spectrum holds what the real and
//! imaginary parts' two half spectra hold, and the convolution of a
//! complex kernel with complex densities is one pointwise product per
//! frequency instead of four.

use std::sync::Arc;

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// Planned transforms for one grid size `N`.
pub(crate) struct Fft3d {
    n: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

/// Scratch space of [`Fft3d::forward`] and [`Fft3d::inverse`], made once
/// per thread ([`Fft3d::workspace`]) and reused for every transform, so
/// that no transform allocates or zero-fills.
pub(crate) struct FftWorkspace {
    /// Lines gathered for one batched complex transform (`N^2 H`; grown
    /// to `N^3` by the first transform of a complex grid along `x`).
    lines: Vec<Complex<f64>>,
    /// The complex plans' scratch.
    complex: Vec<Complex<f64>>,
    /// The real plans' scratch.
    real: Vec<Complex<f64>>,
    /// One real line.
    real_line: Vec<f64>,
    /// One half-spectrum line.
    half_line: Vec<Complex<f64>>,
}

impl Fft3d {
    /// Scratch space for this size's transforms.
    pub(crate) fn workspace(&self) -> FftWorkspace {
        let (n, h) = (self.n, self.n / 2 + 1);
        let complex = self
            .forward
            .get_inplace_scratch_len()
            .max(self.inverse.get_inplace_scratch_len());
        let real = self.r2c.get_scratch_len().max(self.c2r.get_scratch_len());
        FftWorkspace {
            lines: vec![Complex::new(0.0, 0.0); n * n * h],
            complex: vec![Complex::new(0.0, 0.0); complex],
            real: vec![Complex::new(0.0, 0.0); real],
            real_line: vec![0.0; n],
            half_line: vec![Complex::new(0.0, 0.0); h],
        }
    }

    /// Plans for an `n x n x n` grid.
    ///
    /// # Panics
    /// When `n` is zero.
    pub(crate) fn new(n: usize) -> Self {
        assert!(n > 0, "FFT grid size must be positive");
        let mut real = RealFftPlanner::<f64>::new();
        let mut complex = FftPlanner::<f64>::new();
        Fft3d {
            n,
            r2c: real.plan_fft_forward(n),
            c2r: real.plan_fft_inverse(n),
            forward: complex.plan_fft_forward(n),
            inverse: complex.plan_fft_inverse(n),
        }
    }

    /// Values of one real grid: `N^3`.
    pub(crate) fn real_len(&self) -> usize {
        self.n * self.n * self.n
    }

    /// Values of one spectrum: `N^2 (floor(N/2) + 1)`.
    pub(crate) fn spectrum_len(&self) -> usize {
        self.n * self.n * (self.n / 2 + 1)
    }

    /// `spectrum = forward(grid)` for a grid that is zero outside
    /// `[0, support)^3` (`support = N`: any grid). Lines that are all zero
    /// are skipped (with `support = p`, about `N/2` of the grid, the
    /// transform costs ~60% of a full one); `grid` is not changed.
    pub(crate) fn forward(
        &self,
        grid: &[f64],
        spectrum: &mut [Complex<f64>],
        support: usize,
        work: &mut FftWorkspace,
    ) {
        let (n, h, support) = self.dims(grid, spectrum, support);
        spectrum.fill(Complex::new(0.0, 0.0));
        for x in 0..support {
            for y in 0..support {
                let line = &mut work.real_line;
                line.copy_from_slice(&grid[(x * n + y) * n..(x * n + y + 1) * n]);
                self.r2c
                    .process_with_scratch(
                        line,
                        &mut spectrum[(x * n + y) * h..][..h],
                        &mut work.real,
                    )
                    .expect("lengths match the plan");
            }
        }
        for x in 0..support {
            self.along_y(spectrum, x, &self.forward, work, n);
        }
        self.along_x(spectrum, &self.forward, work, n);
    }

    /// `grid = inverse(spectrum)` (divided by `N^3`) at the points of
    /// `[0, support)^3`; the rest of `grid` is left as it was (`support =
    /// N`: all of it). `spectrum` is used as scratch.
    pub(crate) fn inverse(
        &self,
        spectrum: &mut [Complex<f64>],
        grid: &mut [f64],
        support: usize,
        work: &mut FftWorkspace,
    ) {
        let (n, h, support) = self.dims(grid, spectrum, support);
        self.along_x(spectrum, &self.inverse, work, support);
        for x in 0..support {
            self.along_y(spectrum, x, &self.inverse, work, support);
        }
        let norm = 1.0 / (n * n * n) as f64;
        for x in 0..support {
            for y in 0..support {
                let line = &mut work.half_line;
                line.copy_from_slice(&spectrum[(x * n + y) * h..][..h]);
                // A real signal's z-spectrum has a real DC term (and a real
                // Nyquist term for even `N`); drop the rounding left in
                // their imaginary parts.
                line[0].im = 0.0;
                if n.is_multiple_of(2) {
                    line[h - 1].im = 0.0;
                }
                let out = &mut grid[(x * n + y) * n..][..n];
                self.c2r
                    .process_with_scratch(line, out, &mut work.real)
                    .expect("lengths match the plan and the end terms are real");
                for v in out.iter_mut() {
                    *v *= norm;
                }
            }
        }
    }

    /// Values of one complex grid and of its spectrum: `N^3`.
    pub(crate) fn complex_len(&self) -> usize {
        self.real_len()
    }

    /// The spectrum of a complex grid, in place: on entry `data` is the grid
    /// (flat index `(x N + y) N + z`), zero outside `[0, support)^3`; on
    /// return it is `G[a][b][c]` at `(a N + b) N + c`. The `z` lines of
    /// zero `(x, y)` and the `y` lines of zero planes are skipped.
    pub(crate) fn forward_complex(
        &self,
        data: &mut [Complex<f64>],
        support: usize,
        work: &mut FftWorkspace,
    ) {
        let (n, support) = self.complex_dims(data, support);
        for x in 0..support {
            for y in 0..support {
                self.forward
                    .process_with_scratch(&mut data[(x * n + y) * n..][..n], &mut work.complex);
            }
        }
        for x in 0..support {
            Self::along(
                &mut data[x * n * n..(x + 1) * n * n],
                n,
                &self.forward,
                work,
                n,
            );
        }
        Self::along(data, n * n, &self.forward, work, n);
    }

    /// The inverse of [`Fft3d::forward_complex`] (divided by `N^3`), in
    /// place, correct at the points of `[0, support)^3` (the rest of
    /// `data` is scratch on return).
    pub(crate) fn inverse_complex(
        &self,
        data: &mut [Complex<f64>],
        support: usize,
        work: &mut FftWorkspace,
    ) {
        let (n, support) = self.complex_dims(data, support);
        Self::along(data, n * n, &self.inverse, work, support);
        for x in 0..support {
            Self::along(
                &mut data[x * n * n..(x + 1) * n * n],
                n,
                &self.inverse,
                work,
                support,
            );
        }
        let norm = 1.0 / (n * n * n) as f64;
        for x in 0..support {
            for y in 0..support {
                let line = &mut data[(x * n + y) * n..][..n];
                self.inverse.process_with_scratch(line, &mut work.complex);
                for v in &mut line[..support] {
                    *v *= norm;
                }
            }
        }
    }

    /// `(N, min(support, N))`, after checking the length of a complex grid.
    fn complex_dims(&self, data: &[Complex<f64>], support: usize) -> (usize, usize) {
        assert_eq!(data.len(), self.complex_len());
        (self.n, support.min(self.n))
    }

    /// `(N, N/2 + 1, min(support, N))`, after checking the lengths of a
    /// grid and a spectrum.
    fn dims(
        &self,
        grid: &[f64],
        spectrum: &[Complex<f64>],
        support: usize,
    ) -> (usize, usize, usize) {
        assert_eq!(grid.len(), self.real_len());
        assert_eq!(spectrum.len(), self.spectrum_len());
        (self.n, self.n / 2 + 1, support.min(self.n))
    }

    /// Transform along `y` every `c` column of plane `x`, keeping the first
    /// `keep` outputs of each (all `N` for a forward step).
    fn along_y(
        &self,
        spectrum: &mut [Complex<f64>],
        x: usize,
        fft: &Arc<dyn Fft<f64>>,
        work: &mut FftWorkspace,
        keep: usize,
    ) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let plane = &mut spectrum[x * n * h..(x + 1) * n * h];
        Self::along(plane, h, fft, work, keep);
    }

    /// Transform along `x` every `(y, c)` line, keeping the first `keep`
    /// outputs of each.
    fn along_x(
        &self,
        spectrum: &mut [Complex<f64>],
        fft: &Arc<dyn Fft<f64>>,
        work: &mut FftWorkspace,
        keep: usize,
    ) {
        let m = self.n * (self.n / 2 + 1);
        Self::along(spectrum, m, fft, work, keep);
    }

    /// Transform the `stride` lines of `data` along its slowest index
    /// (element `k` of line `l` at `k stride + l`, `k < N`), keeping the
    /// first `keep` outputs of each: the lines are gathered contiguous into
    /// the workspace, transformed in one batch and scattered back.
    fn along(
        data: &mut [Complex<f64>],
        stride: usize,
        fft: &Arc<dyn Fft<f64>>,
        work: &mut FftWorkspace,
        keep: usize,
    ) {
        let n = data.len() / stride;
        if work.lines.len() < n * stride {
            work.lines.resize(n * stride, Complex::new(0.0, 0.0));
        }
        let lines = &mut work.lines[..n * stride];
        for k in 0..n {
            for l in 0..stride {
                lines[l * n + k] = data[k * stride + l];
            }
        }
        fft.process_with_scratch(lines, &mut work.complex);
        for k in 0..keep {
            for l in 0..stride {
                data[k * stride + l] = lines[l * n + k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Round trip, and a pointwise product is a circular convolution.
    #[test]
    fn inverse_of_forward_and_convolution() {
        for n in [6, 7] {
            round_trip_and_convolution(n);
        }
    }

    /// The complex transforms: round trip, a pointwise product is a
    /// circular convolution, and a real grid's spectrum is the real
    /// transform's (on its half), with the pruned support too.
    #[test]
    fn complex_transforms_round_trip_and_convolve() {
        for (n, support) in [(6, 6), (7, 4), (12, 6)] {
            complex_round_trip_and_convolution(n, support);
        }
    }

    fn complex_round_trip_and_convolution(n: usize, support: usize) {
        let fft = Fft3d::new(n);
        let mut s = 7u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let idx = |x: usize, y: usize, z: usize| (x * n + y) * n + z;
        let inside = |i: usize| {
            let (x, y, z) = (i / (n * n), i / n % n, i % n);
            x < support && y < support && z < support
        };
        let mut grid = |full: bool| -> Vec<Complex<f64>> {
            (0..n * n * n)
                .map(|i| {
                    if full || inside(i) {
                        Complex::new(next(), next())
                    } else {
                        Complex::new(0.0, 0.0)
                    }
                })
                .collect()
        };
        let (a, b) = (grid(false), grid(true));
        let mut work = fft.workspace();
        let (mut sa, mut sb) = (a.clone(), b.clone());
        fft.forward_complex(&mut sa, support, &mut work);
        fft.forward_complex(&mut sb, n, &mut work);
        // A real grid: the real transform's half spectrum.
        let re: Vec<f64> = a.iter().map(|z| z.re).collect();
        let mut half = vec![Complex::new(0.0, 0.0); fft.spectrum_len()];
        fft.forward(&re, &mut half, support, &mut work);
        let mut sre: Vec<Complex<f64>> = re.iter().map(|&x| Complex::new(x, 0.0)).collect();
        fft.forward_complex(&mut sre, support, &mut work);
        let h = n / 2 + 1;
        for (i, z) in half.iter().enumerate() {
            let (ab, c) = (i / h, i % h);
            assert!((sre[ab * n + c] - z).norm() < 1e-12, "{i}");
        }
        let mut back = sa.clone();
        fft.inverse_complex(&mut back, n, &mut work);
        for (x, y) in a.iter().zip(&back) {
            assert!((x - y).norm() < 1e-14);
        }
        let mut conv: Vec<Complex<f64>> = sa.iter().zip(&sb).map(|(x, y)| x * y).collect();
        fft.inverse_complex(&mut conv, support, &mut work);
        for (x, y, z) in [(0, 0, 0), (1, 3, 2), (3, 3, 3), (2, 0, 3)] {
            if x >= support || y >= support || z >= support {
                continue;
            }
            let mut want = Complex::new(0.0, 0.0);
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        want += a[idx(i, j, k)]
                            * b[idx((x + n - i) % n, (y + n - j) % n, (z + n - k) % n)];
                    }
                }
            }
            assert!((conv[idx(x, y, z)] - want).norm() < 1e-12, "{x} {y} {z}");
        }
    }

    fn round_trip_and_convolution(n: usize) {
        let fft = Fft3d::new(n);
        let mut s = 1u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let a: Vec<f64> = (0..n * n * n).map(|_| next()).collect();
        let b: Vec<f64> = (0..n * n * n).map(|_| next()).collect();
        let mut sa = vec![Complex::new(0.0, 0.0); fft.spectrum_len()];
        let mut sb = sa.clone();
        let mut work = fft.workspace();
        fft.forward(&a, &mut sa, n, &mut work);
        fft.forward(&b, &mut sb, n, &mut work);
        let mut back = vec![0.0; n * n * n];
        fft.inverse(&mut sa.clone(), &mut back, n, &mut work);
        for (x, y) in a.iter().zip(&back) {
            assert!((x - y).abs() < 1e-14);
        }
        let mut prod: Vec<Complex<f64>> = sa.iter().zip(&sb).map(|(x, y)| x * y).collect();
        let mut conv = vec![0.0; n * n * n];
        fft.inverse(&mut prod, &mut conv, n, &mut work);
        let idx = |x: usize, y: usize, z: usize| (x * n + y) * n + z;
        for (x, y, z) in [(0, 0, 0), (1, 4, 5), (5, 5, 5), (2, 0, 3)] {
            let mut want = 0.0;
            for i in 0..n {
                for j in 0..n {
                    for k in 0..n {
                        want += a[idx(i, j, k)]
                            * b[idx((x + n - i) % n, (y + n - j) % n, (z + n - k) % n)];
                    }
                }
            }
            assert!((conv[idx(x, y, z)] - want).abs() < 1e-12, "{x} {y} {z}");
        }
    }
}
