//! Every file form the readers take (`ferrofmm_testing::files`: CSV with
//! and without a header, spaces, tabs, CRLF; `.npy` float32, float64,
//! complex64, complex128 in both byte orders and C or Fortran order; raw
//! `.f64`), through `ferrofmm eval`: the same result from each, and the
//! result a direct sum gives; a complex `.npy` of charges gives a complex
//! `.npy` output. Every malformed file of the shared table
//! (`crates/testing/data/malformed.json`) gets its message.

use crate::common;

use std::path::Path;

use common::{ferrofmm, scratch, texts};
use ferrofmm_testing::files::{Table, direct, eval_args, f32_exact, malformed, write_forms};

const N: usize = 240;
const WAVENUMBER: f64 = 2.0;

fn relative(a: &[f64], b: &[f64]) -> f64 {
    ferrofmm_testing::errors::relative_l2(a, b)
}

/// An output `.npy`: its dtype, shape and values (complex as pairs).
fn read_output(path: &Path) -> (String, Vec<u64>, Vec<f64>) {
    let npy = npyz::NpyFile::new(std::fs::File::open(path).unwrap()).unwrap();
    let shape = npy.shape().to_vec();
    let descr = npy.dtype().descr();
    let values = match descr.as_str() {
        "'<f8'" => npy.into_vec::<f64>().unwrap(),
        "'<c16'" => npy
            .into_vec::<npyz::num_complex::Complex<f64>>()
            .unwrap()
            .iter()
            .flat_map(|c| [c.re, c.im])
            .collect(),
        other => panic!("unexpected output dtype {other}"),
    };
    (descr, shape, values)
}

/// `ferrofmm eval` on these files; the output's dtype, shape and values.
fn eval(dir: &Path, sources: &Path, charges: &Path, kernel: &str) -> (String, Vec<u64>, Vec<f64>) {
    let out = dir.join("out.npy");
    let cache = dir.join("cache");
    let args = eval_args(sources, charges, kernel, &cache, &out);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let run = ferrofmm(&args);
    let (stdout, stderr) = texts(&run);
    assert!(run.status.success(), "{args:?}: {stdout} {stderr}");
    read_output(&out)
}

#[test]
fn every_file_form_gives_the_same_result() {
    let dir = scratch("file-forms");
    let points = f32_exact(&ferrofmm_testing::points::uniform_cube(N, 0.0, 1.0, 11));
    let charges = f32_exact(&ferrofmm_testing::charges::uniform_in(N, -0.5, 0.5, 12));
    let complex = f32_exact(&ferrofmm_testing::charges::uniform_in(2 * N, -0.5, 0.5, 13));
    let point_forms = write_forms(&dir, "p", &points, Table::Real(3));
    let charge_forms = write_forms(&dir, "q", &charges, Table::Real(1));
    let complex_forms = write_forms(&dir, "z", &complex, Table::Complex);

    // Laplace: every form of points (with a form of charges each), then
    // every form of charges: the same values, near the direct sum.
    let reference = direct(&points, &charges, None);
    let (_, shape, first) = eval(&dir, &point_forms[0].1, &charge_forms[0].1, "laplace");
    assert_eq!(shape, [N as u64]);
    let error = relative(&first, &reference);
    assert!(error < 1e-4, "against the direct sum: {error:e}");
    let pairs = (0..point_forms.len().max(charge_forms.len())).map(|k| {
        (
            &point_forms[k % point_forms.len()],
            &charge_forms[k % charge_forms.len()],
        )
    });
    for ((p_label, p), (q_label, q)) in pairs {
        let (descr, shape, values) = eval(&dir, p, q, "laplace");
        assert_eq!(
            (descr.as_str(), shape.as_slice()),
            ("'<f8'", &[N as u64][..])
        );
        let d = relative(&values, &first);
        assert!(d < 1e-12, "points {p_label}, charges {q_label}: {d:e}");
    }

    // Helmholtz: complex charges in every form. A complex .npy gives a
    // complex128 output (N,), the other forms an (N, 2) real one; the
    // real parts alone are charges with zero imaginary parts.
    let kernel = format!("helmholtz:{WAVENUMBER}");
    let real_parts: Vec<f64> = complex.iter().step_by(2).flat_map(|&r| [r, 0.0]).collect();
    let references = [
        direct(&points, &complex, Some(WAVENUMBER)),
        direct(&points, &real_parts, Some(WAVENUMBER)),
    ];
    let mut firsts: [Option<Vec<f64>>; 2] = [None, None];
    for (k, (label, q)) in complex_forms.iter().enumerate() {
        let (p_label, p) = &point_forms[k % point_forms.len()];
        let (descr, shape, values) = eval(&dir, p, q, &kernel);
        let complex_dtype = label.contains("c16") || label.contains("c8");
        if complex_dtype {
            assert_eq!(
                (descr.as_str(), shape.as_slice()),
                ("'<c16'", &[N as u64][..])
            );
        } else {
            assert_eq!(
                (descr.as_str(), shape.as_slice()),
                ("'<f8'", &[N as u64, 2][..]),
                "{label}"
            );
        }
        let which = usize::from(label.starts_with("real-"));
        let error = relative(&values, &references[which]);
        assert!(error < 1e-4, "{label} against the direct sum: {error:e}");
        match &firsts[which] {
            Some(first) => {
                let d = relative(&values, first);
                assert!(d < 1e-12, "points {p_label}, charges {label}: {d:e}");
            }
            None => firsts[which] = Some(values),
        }
    }
    assert!(firsts.iter().all(Option::is_some));
}

#[test]
fn malformed_files_get_the_shared_messages() {
    let dir = scratch("malformed-forms");
    let good_points = dir.join("good-p.csv");
    let good_charges = dir.join("good-q.csv");
    std::fs::write(&good_points, "0,0,0\n1,0,0\n0,1,0\n0,0,1\n").unwrap();
    std::fs::write(&good_charges, "1\n2\n3\n4\n").unwrap();
    let out = dir.join("out.npy");
    for case in malformed(&dir) {
        let bad = case.path.to_str().unwrap();
        let (sources, charges) = match case.what.as_str() {
            "points" => (bad, good_charges.to_str().unwrap()),
            _ => (good_points.to_str().unwrap(), bad),
        };
        let args = [
            "eval",
            "--sources",
            sources,
            "--charges",
            charges,
            "--kernel",
            &case.kernel,
            "--out",
            out.to_str().unwrap(),
        ];
        let run = ferrofmm(&args);
        let (_, stderr) = texts(&run);
        assert_eq!(run.status.code(), Some(1), "{args:?}: {stderr}");
        let expected = format!("error: {bad}");
        assert!(
            stderr.starts_with(&expected) && stderr.contains(&case.message),
            "{args:?}: '{}' expected in {stderr}",
            case.message
        );
        assert!(!out.exists());
    }
}
