//! The octant `m_d >= 0` of a reciprocal lattice within a cut-off, in
//! columns along `m_z`: what the pairwise periodic Green's functions sum
//! over, with cosines (and sines) folded by symmetry.

use std::f64::consts::PI;

/// The wave vectors `k = 2 pi (m_x / L_x, m_y / L_y, m_z / L_z)`, `m_d >= 0`,
/// `|k| <= k_c`, in columns `(m_x, m_y, offset, len)`: the column's `m_z`
/// runs over `0..len`, and its wave vectors are numbered from `offset` in
/// storage order.
#[derive(Clone, Debug)]
pub(crate) struct Octant {
    /// `2 pi / L_d`.
    pub(crate) k0: [f64; 3],
    /// The largest `m_d` per axis.
    pub(crate) kmax: [usize; 3],
    /// `(m_x, m_y, offset, len)`.
    pub(crate) columns: Vec<(usize, usize, usize, usize)>,
}

impl Octant {
    /// The octant of the cell of sides `lengths` within `k_cut`.
    pub(crate) fn new(lengths: [f64; 3], k_cut: f64) -> Self {
        let k0 = [0, 1, 2].map(|d| 2.0 * PI / lengths[d]);
        let kmax = [0, 1, 2].map(|d| (k_cut / k0[d]).floor() as usize);
        let kc2 = k_cut * k_cut;
        let mut columns = Vec::new();
        let mut offset = 0;
        for mx in 0..=kmax[0] {
            let kx = mx as f64 * k0[0];
            for my in 0..=kmax[1] {
                let ky = my as f64 * k0[1];
                let rem = kc2 - kx * kx - ky * ky;
                if rem < 0.0 {
                    continue;
                }
                let len = ((rem.sqrt() / k0[2]).floor() as usize).min(kmax[2]) + 1;
                columns.push((mx, my, offset, len));
                offset += len;
            }
        }
        Self { k0, kmax, columns }
    }

    /// Calls `f(k, multiplicity)` for every wave vector in storage order
    /// (`k = 0` included, first), the multiplicity `2^(number of nonzero
    /// m_d)` counting the sign flips the octant folds together.
    pub(crate) fn for_each(&self, mut f: impl FnMut([f64; 3], f64)) {
        for &(mx, my, _, len) in &self.columns {
            for mz in 0..len {
                let nz = (mx > 0) as i32 + (my > 0) as i32 + (mz > 0) as i32;
                let k = [
                    mx as f64 * self.k0[0],
                    my as f64 * self.k0[1],
                    mz as f64 * self.k0[2],
                ];
                f(k, f64::from(1 << nz));
            }
        }
    }
}
