use std::time::Instant;
use ferrofmm_fmm::{FmmBuilder, relative_errors, sample_indices, Geometry, charges};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real};
use ferrofmm_field::{SvdConfig, SvdM2l};
use rand::{RngExt, SeedableRng};
use rand::rngs::StdRng;

fn err<T: Real>(src: &[T], tgt: Option<&[T]>, q: &[T], p: usize, leaf: usize, rcond: Option<f64>) -> (f64, u32, f64) {
    let t0 = Instant::now();
    let mut b = FmmBuilder::new(src).order(p).leaf_size(leaf).pinv_rcond(rcond);
    if let Some(t) = tgt { b = b.targets(t); }
    let fmm = b.build_dense().unwrap();
    let v = fmm.evaluate(q).unwrap();
    let t = tgt.unwrap_or(src);
    let m = t.len()/3;
    let e = relative_errors(&Laplace3d, EvalMode::Potential, src, q, t, &v, &sample_indices(m, 500));
    (e.potential, fmm.tree().depth(), t0.elapsed().as_secs_f64())
}

#[test] #[ignore]
fn explore_geometry() {
    let mut rng = StdRng::seed_from_u64(1);
    let n = 2000;
    let q: Vec<f64> = (0..n).map(|_| rng.random::<f64>()).collect();
    // coincident
    let pts = vec![0.3f64; 3*n];
    println!("coincident {:?}", err(&pts, None, &q, 6, 16, None));
    // duplicates
    let base: Vec<f64> = Geometry::Cube.points(200, 3);
    let pts: Vec<f64> = (0..n).flat_map(|i| { let k = i % 200; [base[3*k], base[3*k+1], base[3*k+2]] }).collect();
    println!("dup {:?}", err(&pts, None, &q, 6, 16, None));
    let pts: Vec<f64> = (0..n).flat_map(|_| { let t: f64 = rng.random(); [t, 0.5, 0.5] }).collect();
    println!("collinear {:?}", err(&pts, None, &q, 6, 16, None));
    let pts: Vec<f64> = (0..n).flat_map(|_| { let t: f64 = rng.random(); [t, t, t] }).collect();
    println!("diag {:?}", err(&pts, None, &q, 6, 16, None));
    let pts: Vec<f64> = (0..n).flat_map(|_| { [rng.random::<f64>(), rng.random::<f64>(), 0.25] }).collect();
    println!("coplanar {:?}", err(&pts, None, &q, 6, 16, None));
    let pts: Vec<f64> = (0..9*9*9).flat_map(|i| [(i%9) as f64 / 8.0, ((i/9)%9) as f64/8.0, (i/81) as f64/8.0]).collect();
    let q2: Vec<f64> = (0..729).map(|_| rng.random::<f64>()).collect();
    println!("lattice {:?}", err(&pts, None, &q2, 6, 8, None));
    // clusters 1e4 and deep
    for s in [1e-4, 1e-6, 1e-8, 1e-12, 0.0] {
        let pts: Vec<f64> = (0..n).flat_map(|i| { let (c, w) = if i % 2 == 0 { (0.0, 1.0) } else { (0.7, s) }; [c + w*rng.random::<f64>(), c+w*rng.random::<f64>(), c+w*rng.random::<f64>()] }).collect();
        println!("clusters {s} {:?}", err(&pts, None, &q, 6, 16, None));
    }
    let one = [0.1f64, 0.2, 0.3];
    println!("single {:?}", err(&one, None, &[1.0], 6, 16, None));
    let tg: Vec<f64> = Geometry::Cube.points::<f64>(500, 4).iter().map(|x| x+2.0).collect();
    let src: Vec<f64> = Geometry::Cube.points(n, 5);
    println!("disjoint {:?}", err(&src, Some(&tg), &q, 6, 16, None));
    let tg: Vec<f64> = Geometry::Cube.points::<f64>(500, 4).iter().map(|x| x+1e3).collect();
    println!("far targets {:?}", err(&src, Some(&tg), &q, 6, 16, None));
    let tg: Vec<f64> = Geometry::Cube.points::<f64>(500, 4).iter().map(|x| x*1e3).collect();
    println!("spread targets {:?}", err(&src, Some(&tg), &q, 6, 16, None));
    let off: Vec<f64> = src.iter().map(|x| x + 1e6).collect();
    println!("offset 1e6 f64 {:?}", err(&off, None, &q, 6, 16, None));
    println!("offset 1e6 f64 p10 {:?}", err(&off, None, &q, 10, 16, None));
    println!("orig f64 p10 {:?}", err(&src, None, &q, 10, 16, None));
    let tiny: Vec<f64> = src.iter().map(|x| x * 1e-8).collect();
    println!("tiny f64 {:?}", err(&tiny, None, &q, 6, 16, None));
    let src32: Vec<f32> = src.iter().map(|&x| x as f32).collect();
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    println!("f32 base {:?}", err(&src32, None, &q32, 6, 16, None));
    for o in [1e2f32, 1e3, 1e4, 1e5] {
        let off32: Vec<f32> = src32.iter().map(|&x| x + o).collect();
        println!("f32 offset {o} {:?}", err(&off32, None, &q32, 6, 16, None));
    }
    let tiny32: Vec<f32> = src32.iter().map(|&x| x * 1e-8).collect();
    println!("f32 tiny {:?}", err(&tiny32, None, &q32, 6, 16, None));
    let tiny32: Vec<f32> = src32.iter().map(|&x| x * 1e-30).collect();
    println!("f32 tiny 1e-30 {:?}", err(&tiny32, None, &q32, 6, 16, None));
    let big32: Vec<f32> = src32.iter().map(|&x| x * 1e30).collect();
    println!("f32 big 1e30 {:?}", err(&big32, None, &q32, 6, 16, None));
    let tiny64: Vec<f64> = src.iter().map(|&x| x * 1e-200).collect();
    println!("f64 tiny 1e-200 {:?}", err(&tiny64, None, &q, 6, 16, None));
    // mixed-sign
    let qs: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
    println!("mixed {:?}", err(&src, None, &qs, 6, 16, None));
    // dipoles
    let dp: Vec<f64> = (0..n).flat_map(|i| { let k = i/2; let d = if i%2==0 {0.0} else {1e-6}; [src[3*k]+d, src[3*k+1], src[3*k+2]] }).collect();
    let qd: Vec<f64> = (0..n).map(|i| if i%2==0 {1.0} else {-1.0}).collect();
    println!("dipoles {:?}", err(&dp, None, &qd, 6, 16, None));
}

