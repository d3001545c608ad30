//! The kernel of `examples/custom_kernel.rs`, defined outside the crates
//! with a SIMD micro-kernel, runs through the FMM with every M2L scheme
//! and meets its accuracy against direct summation (the example asserts
//! it).

#[path = "../../examples/custom_kernel.rs"]
#[allow(dead_code)] // its `main` is the example's
mod example;

#[test]
fn a_kernel_from_outside_the_crates_runs_through_the_fmm() {
    example::run(4000);
}
