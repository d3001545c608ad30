//! The facade crate used as a user would: the examples in `examples/` (a
//! kernel and an M2L scheme written outside the library, and the front
//! page's Laplace run), checked against direct summation. These tests run
//! the example programs that `cargo test` has just built; the first two
//! assert their own accuracy and panic on a miss.
//!
//! They run the built programs instead of compiling the examples' code a
//! second time into this binary: the generic driver instantiated for a new
//! kernel and scheme is most of a minute of compiling on two cores.

use std::path::PathBuf;
use std::process::Command;

/// The example program `name` that `cargo test` built beside this test
/// binary (`target/<profile>/deps/examples-*` -> `target/<profile>/examples/`).
fn example(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the test's own path");
    let profile_dir = exe
        .parent()
        .and_then(|deps| deps.parent())
        .expect("the test binary lies in target/<profile>/deps");
    let path = profile_dir
        .join("examples")
        .join(format!("{name}{}", std::env::consts::EXE_SUFFIX));
    assert!(
        path.is_file(),
        "{} was not built: `cargo test` builds the examples before it runs \
         the tests (with `--test examples` alone, run `cargo build --examples` first)",
        path.display()
    );
    path
}

/// Runs example `name` with `args`; panics with its output unless it
/// exits successfully.
fn run(name: &str, args: &[&str]) -> String {
    let out = Command::new(example(name))
        .args(args)
        .output()
        .expect("the example starts");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "example {name} {args:?} failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `examples/custom_kernel.rs`: a softened Laplace kernel defined outside
/// the crates, with a SIMD micro-kernel, through the FMM with every M2L
/// scheme; within 3x of Laplace's error and below 1e-5 at order 7 (the
/// example asserts both).
#[test]
fn a_kernel_from_outside_the_crates_runs_through_the_fmm() {
    let out = run("custom_kernel", &["4000"]);
    for scheme in ["svd", "dense", "fft"] {
        assert!(
            out.lines().any(|l| l.trim_start().starts_with(scheme)),
            "no {scheme} row in:\n{out}"
        );
    }
}

/// `examples/custom_m2l.rs`: an M2L scheme written against the public
/// plumbing passes the conformance check and runs through the FMM within
/// 3x of the built-in SVD scheme's error (the example asserts both).
#[test]
fn a_scheme_from_outside_the_crate_conforms_and_runs_through_the_fmm() {
    let out = run("custom_m2l", &[]);
    assert!(out.contains("conformance: relative error"), "{out}");
}

/// `examples/laplace.rs`, the front page's example, at order 6 on 40,000
/// points (fewer are one leaf: the order alone lets the chooser take the
/// direct sum): a tree at least two levels deep, and printed errors below
/// 1e-4 (order 6 gives about 2e-6 / 7e-6 here).
#[test]
fn the_laplace_example_meets_its_order() {
    let out = run("laplace", &["40000", "6"]);
    let number_after = |text: &str, name: &str| -> f64 {
        let rest = &text[text
            .find(name)
            .unwrap_or_else(|| panic!("no {name} in:\n{out}"))
            + name.len()..];
        rest.trim_start()
            .split(|c: char| c == ',' || c.is_whitespace())
            .next()
            .and_then(|v| v.parse().ok())
            .unwrap_or_else(|| panic!("no {name} value in:\n{out}"))
    };
    assert!(out.contains("N = 40000, p = 6"), "{out}");
    assert!(number_after(&out, "depth") >= 2.0, "{out}");
    let line = out
        .lines()
        .find(|l| l.starts_with("relative L2 error"))
        .unwrap_or_else(|| panic!("no error line in:\n{out}"));
    let (potential, gradient) = (
        number_after(line, "potential"),
        number_after(line, "gradient"),
    );
    assert!(potential < 1e-4 && gradient < 1e-4, "{line}");
}
