//! The far images of a periodic cell: the periodisation operator `P`
//! (root multipole to root check potential), the neutral projection of the
//! root multipole, and the constant and dipole terms (see the
//! [module docs](super)).

use ferrofmm_field::{SurfaceRadii, surface_points};
use ferrofmm_kernels::{
    Helmholtz3d, Kernel, Laplace3d, ModifiedHelmholtz3d, PeriodicCell, PeriodicGreen,
    PeriodicStokeslet, Real, RodGreen, SlabGreen, Stokes3d,
};

use super::{Periodic, PeriodicAxes, SurfaceTerm};
use crate::FmmError;

/// Accuracy asked of the Ewald sums that build `P`: far below what any
/// order reaches, so `P` adds no error of its own.
const GREEN_TOLERANCE: f64 = 1e-15;

/// Residual charge, relative to `sum |q|`, above which a Laplace cell is
/// refused as not neutral.
pub(crate) const NEUTRALITY: f64 = 1e-8;

/// The lattice sum a periodic run of a kernel computes
/// ([`lattice_sum`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum LatticeSum {
    /// Laplace, `1 / (4 pi r)`: Ewald's sum (conditionally convergent;
    /// the cell must be neutral; tin-foil or vacuum surroundings).
    Laplace,
    /// Yukawa, `e^{-kappa r} / (4 pi r)`: absolutely convergent, any
    /// charges.
    Yukawa {
        /// The screening `kappa > 0`.
        kappa: f64,
    },
    /// The Stokeslet of viscosity `mu`: Hasimoto's sum (zero mean velocity,
    /// a net force balanced by a uniform pressure gradient), any forces.
    Stokes {
        /// The viscosity `mu > 0`.
        viscosity: f64,
    },
    /// Any other kernel whose lattice sum converges absolutely (a user's
    /// kernel, damped Helmholtz waves): summed over super-cells of images
    /// with the kernel's own values, any charges, no surface term
    /// (docs/periodic.md, "Your own kernels"). A kernel whose sum does not converge is refused
    /// when the run is built.
    Images {
        /// The kernel's components `c` (2 for a complex kernel).
        components: usize,
    },
}

impl LatticeSum {
    /// Components per density and per value: 3 for Stokes, else 1.
    pub fn components(self) -> usize {
        match self {
            LatticeSum::Stokes { .. } => 3,
            LatticeSum::Images { components } => components,
            _ => 1,
        }
    }
}

/// The lattice sum the periodic FMM computes for `kernel`:
/// [`Laplace3d`], [`ModifiedHelmholtz3d`] (Yukawa, `k > 0`) and
/// [`Stokes3d`] by their own sums; undamped Helmholtz waves
/// ([`Helmholtz3d`] with `Im k = 0`), whose lattice sum does not converge,
/// `None` ([`crate::FmmBuilder::periodic`] refuses it); any other kernel,
/// damped waves and a user's own included, [`LatticeSum::Images`] (refused
/// when the run is built should its sum not converge).
///
/// ```
/// use ferrofmm_fmm::periodic::{lattice_sum, LatticeSum};
/// use ferrofmm_kernels::{Helmholtz3d, Laplace3d, ModifiedHelmholtz3d, Stokes3d};
/// assert_eq!(lattice_sum(&Laplace3d), Some(LatticeSum::Laplace));
/// assert_eq!(
///     lattice_sum(&ModifiedHelmholtz3d::new(2.0).unwrap()),
///     Some(LatticeSum::Yukawa { kappa: 2.0 })
/// );
/// assert_eq!(lattice_sum(&Stokes3d::new(0.5).unwrap()), Some(LatticeSum::Stokes { viscosity: 0.5 }));
/// assert_eq!(lattice_sum(&Helmholtz3d::new(2.0).unwrap()), None);
/// assert_eq!(
///     lattice_sum(&Helmholtz3d::new_complex(2.0, 1.0).unwrap()),
///     Some(LatticeSum::Images { components: 2 })
/// );
/// ```
pub fn lattice_sum<K: Kernel>(kernel: &K) -> Option<LatticeSum> {
    let any = kernel as &dyn std::any::Any;
    if any.downcast_ref::<Laplace3d>().is_some() {
        return Some(LatticeSum::Laplace);
    }
    if let Some(k) = any.downcast_ref::<ModifiedHelmholtz3d>() {
        return Some(if k.k == 0.0 {
            LatticeSum::Laplace
        } else {
            LatticeSum::Yukawa { kappa: k.k }
        });
    }
    if let Some(s) = any.downcast_ref::<Stokes3d>() {
        return Some(LatticeSum::Stokes {
            viscosity: s.viscosity,
        });
    }
    if let Some(h) = any.downcast_ref::<Helmholtz3d>()
        && h.k_im == 0.0
    {
        return None;
    }
    Some(LatticeSum::Images {
        components: kernel.components(),
    })
}

