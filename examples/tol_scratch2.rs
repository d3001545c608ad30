use ferrofmm::fmm::{
    Geometry,
    tuning::{Occupancy, Tuner},
};
use ferrofmm::kernels::Precision;
use std::time::Instant;
fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map(|a| a.parse().unwrap())
        .unwrap_or(1_000_000);
    for g in Geometry::ALL {
        let pts: Vec<f64> = g.points(n, 1);
        let t = Instant::now();
        let occ = Occupancy::new(&pts, None, None, 19).unwrap();
        let t_occ = t.elapsed().as_secs_f64();
        let mut line = String::new();
        for leaf in [
            16, 24, 32, 48, 64, 96, 128, 192, 256, 384, 512, 768, 1024, 1536,
        ] {
            let t = Instant::now();
            let w = occ.work(leaf);
            line += &format!(
                " {leaf}:{:.0}ms/{}",
                1e3 * t.elapsed().as_secs_f64(),
                w.n_boxes
            );
        }
        println!("{:12} occupancy {:.0}ms |{line}", g.name(), 1e3 * t_occ);
        for eps in [1e-3, 1e-5, 1e-7, 1e-9] {
            let t = Instant::now();
            let c = Tuner::new(Precision::F64).choose_with(eps, &occ).unwrap();
            let dt = t.elapsed().as_secs_f64();
            let n_cand = Tuner::new(Precision::F64)
                .candidates(eps, &occ)
                .unwrap()
                .len();
            println!(
                "   eps {eps:.0e}: choose {:.0}ms p {} leaf {} ({} candidates)",
                1e3 * dt,
                c.order,
                c.leaf_size,
                n_cand
            );
        }
    }
}
