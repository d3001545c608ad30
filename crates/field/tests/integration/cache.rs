//! The on-disk operator cache: bit-identical round trips, and every kind of
//! bad file detected and rebuilt.

use std::fs;
use std::path::{Path, PathBuf};

use ferrofmm_testing::TempDir;

use ferrofmm_field::{
    CacheStatus, DenseConfig, DenseM2l, M2lInteractions, M2lScheme, OperatorParams, Operators,
    SvdConfig, SvdM2l,
};
use ferrofmm_kernels::{Laplace3d, ModifiedHelmholtz3d, Real};

fn params(p: usize, dir: &Path) -> OperatorParams {
    let mut params = OperatorParams::new(p);
    params.cache_dir = Some(dir.to_path_buf());
    params
}

/// Everything the operators do to a fixed input, as raw bits.
fn fingerprint<T: Real>(ops: &Operators<T>) -> Vec<u64> {
    let n = ops.n_surface();
    let input: Vec<T> = (0..2 * n)
        .map(|i| T::from_f64((i as f64 * 0.37).sin()))
        .collect();
    let mut out = vec![T::ZERO; 2 * n];
    let mut bits = Vec::new();
    for level in 0..=ops.depth() {
        ops.uc2e(level, &input, &mut out);
        ops.dc2e(level, &input, &mut out);
        if level >= 1 {
            for o in 0..8 {
                ops.m2m(level, o, &input, &mut out);
                ops.l2l(level, o, &input, &mut out);
            }
        }
        bits.extend(out.iter().map(|x| x.to_f64().to_bits()));
    }
    bits
}

fn scheme_fingerprint<T: Real, S: M2lScheme<T>>(s: &S, n: usize) -> Vec<u64> {
    let vs = ferrofmm_field::transfer_vectors();
    let pairs: Vec<_> = (0..20).map(|i| (i % 3, i % 4, vs[i * 13 % 316])).collect();
    let inter = M2lInteractions::new(3, 4, &pairs);
    let m: Vec<T> = (0..4 * n)
        .map(|i| T::from_f64((i as f64 * 0.11).cos()))
        .collect();
    let mut check = vec![T::ZERO; 3 * n];
    s.apply(2, &inter, &m, &mut check);
    check.iter().map(|x| x.to_f64().to_bits()).collect()
}

fn assert_computed(status: &CacheStatus, rejected: bool) -> PathBuf {
    match status {
        CacheStatus::Computed {
            path,
            rejected: r,
            write_error,
        } => {
            assert_eq!(r.is_some(), rejected, "rejected = {r:?}");
            assert!(write_error.is_none(), "{write_error:?}");
            assert!(path.exists());
            path.clone()
        }
        other => panic!("expected a computation, got {other:?}"),
    }
}

fn rejection(status: &CacheStatus) -> String {
    match status {
        CacheStatus::Computed {
            rejected: Some(r), ..
        } => r.clone(),
        other => panic!("expected a rejected file, got {other:?}"),
    }
}

