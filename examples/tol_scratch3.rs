use ferrofmm::fmm::{Geometry, tuning::Occupancy};
fn main() {
    let pts: Vec<f64> = Geometry::Plummer.points(1_000_000, 1);
    let occ = Occupancy::new(&pts, None, None, 19).unwrap();
    for leaf in [16, 32, 64, 128] {
        occ.work(leaf);
    }
}
