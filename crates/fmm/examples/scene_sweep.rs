//! Scratch: dimension estimates of the tolerance suite's geometries.
use ferrofmm_fmm::Geometry;
use ferrofmm_fmm::tuning::Occupancy;

fn main() {
    let ns: Vec<usize> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    for &n in &ns {
        for g in Geometry::ALL {
            let pts: Vec<f64> = g.points(n, 7);
            let occ = Occupancy::new(&pts, None, None, 19).unwrap();
            let mut s = format!("{n:8} {:13}", g.name());
            for (leaf, min_pts, skip1) in [
                (64, 64, false),
                (64, 512, false),
                (64, 64, true),
                (32, 256, false),
            ] {
                let shape = occ.refine(leaf);
                let (mut splits, mut children) = (0usize, 0usize);
                for l in 0..shape.n_levels().saturating_sub(1) {
                    let kids: Vec<_> = shape.level(l + 1).map(|b| b.key.parent()).collect();
                    let mut j = 0;
                    for b in shape.level(l) {
                        let mut c = 0;
                        while j < kids.len() && kids[j] == b.key {
                            c += 1;
                            j += 1;
                        }
                        if c == 0 || b.n_sources() < min_pts || (skip1 && c == 1) {
                            continue;
                        }
                        splits += 1;
                        children += c;
                    }
                }
                let d = (children as f64 / splits.max(1) as f64).log2();
                s += &format!(" {d:.2}({splits})");
            }
            println!("{s}");
        }
    }
}