#[test]
fn round_trip_is_bit_identical() {
    let dir = TempDir::new("roundtrip");
    let p = params(4, dir.path());
    let a = Operators::<f64>::new(&Laplace3d, &p, 1.0, 3).unwrap();
    let path = assert_computed(a.cache_status(), false);
    let b = Operators::<f64>::new(&Laplace3d, &p, 1.0, 3).unwrap();
    assert_eq!(b.cache_status(), &CacheStatus::Hit { path: path.clone() });
    assert_eq!(fingerprint(&a), fingerprint(&b));
    assert_eq!(a.diagnostics(), b.diagnostics());
    // f32 lives in its own file.
    let c = Operators::<f32>::new(&Laplace3d, &p, 1.0, 3).unwrap();
    assert_ne!(assert_computed(c.cache_status(), false), path);
    let d = Operators::<f32>::new(&Laplace3d, &p, 1.0, 3).unwrap();
    assert!(d.cache_status().is_hit());
    assert_eq!(fingerprint(&c), fingerprint(&d));
    // A homogeneous kernel's file does not depend on the domain or depth...
    let e = Operators::<f64>::new(&Laplace3d, &p, 7.0, 5).unwrap();
    assert!(e.cache_status().is_hit());
    // ...a non-homogeneous kernel's does.
    let k = ModifiedHelmholtz3d::new(2.0).unwrap();
    let f = Operators::<f64>::new(&k, &p, 1.0, 3).unwrap();
    assert_computed(f.cache_status(), false);
    let g = Operators::<f64>::new(&k, &p, 1.0, 3).unwrap();
    assert!(g.cache_status().is_hit());
    assert_eq!(fingerprint(&f), fingerprint(&g));
    let h = Operators::<f64>::new(&k, &p, 2.0, 3).unwrap();
    assert_computed(h.cache_status(), false);

    // M2L schemes.
    let n = a.n_surface();
    let d1 = DenseM2l::<f64>::precompute(&Laplace3d, &p, &DenseConfig, 1.0, 3).unwrap();
    assert_computed(&d1.cache_status(), false);
    let d2 = DenseM2l::<f64>::precompute(&Laplace3d, &p, &DenseConfig, 1.0, 3).unwrap();
    assert!(d2.cache_status().is_hit());
    assert_eq!(scheme_fingerprint(&d1, n), scheme_fingerprint(&d2, n));
    let cfg = SvdConfig {
        rank: None,
        tolerance: 1e-4,
    };
    let s1 = SvdM2l::<f32>::precompute(&Laplace3d, &p, &cfg, 1.0, 3).unwrap();
    assert_computed(&s1.cache_status(), false);
    let s2 = SvdM2l::<f32>::precompute(&Laplace3d, &p, &cfg, 1.0, 3).unwrap();
    assert!(s2.cache_status().is_hit());
    assert_eq!(s1.rank(), s2.rank());
    assert_eq!(scheme_fingerprint(&s1, n), scheme_fingerprint(&s2, n));
    // Another tolerance is another file.
    let s3 = SvdM2l::<f32>::precompute(
        &Laplace3d,
        &p,
        &SvdConfig {
            rank: None,
            tolerance: 1e-3,
        },
        1.0,
        3,
    )
    .unwrap();
    assert_computed(&s3.cache_status(), false);
    assert!(s3.rank() < s1.rank());
}

/// Damage the cache file of `Operators` p=4 with `damage`, check that the
/// next construction rejects it for `reason`, rebuilds identical operators
/// and rewrites a good file.
fn damaged_file_is_rebuilt(name: &str, reason: &str, damage: impl FnOnce(&Path)) {
    let dir = TempDir::new(name);
    let p = params(4, dir.path());
    let a = Operators::<f64>::new(&Laplace3d, &p, 1.0, 2).unwrap();
    let path = assert_computed(a.cache_status(), false);
    damage(&path);
    let b = Operators::<f64>::new(&Laplace3d, &p, 1.0, 2).unwrap();
    let why = rejection(b.cache_status());
    assert!(
        why.contains(reason),
        "rejection {why:?} does not mention {reason:?}"
    );
    assert_eq!(fingerprint(&a), fingerprint(&b));
    let c = Operators::<f64>::new(&Laplace3d, &p, 1.0, 2).unwrap();
    assert!(
        c.cache_status().is_hit(),
        "file was not rewritten: {:?}",
        c.cache_status()
    );
    assert_eq!(fingerprint(&a), fingerprint(&c));
}

#[test]
fn truncated_file_is_rebuilt() {
    damaged_file_is_rebuilt("truncated", "truncated", |path| {
        let bytes = fs::read(path).unwrap();
        fs::write(path, &bytes[..bytes.len() - 1000]).unwrap();
    });
    // Cut inside the header too.
    damaged_file_is_rebuilt("truncated-header", "truncated", |path| {
        let bytes = fs::read(path).unwrap();
        fs::write(path, &bytes[..40]).unwrap();
    });
}

#[test]
fn corrupted_payload_is_rebuilt() {
    damaged_file_is_rebuilt("corrupt", "checksum", |path| {
        let mut bytes = fs::read(path).unwrap();
        let i = bytes.len() - 12345;
        bytes[i] ^= 0x10;
        fs::write(path, &bytes).unwrap();
    });
}

#[test]
fn wrong_version_is_rebuilt() {
    damaged_file_is_rebuilt("version", "format version", |path| {
        let mut bytes = fs::read(path).unwrap();
        bytes[8..12].copy_from_slice(&(ferrofmm_field::CACHE_FORMAT_VERSION + 1).to_le_bytes());
        fs::write(path, &bytes).unwrap();
    });
    damaged_file_is_rebuilt("magic", "magic", |path| {
        let mut bytes = fs::read(path).unwrap();
        bytes[0] = b'X';
        fs::write(path, &bytes).unwrap();
    });
}

