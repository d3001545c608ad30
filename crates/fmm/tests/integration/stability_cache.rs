//! Stability suite, operator cache through the driver
//! (`FmmBuilder::cache_dir`): a hit gives bitwise the results of a fresh
//! build; a truncated, corrupted, other-version or other-parameter file is
//! detected (the status says why), recomputed and rewritten, and the results
//! are still bitwise those of a build without cache.
//!
//! Each test works in its own temporary directory (removed afterwards).
//! The file format is the field crate's (`ferrofmm_field` cache module):
//! 8 bytes magic, 4 bytes format version (u32 LE), 4 bytes header length,
//! the header, then the payload.

use crate::stability_common;

use std::fs;
use std::path::{Path, PathBuf};

use ferrofmm_field::{CACHE_FORMAT_VERSION, CacheStatus, M2lScheme, SvdM2l};
use ferrofmm_fmm::{Fmm, FmmBuilder};
use ferrofmm_kernels::Laplace3d;
use ferrofmm_testing::TempDir;
use stability_common::{charges_in, potential_error, tol, uniform};

const N: usize = 800;

struct Problem {
    points: Vec<f64>,
    charges: Vec<f64>,
}

fn problem() -> Problem {
    Problem {
        points: uniform(N, 0.0, 1.0, 1),
        charges: charges_in(N, -1.0, 1.0, 2),
    }
}

type SvdFmm = Fmm<f64, Laplace3d, SvdM2l<f64>>;

fn build(pb: &Problem, order: usize, dir: Option<&Path>) -> SvdFmm {
    let mut b = FmmBuilder::new(&pb.points).order(order).leaf_size(16);
    if let Some(d) = dir {
        b = b.cache_dir(d);
    }
    b.build_svd().unwrap()
}

/// Both cache statuses of a build: operators, then M2L.
fn statuses(fmm: &SvdFmm) -> [CacheStatus; 2] {
    [
        fmm.operators().cache_status().clone(),
        fmm.m2l_scheme().cache_status(),
    ]
}

fn is_fresh(s: &CacheStatus) -> bool {
    matches!(
        s,
        CacheStatus::Computed {
            rejected: None,
            write_error: None,
            ..
        }
    )
}

/// Why an existing file was rejected, if it was.
fn rejection(s: &CacheStatus) -> Option<String> {
    match s {
        CacheStatus::Computed { rejected, .. } => rejected.clone(),
        _ => None,
    }
}

fn cache_files(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "ffmm"))
        .collect();
    files.sort();
    files
}

/// Damage every cache file with `damage`, rebuild, and check that each
/// file was rejected for a reason containing `reason`, recomputed and
/// rewritten, and that results equal `reference` bitwise.
fn damaged_files_are_rebuilt(name: &str, damage: impl Fn(&mut Vec<u8>), reason: &str) {
    let pb = problem();
    let reference = build(&pb, 4, None).evaluate(&pb.charges).unwrap();
    let dir = TempDir::new(name);
    build(&pb, 4, Some(dir.path()));
    let files = cache_files(dir.path());
    assert_eq!(files.len(), 3, "operators, SVD bases, M2L: {files:?}");
    let mut damaged = Vec::new();
    for f in &files {
        let mut bytes = fs::read(f).unwrap();
        damage(&mut bytes);
        fs::write(f, &bytes).unwrap();
        damaged.push(bytes);
    }
    let fmm = build(&pb, 4, Some(dir.path()));
    for s in statuses(&fmm) {
        let why = rejection(&s).unwrap_or_else(|| panic!("{name}: not rejected: {s:?}"));
        eprintln!("{name}: rejected: {why}");
        assert!(why.contains(reason), "{name}: unexpected reason {why:?}");
        assert!(
            matches!(
                s,
                CacheStatus::Computed {
                    write_error: None,
                    ..
                }
            ),
            "{s:?}"
        );
    }
    // Every file was rewritten, the bases' (not in the statuses) too.
    for (f, bytes) in files.iter().zip(&damaged) {
        assert_ne!(&fs::read(f).unwrap(), bytes, "{name}: {f:?} not rewritten");
    }
    let values = fmm.evaluate(&pb.charges).unwrap();
    assert_eq!(values, reference, "{name}: results differ after rebuild");
    // The rewritten files are good again.
    let again = build(&pb, 4, Some(dir.path()));
    assert!(statuses(&again).iter().all(CacheStatus::is_hit), "{name}");
    assert_eq!(again.evaluate(&pb.charges).unwrap(), reference);
}

