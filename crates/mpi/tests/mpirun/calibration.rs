//! The cost model's calibration across ranks: rank 0's chooser weighs the
//! costs with the calibration in the cache folder when it is one of this
//! processor at the ranks' thread count, and ignores it otherwise.

use ferrofmm_fmm::tuning::{GroupScales, MachineCalibration, this_processor};

use crate::common::{json_number, mpirun, write_npy};

/// The chosen leaf size of an `eval --tolerance 1e-4 --json` run on 2
/// ranks with `cache` as the cache folder, and whether the report says the
/// costs were calibrated.
fn choice(points: &str, charges: &str, cache: &str) -> (f64, bool) {
    let (ok, text) = mpirun(
        2,
        &[
            "eval",
            "--sources",
            points,
            "--charges",
            charges,
            "--tolerance",
            "1e-4",
            "--threads",
            "1",
            "--cache-dir",
            cache,
            "--json",
        ],
    );
    assert!(ok && text.contains("\"tolerance_met\":true"), "{text}");
    let chosen = &text[text.find("\"chosen\":").expect("a chosen object")..];
    let leaf = json_number(chosen, "leaf_size").expect("chosen leaf size");
    let calibrated = chosen.contains("\"calibrated\":true");
    assert!(
        calibrated || chosen.contains("\"calibrated\":false"),
        "{text}"
    );
    (leaf, calibrated)
}

/// A calibration that makes P2P 30 times dearer (this processor, 1
/// thread) shrinks the chosen leaves and is reported; the same file for 2
/// threads is another machine's and changes nothing.
#[test]
fn rank_zero_chooses_with_this_machines_calibration() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-calib-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 20_000;
    let pts: Vec<f64> = (0..3 * n)
        .map(|i| (i as f64 * 0.754_877_666).fract())
        .collect();
    let q: Vec<f64> = (0..n)
        .map(|i| ((i * 53) % 97) as f64 / 97.0 - 0.5)
        .collect();
    write_npy(&path("s.npy"), &pts, 3);
    write_npy(&path("q.npy"), &q, 1);
    let cache = path("cache");
    std::fs::create_dir_all(&cache).unwrap();

    let (built_in, calibrated) = choice(&path("s.npy"), &path("q.npy"), &cache);
    assert!(!calibrated);

    let dear_p2p = |threads| MachineCalibration {
        processor: this_processor(),
        threads,
        scales: GroupScales {
            p2p: 30.0,
            ..GroupScales::default()
        },
    };
    dear_p2p(2).save(std::path::Path::new(&cache)).unwrap();
    let (foreign, calibrated) = choice(&path("s.npy"), &path("q.npy"), &cache);
    assert!(
        !calibrated && foreign == built_in,
        "{foreign} vs {built_in}"
    );

    dear_p2p(1).save(std::path::Path::new(&cache)).unwrap();
    let (dear, calibrated) = choice(&path("s.npy"), &path("q.npy"), &cache);
    assert!(
        calibrated && dear < built_in,
        "leaf {dear} with P2P 30x dearer, {built_in} built-in"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