#[test]
fn file_of_other_parameters_is_rebuilt() {
    // A file written for p = 5 placed where the p = 4 file belongs.
    let dir = TempDir::new("other-params");
    let other = Operators::<f64>::new(&Laplace3d, &params(5, dir.path()), 1.0, 2).unwrap();
    let other_path = assert_computed(other.cache_status(), false);
    damaged_file_is_rebuilt("other-params-order", "stale", |path| {
        fs::copy(&other_path, path).unwrap();
    });
    // Another cutoff.
    let mut p2 = params(4, dir.path());
    p2.pinv_rcond = Some(1e-6);
    let other = Operators::<f64>::new(&Laplace3d, &p2, 1.0, 2).unwrap();
    let other_path = assert_computed(other.cache_status(), false);
    damaged_file_is_rebuilt("other-params-rcond", "stale", |path| {
        fs::copy(&other_path, path).unwrap();
    });
    // Another kernel parameter (same name, different k) for an M2L scheme.
    let (k1, k2) = (
        ModifiedHelmholtz3d::new(1.0).unwrap(),
        ModifiedHelmholtz3d::new(2.0).unwrap(),
    );
    let p = params(3, dir.path());
    let a = DenseM2l::<f64>::precompute(&k1, &p, &DenseConfig, 1.0, 2).unwrap();
    let pa = assert_computed(&a.cache_status(), false);
    let b = DenseM2l::<f64>::precompute(&k2, &p, &DenseConfig, 1.0, 2).unwrap();
    let pb = assert_computed(&b.cache_status(), false);
    assert_ne!(pa, pb);
    fs::copy(&pa, &pb).unwrap();
    let c = DenseM2l::<f64>::precompute(&k2, &p, &DenseConfig, 1.0, 2).unwrap();
    assert!(rejection(&c.cache_status()).contains("stale"));
    assert_eq!(scheme_fingerprint(&b, 26), scheme_fingerprint(&c, 26));
}

#[test]
fn unwritable_cache_does_not_fail_the_computation() {
    let dir = TempDir::new("unwritable");
    let blocker = dir.join("a-file");
    fs::write(&blocker, b"not a directory").unwrap();
    let p = params(3, &blocker.join("sub"));
    let a = Operators::<f64>::new(&Laplace3d, &p, 1.0, 2).unwrap();
    match a.cache_status() {
        CacheStatus::Computed {
            write_error: Some(e),
            ..
        } => println!("write error reported: {e}"),
        other => panic!("expected a write error, got {other:?}"),
    }
    let plain = Operators::<f64>::new(&Laplace3d, &OperatorParams::new(3), 1.0, 2).unwrap();
    assert_eq!(plain.cache_status(), &CacheStatus::Disabled);
    assert_eq!(fingerprint(&a), fingerprint(&plain));
}

