//! Ewald summation for the 3D Laplace kernel `K(r) = 1 / (4 pi |r|)`, and
//! the screened (Yukawa) kernel `e^{-kappa |r|} / (4 pi |r|)`, in a
//! fully periodic orthorhombic cell: the reference sum [`EwaldSum`] and the
//! pairwise periodic Green's function [`PeriodicGreen`] (with and without
//! its 27 nearest images) from which the FMM builds its periodisation
//! operator.
//!
//! # Conventions
//! The cell ([`PeriodicCell`]) is the box `origin + [0, L_x) x [0, L_y) x
//! [0, L_z)`, periodic in x, y and z, of volume `V = L_x L_y L_z`; lattice
//! vectors are `n∘L = (n_x L_x, n_y L_y, n_z L_z)` with `n` in `Z^3`. The
//! periodic Green's function is the Ewald sum with conducting ("tin-foil")
//! surroundings, i.e. the `k = 0` term dropped, which for a charge that is
//! not compensated within the cell is the potential of that charge plus a
//! uniform neutralising background of density `-1 / V`:
//!
//! ```text
//! G(r) = 1/(4 pi) [ sum_n erfc(alpha |r + n∘L|) / |r + n∘L|
//!                 + (4 pi / V) sum_{k != 0} exp(-k^2 / (4 alpha^2)) / k^2 cos(k . r)
//!                 - pi / (alpha^2 V) ]
//! ```
//!
//! with `k` over the reciprocal lattice `2 pi (m_x / L_x, m_y / L_y, m_z /
//! L_z)`. `G` does not depend on the splitting parameter `alpha > 0`, is
//! periodic, has zero mean over the cell, and solves `-Delta G = delta -
//! 1/V` (per cell). The self constant (the potential of a source's own
//! images and of its background at the source) is
//!
//! ```text
//! xi = lim_{r -> 0} (G(r) - 1/(4 pi r))
//!    = 1/(4 pi) [ sum_{n != 0} erfc(alpha |n∘L|) / |n∘L|
//!               + (4 pi / V) sum_{k != 0} exp(-k^2/(4 alpha^2)) / k^2
//!               - pi / (alpha^2 V) - 2 alpha / sqrt(pi) ].
//! ```
//!
//! For charges `q_j` at `x_j`, the potential at a target `y` and the one at
//! source `i` are
//!
//! ```text
//! phi(y)  = sum_j q_j G(y - x_j)
//! phi_i   = sum_{j != i} q_j G(x_i - x_j) + q_i xi
//!         = sum_j sum_n' q_j K(x_i - x_j - n∘L)   (Ewald sense, tin-foil)
//! ```
//!
//! where `'` omits only `(j = i, n = 0)`; the energy is `E = 1/2 sum_i q_i
//! phi_i`. For a non-neutral set (`Q = sum_j q_j != 0`) this includes the
//! interaction with the uniform background `-Q / V` (the constant `-Q /
//! (4 alpha^2 V)` in `phi`, i.e. `-pi Q / (alpha^2 V)` in Gaussian units),
//! as in every tin-foil Ewald code. Gradients are with respect to the
//! target, `grad K = -d / (4 pi r^3)` with `d = target - source`. A target
//! that coincides with a source skips that pair's direct (`n = 0`) term and
//! keeps its images: it gets `q_j xi` from it, exactly like a source from
//! itself (the crate-wide `K(x, x) = 0`).
//!
//! # Relation to a lattice sum over cubes
//! The plain lattice sum of a **neutral** set over growing cubes of images,
//! `phi_cube(y) = lim_M sum_{n in [-M, M]^3} sum_j q_j K(y - x_j - n∘L)`,
//! differs from the tin-foil sum by the shape (surface) term of a cube,
//! which for `1/(4 pi r)` units is
//!
//! ```text
//! phi_cube(y) - phi(y) = -1/(6 V) sum_j q_j |y - x_j|^2
//!                      = (1/(3V)) y . D - 1/(6V) sum_j q_j |x_j|^2,   D = sum_j q_j x_j
//! ```
//!
//! (a dipole field plus a constant; note the sign, which makes `E_cube - E
//! = |D|^2 / (6V)`, the `2 pi |D|^2 / (3V)` of Gaussian units). Verified in
//! the tests against brute-force cubic sums over the far images (`M = 24`
//! and `48`, Richardson-extrapolated) to `~2e-7`. A driver that wants
//! vacuum boundary conditions adds the dipole term itself.
//!
//! # Splitting and truncation
//! See [`EwaldParameters`]: with `s = sqrt(ln(1/tol))` the real-space sum
//! runs to `r_c = s / alpha` (every dropped pair term is below
//! `erfc(s) / r_c < tol / r_c`) and the reciprocal sum to `|k| <= k_c = 2
//! alpha s` (every dropped Gaussian factor is below `exp(-s^2) = tol`).
//! `alpha` balances the two sums' costs, which makes the sum over all `N`
//! targets `O(N^1.5)`; few targets ([`EwaldOptions::expected_targets`]) get a
//! smaller `alpha`.
//!
//! # The screened (Yukawa) kernel
//! The same sums serve the modified Helmholtz kernel `K(r) = e^{-kappa r}
//! / (4 pi r)` ([`EwaldOptions::screening`], [`PeriodicGreen::screened`]),
//! whose lattice sum converges absolutely: `erfc(alpha r) / r` becomes the
//! screened short-range kernel, the reciprocal coefficients `exp(-(k^2 +
//! kappa^2) / (4 alpha^2)) / (k^2 + kappa^2)`, the `k = 0` term is kept
//! (`Q exp(-kappa^2 / (4 alpha^2)) / (V kappa^2)`; no background, no
//! neutrality), and the self constant is
//! `xi = sum_{n != 0} K(n∘L)` in the Ewald form, with
//! `l(0) = 2 alpha e^{-b^2} / sqrt(pi) - kappa erfc(b)`, `b = kappa / (2
//! alpha)`, in place of `2 alpha / sqrt(pi)` (`screening.rs` has the
//! split). As `kappa -> 0` a neutral set's screened sum tends to the
//! tin-foil Laplace sum.
//!
//! # Layout
//! * the crate's `lattice/` (shared with the Stokes sum): the cell, the
//!   options and the choice of `alpha`, `r_c`, `k_c`; the cell list; the
//!   reciprocal lattice, structure factors and their evaluation at
//!   targets;
//! * `real_space.rs`: the real-space sum;
//! * `screening.rs`: the split of `e^{-kappa r} / r` (Laplace's at
//!   `kappa = 0`) into short- and long-range parts;
//! * `sum.rs`: [`EwaldSum`];
//! * `green.rs`: [`PeriodicGreen`];
//! * `slab.rs` and `rod.rs`: [`SlabGreen`] and [`RodGreen`], the Green's
//!   functions of cells that repeat along two axes or one (Parry's sum and
//!   its one-dimensional analogue), pair by pair;
//! * `pairwise.rs`: their sums over charges pair by pair, and
//!   `interpolated.rs` the same for many sources: the nearest images
//!   directly, the rest through a Chebyshev grid.

mod green;
mod interpolated;
mod pairwise;
mod real_space;
mod rod;
mod screening;
mod slab;
mod sum;

pub use crate::lattice::{EwaldOptions, EwaldParameters, PeriodicCell};
pub use green::PeriodicGreen;
pub use rod::RodGreen;
pub use slab::SlabGreen;
pub use sum::EwaldSum;

/// `2 / sqrt(pi)`.
const TWO_OVER_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;