/// The screening `kappa` of a scalar kernel whose lattice sum the periodic
/// FMM sums: `0` for [`Laplace3d`] (whose cell must be neutral), `k` for
/// [`ModifiedHelmholtz3d`] (whose `k = 0` is Laplace); `None` for any other
/// kernel, [`Stokes3d`] included (see [`lattice_sum`]).
///
/// ```
/// use ferrofmm_fmm::periodic::lattice_screening;
/// use ferrofmm_kernels::{Helmholtz3d, Laplace3d, ModifiedHelmholtz3d};
/// assert_eq!(lattice_screening(&Laplace3d), Some(0.0));
/// assert_eq!(lattice_screening(&ModifiedHelmholtz3d::new(2.0).unwrap()), Some(2.0));
/// assert_eq!(lattice_screening(&Helmholtz3d::new(2.0).unwrap()), None);
/// ```
pub fn lattice_screening<K: Kernel>(kernel: &K) -> Option<f64> {
    match lattice_sum(kernel)? {
        LatticeSum::Laplace => Some(0.0),
        LatticeSum::Yukawa { kappa } => Some(kappa),
        LatticeSum::Stokes { .. } | LatticeSum::Images { .. } => None,
    }
}

/// [`lattice_sum`], or the error that names a kernel without a lattice sum
/// here.
pub(crate) fn required_lattice<K: Kernel>(kernel: &K) -> Result<LatticeSum, FmmError> {
    lattice_sum(kernel).ok_or_else(|| {
        FmmError::InvalidParameter(format!("no periodic lattice sum for {}", kernel.name()))
    })
}

/// What a periodic FMM keeps for its far images.
#[derive(Clone, Debug)]
pub(crate) struct FarImages {
    pub(crate) cell: Periodic,
    /// The lattice sum (Laplace: with its neutral projection, constant and
    /// surface term; Yukawa: none of them; Stokes: a constant velocity).
    lattice: LatticeSum,
    /// `P`, row-major `c n x c n` (check point `i` and component `a`,
    /// equivalent point `j` and component `b`, at row `c i + a` and column
    /// `c j + b`).
    operator: Vec<f64>,
    /// The root's upward equivalent points relative to the cell's centre.
    equivalent: Vec<f64>,
}

impl FarImages {
    /// `P` for `cell` at `order`, for the lattice sum `lattice`
    /// ([`lattice_sum`]), with the root surfaces of `radii` (half-widths)
    /// and, for [`LatticeSum::Images`], the pseudo-inverse cutoff `rcond`
    /// of its super-cells.
    ///
    /// `P` is kept in the operator cache of `params` (keyed by the kernel,
    /// the order, the cell's sides and axes and the surfaces), so a second
    /// run of the same cell reads it instead of summing it again.
    pub(crate) fn new<K: Kernel>(
        cell: Periodic,
        lattice: LatticeSum,
        kernel: &K,
        params: &ferrofmm_field::OperatorParams,
        radii: SurfaceRadii,
        rcond: f64,
    ) -> Result<(Self, ferrofmm_field::CacheStatus), FmmError> {
        let order = params.order;
        let half = 0.5 * cell.width();
        let (upward_equivalent, downward_check) = (radii.upward_equivalent, radii.downward_check);
        let equivalent = surface_points::<f64>(order, [0.0; 3], half, upward_equivalent);
        let check = surface_points::<f64>(order, [0.0; 3], half, downward_check);
        let c = lattice.components();
        let len = (c * check.len() / 3) * (c * equivalent.len() / 3);
        let description = match lattice {
            LatticeSum::Images { .. } => format!(
                "periodisation by super-cells: sides {:?}, axes {}, surfaces {:?}, rcond \
                 {rcond:e}, tolerance {:e}",
                cell.lengths(),
                cell.axes(),
                radii.to_array(),
                super::images::OPERATOR_TOLERANCE
            ),
            _ => format!(
                "periodisation: {lattice:?}, sides {:?}, axes {}, surfaces {upward_equivalent} -> \
                 {downward_check}, tolerance {GREEN_TOLERANCE:e}",
                cell.lengths(),
                cell.axes()
            ),
        };
        let mut failure = None;
        let (operator, status) = ferrofmm_field::cached_values(
            params,
            kernel,
            "periodisation",
            &description,
            len,
            || {
                let built = match lattice {
                    LatticeSum::Images { .. } => {
                        super::images::periodisation_operator(kernel, &cell, order, radii, rcond)
                    }
                    _ => Self::operator(cell, lattice, &check, &equivalent),
                };
                built.map_err(|e| {
                    let text = e.to_string();
                    failure = Some(e);
                    ferrofmm_field::FieldError::InvalidParams(text)
                })
            },
        )
        .map_err(|e| failure.take().unwrap_or(FmmError::from(e)))?;
        Ok((
            FarImages {
                cell,
                lattice,
                operator,
                equivalent,
            },
            status,
        ))
    }

