//! The distributed tree against the single-machine tree, and the files
//! `tree` reads.

use crate::common::*;

#[test]
fn distributed_tree_equals_the_single_machine_tree_on_1_to_4_ranks() {
    for ranks in 1..=4 {
        let (ok, out) = mpirun(ranks, &["check", "--n", "6000", "--leaf-size", "1,20,150"]);
        assert!(ok && out.contains("CHECK PASSED"), "R = {ranks}:\n{out}");
    }
}

/// Fewer points than ranks, and all points in one leaf (the root).
#[test]
fn tiny_inputs_and_a_single_leaf() {
    for ranks in 1..=4 {
        for n in ["3", "100"] {
            let (ok, out) = mpirun(ranks, &["check", "--n", n, "--leaf-size", "1,150"]);
            assert!(
                ok && out.contains("CHECK PASSED"),
                "R = {ranks}, n = {n}:\n{out}"
            );
        }
    }
}

#[test]
fn bad_input_on_one_rank_is_the_same_error_on_every_rank() {
    for ranks in 1..=4 {
        for case in [
            "nan", "infinite", "length", "empty", "leaf0", "options", "weights",
        ] {
            let (ok, out) = mpirun(ranks, &["bad", "--case", case]);
            assert!(
                ok && out.contains("ERROR AGREED"),
                "R = {ranks}, {case}:\n{out}"
            );
        }
    }
}

/// `tree --points` reads what `ferrofmm eval` reads (issue 37): a comma
/// CSV with a header and a `.npy` file build the same tree; ragged rows
/// are an error naming the line; a binary file, a directory and a missing
/// file are their own one error, not a NaN coordinate.
#[test]
fn tree_reads_the_files_eval_reads() {
    let dir = std::env::temp_dir().join(format!("ferrofmm-mpi-tree-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(dir.join("d.csv")).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let n = 1500;
    let pts: Vec<f64> = (0..3 * n).map(|i| (i as f64 * 0.381_966).fract()).collect();
    write_npy(&path("p.npy"), &pts, 3);
    std::fs::write(
        path("p.csv"),
        pts.chunks(3).fold("x,y,z\n".to_string(), |s, p| {
            s + &format!("{},{},{}\n", p[0], p[1], p[2])
        }),
    )
    .unwrap();
    std::fs::copy(path("p.npy"), path("binary.csv")).unwrap();
    std::fs::write(path("ragged.csv"), "0.1 0.2\n0.3 0.4 0.5 0.6\n").unwrap();
    std::fs::write(path("six.csv"), "0.1,0.2,0.3\n0.1,0.2,0.3,0.4,0.5,0.6\n").unwrap();
    let mut totals = Vec::new();
    // Raw little-endian f64 (what `tree --points` read before it took
    // .csv and .npy): read again, the same tree.
    std::fs::write(
        path("p.f64"),
        pts.iter()
            .flat_map(|x| x.to_le_bytes())
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    std::fs::write(path("short.f64"), [0u8; 40]).unwrap();
    for file in ["p.npy", "p.csv", "p.f64"] {
        let (ok, text) = mpirun(2, &["tree", "--points", &path(file), "--leaf-size", "30"]);
        assert!(
            ok && text.contains(&format!("total {n} points")),
            "{file}: {text}"
        );
        let leaves: Vec<&str> = text.lines().filter(|l| l.contains("leaves")).collect();
        totals.push(leaves.len());
    }
    assert_eq!(totals, [2, 2, 2]);
    for (file, needle) in [
        (
            "ragged.csv",
            "ragged.csv, line 1: expected 3 values (x, y, z), found 2",
        ),
        (
            "six.csv",
            "six.csv, line 2: expected 3 values (x, y, z), found 6",
        ),
        ("binary.csv", "not UTF-8"),
        (
            "short.f64",
            "short.f64: 40 bytes are not a whole number of points (raw .f64: 24 bytes each",
        ),
        ("d.csv", "is a directory"),
        ("missing.npy", "No such file"),
    ] {
        let (ok, text) = mpirun(2, &["tree", "--points", &path(file)]);
        assert!(!ok && text.contains(needle), "{file}: {text}");
        let errors = text.lines().filter(|l| l.starts_with("error:")).count();
        assert_eq!(errors, 1, "{file}: {text}");
        assert!(!text.contains("NaN"), "{file}: {text}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
