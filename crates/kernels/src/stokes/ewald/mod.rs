//! Ewald summation for the Stokeslet in a fully periodic orthorhombic cell
//! (Hasimoto's sum): the reference sum [`StokesEwaldSum`] and the pairwise
//! periodic Stokeslet [`PeriodicStokeslet`] (with and without its 27
//! nearest images) from which the FMM builds its periodisation operator.
//!
//! # Conventions
//! The cell is a [`PeriodicCell`](crate::PeriodicCell) of volume `V`. The
//! Stokeslet is [`Stokes3d`](crate::Stokes3d)'s, `G(d) = S(d) / (8 pi mu)`
//! with `S(d) = I / r + d d^T / r^3`, `d` = target minus source. Its
//! lattice sum does not converge; the periodic Stokeslet is defined, after
//! Hasimoto (J. Fluid Mech. 5, 1959), by its Fourier series with the `k =
//! 0` term dropped:
//!
//! ```text
//! G_per(r) = (1 / (mu V)) sum_{k != 0} (I - k k^T / k^2) / k^2  e^{i k . r}
//! ```
//!
//! (`k` over the reciprocal lattice). It solves `mu Delta u - grad p = -f
//! sum_n delta(r - n∘L) + f / V`, `div u = 0`: the **mean velocity over the
//! cell is zero**, and the net force of the cell is balanced by a uniform
//! pressure gradient (the fluid is held at rest on average, as in a
//! suspension or a fixed bed). Any forces are accepted, a non-zero total
//! included. The self term of a source (the velocity of its own images at
//! itself) for a simple cubic lattice is Hasimoto's `-2.837297 F / (6 pi
//! mu L)` (tested).
//!
//! # Splitting
//! With `alpha > 0`, `E(r) = 2 alpha e^{-alpha^2 r^2} / sqrt(pi)`, and `S =
//! S_R + S_L`:
//!
//! ```text
//! S_R(d) = (erfc(alpha r)/r - E) I + (erfc(alpha r)/r^3 + E/r^2) d d^T     (short range)
//! S_L(d) = (erf(alpha r)/r + E) I + ((erf(alpha r)/r - E)/r^2) d d^T       (smooth, S_L(0) = 4 alpha / sqrt(pi) I)
//! S_L^(k) = 8 pi (1 + k^2/(4 alpha^2)) e^{-k^2/(4 alpha^2)} (I - k k^T/k^2) / k^2
//! ```
//!
//! (`S_R = (Delta I - grad grad)[r erfc(alpha r) - e^{-alpha^2 r^2} /
//! (alpha sqrt(pi))]`), so that
//!
//! ```text
//! G_per(r) = 1/(8 pi mu) sum_n S_R(r + n∘L)
//!          + 1/(8 pi mu V) sum_{k != 0} S_L^(k) e^{i k . r}
//! ```
//!
//! independent of `alpha` (tested to rounding). The cut-offs follow
//! Laplace's rule ([`EwaldParameters`](crate::EwaldParameters)) at a
//! tolerance 100 times tighter than asked, which covers the factors `2
//! alpha r / sqrt(pi)` and `1 + k^2 / (4 alpha^2)` that the Stokes terms
//! carry beyond Laplace's.
//!
//! # Layout
//! * `split.rs`: `S_R`, `S_L` and the Fourier weight;
//! * `sum.rs`: [`StokesEwaldSum`], over the cell list and the structure
//!   factors of the crate's shared `lattice/` module;
//! * `green.rs`: [`PeriodicStokeslet`].

mod green;
mod split;
mod sum;

pub use green::PeriodicStokeslet;
pub use sum::StokesEwaldSum;
