//! The cost model calibrated on this machine.
//!
//! [`CostModel::default`] was fitted on one machine. Another machine has
//! other ratios between the kinds of work: a core with AVX2 evaluates half
//! as many kernel pairs per instruction as one with AVX-512, while the
//! FFT M2L depends more on memory bandwidth. The choice of leaf size and
//! scheme depends on those ratios only, so calibrating them is enough.
//!
//! [`MachineCalibration::measure`] builds and times a few Laplace FMMs on
//! this machine (uniform cube, zero-mean charges, potentials, `f64`; the
//! FFT and the SVD scheme, small and large leaves, each evaluated
//! [`CALIBRATION_REPEATS`] times and the fastest kept). For each group `g`
//! of the cost model's coefficients (P2P, far field, SVD M2L, FFT M2L,
//! tree) it takes
//!
//! ```text
//! s_g = sum_r t_g(r) / sum_r t^_g(r)
//! ```
//!
//! over the runs `r`, with `t_g` the measured seconds of the group's passes
//! and `t^_g` what [`CostModel::default`] predicts for the same tree. Every
//! coefficient of group `g` is then multiplied by `s_g`
//! ([`MachineCalibration::apply`]): the shape of each group (how its work
//! is counted) stays the one fitted on many runs, the balance between the
//! groups becomes this machine's.
//!
//! A calibration is stored as a small text file, [`CALIBRATION_FILE`], in
//! the operator cache folder ([`MachineCalibration::save`]), for the
//! processor and the number of threads it was measured with; a build whose
//! cache is that folder uses it when both match
//! ([`FmmBuilder::calibration`](crate::FmmBuilder::calibration)). The
//! command line measures and saves one with `ferrofmm calibrate`.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use ferrofmm_field::{CacheLocation, CacheSetting, FftM2l, M2lCostShape, M2lScheme};
use ferrofmm_kernels::Laplace3d;

use super::cost::{CostModel, CostPrediction};
use super::work::WorkCounts;
use crate::{Charges, EvalTimings, Fmm, FmmBuilder, FmmError, Geometry};

/// Name of the calibration file in the cache folder.
pub const CALIBRATION_FILE: &str = "machine-calibration.txt";

/// Version of the file's format; a file of another version is ignored.
const FORMAT: u32 = 1;

/// Evaluations of each calibration run; the fastest of each pass is kept
/// (the first also touches the memory the others reuse).
pub const CALIBRATION_REPEATS: usize = 3;

/// Points of the calibration runs by default: large enough that every pass
/// runs for milliseconds on many cores (a uniform cube of depth 3 to 5),
/// small enough that the whole calibration takes seconds.
pub const CALIBRATION_POINTS: usize = 200_000;

/// The calibration runs: M2L scheme, order and leaf size. Small leaves
/// weigh the far field and the M2L, large ones the P2P; both schemes at
/// two orders.
const RUNS: [(M2lCostShape, usize, usize); 6] = [
    (M2lCostShape::Fft, 5, 64),
    (M2lCostShape::Fft, 7, 256),
    (M2lCostShape::Fft, 6, 512),
    (M2lCostShape::Compressed, 5, 128),
    (M2lCostShape::Compressed, 6, 64),
    (M2lCostShape::Compressed, 6, 384),
];

/// Which calibration of the cost model a build's parameter chooser uses
/// ([`FmmBuilder::calibration`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum CalibrationSetting {
    /// The one saved in the build's operator cache folder for this
    /// processor and number of threads, if any (the default).
    #[default]
    FromCache,
    /// This one, whatever machine it was measured on.
    Given(MachineCalibration),
    /// None: the built-in cost model.
    Off,
}

/// Measured over predicted seconds for each group of the cost model's
/// coefficients (1 keeps [`CostModel::default`]'s).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct GroupScales {
    /// P2P (`p2p_pair`, `p2p_entry`).
    pub p2p: f64,
    /// P2M, L2P, M2P, P2L, M2M and L2L (`surface_point`, `far_point`,
    /// `dense`, `box_surface`).
    pub far: f64,
    /// The SVD (compressed) M2L (`m2l_flop`, `m2l_pair`, `m2l_box`).
    pub m2l_compressed: f64,
    /// The FFT M2L (`fft_pair`, `fft_box`).
    pub m2l_fft: f64,
    /// Building the tree (`tree_point`, `tree_box`, `tree_pair`).
    pub tree: f64,
}