#[test]
fn second_build_hits_the_cache_with_bitwise_identical_results() {
    let pb = problem();
    let reference = build(&pb, 4, None).evaluate(&pb.charges).unwrap();
    let e = potential_error(&pb.points, &pb.points, &pb.charges, &reference);
    assert!(e <= tol::<f64>(4) * 10.0, "{e:.2e}"); // mixed signs: see geometry
    let dir = TempDir::new("hit");
    let first = build(&pb, 4, Some(dir.path()));
    assert!(
        statuses(&first).iter().all(is_fresh),
        "{:?}",
        statuses(&first)
    );
    let second = build(&pb, 4, Some(dir.path()));
    assert!(
        statuses(&second).iter().all(CacheStatus::is_hit),
        "{:?}",
        statuses(&second)
    );
    let v1 = first.evaluate(&pb.charges).unwrap();
    let v2 = second.evaluate(&pb.charges).unwrap();
    assert_eq!(v1, reference);
    assert_eq!(v2, reference);
    // The dense scheme's file too.
    let dense = |dir: &Path| {
        FmmBuilder::new(&pb.points)
            .order(4)
            .leaf_size(16)
            .cache_dir(dir)
            .build_dense()
            .unwrap()
    };
    let d1 = dense(dir.path());
    let d2 = dense(dir.path());
    assert!(d1.operators().cache_status().is_hit()); // shared with the SVD builds
    assert!(!d1.m2l_scheme().cache_status().is_hit());
    assert!(d2.m2l_scheme().cache_status().is_hit());
    assert_eq!(
        d1.evaluate(&pb.charges).unwrap(),
        d2.evaluate(&pb.charges).unwrap()
    );
}

#[test]
fn truncated_files_are_detected_and_rebuilt() {
    damaged_files_are_rebuilt("truncated-half", |b| b.truncate(b.len() / 2), "truncated");
    damaged_files_are_rebuilt(
        "truncated-last-byte",
        |b| b.truncate(b.len() - 1),
        "truncated",
    );
    damaged_files_are_rebuilt("truncated-preamble", |b| b.truncate(10), "truncated");
    damaged_files_are_rebuilt("empty", |b| b.clear(), "truncated");
    damaged_files_are_rebuilt("padded", |b| b.push(0), "padded");
}

#[test]
fn corrupted_files_are_detected_and_rebuilt() {
    // One flipped bit in the payload: the checksum catches it.
    damaged_files_are_rebuilt(
        "payload-bit",
        |b| {
            let i = b.len() - 5;
            b[i] ^= 0x01;
        },
        "checksum",
    );
    // A flipped byte in the middle of the payload.
    damaged_files_are_rebuilt(
        "payload-byte",
        |b| {
            let i = b.len() - b.len() / 4;
            b[i] = !b[i];
        },
        "checksum",
    );
    // Not a cache file at all.
    damaged_files_are_rebuilt("magic", |b| b[0] = b'X', "magic");
}

#[test]
fn other_format_version_is_detected_and_rebuilt() {
    damaged_files_are_rebuilt(
        "version",
        |b| b[8..12].copy_from_slice(&(CACHE_FORMAT_VERSION + 1).to_le_bytes()),
        "format version",
    );
    damaged_files_are_rebuilt(
        "version-0",
        |b| b[8..12].copy_from_slice(&0u32.to_le_bytes()),
        "format version",
    );
}

