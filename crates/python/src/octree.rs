//! `NativeOctree`: the linear adaptive octree of `ferrofmm-tree` with its
//! arrays handed to NumPy.

use ferrofmm_tree::{Csr, InteractionLists, Octree, TreeOptions};
use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::engine::Floats;
use crate::errors::tree_error;
use crate::run::{Threads, interruptible};

/// The octree of a point set (and optionally a separate target set):
/// boxes in (level, Morton) order, each holding a contiguous range of the
/// points sorted along the Morton curve.
///
/// The public wrapper is `ferrofmm.Octree`.
#[pyclass(module = "ferrofmm._ferrofmm", frozen)]
pub(crate) struct NativeOctree {
    tree: Octree,
}

fn to_f64(what: &str, a: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    Ok(match Floats::from_numpy(what, a)? {
        Floats::F64(v) => v,
        Floats::F32(v) => v.into_iter().map(f64::from).collect(),
    })
}

/// A CSR list as two NumPy arrays: `(offsets, indices)`.
pub(crate) type CsrArrays<'py> = (Bound<'py, PyArray1<i64>>, Bound<'py, PyArray1<i64>>);

pub(crate) fn usize_array<'py>(
    py: Python<'py>,
    values: impl Iterator<Item = usize>,
) -> Bound<'py, PyArray1<i64>> {
    PyArray1::from_vec(py, values.map(|v| v as i64).collect())
}

#[pymethods]
impl NativeOctree {
    #[new]
    #[pyo3(signature = (sources, targets, leaf_size, balance, max_level))]
    fn new(
        py: Python<'_>,
        sources: &Bound<'_, PyAny>,
        targets: Option<&Bound<'_, PyAny>>,
        leaf_size: usize,
        balance: bool,
        max_level: u32,
    ) -> PyResult<Self> {
        let sources = to_f64("points", sources)?;
        let targets = targets.map(|t| to_f64("targets", t)).transpose()?;
        let options = TreeOptions::adaptive(leaf_size)
            .with_max_level(max_level)
            .with_balance(balance);
        let tree = interruptible(py, &Threads::default(), None, move || {
            Octree::new(&sources, targets.as_deref(), &options)
        })?
        .map_err(tree_error)?;
        Ok(NativeOctree { tree })
    }

    /// Number of boxes.
    #[getter]
    fn n_boxes(&self) -> usize {
        self.tree.n_boxes()
    }

    /// Deepest level.
    #[getter]
    fn depth(&self) -> u32 {
        self.tree.depth()
    }

    /// Whether the tree is 2:1 balanced and has interaction lists.
    #[getter]
    fn has_lists(&self) -> bool {
        self.tree.has_lists()
    }

    /// Whether the targets are the sources.
    #[getter]
    fn sources_are_targets(&self) -> bool {
        self.tree.sources_are_targets()
    }

    /// `(origin, width)` of the root cube.
    #[getter]
    fn domain(&self) -> ([f64; 3], f64) {
        let d = self.tree.domain();
        (d.origin, d.width)
    }

    /// The 64-bit keys (Morton code and level; `MortonKey::raw`).
    #[getter]
    fn keys<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.tree.keys().iter().map(|k| k.raw()).collect())
    }

    /// The Morton codes (interleaved anchor bits at the deepest level).
    #[getter]
    fn morton<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.tree.keys().iter().map(|k| k.morton()).collect())
    }

    /// Level of every box.
    #[getter]
    fn levels<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u32>> {
        PyArray1::from_vec(py, self.tree.keys().iter().map(|k| k.level()).collect())
    }

    /// Integer anchor (lower corner, in deepest-level cells) of every box.
    #[getter]
    fn anchors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u32>>> {
        let flat: Vec<u32> = self.tree.keys().iter().flat_map(|k| k.anchor()).collect();
        PyArray1::from_vec(py, flat).reshape([self.tree.n_boxes(), 3])
    }

    /// Parent of every box (-1 for the root).
    #[getter]
    fn parents<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        let p = (0..self.tree.n_boxes()).map(|b| self.tree.parent(b).map_or(-1, |p| p as i64));
        PyArray1::from_vec(py, p.collect())
    }

    /// Indices of the leaves.
    #[getter]
    fn leaves<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.leaves().iter().copied())
    }

    /// Centres of the boxes, shape `(n_boxes, 3)`.
    #[getter]
    fn centers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let d = self.tree.domain();
        let flat: Vec<f64> = self.tree.keys().iter().flat_map(|k| k.center(d)).collect();
        PyArray1::from_vec(py, flat).reshape([self.tree.n_boxes(), 3])
    }

    /// Half-widths of the boxes.
    #[getter]
    fn half_widths<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        let d = self.tree.domain();
        PyArray1::from_vec(
            py,
            self.tree.keys().iter().map(|k| k.half_width(d)).collect(),
        )
    }

    /// `(start, end)` of every box's sources in the sorted order, shape
    /// `(n_boxes, 2)`.
    #[getter]
    fn source_ranges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let n = self.tree.n_boxes();
        let flat = (0..n).flat_map(|b| {
            let r = self.tree.source_range(b);
            [r.start, r.end]
        });
        usize_array(py, flat).reshape([n, 2])
    }

    /// `(start, end)` of every box's targets in the sorted order.
    #[getter]
    fn target_ranges<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i64>>> {
        let n = self.tree.n_boxes();
        let flat = (0..n).flat_map(|b| {
            let r = self.tree.target_range(b);
            [r.start, r.end]
        });
        usize_array(py, flat).reshape([n, 2])
    }

    /// `permutation[i]`: the caller's index of the `i`-th sorted source.
    #[getter]
    fn source_permutation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.source_permutation().iter().copied())
    }

    /// `permutation[i]`: the caller's index of the `i`-th sorted target.
    #[getter]
    fn target_permutation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.target_permutation().iter().copied())
    }

    /// One interaction list in CSR form: `(offsets, indices)`, row `b`
    /// being `indices[offsets[b]:offsets[b + 1]]`. `kind` is `"u"`, `"v"`,
    /// `"w"` or `"x"`.
    fn list_csr<'py>(&self, py: Python<'py>, kind: &str) -> PyResult<CsrArrays<'py>> {
        if !self.tree.has_lists() {
            return Err(PyValueError::new_err(
                "this tree was built with balance=False: interaction lists need a 2:1-balanced tree",
            ));
        }
        let csr = list_of(self.tree.interaction_lists(), kind)?;
        Ok((
            usize_array(py, csr.offsets().iter().copied()),
            usize_array(py, csr.indices().iter().copied()),
        ))
    }
}

/// The interaction list `kind` names (`"u"`, `"v"`, `"w"`, `"x"`), or
/// `ValueError`.
pub(crate) fn list_of<'a>(lists: &'a InteractionLists, kind: &str) -> PyResult<&'a Csr> {
    match kind {
        "u" => Ok(&lists.u),
        "v" => Ok(&lists.v),
        "w" => Ok(&lists.w),
        "x" => Ok(&lists.x),
        other => Err(PyValueError::new_err(format!(
            "unknown interaction list {other:?}: use \"u\", \"v\", \"w\" or \"x\""
        ))),
    }
}
