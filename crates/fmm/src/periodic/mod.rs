//! Periodic boundary conditions: charges in a cell that repeats in every
//! direction, as molecular dynamics, materials and cosmology need.
//!
//! # What is computed
//!
//! For a cubic cell of side `L` (a [`Periodic`] boundary condition, given
//! to [`crate::FmmBuilder::periodic`]) and charges `q_j` at `x_j`, the value
//! at a target `y` is the lattice sum over every image of every source,
//!
//! ```text
//! phi(y) = sum_{n in Z^3} sum_j' q_j K(y - x_j - n L)
//! ```
//!
//! leaving out only `(j, n) = (i, 0)` when `y` is source `i` itself (its own
//! images are included): the Ewald convention. For the Laplace kernel
//! `K = 1 / (4 pi r)` the sum converges only conditionally. It is defined
//! as Ewald's, with conducting ("tin-foil") surroundings
//! ([`SurfaceTerm::TinFoil`], the default: the `k = 0` term of the
//! reciprocal sum dropped, so that the potential has zero mean over the
//! cell), or in vacuum ([`SurfaceTerm::Vacuum`]: a sphere of cells
//! surrounded by vacuum, which adds the dipole term
//! `phi(y) += D . (y - c) / (3 V)`, `D = sum_j q_j (x_j - c)`, `c` the
//! cell's centre, `V = L^3`, the positions wrapped into the cell). The cell
//! must be neutral, `sum_j q_j = 0` (to `1e-8` of `sum_j |q_j|`; a
//! residual charge is treated with Ewald's uniform neutralising
//! background). The total energy is `E = 1/2 sum_i q_i phi_i`
//! ([`crate::Fmm::energy`]).
//!
//! The Yukawa kernel `e^{-kappa r} / (4 pi r)`
//! ([`ferrofmm_kernels::ModifiedHelmholtz3d`]) is summed too
//! ([`lattice_screening`]): its lattice sum converges absolutely, so any
//! charges are accepted and there is no surface term.
//!
//! The Stokeslet ([`ferrofmm_kernels::Stokes3d`], point forces `f_j`,
//! velocities and velocity gradients) is summed with Hasimoto's convention
//! ([`ferrofmm_kernels::StokesEwaldSum`]): the lattice sum, which does not
//! converge, is defined by its Fourier series with the `k = 0` term
//! dropped, so the **mean velocity over the cell is zero** and the cell's
//! net force `F = sum_j f_j` is balanced by a uniform pressure gradient
//! `-F / V` (a suspension held at rest on average, a fixed bed, or a
//! sedimenting suspension in the frame of zero mean velocity). Any forces
//! are accepted; there is no surface term. With a net force the velocities
//! are a small difference of large terms (the images' mean flow against
//! the back pressure), which costs accuracy: about `sqrt(N)` times the
//! error of zero-sum forces at the same order, measured and met by the
//! verification.
//!
//! # How
//!
//! Points are wrapped into the cell `[origin, origin + L)^3`, and the
//! octree's root is the cell. Its lists wrap around the faces
//! ([`ferrofmm_tree::TreeOptions::periodic`]): an entry is a box and the
//! image shift `s in {-1, 0, 1}^3` it is seen at, so the tree's passes
//! (P2P, M2L, M2P, P2L) cover, each exactly once, every interaction of a
//! leaf with the 27 images of the cell nearest to it (`|n|_inf <= 1`).
//!
//! The images further away (`|n|_inf >= 2`) are one cell or more from the
//! root, the separation of a V-list pair, and act on the root through its
//! multipole: with `u` the root's upward equivalent density on the points
//! `x_e` of its equivalent surface, their potential on the root's
//! downward check surface `y_c` is
//!
//! ```text
//! c_root = P u,    P_ij = G(y_c,i - x_e,j) - sum_{|n|_inf <= 1} K(y_c,i - x_e,j - n L)
//! ```
//!
//! with `G` the periodic Green's function (Ewald's, tin-foil, with a
//! neutralising background: [`ferrofmm_kernels::PeriodicGreen`]). `P` is
//! the **periodisation operator**, one `n x n` matrix per order (the
//! kernel is homogeneous: `P` of a cell of side `L` is that of the unit
//! cell over `L`), built once. The root's local expansion then passes down
//! the tree as every local expansion does (L2L, L2P).
//!
//! For Yukawa `G` is the screened periodic Green's function
//! ([`ferrofmm_kernels::PeriodicGreen::screened`]); `G` minus its 27
//! nearest images solves `(-Delta + kappa^2) u = 0` in the root, the local
//! expansion keeps it exactly, and none of the Laplace corrections below
//! apply.
//!
//! For Laplace, `G` minus its 27 nearest images is smooth inside the root's check
//! surface but not harmonic: `Laplacian G = -delta + 1 / V` (the
//! background), so it holds the quadratic `|r|^2 / (6 V)`. Applied to a
//! neutral density the quadratic leaves a linear function (harmonic, kept
//! exactly by the local expansion) and the constant
//! `sum_j w_j |x_j|^2 / (6 V)`, which depends on the density's second
//! moment, a quantity the equivalent density does not reproduce (it
//! matches the far field only). So the driver makes `u` exactly neutral
//! (subtracting its mean, which removes a spurious monopole of the size of
//! the expansion's error and changes no other moment, the surface grid
//! being symmetric), and adds to every potential the constant
//!
//! ```text
//! C = (sum_j q_j |x_j - c|^2 - sum_j u_j |x_e,j - c|^2) / (6 V)
//! ```
//!
//! which makes the result Ewald's to the FMM's accuracy, the constant
//! included. Gradients do not see `C`.
//!
//! For Stokes, `G` is the periodic Stokeslet
//! ([`ferrofmm_kernels::PeriodicStokeslet`]) and `P` a `3n x 3n` matrix.
//! `G` minus its 27 nearest images solves `mu Delta u - grad p = F / V`
//! in the root, a uniform force that the pressure takes (`p' = p + F . r /
//! V`), so its velocity is a smooth Stokes flow there, kept exactly by the
//! local expansion: no projection. Laplace's constant has no Stokes
//! analogue in exact arithmetic: the difference `w` of the fields of the
//! forces and of `u` is divergence-free and vanishes outside the root, so
//! `int w = -int x (div w) = 0`. The equivalent density matches the forces
//! only to the expansion's accuracy, though, and the constant part of that
//! error is estimated from the second moments `M_jab = sum f_j r_a r_b` of
//! the forces and of `u` (`r` from the cell's centre) as the direction
//! average of the limit `k -> 0` of `(I - k k^T / k^2) k_a k_b dM_jab / (2
//! mu k^2)`:
//!
//! ```text
//! C_i = ((2/15) dT_i - (1/15) dS_i) / (mu V),   T_i = sum f_i |r|^2,   S_i = sum (f . r) r_i
//! ```
//!
//! (`d`: the forces' moments less `u`'s), and added. Measured, it lowers
//! the error by up to 30% (a net force) and never raises it, orders 4 to
//! 12.

mod cell;
mod far_field;
pub(crate) mod images;

pub use cell::{Periodic, PeriodicAxes, SurfaceTerm};
pub(crate) use far_field::{FarImages, check_neutral, check_screened_tolerance, required_lattice};
pub use far_field::{LatticeSum, lattice_screening, lattice_sum};