impl Default for GroupScales {
    fn default() -> Self {
        GroupScales {
            p2p: 1.0,
            far: 1.0,
            m2l_compressed: 1.0,
            m2l_fft: 1.0,
            tree: 1.0,
        }
    }
}

impl GroupScales {
    /// The scales by name, in the file's order.
    fn named(&self) -> [(&'static str, f64); 5] {
        [
            ("p2p", self.p2p),
            ("far", self.far),
            ("m2l_compressed", self.m2l_compressed),
            ("m2l_fft", self.m2l_fft),
            ("tree", self.tree),
        ]
    }

    fn set(&mut self, name: &str, value: f64) -> bool {
        let slot = match name {
            "p2p" => &mut self.p2p,
            "far" => &mut self.far,
            "m2l_compressed" => &mut self.m2l_compressed,
            "m2l_fft" => &mut self.m2l_fft,
            "tree" => &mut self.tree,
            _ => return false,
        };
        *slot = value;
        true
    }
}

/// The cost model's group scales measured on one machine, for one number
/// of threads.
///
/// [`CostModel::default`] was fitted on one machine; another has other
/// ratios between the kinds of work (AVX2 against AVX-512 for the kernel
/// evaluations, memory bandwidth for the FFT M2L), and the leaf size and
/// scheme depend on those ratios only. [`MachineCalibration::measure`]
/// times a few Laplace FMMs here and takes, for each group `g` of the
/// coefficients (P2P, far field, SVD M2L, FFT M2L, tree),
///
/// ```text
/// s_g = sum_r t_g(r) / sum_r t^_g(r)
/// ```
///
/// over the runs `r`: `t_g` the measured seconds of the group's passes,
/// `t^_g` what [`CostModel::default`] predicts on the same tree.
/// [`MachineCalibration::apply`] multiplies every coefficient of group
/// `g` by `s_g`: each group keeps the form fitted on many runs, the
/// balance between the groups becomes this machine's. It is stored as
/// [`CALIBRATION_FILE`] in the operator cache folder
/// ([`MachineCalibration::save`]) and used by the builds whose cache is
/// that folder, on this processor, with as many threads
/// ([`FmmBuilder::calibration`]); `ferrofmm calibrate` measures and saves
/// one.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineCalibration {
    /// The processor it was measured on ([`this_processor`]).
    pub processor: String,
    /// Rayon threads of the measurement.
    pub threads: usize,
    /// Measured over predicted seconds, per group.
    pub scales: GroupScales,
}

/// One calibration run: what was built, measured and predicted.
#[derive(Clone, Copy, Debug)]
pub struct CalibrationRun {
    /// M2L scheme.
    pub shape: M2lCostShape,
    /// Expansion order.
    pub order: usize,
    /// Leaf size.
    pub leaf_size: usize,
    /// Measured seconds per group (the fastest of the repeats).
    pub measured: CostPrediction,
    /// What [`CostModel::default`] predicts for the same tree.
    pub predicted: CostPrediction,
}

impl MachineCalibration {
    /// Every coefficient of `model` times its group's scale.
    ///
    /// ```
    /// use ferrofmm_fmm::tuning::{CostModel, GroupScales, MachineCalibration};
    /// let c = MachineCalibration {
    ///     processor: "any".into(),
    ///     threads: 2,
    ///     scales: GroupScales { p2p: 2.0, m2l_fft: 0.5, ..GroupScales::default() },
    /// };
    /// let (one, m) = (CostModel::default(), c.apply(CostModel::default()));
    /// assert_eq!(m.p2p_pair, 2.0 * one.p2p_pair);
    /// assert_eq!(m.fft_box, 0.5 * one.fft_box);
    /// assert_eq!(m.m2l_flop, one.m2l_flop);
    /// ```
    pub fn apply(&self, model: CostModel) -> CostModel {
        let s = &self.scales;
        CostModel {
            p2p_pair: model.p2p_pair * s.p2p,
            p2p_entry: model.p2p_entry * s.p2p,
            surface_point: model.surface_point * s.far,
            far_point: model.far_point * s.far,
            dense: model.dense * s.far,
            box_surface: model.box_surface * s.far,
            m2l_flop: model.m2l_flop * s.m2l_compressed,
            m2l_pair: model.m2l_pair * s.m2l_compressed,
            m2l_box: model.m2l_box * s.m2l_compressed,
            fft_pair: model.fft_pair * s.m2l_fft,
            fft_box: model.fft_box * s.m2l_fft,
            tree_point: model.tree_point * s.tree,
            tree_box: model.tree_box * s.tree,
            tree_pair: model.tree_pair * s.tree,
        }
    }