    /// `P` between the `check` and `equivalent` points (relative to the
    /// cell's centre).
    fn operator(
        cell: Periodic,
        lattice: LatticeSum,
        check: &[f64],
        equivalent: &[f64],
    ) -> Result<Vec<f64>, FmmError> {
        let green_cell = PeriodicCell::new([0.0; 3], cell.lengths())?;
        // `far_images(r)` depends on differences only: the cell's origin
        // does not matter, the points are relative to its centre.
        let kappa = match lattice {
            LatticeSum::Yukawa { kappa } => kappa,
            _ => 0.0,
        };
        let (check, equivalent) = (check.to_vec(), equivalent.to_vec());
        let operator = match (lattice, cell.axes()) {
            (LatticeSum::Stokes { viscosity }, PeriodicAxes::Xyz) => {
                PeriodicStokeslet::new(green_cell, viscosity, GREEN_TOLERANCE)?
                    .far_images_matrix(&check, &equivalent)?
            }
            (LatticeSum::Images { .. }, _) => {
                return Err(FmmError::InvalidParameter(
                    "a lattice sum by images is built by super-cells".to_string(),
                ));
            }
            (LatticeSum::Stokes { .. }, axes) => {
                return Err(FmmError::InvalidParameter(format!(
                    "no Stokes lattice sum for a {}",
                    axes.kind()
                )));
            }
            (_, PeriodicAxes::Xyz) => PeriodicGreen::screened(green_cell, kappa, GREEN_TOLERANCE)?
                .far_images_matrix(&check, &equivalent)?,
            (_, PeriodicAxes::Xy) => SlabGreen::screened(green_cell, kappa, GREEN_TOLERANCE)?
                .far_images_matrix(&check, &equivalent)?,
            (_, PeriodicAxes::X) => RodGreen::screened(green_cell, kappa, GREEN_TOLERANCE)?
                .far_images_matrix(&check, &equivalent)?,
        };
        Ok(operator)
    }

    /// The lattice sum.
    pub(crate) fn lattice(&self) -> LatticeSum {
        self.lattice
    }

    /// Whether the cell must be neutral (Laplace).
    pub(crate) fn needs_neutral(&self) -> bool {
        self.lattice == LatticeSum::Laplace
    }

    /// Values per expansion: surface points times components.
    fn len(&self) -> usize {
        self.lattice.components() * self.equivalent.len() / 3
    }