/// The FFT scheme's kernel spectra: one `f64` file whatever `T`, per level
/// for a non-homogeneous kernel, bit-identical on reload, and a corrupt or
/// truncated file is detected and rebuilt.
#[test]
fn fft_spectra_round_trip_and_damaged_files_are_rebuilt() {
    use ferrofmm_field::{FftConfig, FftM2l};
    let dir = TempDir::new("fft");
    let p = params(5, dir.path());
    let n = ferrofmm_field::n_surface_points(5);
    let a = FftM2l::<f64>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    let path = assert_computed(&a.cache_status(), false);
    let b = FftM2l::<f64>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    assert_eq!(b.cache_status(), CacheStatus::Hit { path: path.clone() });
    assert_eq!(scheme_fingerprint(&a, n), scheme_fingerprint(&b, n));
    // The spectra are f64 for both float types: the f32 scheme reads the
    // same file.
    let c = FftM2l::<f32>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    assert_eq!(c.cache_status(), CacheStatus::Hit { path: path.clone() });
    // A non-homogeneous kernel has a file per domain and depth.
    let k = ModifiedHelmholtz3d::new(2.0).unwrap();
    let h1 = FftM2l::<f64>::precompute(&k, &p, &FftConfig, 1.0, 3).unwrap();
    assert_ne!(assert_computed(&h1.cache_status(), false), path);
    let h2 = FftM2l::<f64>::precompute(&k, &p, &FftConfig, 1.0, 3).unwrap();
    assert!(h2.cache_status().is_hit());
    assert_eq!(scheme_fingerprint(&h1, n), scheme_fingerprint(&h2, n));
    // Damage: one flipped payload bit, then a truncation.
    let mut bytes = fs::read(&path).unwrap();
    let i = bytes.len() - 777;
    bytes[i] ^= 0x04;
    fs::write(&path, &bytes).unwrap();
    let d = FftM2l::<f64>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    assert!(rejection(&d.cache_status()).contains("checksum"));
    assert_eq!(scheme_fingerprint(&a, n), scheme_fingerprint(&d, n));
    let bytes = fs::read(&path).unwrap();
    fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    let e = FftM2l::<f64>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    assert!(rejection(&e.cache_status()).contains("truncated"));
    assert_eq!(scheme_fingerprint(&a, n), scheme_fingerprint(&e, n));
    let f = FftM2l::<f64>::precompute(&Laplace3d, &p, &FftConfig, 1.0, 3).unwrap();
    assert!(f.cache_status().is_hit(), "file was not rewritten");
}

/// Operators built only from level 2 down (`Operators::from_level`) apply
/// the same operators at those levels as the full set (to rounding: the
/// sets may be factorised with other parallel splits), are cached under
/// their own key, and a cached run is bit-identical to the cold one.
#[test]
fn operators_from_a_level_equal_the_full_set_and_cache() {
    let dir = TempDir::new("ferrofmm-from-level");
    let yukawa = ModifiedHelmholtz3d::new(3.0).unwrap();
    let plain = OperatorParams::new(4);
    let full = Operators::<f64>::new(&yukawa, &plain, 1.0, 4).unwrap();
    let part = Operators::<f64>::from_level(&yukawa, &plain, 1.0, 4, 2).unwrap();
    assert_eq!((full.first_level(), part.first_level()), (0, 2));
    assert_eq!(part.diagnostics().uc2e.len(), 3);
    assert_eq!(part.diagnostics().uc2e[..], full.diagnostics().uc2e[2..]);
    let n = full.n_surface();
    let input: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).sin()).collect();
    let close = |what: &str, f: &dyn Fn(&Operators<f64>, &mut [f64])| {
        let (mut a, mut b) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
        f(&full, &mut a);
        f(&part, &mut b);
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        let diff = a
            .iter()
            .zip(&b)
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        assert!(diff <= 1e-9 * scale, "{what}: {diff:.1e} of {scale:.1e}");
    };
    for level in 2..=4 {
        close("uc2e", &|o, out| o.uc2e(level, &input, out));
        close("dc2e", &|o, out| o.dc2e(level, &input, out));
        if level >= 3 {
            for oct in 0..8 {
                close("m2m", &|o, out| o.m2m(level, oct, &input, out));
                close("l2l", &|o, out| o.l2l(level, oct, &input, out));
            }
        }
    }
    // Cold, then from the cache: identical; the full set's file is another.
    let cached = params(4, dir.path());
    let cold = Operators::<f64>::from_level(&yukawa, &cached, 1.0, 4, 2).unwrap();
    let path = assert_computed(cold.cache_status(), false);
    let warm = Operators::<f64>::from_level(&yukawa, &cached, 1.0, 4, 2).unwrap();
    assert_eq!(
        warm.cache_status(),
        &CacheStatus::Hit { path: path.clone() }
    );
    let bits = |ops: &Operators<f64>| {
        let mut out = vec![0.0; 2 * n];
        let mut bits = Vec::new();
        for level in 2..=4 {
            ops.uc2e(level, &input, &mut out);
            ops.dc2e(level, &input, &mut out);
            if level >= 3 {
                for o in 0..8 {
                    ops.m2m(level, o, &input, &mut out);
                    ops.l2l(level, o, &input, &mut out);
                }
            }
            bits.extend(out.iter().map(|x| x.to_bits()));
        }
        bits
    };
    assert_eq!(bits(&cold), bits(&warm));
    let whole = Operators::<f64>::new(&yukawa, &cached, 1.0, 4).unwrap();
    assert_ne!(assert_computed(whole.cache_status(), false), path);
    // A homogeneous kernel has one set for all levels: nothing to skip.
    let laplace = Operators::<f64>::from_level(&Laplace3d, &plain, 1.0, 4, 2).unwrap();
    assert_eq!(laplace.first_level(), 0);
}

