//! The M2L scheme of `examples/custom_m2l.rs`, written against the public
//! plumbing only, passes the conformance check and runs through the FMM
//! within 3x of the built-in SVD scheme's error (the example asserts both).

#[path = "../../examples/custom_m2l.rs"]
mod example;

#[test]
fn a_scheme_from_outside_the_crate_conforms_and_runs_through_the_fmm() {
    example::main();
}