    /// Measure this machine with the current rayon threads: six Laplace
    /// FMMs (uniform cube, zero-mean charges, potentials, `f64`; the FFT
    /// scheme at (order, leaf) (5, 64), (7, 256), (6, 512), the SVD at
    /// (5, 128), (6, 64), (6, 384), each evaluated
    /// [`CALIBRATION_REPEATS`] times, the fastest pass kept) on `n_points` uniform points
    /// ([`CALIBRATION_POINTS`] is the default), operators from `cache`
    /// (a folder, or `None` to compute them). Returns the calibration and
    /// the runs it was fitted on.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] for fewer than 1000 points; any
    /// error of building or evaluating the runs.
    pub fn measure(
        n_points: usize,
        cache: Option<&Path>,
    ) -> Result<(Self, Vec<CalibrationRun>), FmmError> {
        if n_points < 1000 {
            return Err(FmmError::InvalidParameter(format!(
                "a calibration needs at least 1000 points (got {n_points})"
            )));
        }
        let points: Vec<f64> = Geometry::Cube.points(n_points, 5);
        let charges: Vec<f64> = Charges::Signed.generate(n_points, 6);
        let mut runs = Vec::with_capacity(RUNS.len());
        for (shape, order, leaf_size) in RUNS {
            let mut builder = FmmBuilder::new(&points).order(order).leaf_size(leaf_size);
            if let Some(dir) = cache {
                builder = builder.cache_dir(dir);
            }
            let (measured, work, rank) = match shape {
                M2lCostShape::Fft => {
                    let fmm = builder.build_with::<FftM2l<f64>>(Default::default())?;
                    timed(&fmm, &charges, 0)?
                }
                _ => {
                    let fmm = builder.build_svd()?;
                    let rank = fmm.m2l_scheme().rank();
                    timed(&fmm, &charges, rank)?
                }
            };
            let predicted = CostModel::default().predict_for(shape, &work, order, rank);
            runs.push(CalibrationRun {
                shape,
                order,
                leaf_size,
                measured,
                predicted,
            });
        }
        let calibration = MachineCalibration {
            processor: this_processor(),
            threads: rayon::current_num_threads(),
            scales: fit_scales(&runs),
        };
        Ok((calibration, runs))
    }

    /// [`MachineCalibration::measure`] with the operators in the folder
    /// `cache` resolves to, then [`MachineCalibration::save`] there: what
    /// `ferrofmm calibrate` and Python's `ferrofmm.calibrate` do. Returns
    /// the calibration, its runs and the file written.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] when `cache` resolves to no folder
    /// (`FERROFMM_CACHE=off`, no home folder), naming why; otherwise as
    /// [`MachineCalibration::measure`] and [`MachineCalibration::save`].
    pub fn measure_and_save(
        cache: &CacheSetting,
        n_points: usize,
    ) -> Result<(Self, Vec<CalibrationRun>, PathBuf), FmmError> {
        let dir = match cache.resolve()? {
            CacheLocation::Folder { dir, .. } => dir,
            CacheLocation::Off(why) => {
                return Err(FmmError::InvalidParameter(format!(
                    "no folder to keep the calibration in ({why}): name a cache folder"
                )));
            }
        };
        let (calibration, runs) = Self::measure(n_points, Some(&dir))?;
        let path = calibration.save(&dir)?;
        Ok((calibration, runs, path))
    }

    /// Whether this calibration was measured on this processor with
    /// `threads` threads.
    pub fn fits(&self, threads: usize) -> bool {
        self.threads == threads && self.processor == this_processor()
    }

    /// The file's text.
    fn to_text(&self) -> String {
        let mut s = format!(
            "# ferrofmm machine calibration (`ferrofmm calibrate`): measured over predicted\n\
             # seconds of each group of the built-in cost model, on this processor and\n\
             # number of threads\nformat {FORMAT}\nprocessor {}\nthreads {}\n",
            self.processor, self.threads
        );
        for (name, value) in self.scales.named() {
            let _ = writeln!(s, "{name} {value:e}");
        }
        s
    }

