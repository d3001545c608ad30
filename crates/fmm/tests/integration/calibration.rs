//! The cost model calibrated on this machine (`tuning::MachineCalibration`):
//! measured from real runs, saved in a cache folder, used by the builds
//! whose cache is that folder (and said so), and moving the choice the
//! way its scales say.

use ferrofmm_field::{FftM2l, M2lCostShape};
use ferrofmm_fmm::tuning::{CALIBRATION_FILE, GroupScales, MachineCalibration, Tuner};
use ferrofmm_fmm::{CalibrationSetting, FmmBuilder, Geometry};
use ferrofmm_kernels::Precision;

#[test]
fn a_calibration_is_measured_saved_and_used_by_builds_with_its_folder() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("calibration-test");
    let _ = std::fs::remove_file(dir.join(CALIBRATION_FILE));
    let (c, runs) = MachineCalibration::measure(20_000, Some(&dir)).unwrap();
    assert_eq!(runs.len(), 6);
    for r in &runs {
        let (m, p) = (&r.measured, &r.predicted);
        assert!(
            m.p2p > 0.0 && m.far > 0.0 && m.m2l > 0.0 && m.tree > 0.0,
            "{r:?}"
        );
        assert!(
            p.p2p > 0.0 && p.far > 0.0 && p.m2l > 0.0 && p.tree > 0.0,
            "{r:?}"
        );
    }
    let s = c.scales;
    for (name, v) in [
        ("p2p", s.p2p),
        ("far", s.far),
        ("svd m2l", s.m2l_compressed),
        ("fft m2l", s.m2l_fft),
        ("tree", s.tree),
    ] {
        assert!(v.is_finite() && v > 0.0, "{name}: {v}");
    }
    assert!(c.fits(rayon::current_num_threads()));

    // Saved in the folder: a build with it uses it, one told not to does
    // not, and one with another folder finds none.
    c.save(&dir).unwrap();
    let points: Vec<f64> = Geometry::Cube.points(20_000, 2);
    let model = |setting: CalibrationSetting, folder: &std::path::Path| {
        let fmm = FmmBuilder::new(&points)
            .tolerance(1e-5)
            .allow_direct(false)
            .cache_dir(folder)
            .calibration(setting)
            .build_with::<FftM2l<f64>>(Default::default())
            .unwrap();
        fmm.chosen_parameters().unwrap().clone()
    };
    assert!(
        model(CalibrationSetting::FromCache, &dir)
            .model
            .contains("calibrated on this machine")
    );
    assert!(
        !model(CalibrationSetting::Off, &dir)
            .model
            .contains("calibrated")
    );
    let elsewhere = dir.join("elsewhere");
    assert!(
        !model(CalibrationSetting::FromCache, &elsewhere)
            .model
            .contains("calibrated")
    );

    // Dearer P2P, smaller leaves (through the builder); dearer far field
    // and M2L, larger ones (the chooser alone, on enough points for trees
    // of several depths).
    let with = |scales| MachineCalibration {
        scales,
        ..c.clone()
    };
    let slow_p2p = with(GroupScales {
        p2p: 20.0,
        ..GroupScales::default()
    });
    let slow_far = with(GroupScales {
        far: 20.0,
        m2l_fft: 20.0,
        ..GroupScales::default()
    });
    let leaf = |setting| model(setting, &elsewhere).leaf_size;
    let plain = leaf(CalibrationSetting::Off);
    assert!(leaf(CalibrationSetting::Given(slow_p2p.clone())) < plain);
    let many: Vec<f64> = Geometry::Cube.points(400_000, 3);
    let chosen = |c: Option<MachineCalibration>| {
        Tuner::new(Precision::F64)
            .for_scheme(M2lCostShape::Fft)
            .with_calibration(c)
            .choose(1e-6, &many, None, None, 16)
            .unwrap()
            .leaf_size
    };
    let plain = chosen(None);
    assert!(chosen(Some(slow_p2p)) < plain);
    assert!(chosen(Some(slow_far)) > plain);
}
