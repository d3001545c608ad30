//! Three-dimensional real FFTs on an `N x N x N` grid (pure Rust: realfft
//! on rustfft), for the FFT M2L scheme.
//!
//! The forward transform of a real grid `g[x][y][z]` (flat index
//! `(x N + y) N + z`) is
//!
//! ```text
//! G[a][b][c] = sum_{x,y,z} g[x][y][z] e^{-2 pi i (a x + b y + c z) / N},  c = 0..=N/2,
//! ```
//!
//! stored at `(a N + b) H + c` with `H = N/2 + 1` (the other half follows
//! from `G[-a][-b][-c] = conj(G[a][b][c])`). It runs as real-to-complex
//! transforms along `z`, then complex transforms along `y` and `x`; the
//! inverse undoes them in reverse order and divides by `N^3`, so that
//! `inverse(forward(g)) = g` and a pointwise product of two spectra is the
//! spectrum of the circular convolution of the grids.

use std::sync::Arc;

use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// Planned transforms for one grid size `N` (even).
pub(crate) struct Fft3d {
    n: usize,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl Fft3d {
    /// Plans for an `n x n x n` grid.
    ///
    /// # Panics
    /// When `n` is odd or zero.
    pub(crate) fn new(n: usize) -> Self {
        assert!(
            n > 0 && n.is_multiple_of(2),
            "FFT grid size must be even, got {n}"
        );
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

    /// Values of one spectrum: `N^2 (N/2 + 1)`.
    pub(crate) fn spectrum_len(&self) -> usize {
        self.n * self.n * (self.n / 2 + 1)
    }

    /// `spectrum = forward(grid)`; `grid` is used as scratch.
    pub(crate) fn forward(&self, grid: &mut [f64], spectrum: &mut [Complex<f64>]) {
        let (n, h) = (self.n, self.n / 2 + 1);
        assert_eq!(grid.len(), self.real_len());
        assert_eq!(spectrum.len(), self.spectrum_len());
        let mut scratch = self.r2c.make_scratch_vec();
        for (line, out) in grid.chunks_exact_mut(n).zip(spectrum.chunks_exact_mut(h)) {
            self.r2c
                .process_with_scratch(line, out, &mut scratch)
                .expect("lengths match the plan");
        }
        self.along_y_and_x(spectrum, &self.forward);
    }

    /// `grid = inverse(spectrum)` (divided by `N^3`); `spectrum` is used as
    /// scratch.
    pub(crate) fn inverse(&self, spectrum: &mut [Complex<f64>], grid: &mut [f64]) {
        let (n, h) = (self.n, self.n / 2 + 1);
        assert_eq!(grid.len(), self.real_len());
        assert_eq!(spectrum.len(), self.spectrum_len());
        self.along_y_and_x(spectrum, &self.inverse);
        let mut scratch = self.c2r.make_scratch_vec();
        let norm = 1.0 / (n * n * n) as f64;
        for (line, out) in spectrum.chunks_exact_mut(h).zip(grid.chunks_exact_mut(n)) {
            // A real signal's z-spectrum has real DC and Nyquist terms; drop
            // the rounding left in their imaginary parts.
            line[0].im = 0.0;
            line[h - 1].im = 0.0;
            self.c2r
                .process_with_scratch(line, out, &mut scratch)
                .expect("lengths match the plan and the end terms are real");
            for v in out.iter_mut() {
                *v *= norm;
            }
        }
    }

    /// Complex transforms along `y`, then `x`, of every `c` column.
    fn along_y_and_x(&self, spectrum: &mut [Complex<f64>], fft: &Arc<dyn Fft<f64>>) {
        let (n, h) = (self.n, self.n / 2 + 1);
        let mut line = vec![Complex::new(0.0, 0.0); n];
        let mut scratch = vec![Complex::new(0.0, 0.0); fft.get_inplace_scratch_len()];
        // Along y: stride h, for each (x, c).
        for x in 0..n {
            let plane = &mut spectrum[x * n * h..(x + 1) * n * h];
            for c in 0..h {
                for (y, v) in line.iter_mut().enumerate() {
                    *v = plane[y * h + c];
                }
                fft.process_with_scratch(&mut line, &mut scratch);
                for (y, v) in line.iter().enumerate() {
                    plane[y * h + c] = *v;
                }
            }
        }
        // Along x: stride n h, for each (y, c).
        for yc in 0..n * h {
            for (x, v) in line.iter_mut().enumerate() {
                *v = spectrum[x * n * h + yc];
            }
            fft.process_with_scratch(&mut line, &mut scratch);
            for (x, v) in line.iter().enumerate() {
                spectrum[x * n * h + yc] = *v;
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
        let n = 6;
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
        fft.forward(&mut a.clone(), &mut sa);
        fft.forward(&mut b.clone(), &mut sb);
        let mut back = vec![0.0; n * n * n];
        fft.inverse(&mut sa.clone(), &mut back);
        for (x, y) in a.iter().zip(&back) {
            assert!((x - y).abs() < 1e-14);
        }
        let mut prod: Vec<Complex<f64>> = sa.iter().zip(&sb).map(|(x, y)| x * y).collect();
        let mut conv = vec![0.0; n * n * n];
        fft.inverse(&mut prod, &mut conv);
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