    /// The calibration of a file's text, or `None` for another format or
    /// a damaged file.
    fn from_text(text: &str) -> Option<Self> {
        let (mut format, mut processor, mut threads) = (None, None, None);
        let mut scales = GroupScales::default();
        let mut seen = 0;
        for line in text.lines().map(str::trim) {
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (key, value) = line.split_once(' ')?;
            let value = value.trim();
            match key {
                "format" => format = value.parse::<u32>().ok(),
                "processor" => processor = Some(value.to_string()),
                "threads" => threads = value.parse::<usize>().ok(),
                name => {
                    let v: f64 = value.parse().ok()?;
                    let valid = v.is_finite() && v > 0.0;
                    if !valid || !scales.set(name, v) {
                        return None;
                    }
                    seen += 1;
                }
            }
        }
        (format == Some(FORMAT) && seen == scales.named().len()).then_some(())?;
        Some(MachineCalibration {
            processor: processor?,
            threads: threads.filter(|&t| t > 0)?,
            scales,
        })
    }

    /// Write this calibration to [`CALIBRATION_FILE`] in `dir` (created
    /// if missing), replacing the file at once (written beside it, then
    /// renamed). Returns the file's path.
    ///
    /// # Errors
    /// [`FmmError::InvalidParameter`] naming the file when it cannot be
    /// written.
    pub fn save(&self, dir: &Path) -> Result<PathBuf, FmmError> {
        let path = dir.join(CALIBRATION_FILE);
        let failed = |e: std::io::Error| {
            FmmError::InvalidParameter(format!(
                "cannot write the calibration {}: {e}",
                path.display()
            ))
        };
        std::fs::create_dir_all(dir).map_err(failed)?;
        let partial = dir.join(format!("{CALIBRATION_FILE}.{}.partial", std::process::id()));
        std::fs::write(&partial, self.to_text()).map_err(failed)?;
        std::fs::rename(&partial, &path).map_err(|e| {
            let _ = std::fs::remove_file(&partial);
            failed(e)
        })?;
        Ok(path)
    }

    /// The calibration in the folder `cache` resolves to, if any, for
    /// this processor and the current rayon threads
    /// ([`MachineCalibration::load`]); `None` without a folder.
    pub fn from_cache(cache: &CacheSetting) -> Option<Self> {
        let location = cache.resolve().ok()?;
        Self::load(location.dir()?, rayon::current_num_threads())
    }

    /// The calibration in `dir`, if there is one for this processor and
    /// `threads` threads. A missing, damaged or foreign file is no
    /// calibration (the built-in model is used), never an error: a run
    /// must not fail for want of a tuning hint.
    pub fn load(dir: &Path, threads: usize) -> Option<Self> {
        let text = std::fs::read_to_string(dir.join(CALIBRATION_FILE)).ok()?;
        Self::from_text(&text).filter(|c| c.fits(threads))
    }
}

/// Group scales from the runs: measured over predicted seconds, summed
/// over the runs where the group has work (1 where none has).
fn fit_scales(runs: &[CalibrationRun]) -> GroupScales {
    let ratio = |group: &dyn Fn(&CostPrediction) -> f64, of: &dyn Fn(&CalibrationRun) -> bool| {
        let (mut measured, mut predicted) = (0.0, 0.0);
        for r in runs.iter().filter(|r| of(r)) {
            measured += group(&r.measured);
            predicted += group(&r.predicted);
        }
        if measured > 0.0 && predicted > 0.0 {
            measured / predicted
        } else {
            1.0
        }
    };
    let all = |_: &CalibrationRun| true;
    GroupScales {
        p2p: ratio(&|p| p.p2p, &all),
        far: ratio(&|p| p.far, &all),
        m2l_compressed: ratio(&|p| p.m2l, &|r| r.shape != M2lCostShape::Fft),
        m2l_fft: ratio(&|p| p.m2l, &|r| r.shape == M2lCostShape::Fft),
        tree: ratio(&|p| p.tree, &all),
    }
}

