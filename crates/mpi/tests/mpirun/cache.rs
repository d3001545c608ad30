//! The operator cache shared by the ranks.

use crate::common::*;

/// The default cache on 3 ranks (`FERROFMM_CACHE`): rank 0 fills it, the
/// others and the next run read it, with the same values; the report
/// names the folder; `--no-cache` and `FERROFMM_CACHE=off` write nothing.
#[test]
fn default_cache_is_shared_by_the_ranks() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-cache-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let cache = dir.join("cache");
    let cache_s = cache.to_string_lossy().into_owned();
    let out = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let (o1, o2, o3) = (out("o1.npy"), out("o2.npy"), out("o3.npy"));
    let args = |o: &str, extra: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = [
            "eval",
            "--generate",
            "uniform",
            "--n",
            "3000",
            "--order",
            "4",
            "--leaf-size",
            "40",
            "--scheme",
            "svd",
            "--json",
            "--out",
            o,
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        v.extend(extra.iter().map(|s| s.to_string()));
        v
    };
    let run = |o: &str, extra: &[&str], env: &[(&str, &str)]| {
        let a = args(o, extra);
        let a: Vec<&str> = a.iter().map(String::as_str).collect();
        let (ok, text) = mpmd(&[(3, &a)], env);
        assert!(ok, "{text}");
        text
    };
    let with_cache = [("FERROFMM_CACHE", cache_s.as_str())];
    let first = run(&o1, &[], &with_cache);
    assert!(
        first.contains(r#""cache":"miss (computed, saved)""#)
            && first.contains(&format!(r#""cache_dir":"{cache_s}""#)),
        "{first}"
    );
    let names = listing(&cache);
    // The operators, the SVD's bases and its truncated sets.
    assert_eq!(names.len(), 3, "operators and M2L, no temporary: {names:?}");
    let second = run(&o2, &[], &with_cache);
    assert!(second.contains(r#""cache":"hit""#), "{second}");
    assert_eq!(std::fs::read(&o1).unwrap(), std::fs::read(&o2).unwrap());

    let off_dir = dir.join("off");
    let off_s = off_dir.to_string_lossy().into_owned();
    let text = run(&o3, &["--no-cache"], &[("FERROFMM_CACHE", off_s.as_str())]);
    assert!(text.contains(r#""cache":"off (--no-cache)""#), "{text}");
    let text = run(&o3, &[], &[("FERROFMM_CACHE", "off")]);
    assert!(
        text.contains(r#""cache":"off (FERROFMM_CACHE=off)""#),
        "{text}"
    );
    assert!(!off_dir.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