#[test] #[ignore]
fn explore_order() {
    let n = 2000;
    let src: Vec<f64> = Geometry::Cube.points(n, 5);
    let q: Vec<f64> = charges(n, 1);
    let src32: Vec<f32> = src.iter().map(|&x| x as f32).collect();
    let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
    for p in [2, 3, 4, 5, 6, 7, 8, 9, 10] {
        println!("p {p} f64 {:?} nocut {:?}", err(&src, None, &q, p, 32, None), err(&src, None, &q, p, 32, Some(0.0)));
        println!("p {p} f32 {:?} nocut {:?}", err(&src32, None, &q32, p, 32, None), err(&src32, None, &q32, p, 32, Some(0.0)));
    }
}

#[test] #[ignore]
fn explore_rank() {
    let n = 3000;
    let src: Vec<f64> = Geometry::Cube.points(n, 5);
    let q: Vec<f64> = charges(n, 1);
    for r in [1usize, 2, 4, 8, 16, 32, 64, 100000] {
        let fmm = FmmBuilder::new(&src).order(6).leaf_size(32).build_with::<SvdM2l<f64>>(SvdConfig{rank: Some(r), tolerance: 0.0}).unwrap();
        let v = fmm.evaluate(&q).unwrap();
        let e = relative_errors(&Laplace3d, EvalMode::Potential, &src, &q, &src, &v, &sample_indices(n, 500));
        println!("rank {r} -> {} err {:.3e} trunc {:.3e}", fmm.m2l_scheme().rank(), e.potential, fmm.m2l_scheme().truncation_estimate());
    }
    for leaf in [1usize, 2, 4000] {
        println!("leaf {leaf} {:?}", err(&src, None, &q, 6, leaf, None));
    }
}

#[test] #[ignore]
fn explore_setup() {
    let n = 2000;
    let src: Vec<f64> = Geometry::Cube.points(n, 5);
    for p in [4usize, 6, 8] {
        let f = FmmBuilder::new(&src).order(p).leaf_size(32).build_svd().unwrap();
        println!("p {p} svd {:?}", f.setup_timings());
        let f = FmmBuilder::new(&src).order(p).leaf_size(32).build_dense().unwrap();
        println!("p {p} dense {:?}", f.setup_timings());
    }
}

#[test] #[ignore]
fn explore_diag() {
    use ferrofmm_field::{Operators, OperatorParams};
    for p in 2..=16usize {
        for rc in [None, Some(0.0)] {
            let mut prm = OperatorParams::new(p); prm.pinv_rcond = rc;
            let t = Instant::now();
            let o32 = Operators::<f32>::new(&Laplace3d, &prm, 1.0, 3).unwrap();
            let d = o32.diagnostics();
            println!("p {p} rc {rc:?} f32 cond {:.2e} amp {:.2e} rank {}/{} warn {} t {:.2}", d.max_condition, d.rounding_amplification, d.uc2e[0].rank, d.uc2e[0].n, d.warnings.len(), t.elapsed().as_secs_f64());
            let o64 = Operators::<f64>::new(&Laplace3d, &prm, 1.0, 3).unwrap();
            let d = o64.diagnostics();
            println!("p {p} rc {rc:?} f64 cond {:.2e} amp {:.2e} rank {}/{} warn {}", d.max_condition, d.rounding_amplification, d.uc2e[0].rank, d.uc2e[0].n, d.warnings.len());
        }
    }
}
