//! The operator cache as a shared, bounded folder: eviction under a size
//! cap (least recently used first, only our files, never the file just
//! written), several writers of one entry at once, a read-only folder.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Barrier;
use std::time::{Duration, SystemTime};

use ferrofmm_testing::TempDir;

use ferrofmm_field::{CacheStatus, OperatorParams, Operators};
use ferrofmm_kernels::Laplace3d;

fn params(p: usize, dir: &Path, cap: Option<u64>) -> OperatorParams {
    let mut params = OperatorParams::new(p);
    params.cache_dir = Some(dir.to_path_buf());
    params.cache_size_limit = cap;
    params
}

fn build(p: usize, dir: &Path, cap: Option<u64>) -> Operators<f64> {
    Operators::<f64>::new(&Laplace3d, &params(p, dir, cap), 1.0, 2).unwrap()
}

/// The cache file of a fresh computation.
fn written(ops: &Operators<f64>) -> PathBuf {
    match ops.cache_status() {
        CacheStatus::Computed {
            path,
            write_error: None,
            ..
        } => path.clone(),
        other => panic!("expected a written file, got {other:?}"),
    }
}

fn age(path: &Path, seconds: u64) {
    let f = fs::File::options().write(true).open(path).unwrap();
    f.set_modified(SystemTime::now() - Duration::from_secs(seconds))
        .unwrap();
}

fn len(path: &Path) -> u64 {
    fs::metadata(path).unwrap().len()
}

/// What the operators give for a fixed input, as bits.
fn fingerprint(ops: &Operators<f64>) -> Vec<u64> {
    let n = ops.n_surface();
    let input: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
    let mut out = vec![0.0; n];
    let mut bits = Vec::new();
    for level in 0..=ops.depth() {
        ops.uc2e(level, &input, &mut out);
        bits.extend(out.iter().map(|x| x.to_bits()));
    }
    bits
}

#[test]
fn eviction_keeps_the_newest_and_the_recently_used() {
    let dir = TempDir::new("evict");
    let cache = dir.join("cache");
    // The size of the order-5 file, from a folder of its own.
    let p5_len = len(&written(&build(5, &dir.join("sizes"), None)));

    // Files that are not ours: never touched, never counted.
    fs::create_dir_all(&cache).unwrap();
    let notes = cache.join("notes.txt");
    fs::write(&notes, vec![b'x'; 1 << 20]).unwrap();
    let lookalike = cache.join("operators_laplace_p9_f64_0123456789abcdef.ffmm");
    fs::write(&lookalike, b"no magic here").unwrap();
    let foreign_tmp = cache.join(".notes.txt.1.2.3.tmp");
    fs::write(&foreign_tmp, b"x").unwrap();
    age(&notes, 1_000_000);
    age(&lookalike, 1_000_000);
    age(&foreign_tmp, 1_000_000);
    // A temporary file of ours left by a killed writer two days ago, and
    // one being written now.
    let p3 = written(&build(3, &cache, None));
    let name = p3.file_name().unwrap().to_str().unwrap();
    let stale = cache.join(format!(".{name}.99.00000000000000aa.0.tmp"));
    let fresh = cache.join(format!(".{name}.98.00000000000000bb.0.tmp"));
    fs::write(&stale, b"half").unwrap();
    fs::write(&fresh, b"half").unwrap();
    age(&stale, 2 * 24 * 3600);

    let p4 = written(&build(4, &cache, None));
    age(&p3, 300);
    age(&p4, 200);
    // A hit makes order 3 the most recently used of the two.
    assert!(build(3, &cache, None).cache_status().is_hit());

    // Room for all but one: the least recently used (order 4) goes.
    let cap = len(&p3) + len(&p4) + p5_len - 1;
    let p5 = written(&build(5, &cache, Some(cap)));
    assert!(p3.exists() && p5.exists(), "the newest two stay");
    assert!(!p4.exists(), "the least recently used is evicted");
    assert!(!stale.exists(), "a stale temporary file of ours is removed");
    for kept in [&notes, &lookalike, &foreign_tmp, &fresh] {
        assert!(kept.exists(), "{} was touched", kept.display());
    }

    // A cap below one file: everything of ours but the file just written.
    let p6 = written(&build(6, &cache, Some(0)));
    assert!(p6.exists() && !p3.exists() && !p5.exists());
    assert!(notes.exists() && lookalike.exists());
    assert!(build(6, &cache, Some(0)).cache_status().is_hit());

    // Evicted entries are recomputed: the same operators.
    let again = build(4, &cache, None);
    assert!(!again.cache_status().is_hit());
    let plain = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(4), 1.0, 2).unwrap();
    assert_eq!(fingerprint(&again), fingerprint(&plain));
}

#[test]
fn concurrent_writers_of_one_entry_leave_one_valid_file() {
    let dir = TempDir::new("writers");
    let cache = dir.join("cache");
    let reference =
        fingerprint(&Operators::<f64>::new(&Laplace3d, &OperatorParams::new(5), 1.0, 2).unwrap());
    let n = 4;
    let barrier = Barrier::new(n);
    let prints: Vec<Vec<u64>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..n)
            .map(|_| {
                s.spawn(|| {
                    barrier.wait();
                    fingerprint(&build(5, &cache, Some(1 << 30)))
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for p in &prints {
        assert_eq!(p, &reference);
    }
    let names: Vec<String> = fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 1, "one file, no temporary left: {names:?}");
    let hit = build(5, &cache, None);
    assert!(hit.cache_status().is_hit());
    assert_eq!(fingerprint(&hit), reference);
}

/// A folder the process may not write: computed, kept in memory, the
/// status says why. Root writes anywhere, so there the check is skipped
/// (the path below a regular file covers the same code path).
#[cfg(unix)]
#[test]
fn read_only_folder_falls_back_to_memory() {
    use std::os::unix::fs::PermissionsExt;
    let dir = TempDir::new("read-only");
    let ro = dir.join("ro");
    fs::create_dir_all(&ro).unwrap();
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o555)).unwrap();
    let permissions_bite = fs::write(ro.join("probe"), b"x").is_err();
    for folder in [ro.clone(), ro.join("sub")] {
        let ops = build(3, &folder, Some(1 << 30));
        match ops.cache_status() {
            CacheStatus::Computed {
                write_error: Some(e),
                ..
            } => assert!(e.contains("ermission denied"), "{e}"),
            other if !permissions_bite => println!("running as root: {other:?}"),
            other => panic!("expected a write error, got {other:?}"),
        }
        let plain = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(3), 1.0, 2).unwrap();
        assert_eq!(fingerprint(&ops), fingerprint(&plain));
    }
    fs::set_permissions(&ro, fs::Permissions::from_mode(0o755)).unwrap();
}