    /// The far images' potentials on the root's downward check surface
    /// for the root multipole `root` (its first `c n` values), and the
    /// constant `C` (one per component) of the module docs for the wrapped
    /// densities `q` at the wrapped points `x` (relative to anything: only
    /// differences and the cell's centre `centre`, in the same frame,
    /// matter). A screened kernel's far images are a smooth solution of
    /// `(-Delta + kappa^2) u = 0` in the root, kept exactly by the local
    /// expansion: no projection, `C = 0`. Stokes' are a smooth Stokes flow
    /// there (the uniform force that balances the cell's is taken by the
    /// pressure); `C` is zero in exact arithmetic, and the constant part of
    /// the expansion's error is estimated from the second moments of the
    /// forces and of `u` (see the [module docs](super)).
    pub(crate) fn root_check<T: Real>(
        &self,
        root: &[T],
        x: &[T],
        centre: [f64; 3],
        q: &[T],
    ) -> (Vec<T>, [f64; 3]) {
        let mut u: Vec<f64> = root[..self.len()].iter().map(|v| v.to_f64()).collect();
        match self.lattice {
            LatticeSum::Yukawa { .. } | LatticeSum::Images { .. } => (self.apply(&u), [0.0; 3]),
            LatticeSum::Stokes { viscosity } => {
                let constant = self.stokes_constant(&u, x, centre, q, viscosity);
                (self.apply(&u), constant)
            }
            LatticeSum::Laplace => {
                let n = u.len();
                let mean = u.iter().sum::<f64>() / n as f64;
                u.iter_mut().for_each(|v| *v -= mean);
                let check = self.apply(&u);
                if self.cell.axes() != PeriodicAxes::Xyz {
                    // A slab's or rod's far images are harmonic in the
                    // root (no background): no constant.
                    return (check, [0.0; 3]);
                }
                // Second moments `sum w |p - c|^2` of the charges and of `u`.
                let charges: f64 = x
                    .chunks_exact(3)
                    .zip(q)
                    .map(|(p, q)| {
                        q.to_f64()
                            * (0..3)
                                .map(|a| (p[a].to_f64() - centre[a]).powi(2))
                                .sum::<f64>()
                    })
                    .sum();
                let equivalent: f64 = self
                    .equivalent
                    .chunks_exact(3)
                    .zip(&u)
                    .map(|(p, u)| u * (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]))
                    .sum();
                let constant = (charges - equivalent) / (6.0 * self.cell.volume());
                (check, [constant, 0.0, 0.0])
            }
        }
    }

    /// Stokes' constant velocity `C_i = ((2/15) dT_i - (1/15) dS_i) / (mu
    /// V)` with `T_i = sum f_i |r|^2` and `S_i = sum (f . r) r_i`, `r = p -
    /// c`, `d` the forces' moment less the equivalent density's (see the
    /// [module docs](super)).
    fn stokes_constant<T: Real>(
        &self,
        u: &[f64],
        x: &[T],
        centre: [f64; 3],
        q: &[T],
        viscosity: f64,
    ) -> [f64; 3] {
        let mut t = [0.0f64; 3];
        let mut s = [0.0f64; 3];
        let mut add = |p: [f64; 3], f: [f64; 3], sign: f64| {
            let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
            let pf = p[0] * f[0] + p[1] * f[1] + p[2] * f[2];
            for i in 0..3 {
                t[i] += sign * f[i] * r2;
                s[i] += sign * pf * p[i];
            }
        };
        for (p, f) in x.chunks_exact(3).zip(q.chunks_exact(3)) {
            let p = std::array::from_fn(|a| p[a].to_f64() - centre[a]);
            add(p, std::array::from_fn(|a| f[a].to_f64()), 1.0);
        }
        for (p, f) in self.equivalent.chunks_exact(3).zip(u.chunks_exact(3)) {
            add([p[0], p[1], p[2]], [f[0], f[1], f[2]], -1.0);
        }
        let scale = 1.0 / (viscosity * self.cell.volume());
        std::array::from_fn(|i| scale * (2.0 * t[i] - s[i]) / 15.0)
    }

    /// `P u`.
    fn apply<T: Real>(&self, u: &[f64]) -> Vec<T> {
        self.operator
            .chunks_exact(self.len())
            .map(|row| T::from_f64(row.iter().zip(u).map(|(a, b)| a * b).sum()))
            .collect()
    }

    /// Adds the constant `constant` (Laplace: the potential's, its first
    /// entry; Stokes: the velocity's three) and, in vacuum, the dipole term
    /// to the values `out` (`w` per target: potential, then gradient) at
    /// the wrapped targets `y` for the wrapped sources `x` with charges `q`
    /// (all relative to the frame in which the cell's centre is `centre`).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn add_terms<T: Real>(
        &self,
        constant: [f64; 3],
        w: usize,
        x: &[T],
        q: &[T],
        y: &[T],
        centre: [f64; 3],
        out: &mut [T],
    ) {
        if constant == [0.0; 3] && self.cell.surface() == SurfaceTerm::TinFoil {
            // Nothing to add (a screened kernel's far images need no
            // terms): no pass over the targets.
            return;
        }
        if let LatticeSum::Stokes { .. } = self.lattice {
            // A constant velocity; no surface term (refused when building).
            for o in out.chunks_exact_mut(w) {
                for i in 0..3 {
                    o[i] += T::from_f64(constant[i]);
                }
            }
            return;
        }
        let constant = constant[0];
        let dipole: [f64; 3] = match self.cell.surface() {
            SurfaceTerm::TinFoil => [0.0; 3],
            SurfaceTerm::Vacuum => {
                let mut d = [0.0; 3];
                for (p, q) in x.chunks_exact(3).zip(q) {
                    for a in 0..3 {
                        d[a] += q.to_f64() * (p[a].to_f64() - centre[a]);
                    }
                }
                d.map(|d| d / (3.0 * self.cell.volume()))
            }
        };
        for (p, o) in y.chunks_exact(3).zip(out.chunks_exact_mut(w)) {
            let lin: f64 = (0..3)
                .map(|a| dipole[a] * (p[a].to_f64() - centre[a]))
                .sum();
            o[0] += T::from_f64(constant + lin);
            if w >= 4 {
                for a in 0..3 {
                    o[1 + a] += T::from_f64(dipole[a]);
                }
            }
        }
    }
}

