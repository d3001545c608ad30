use ferrofmm_fmm::{FmmBuilder, Geometry, charges, relative_errors, sample_indices};
use ferrofmm_kernels::{EvalMode, Laplace3d, Real};
use std::time::Instant;

fn run<T: Real>(label: &str, points: &[T], targets: Option<&[T]>, q: &[T]) {
    let mode = EvalMode::PotentialGradient;
    let t = Instant::now();
    let mut b = FmmBuilder::new(points).order(6).mode(mode);
    if let Some(tg) = targets {
        b = b.targets(tg);
    }
    let fmm = b.build_svd().unwrap();
    let (v, tm) = fmm.evaluate_timed(q).unwrap();
    let total = t.elapsed().as_secs_f64();
    let tg = targets.unwrap_or(points);
    let m = tg.len() / 3;
    let e = relative_errors(&Laplace3d, mode, points, q, tg, &v, &sample_indices(m, 499));
    let s = fmm.summary();
    println!(
        "{label:40} pot {:.2e} grad {:.2e} total {total:.3}s p2p {:.3}s far {:.3}s clusters {} far_pts {} depth {}",
        e.potential,
        e.gradient.unwrap_or(0.0),
        tm.p2p.as_secs_f64(),
        tm.coupling.as_secs_f64(),
        s.clusters,
        s.far_points,
        s.depth
    );
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|s| s.parse().unwrap())
        .unwrap_or(20000);
    for zero_mean in [true] {
        let _ = zero_mean;
        let base: Vec<f64> = Geometry::Cube.points(n, 3);
        let q: Vec<f64> = charges(n, 4);
        run("clean", &base, None, &q);
        for d in [1e2, 1e3, 1e6, 1e12, 1e15] {
            let mut p = base.clone();
            p[3 * n - 3..].copy_from_slice(&[d; 3]);
            run(&format!("one at {d:e}"), &p, None, &q);
        }
        // several sides
        let mut p = base.clone();
        let outs = [
            [1e6, 0.5, 0.5],
            [-1e6, 0.5, 0.5],
            [0.5, 1e7, 0.5],
            [0.5, 0.5, -1e9],
            [3e5, -2e5, 1e5],
        ];
        for (i, o) in outs.iter().enumerate() {
            p[3 * (n - 1 - i)..3 * (n - i)].copy_from_slice(o);
        }
        run("five on several sides", &p, None, &q);
        // two clouds 1e8 apart
        let mut p = base.clone();
        for i in n / 2..n {
            p[3 * i] += 1e8;
        }
        run("two clouds 1e8 apart", &p, None, &q);
        // offset 1e9 unit spread
        let p: Vec<f64> = base.iter().map(|&x| x + 1e9).collect();
        run("offset 1e9", &p, None, &q);
        // separate targets: targets far cluster
        let mut tg: Vec<f64> = Geometry::Cube.points(n / 2, 7);
        for i in 0..n / 4 {
            tg[3 * i] += 1e6;
        }
        run("targets half at 1e6", &base, Some(&tg), &q);
        let mut p = base.clone();
        p[3 * n - 3..].copy_from_slice(&[1e12; 3]);
        let p32: Vec<f32> = p.iter().map(|&x| x as f32).collect();
        let b32: Vec<f32> = base.iter().map(|&x| x as f32).collect();
        let q32: Vec<f32> = q.iter().map(|&x| x as f32).collect();
        run("f32 clean", &b32, None, &q32);
        run("f32 one at 1e12", &p32, None, &q32);
        let pos: Vec<f64> = q.iter().map(|x| x.abs()).collect();
        run("positive, one at 1e12", &p, None, &pos);
    }
}
