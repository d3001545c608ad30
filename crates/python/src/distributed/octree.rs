//! `NativeDistOctree`: one rank's piece of the distributed octree of
//! `ferrofmm-mpi` ([`DistributedTree`]) with its arrays handed to NumPy.

use ferrofmm_mpi::{DistOptions, DistributedTree, PHASES, agree_text};
use ferrofmm_tree::MortonKey;
use mpi::traits::*;
use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray1};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use super::comm::AdoptedComm;
use super::{Work, dist_error};
use crate::octree::{CsrArrays, list_of, usize_array};

/// One rank's boxes, points, ghosts and lists. The public wrapper is
/// `ferrofmm.distributed.Octree`.
#[pyclass(module = "ferrofmm._ferrofmm", frozen)]
pub(crate) struct NativeDistOctree {
    tree: DistributedTree,
    /// Points of every rank after the partition (rank order).
    points_per_rank: Vec<u64>,
    ranks: usize,
}

fn keys_array<'py>(
    py: Python<'py>,
    keys: impl Iterator<Item = MortonKey>,
) -> Bound<'py, PyArray1<u64>> {
    PyArray1::from_vec(py, keys.map(MortonKey::raw).collect())
}

#[pymethods]
impl NativeDistOctree {
    #[new]
    #[pyo3(signature = (comm, points, leaf_size, max_level))]
    fn new(
        py: Python<'_>,
        comm: i64,
        points: PyReadonlyArray1<'_, f64>,
        leaf_size: usize,
        max_level: u32,
    ) -> PyResult<Self> {
        let adopted = AdoptedComm::duplicate(comm)?;
        let local = if max_level > ferrofmm_tree::DEEPEST_LEVEL {
            Err(format!(
                "max_level must be at most {}, got {max_level}",
                ferrofmm_tree::DEEPEST_LEVEL
            ))
        } else {
            Ok(())
        };
        agree_text(adopted.comm(), local).map_err(PyValueError::new_err)?;
        let work = Work::new(adopted, None)?;
        let points = points.as_slice()?.to_vec();
        let options = DistOptions {
            max_level,
            ..DistOptions::adaptive(leaf_size)
        };
        let (tree, points_per_rank) = work
            .run(py, |comm| {
                let tree = DistributedTree::build(comm, &points, &options)?;
                let mine = tree.points.len() as u64;
                let mut all = vec![0u64; comm.size() as usize];
                comm.all_gather_into(&mine, &mut all[..]);
                Ok((tree, all))
            })
            .map_err(dist_error)?;
        Ok(NativeDistOctree {
            tree,
            points_per_rank,
            ranks: work.size(),
        })
    }

    /// This rank.
    #[getter]
    fn rank(&self) -> usize {
        self.tree.rank()
    }

    /// Ranks of the communicator.
    #[getter]
    fn size(&self) -> usize {
        self.ranks
    }

    /// `(origin, width)` of the root cube (the same on every rank).
    #[getter]
    fn domain(&self) -> ([f64; 3], f64) {
        (self.tree.domain.origin, self.tree.domain.width)
    }

    /// Keys (`MortonKey::raw`) of this rank's boxes, sorted.
    #[getter]
    fn keys<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        keys_array(py, self.tree.boxes.iter().map(|b| b.0))
    }

    /// Whether each of this rank's boxes is a leaf.
    #[getter]
    fn is_leaf<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_vec(py, self.tree.boxes.iter().map(|b| b.1).collect())
    }

    /// Points in each of this rank's boxes.
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.boxes.iter().map(|b| b.2))
    }

    /// Keys of the coarse tree (boxes straddling a cut; on every rank).
    #[getter]
    fn coarse_keys<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        keys_array(py, self.tree.coarse.iter().copied())
    }

    /// `cuts[r]..cuts[r + 1]`: the deepest-level Morton codes of rank `r`.
    #[getter]
    fn cuts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.tree.cuts.clone())
    }

    /// This rank's points after the partition, sorted along the Morton
    /// curve, shape `(n, 3)`.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        PyArray1::from_vec(py, self.tree.points.coords.clone()).reshape([self.tree.points.len(), 3])
    }

    /// Global input index of each of this rank's points (the points of
    /// rank `r`'s input are numbered after those of ranks `< r`).
    #[getter]
    fn point_ids<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.tree.points.ids.clone())
    }

    /// Points every rank passed to the build, in rank order.
    #[getter]
    fn input_counts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.tree.input_counts.clone())
    }

    /// Points every rank holds after the partition, in rank order.
    #[getter]
    fn points_per_rank<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        PyArray1::from_vec(py, self.points_per_rank.clone())
    }

    /// Keys of the ghost boxes (other ranks' boxes and coarse boxes that
    /// this rank's lists reference).
    #[getter]
    fn ghost_keys<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        keys_array(py, self.tree.ghosts.ghosts.iter().map(|g| g.key))
    }

    /// Whether each ghost box is a leaf of the global tree.
    #[getter]
    fn ghost_is_leaf<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_vec(py, self.tree.ghosts.ghosts.iter().map(|g| g.leaf).collect())
    }

    /// Points in each ghost box (0 for a coarse box).
    #[getter]
    fn ghost_counts<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.ghosts.ghosts.iter().map(|g| g.points))
    }

    /// Ranks this one asked for ghost boxes.
    #[getter]
    fn partners<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<i64>> {
        usize_array(py, self.tree.ghosts.partners.iter().copied())
    }

    /// The boxes the lists are given on (this rank's, the coarse tree, the
    /// ghosts and their ancestors), in the tree's order: the rows and
    /// indices of [`NativeDistOctree::list_csr`].
    #[getter]
    fn list_keys<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u64>> {
        keys_array(py, self.tree.ghosts.skeleton.iter().copied())
    }

    /// One interaction list over `list_keys` in CSR form: `(offsets,
    /// indices)`; the rows of this rank's boxes are those of the
    /// single-machine tree. `kind` is `"u"`, `"v"`, `"w"` or `"x"`.
    fn list_csr<'py>(&self, py: Python<'py>, kind: &str) -> PyResult<CsrArrays<'py>> {
        let csr = list_of(&self.tree.ghosts.lists, kind)?;
        Ok((
            usize_array(py, csr.offsets().iter().copied()),
            usize_array(py, csr.indices().iter().copied()),
        ))
    }

    /// Build phases: `(names, seconds, bytes sent)` of this rank, and the
    /// rounds of the distributed 2:1 balance.
    fn build_stats(&self) -> (Vec<&'static str>, Vec<f64>, Vec<u64>, usize) {
        let s = &self.tree.stats;
        (
            PHASES.to_vec(),
            s.seconds.to_vec(),
            s.bytes_sent.to_vec(),
            s.balance_rounds,
        )
    }
}