/// Below this `k L` a periodic Yukawa sum's constant term limits the
/// accuracy ([`check_screened_tolerance`]).
pub(crate) const WEAK_SCREENING: f64 = 0.3;

/// Rounding amplification of a periodic Yukawa run at `k L < 0.3`, times
/// `(k L)^2`: measured (1e3-3e3 points in the unit cell, order 12, f64,
/// positive and zero-mean charges; gradient errors `1.3e-8`, `1.3e-6`,
/// `1.2e-4` at `k L = 0.1, 0.01, 0.001`, i.e. `1.2e6 u / (k L)^2` with `u`
/// the unit roundoff).
const WEAK_SCREENING_AMPLIFICATION: f64 = 1.2e6;

/// Refuse a tolerance that a periodic Yukawa run with weak screening
/// cannot reach. Its lattice sum holds the constant `Q e^{-b^2} / (V
/// k^2)`, about `1 / (k L)^2` times the potential's variation over the
/// cell; the root's local expansion carries it, and its rounding, times
/// the pseudo-inverse's amplification, reaches the gradients (and a
/// neutral cell's potentials): the smallest error is about `1.2e6 u / (k
/// L)^2` (`u` the unit roundoff: `1.7e-9 / ...` below `k L = 0.3` in f64).
/// Laplace and `k L >= 0.3` are not limited here.
pub(crate) fn check_screened_tolerance<K: Kernel>(
    kernel: &K,
    cell: &Periodic,
    eps: f64,
    precision: ferrofmm_kernels::Precision,
) -> Result<(), FmmError> {
    let Some(LatticeSum::Yukawa { kappa }) = lattice_sum(kernel) else {
        return Ok(());
    };
    let kl = kappa * cell.width();
    if kl >= WEAK_SCREENING {
        return Ok(());
    }
    let unit = match precision {
        ferrofmm_kernels::Precision::F32 => f64::from(f32::EPSILON) / 2.0,
        ferrofmm_kernels::Precision::F64 => f64::EPSILON / 2.0,
    };
    let limit = WEAK_SCREENING_AMPLIFICATION * unit / (kl * kl);
    if eps < limit {
        return Err(FmmError::InvalidParameter(format!(
            "tolerance {eps:e} is beyond what a periodic Yukawa sum with k L = {kl:.2e} can \
             promise in {} (smallest: {limit:.1e}): its lattice sum holds the constant \
             Q / (V k^2), 1 / (k L)^2 times the potential's variation, whose rounding the \
             gradients see; ask for a larger tolerance, or use the Laplace kernel where the \
             screening length is this much longer than the cell",
            precision.name()
        )));
    }
    Ok(())
}

/// Refuse a Laplace cell that is not neutral.
pub(crate) fn check_neutral<T: Real>(charges: &[T]) -> Result<(), FmmError> {
    let (sum, abs) = charges.iter().fold((0.0f64, 0.0f64), |(s, a), q| {
        let q = q.to_f64();
        (s + q, a + q.abs())
    });
    if sum.abs() > NEUTRALITY * abs {
        return Err(FmmError::NotNeutral {
            total: sum,
            absolute: abs,
            limit: NEUTRALITY,
        });
    }
    Ok(())
}