/// The cache files under `dir` whose name starts with `kind_`.
fn files_of(dir: &Path, kind: &str) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = fs::read_dir(dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with(&format!("{kind}_")))
        })
        .collect();
    found.sort();
    found
}

/// The SVD scheme's bases (the TSQR and the SVDs of the stacks, most of
/// its cost) are cached apart from its truncated sets: another tolerance
/// or the other working type reuses them, and what it builds is bit for
/// bit what a build without any cache gives; a kernel with operators per
/// level has one bases file per level.
#[test]
fn svd_bases_are_shared_by_tolerances_and_working_types() {
    let dir = TempDir::new("svd-bases");
    let cached = params(5, dir.path());
    let uncached = OperatorParams::new(5);
    let n = Operators::<f64>::new(&Laplace3d, &uncached, 1.0, 3)
        .unwrap()
        .n_surface();
    let at = |tolerance| SvdConfig {
        rank: None,
        tolerance,
    };
    let first = SvdM2l::<f64>::precompute(&Laplace3d, &cached, &at(1e-4), 1.0, 3).unwrap();
    assert_computed(&first.cache_status(), false);
    let bases = files_of(dir.path(), "m2l-svd-bases");
    assert_eq!(bases.len(), 1, "{bases:?}");
    // A hit refreshes the file's time (least recently used eviction) but
    // never rewrites it: the same file (inode) throughout.
    #[cfg(unix)]
    let inode = |p: &Path| std::os::unix::fs::MetadataExt::ino(&fs::metadata(p).unwrap());
    #[cfg(unix)]
    let written = inode(&bases[0]);
    for tolerance in [1e-4, 1e-3, 1e-7] {
        let a = SvdM2l::<f64>::precompute(&Laplace3d, &cached, &at(tolerance), 1.0, 3).unwrap();
        let b = SvdM2l::<f64>::precompute(&Laplace3d, &uncached, &at(tolerance), 1.0, 3).unwrap();
        assert_eq!(a.rank(), b.rank(), "tolerance {tolerance:e}");
        assert_eq!(scheme_fingerprint(&a, n), scheme_fingerprint(&b, n));
        let c = SvdM2l::<f32>::precompute(&Laplace3d, &cached, &at(tolerance), 1.0, 3).unwrap();
        let d = SvdM2l::<f32>::precompute(&Laplace3d, &uncached, &at(tolerance), 1.0, 3).unwrap();
        assert_eq!(scheme_fingerprint(&c, n), scheme_fingerprint(&d, n));
    }
    // Still the one bases file, never rewritten.
    assert_eq!(files_of(dir.path(), "m2l-svd-bases"), bases);
    #[cfg(unix)]
    assert_eq!(inode(&bases[0]), written);
    // The truncated sets are still one file per tolerance and type.
    assert_eq!(files_of(dir.path(), "m2l-svd").len(), 6);

    // Per-level operators: one bases file per level with V lists.
    let yukawa = ModifiedHelmholtz3d::new(3.0).unwrap();
    let p4 = params(4, dir.path());
    let a = SvdM2l::<f64>::precompute(&yukawa, &p4, &at(1e-5), 1.0, 4).unwrap();
    let per_level = files_of(dir.path(), "m2l-svd-bases").len() - 1;
    assert_eq!(per_level, 3, "levels 2..=4");
    let b = SvdM2l::<f64>::precompute(&yukawa, &p4, &at(1e-3), 1.0, 4).unwrap();
    let c = SvdM2l::<f64>::precompute(&yukawa, &OperatorParams::new(4), &at(1e-3), 1.0, 4).unwrap();
    assert_eq!(files_of(dir.path(), "m2l-svd-bases").len(), 1 + per_level);
    let n4 = Operators::<f64>::new(&yukawa, &p4, 1.0, 4)
        .unwrap()
        .n_surface();
    assert_eq!(scheme_fingerprint(&b, n4), scheme_fingerprint(&c, n4));
    assert!(a.rank() >= b.rank());
}