/// The fastest of [`CALIBRATION_REPEATS`] evaluations of `fmm`, per group,
/// with the tree's work counts.
fn timed<S: M2lScheme<f64>>(
    fmm: &Fmm<f64, Laplace3d, S>,
    charges: &[f64],
    rank: usize,
) -> Result<(CostPrediction, WorkCounts, usize), FmmError> {
    let secs = Duration::as_secs_f64;
    let mut best = CostPrediction {
        p2p: f64::INFINITY,
        far: f64::INFINITY,
        m2l: f64::INFINITY,
        tree: 0.0,
        total: 0.0,
    };
    for _ in 0..CALIBRATION_REPEATS {
        let (_, t): (_, EvalTimings) = fmm.evaluate_timed(charges)?;
        let far = t.p2m + t.m2m + t.l2l + t.l2p + t.m2p + t.p2l;
        best.p2p = best.p2p.min(secs(&t.p2p));
        best.far = best.far.min(secs(&far));
        best.m2l = best.m2l.min(secs(&t.m2l));
    }
    let setup = fmm.setup_timings();
    best.tree = secs(&(setup.tree + setup.layout));
    best.total = best.p2p + best.far + best.m2l + best.tree;
    Ok((best, WorkCounts::of_fmm(fmm), rank))
}

/// The processor's name (`model name` of `/proc/cpuinfo` on Linux), else
/// the architecture's: a calibration is kept for the processor it was
/// measured on.
pub fn this_processor() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, name)| name.trim().to_string())
        })
        .filter(|name| !name.is_empty())
        .unwrap_or_else(|| std::env::consts::ARCH.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration() -> MachineCalibration {
        MachineCalibration {
            processor: this_processor(),
            threads: 3,
            scales: GroupScales {
                p2p: 1.75,
                far: 0.5,
                m2l_compressed: 2.0,
                m2l_fft: 0.25,
                tree: 1.5,
            },
        }
    }

    #[test]
    fn a_calibration_is_saved_and_read_back_for_its_machine_only() {
        let dir = std::env::temp_dir().join(format!("ferrofmm-calibration-{}", std::process::id()));
        let c = calibration();
        let path = c.save(&dir).unwrap();
        assert_eq!(path, dir.join(CALIBRATION_FILE));
        assert_eq!(MachineCalibration::load(&dir, 3), Some(c.clone()));
        // Another thread count, another processor: not this machine's.
        assert_eq!(MachineCalibration::load(&dir, 2), None);
        let other = MachineCalibration {
            processor: "another processor".into(),
            ..c.clone()
        };
        other.save(&dir).unwrap();
        assert_eq!(MachineCalibration::load(&dir, 3), None);
        // Damaged files are no calibration.
        let text = c.to_text();
        for damaged in [
            text.replace("format 1", "format 2"),
            text.replace("p2p 1.75e0", "p2p -1"),
            text.replace("p2p 1.75e0", "p2p nan"),
            text.replace("p2p 1.75e0\n", ""),
            text.replace("tree", "trees"),
            text[..text.len() / 2].to_string(),
            String::new(),
        ] {
            assert_eq!(MachineCalibration::from_text(&damaged), None, "{damaged}");
            std::fs::write(dir.join(CALIBRATION_FILE), &damaged).unwrap();
            assert_eq!(MachineCalibration::load(&dir, 3), None);
        }
        std::fs::remove_dir_all(&dir).unwrap();
        assert_eq!(MachineCalibration::load(&dir, 3), None);
    }

    #[test]
    fn scales_are_measured_over_predicted_per_group() {
        let p = |p2p, far, m2l, tree| CostPrediction {
            p2p,
            far,
            m2l,
            tree,
            total: p2p + far + m2l + tree,
        };
        let run = |shape, measured, predicted| CalibrationRun {
            shape,
            order: 6,
            leaf_size: 64,
            measured,
            predicted,
        };
        let runs = [
            run(
                M2lCostShape::Fft,
                p(2.0, 1.0, 3.0, 0.5),
                p(1.0, 1.0, 1.0, 1.0),
            ),
            run(
                M2lCostShape::Compressed,
                p(4.0, 1.0, 1.0, 0.5),
                p(2.0, 3.0, 4.0, 1.0),
            ),
        ];
        let s = fit_scales(&runs);
        assert_eq!(s.p2p, 2.0);
        assert_eq!(s.far, 0.5);
        assert_eq!(s.m2l_fft, 3.0);
        assert_eq!(s.m2l_compressed, 0.25);
        assert_eq!(s.tree, 0.5);
        // No run of a group: its scale is 1.
        assert_eq!(fit_scales(&runs[..1]).m2l_compressed, 1.0);
    }

    #[test]
    fn too_few_points_are_refused() {
        assert!(matches!(
            MachineCalibration::measure(10, None),
            Err(FmmError::InvalidParameter(_))
        ));
    }
}