#[test]
fn other_parameter_sets_share_a_directory() {
    let pb = problem();
    let dir = TempDir::new("params");
    // Orders 4 and 5 side by side: separate files, no cross-talk.
    let reference4 = build(&pb, 4, None).evaluate(&pb.charges).unwrap();
    let reference5 = build(&pb, 5, None).evaluate(&pb.charges).unwrap();
    let a = build(&pb, 4, Some(dir.path()));
    let b = build(&pb, 5, Some(dir.path()));
    assert!(statuses(&a).iter().chain(&statuses(&b)).all(is_fresh));
    // Per order: the operators, the SVD's bases and its truncated sets.
    assert_eq!(cache_files(dir.path()).len(), 6);
    let a = build(&pb, 4, Some(dir.path()));
    let b = build(&pb, 5, Some(dir.path()));
    assert!(
        statuses(&a)
            .iter()
            .chain(&statuses(&b))
            .all(CacheStatus::is_hit)
    );
    assert_eq!(a.evaluate(&pb.charges).unwrap(), reference4);
    assert_eq!(b.evaluate(&pb.charges).unwrap(), reference5);

    // A file of the other order under this order's name (a renamed or
    // copied file, or a name collision): the header's parameters disagree.
    let path_of =
        |fmm: &SvdFmm| -> [PathBuf; 2] { statuses(fmm).map(|s| s.path().unwrap().to_path_buf()) };
    let (pa, pb5) = (path_of(&a), path_of(&b));
    for (dst, src) in pa.iter().zip(&pb5) {
        fs::copy(src, dst).unwrap();
    }
    let a = build(&pb, 4, Some(dir.path()));
    for s in statuses(&a) {
        let why = rejection(&s).unwrap_or_else(|| panic!("not rejected: {s:?}"));
        eprintln!("order-5 file under the order-4 name: rejected: {why}");
        assert!(why.contains("stale"), "{why}");
    }
    assert_eq!(a.evaluate(&pb.charges).unwrap(), reference4);

    // Other cutoff, other float type: other files again.
    let c = FmmBuilder::new(&pb.points)
        .order(4)
        .leaf_size(16)
        .pinv_rcond(Some(1e-10))
        .cache_dir(dir.path())
        .build_svd()
        .unwrap();
    assert!(is_fresh(c.operators().cache_status()));
    assert!(c.m2l_scheme().cache_status().is_hit()); // M2L does not depend on it
    let p32: Vec<f32> = pb.points.iter().map(|&x| x as f32).collect();
    let d = FmmBuilder::new(&p32)
        .order(4)
        .leaf_size(16)
        .cache_dir(dir.path())
        .build_svd()
        .unwrap();
    assert!(is_fresh(d.operators().cache_status()));
    assert!(is_fresh(&d.m2l_scheme().cache_status()));
    // f32 has operators and truncated sets of its own; the SVD's bases
    // (computed in f64 whatever the working type) are shared.
    assert_eq!(cache_files(dir.path()).len(), 9);
}

#[test]
fn unwritable_cache_directory_still_builds() {
    let pb = problem();
    let reference = build(&pb, 4, None).evaluate(&pb.charges).unwrap();
    let dir = TempDir::new("unwritable");
    // A regular file where the directory should be.
    let not_a_dir = dir.path().join("file");
    fs::write(&not_a_dir, b"x").unwrap();
    let fmm = build(&pb, 4, Some(&not_a_dir));
    for s in statuses(&fmm) {
        assert!(
            matches!(
                s,
                CacheStatus::Computed {
                    write_error: Some(_),
                    ..
                }
            ),
            "{s:?}"
        );
    }
    assert_eq!(fmm.evaluate(&pb.charges).unwrap(), reference);
}
