//! The real-space part of an Ewald sum: a cell list over the periodic box
//! that visits the sources and images within `r_c` of a point, for any
//! kernel's short-range part.

/// Sources sorted into a regular grid of cells (structure of arrays,
/// coordinates relative to the cell origin, in `[0, L)`), with the stencil
/// of neighbouring cells (images included) that can hold a source within
/// `r_c` of a point.
#[derive(Clone, Debug)]
pub(crate) struct CellList {
    /// Cells per axis.
    n: [usize; 3],
    /// Cell sizes `L_d / n_d`.
    h: [f64; 3],
    /// The periodic cell's lengths.
    lengths: [f64; 3],
    /// `start[c]..start[c + 1]`: the sources of cell `c` (x fastest).
    start: Vec<usize>,
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    /// `order[k]`: the input index of the source stored `k`-th.
    order: Vec<usize>,
    /// Integer cell offsets (unbounded, so images of the whole cell appear
    /// when `r_c` exceeds `L`) whose cells come within `r_c` of cell 0.
    stencil: Vec<[i64; 3]>,
    r_cut2: f64,
}

impl CellList {
    /// Sort `positions` (relative, in `[0, L)`) into cells of size about
    /// `r_c / 2`, with at most about `2N` cells.
    pub(crate) fn new(lengths: [f64; 3], positions: &[[f64; 3]], r_cut: f64) -> Self {
        let n_src = positions.len();
        let max_cells = (2 * n_src).max(8) as f64;
        let mut h_target = 0.5 * r_cut;
        let mut n = [1usize; 3];
        for _ in 0..200 {
            n = [0, 1, 2].map(|d| ((lengths[d] / h_target).floor() as usize).clamp(1, 1 << 20));
            if (n[0] as f64) * (n[1] as f64) * (n[2] as f64) <= max_cells {
                break;
            }
            h_target *= 1.25;
        }
        let h = [0, 1, 2].map(|d| lengths[d] / n[d] as f64);
        let n_cells = n[0] * n[1] * n[2];
        let cell_of = |p: &[f64; 3]| -> usize {
            let c = [0, 1, 2].map(|d| ((p[d] / h[d]) as usize).min(n[d] - 1));
            c[0] + n[0] * (c[1] + n[1] * c[2])
        };
        let mut count = vec![0usize; n_cells + 1];
        let cells: Vec<usize> = positions.iter().map(cell_of).collect();
        for &c in &cells {
            count[c + 1] += 1;
        }
        for c in 0..n_cells {
            count[c + 1] += count[c];
        }
        let start = count.clone();
        let mut next = count;
        let (mut x, mut y, mut z) = (vec![0.0; n_src], vec![0.0; n_src], vec![0.0; n_src]);
        let mut order = vec![0usize; n_src];
        for (i, &c) in cells.iter().enumerate() {
            let k = next[c];
            next[c] += 1;
            x[k] = positions[i][0];
            y[k] = positions[i][1];
            z[k] = positions[i][2];
            order[k] = i;
        }
        let m = [0, 1, 2].map(|d| (r_cut / h[d]).ceil() as i64);
        let r_cut2 = r_cut * r_cut;
        let mut stencil = Vec::new();
        for oz in -m[2]..=m[2] {
            for oy in -m[1]..=m[1] {
                for ox in -m[0]..=m[0] {
                    let o = [ox, oy, oz];
                    let gap2: f64 = (0..3)
                        .map(|d| {
                            let g = ((o[d].abs() - 1).max(0)) as f64 * h[d];
                            g * g
                        })
                        .sum();
                    if gap2 < r_cut2 {
                        stencil.push(o);
                    }
                }
            }
        }
        Self {
            n,
            h,
            lengths,
            start,
            x,
            y,
            z,
            order,
            stencil,
            r_cut2,
        }
    }

    /// `values` (one item per source, input order) in storage order, so
    /// that [`CellList::visit`]'s index `k` reads item `k`.
    pub(crate) fn sorted<V: Copy>(&self, values: &[V]) -> Vec<V> {
        self.order.iter().map(|&i| values[i]).collect()
    }

    /// Calls `f(k, d, r2)` for every source `k` (storage order) and image
    /// within `r_c` of `t` (relative, in `[0, L)`), with `d = t - x_k -
    /// n∘L` and `r2 = |d|^2` (zero for a source at `t`).
    #[inline]
    pub(crate) fn visit(&self, t: [f64; 3], mut f: impl FnMut(usize, [f64; 3], f64)) {
        let c = [0, 1, 2].map(|d| ((t[d] / self.h[d]) as i64).clamp(0, self.n[d] as i64 - 1));
        for o in &self.stencil {
            let mut idx = [0usize; 3];
            let mut ts = [0.0f64; 3];
            for d in 0..3 {
                let u = c[d] + o[d];
                let nd = self.n[d] as i64;
                idx[d] = u.rem_euclid(nd) as usize;
                ts[d] = t[d] - u.div_euclid(nd) as f64 * self.lengths[d];
            }
            let cell = idx[0] + self.n[0] * (idx[1] + self.n[1] * idx[2]);
            let (lo, hi) = (self.start[cell], self.start[cell + 1]);
            let (xs, ys, zs) = (&self.x[lo..hi], &self.y[lo..hi], &self.z[lo..hi]);
            for j in 0..xs.len() {
                let d = [ts[0] - xs[j], ts[1] - ys[j], ts[2] - zs[j]];
                let r2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if r2 < self.r_cut2 {
                    f(lo + j, d, r2);
                }
            }
        }
    }
}
