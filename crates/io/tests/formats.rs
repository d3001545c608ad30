//! The one reader and writer of the commands, on the inputs users give:
//! CSV with a header, a byte order mark, comments and ragged rows; `.npy`
//! in big-endian and Fortran order; pipes; endless streams; row ranges.

use std::io::Write;
use std::path::{Path, PathBuf};

use ferrofmm_io::{Contents, FileError, Reader, Values, csv, npy, output};
use npyz::WriterBuilder;

/// A fresh directory under the system temp dir, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Scratch {
        let dir =
            std::env::temp_dir().join(format!("ferrofmm-io-formats-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn write_npy<T: npyz::AutoSerialize + Copy>(
    path: &Path,
    descr: &str,
    values: &[T],
    shape: &[u64],
    order: npyz::Order,
) {
    let dtype = npyz::DType::parse(&format!("'{descr}'")).unwrap();
    let mut w = npyz::WriteOptions::new()
        .dtype(dtype)
        .shape(shape)
        .order(order)
        .writer(std::fs::File::create(path).unwrap())
        .begin_nd()
        .unwrap();
    w.extend(values.iter().copied()).unwrap();
    w.finish().unwrap();
}

#[test]
fn csv_header_bom_comments_and_separators() {
    let dir = Scratch::new("csv");
    let p = dir.path("p.csv");
    std::fs::write(
        &p,
        "\u{feff}x,y,z\n# a comment\n\n1, 2, 3\r\n4\t5 6\n# trailing\n",
    )
    .unwrap();
    assert_eq!(
        ferrofmm_io::read_points(&p).unwrap(),
        vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]
    );
}

#[test]
fn ragged_rows_name_the_line() {
    let dir = Scratch::new("ragged");
    for (text, line, found) in [
        ("1,2\n3,4,5,6\n", 1, 2),
        ("1,2,3\n4,5,6,7,8,9\n", 2, 6),
        ("# c\n1 2 3\n4 5\n", 3, 2),
    ] {
        let p = dir.path("r.csv");
        std::fs::write(&p, text).unwrap();
        let e = ferrofmm_io::read_points(&p).unwrap_err();
        assert!(
            matches!(&e, FileError::Csv { line: l, message, .. }
                if *l == line && message.contains(&format!("found {found}"))),
            "{text:?}: {e}"
        );
    }
}

/// A binary file named `.csv` (or a `.npy` file renamed) is named as such,
/// once, not as a NaN; a directory and a missing file say so.
#[test]
fn binary_files_directories_and_missing_files() {
    let dir = Scratch::new("binary");
    let npy_as_csv = dir.path("p.csv");
    write_npy(
        &npy_as_csv,
        "<f8",
        &[1.0f64, 2.0, 3.0],
        &[1, 3],
        npyz::Order::C,
    );
    let e = ferrofmm_io::read_points(&npy_as_csv)
        .unwrap_err()
        .to_string();
    assert!(e.contains("not UTF-8") && e.contains(".npy"), "{e}");
    let d = dir.path("d.csv");
    std::fs::create_dir(&d).unwrap();
    let e = ferrofmm_io::read_points(&d).unwrap_err();
    assert!(matches!(e, FileError::IsDirectory(_)), "{e}");
    let e = ferrofmm_io::read_points(&dir.path("missing.npy")).unwrap_err();
    assert!(
        matches!(&e, FileError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound),
        "{e}"
    );
    let e = ferrofmm_io::read_points(&dir.path("p.txt")).unwrap_err();
    assert!(matches!(e, FileError::UnknownExtension(_)), "{e}");
}

#[test]
fn npy_big_endian_fortran_order_and_float32() {
    let dir = Scratch::new("npy");
    let p = dir.path("p.npy");
    let want = vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    write_npy(&p, ">f8", &want, &[2, 3], npyz::Order::C);
    assert_eq!(ferrofmm_io::read_points(&p).unwrap(), want);
    // Fortran order: stored column by column, big-endian float32.
    write_npy(
        &p,
        ">f4",
        &[1.0f32, 4.0, 2.0, 5.0, 3.0, 6.0],
        &[2, 3],
        npyz::Order::Fortran,
    );
    assert_eq!(ferrofmm_io::read_points(&p).unwrap(), want);
    // Row ranges of each layout: the same rows.
    let reader = Reader::new();
    for order in [npyz::Order::C, npyz::Order::Fortran] {
        let all: Vec<f64> = (0..30).map(f64::from).collect();
        let stored: Vec<f64> = match order {
            npyz::Order::C => all.clone(),
            npyz::Order::Fortran => (0..30).map(|k| all[(k % 10) * 3 + k / 10]).collect(),
        };
        write_npy(&p, "<f8", &stored, &[10, 3], order);
        let (rows, n) = reader
            .read_rows(&p, Contents::Points, |n| n / 2..n)
            .unwrap();
        assert_eq!((rows.as_slice(), n), (&all[15..], 10), "{order:?}");
        let (rows, _) = reader.read_rows(&p, Contents::Points, |_| 3..3).unwrap();
        assert!(rows.is_empty());
    }
}

/// The CSV rows of a range, and a non-finite value in the rows read.
#[test]
fn row_ranges_of_csv_and_non_finite_values() {
    let dir = Scratch::new("rows");
    let p = dir.path("q.csv");
    std::fs::write(&p, "charge\n1\n2\n3\n4\n").unwrap();
    let (rows, n) = Reader::new()
        .read_rows(&p, Contents::Charges(1), |n| 1..n - 1)
        .unwrap();
    assert_eq!((rows, n), (vec![2.0, 3.0], 4));
    let q = dir.path("q.npy");
    write_npy(&q, "<f8", &[1.0, f64::NAN, 3.0], &[3], npyz::Order::C);
    let e = Reader::new()
        .read_rows(&q, Contents::Charges(1), |n| 1..n)
        .unwrap_err()
        .to_string();
    assert!(e.contains("element [1] is not finite"), "{e}");
}

/// A reader that repeats `1,2,3\n` forever.
struct Endless(usize);

impl std::io::Read for Endless {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        const LINE: &[u8] = b"1,2,3\n";
        for b in buf.iter_mut() {
            *b = LINE[self.0 % LINE.len()];
            self.0 += 1;
        }
        Ok(buf.len())
    }
}

#[test]
fn endless_streams_stop_at_the_memory_limit() {
    let e = csv::parse_reader(
        std::io::BufReader::new(Endless(0)),
        Contents::Points,
        Some(1 << 20),
    )
    .unwrap_err();
    assert!(matches!(e.1, csv::ParseError::TooLarge(l) if l == 1 << 20));
    // A stream without line breaks (/dev/zero) stops at the longest line.
    let e = csv::parse_reader(
        std::io::BufReader::new(std::io::repeat(0)),
        Contents::Points,
        None,
    )
    .unwrap_err();
    assert!(
        matches!(&e, (1, csv::ParseError::Message(m)) if m.contains("without a line break")),
        "{e:?}"
    );
    #[cfg(unix)]
    {
        let e = Reader::new()
            .memory_limit(Some(1 << 20))
            .read(Path::new("/dev/zero"), Contents::Points);
        // No extension: refused by its name before reading.
        assert!(matches!(e, Err(FileError::UnknownExtension(_))));
        let dir = Scratch::new("zero");
        let link = dir.path("zero.csv");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = Reader::new()
            .memory_limit(Some(1 << 20))
            .read(&link, Contents::Points)
            .unwrap_err()
            .to_string();
        assert!(e.contains("without a line break"), "{e}");
        let link = dir.path("zero.npy");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        let e = Reader::new()
            .read(&link, Contents::Points)
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a valid .npy file"), "{e}");
    }
}

/// A big `.npy` header is refused at the limit before its data are read.
#[test]
fn npy_beyond_the_memory_limit() {
    let dir = Scratch::new("limit");
    let p = dir.path("p.npy");
    let v: Vec<f64> = (0..3000).map(|i| f64::from(i) * 1e-3).collect();
    write_npy(&p, "<f8", &v, &[1000, 3], npyz::Order::C);
    let e = Reader::new()
        .memory_limit(Some(1000))
        .read(&p, Contents::Points)
        .unwrap_err();
    assert!(matches!(e, FileError::TooLarge { limit: 1000, .. }), "{e}");
    assert!(e.to_string().contains("FERROFMM_MEMORY_LIMIT"), "{e}");
    // A rank's share of it fits.
    let (rows, n) = Reader::new()
        .memory_limit(Some(1000))
        .read_rows(&p, Contents::Points, |_| 10..20)
        .unwrap();
    assert_eq!((rows.as_slice(), n), (&v[30..60], 1000));
}

/// `.npy` and `.csv` through a pipe (`--points <(cat p.npy)`, mkfifo).
#[cfg(unix)]
#[test]
fn npy_and_csv_through_a_fifo() {
    let dir = Scratch::new("fifo");
    let v: Vec<f64> = (0..300).map(|i| f64::from(i) * 0.25).collect();
    let src = dir.path("src.npy");
    write_npy(&src, "<f8", &v, &[100, 3], npyz::Order::C);
    let bytes = std::fs::read(&src).unwrap();
    for (name, data) in [
        ("pipe.npy", bytes.clone()),
        ("pipe.csv", b"x,y,z\n1,2,3\n".to_vec()),
        ("short.npy", bytes[..bytes.len() - 8].to_vec()),
    ] {
        let fifo = dir.path(name);
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        let feeder = {
            let fifo = fifo.clone();
            std::thread::spawn(move || {
                let mut f = std::fs::OpenOptions::new().write(true).open(fifo).unwrap();
                let _ = f.write_all(&data);
            })
        };
        let got = ferrofmm_io::read_points(&fifo);
        feeder.join().unwrap();
        match name {
            "pipe.npy" => assert_eq!(got.unwrap(), v),
            "pipe.csv" => assert_eq!(got.unwrap(), vec![1.0, 2.0, 3.0]),
            _ => {
                let e = got.unwrap_err().to_string();
                assert!(e.contains("cannot read the data"), "{e}");
            }
        }
    }
}

/// The writer: a header line for CSV (that the reader skips), an npy
/// array the reader reads; the header of a written-in-parts array is the
/// one `write` makes; a dropped temporary file leaves nothing.
#[test]
fn writes_read_back_and_parts_match() {
    let dir = Scratch::new("write");
    let v: Vec<f64> = (0..12).map(|i| f64::from(i) - 5.5).collect();
    let names = ferrofmm_io::column_names(4, &[]);
    assert_eq!(names, ["potential", "grad_x", "grad_y", "grad_z"]);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    for ext in ["csv", "npy"] {
        let p = dir.path(&format!("o.{ext}"));
        ferrofmm_io::write(&p, Values::F64(&v), &names).unwrap();
        let back = npy_or_csv_rows(&p, 4);
        assert_eq!(back, v, "{ext}");
    }
    let text = std::fs::read_to_string(dir.path("o.csv")).unwrap();
    assert!(
        text.starts_with("potential,grad_x,grad_y,grad_z\n"),
        "{text}"
    );
    // In parts: header, then rows at their offsets.
    let parts = dir.path("parts.npy");
    let mut tmp = output::Temporary::create(&parts).unwrap();
    let head = npy::header_bytes(3, 4);
    assert_eq!(head.len() % 64, 0);
    let f = tmp.file().unwrap();
    f.write_all(&head).unwrap();
    for x in &v {
        f.write_all(&x.to_le_bytes()).unwrap();
    }
    tmp.commit().unwrap();
    assert_eq!(std::fs::read(&parts).unwrap(), {
        let mut b = head.clone();
        b.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        b
    });
    assert_eq!(npy_or_csv_rows(&parts, 4), v);
    let dropped = output::Temporary::create(&dir.path("never.npy")).unwrap();
    let tmp_path = dropped.path().to_path_buf();
    assert!(tmp_path.exists());
    drop(dropped);
    assert!(!tmp_path.exists() && !dir.path("never.npy").exists());
}

/// A file of `columns` values per record (charges of `columns` components).
fn npy_or_csv_rows(p: &Path, columns: usize) -> Vec<f64> {
    Reader::new().read(p, Contents::Charges(columns)).unwrap()
}

/// Points, real charges and complex charges in every form
/// (`ferrofmm_testing::files`): each reads back exactly the numbers
/// written, whole and by row ranges; a complex `.npy` array says so.
#[test]
fn every_form_reads_the_same_numbers() {
    use ferrofmm_testing::files::{Table, f32_exact, write_forms};
    let dir = Scratch::new("forms");
    let n = 37;
    let points = f32_exact(&ferrofmm_testing::points::uniform_cube(n, -1.0, 1.0, 3));
    let charges = f32_exact(&ferrofmm_testing::charges::uniform_in(n, -0.5, 0.5, 4));
    let complex = f32_exact(&ferrofmm_testing::charges::uniform_in(2 * n, -0.5, 0.5, 5));
    let with_zero_im: Vec<f64> = complex
        .iter()
        .step_by(2)
        .flat_map(|&re| [re, 0.0])
        .collect();
    let cases = [
        ("p", &points, Table::Real(3), Contents::Points),
        ("q", &charges, Table::Real(1), Contents::Charges(1)),
        ("z", &complex, Table::Complex, Contents::ComplexCharges),
    ];
    let mut seen = std::collections::BTreeSet::new();
    for (stem, values, table, contents) in cases {
        let columns = contents.columns() as u64;
        for (label, path) in write_forms(&dir.0, stem, values, table) {
            seen.insert(label.clone());
            let expected: &[f64] = if label.starts_with("real-") {
                &with_zero_im
            } else {
                values
            };
            let t = Reader::new()
                .read_table(&path, contents, |n| 0..n)
                .unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(t.values, expected, "{stem} {label}");
            assert_eq!(t.rows, n as u64, "{stem} {label}");
            let complex_dtype = label.contains("c16") || label.contains("c8");
            assert_eq!(t.complex, complex_dtype, "{stem} {label}");
            // Rows 5..20 (a rank's share): the same rows.
            let part = Reader::new()
                .read_table(&path, contents, |_| 5..20)
                .unwrap();
            assert_eq!(
                part.values,
                &expected[(5 * columns) as usize..(20 * columns) as usize],
                "{stem} {label} rows 5..20"
            );
        }
    }
    // What the issue lists: every form was written.
    for form in [
        "csv-header",
        "csv-spaces",
        "csv-tabs",
        "csv-crlf",
        "npy-lef8-c",
        "npy-bef8-f",
        "npy-lef4-f",
        "npy-bef4-c",
        "npy-lec16-c",
        "npy-bec16-f",
        "npy-lec8-c",
        "npy-bec8-f",
        "npy-re-im-f",
        "real-npy-bef4",
        "real-csv",
        "raw",
    ] {
        assert!(seen.contains(form), "{form} not tried");
    }
}

/// Complex dipoles: a complex (N, 3) array, a real (N, 6) one, real
/// vectors alone (zero imaginary parts); real dipoles of a complex file
/// are refused.
#[test]
fn complex_dipoles_and_real_contents_of_complex_files() {
    use ferrofmm_testing::files::npy_bytes;
    let dir = Scratch::new("dipoles");
    let v: Vec<f64> = (0..12).map(|i| f64::from(i) - 5.0).collect();
    let le: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let p = dir.path("d.npy");
    std::fs::write(&p, npy_bytes("<c16", false, &[2, 3], &le)).unwrap();
    assert_eq!(ferrofmm_io::read(&p, Contents::ComplexDipoles).unwrap(), v);
    std::fs::write(&p, npy_bytes("<f8", false, &[2, 6], &le)).unwrap();
    assert_eq!(ferrofmm_io::read(&p, Contents::ComplexDipoles).unwrap(), v);
    std::fs::write(&p, npy_bytes("<f8", false, &[4, 3], &le)).unwrap();
    let widened: Vec<f64> = v.iter().flat_map(|&x| [x, 0.0]).collect();
    assert_eq!(
        ferrofmm_io::read(&p, Contents::ComplexDipoles).unwrap(),
        widened
    );
    std::fs::write(&p, npy_bytes("<c16", false, &[2, 3], &le)).unwrap();
    let e = ferrofmm_io::read(&p, Contents::Dipoles(1))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("complex dtype '<c16': dipoles are real numbers"),
        "{e}"
    );
    // A non-finite imaginary part is named by its element.
    let mut bad = v.clone();
    bad[3] = f64::INFINITY;
    let le: Vec<u8> = bad.iter().flat_map(|x| x.to_le_bytes()).collect();
    std::fs::write(&p, npy_bytes("<c16", false, &[6], &le)).unwrap();
    let e = ferrofmm_io::read(&p, Contents::ComplexCharges)
        .unwrap_err()
        .to_string();
    assert!(e.contains("element [1] is not finite (inf)"), "{e}");
}

/// A complex output: `complex128` / `complex64` arrays of one complex
/// value per quantity, read back as the pairs written; CSV keeps the re,
/// im columns. Raw `.f64` is not an output.
#[test]
fn complex_outputs_and_no_raw_output() {
    let dir = Scratch::new("complex-out");
    let v: Vec<f64> = (0..16).map(|i| f64::from(i) * 0.5 - 3.0).collect();
    let names = ferrofmm_io::column_names(4, &["re", "im"]);
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    let npy = dir.path("o.npy");
    ferrofmm_io::write_complex(&npy, Values::F64(&v), &names).unwrap();
    let file = npyz::NpyFile::new(std::fs::File::open(&npy).unwrap()).unwrap();
    assert_eq!(file.shape(), &[2, 4]);
    assert_eq!(file.dtype().descr(), "'<c16'");
    assert_eq!(
        ferrofmm_io::read(&npy, Contents::ComplexDipoles)
            .unwrap_err()
            .to_string(),
        format!(
            "{}: expected an (N, 3) array of complex dipoles, found shape (2, 4)",
            npy.display()
        )
    );
    let v32: Vec<f32> = v.iter().map(|&x| x as f32).collect();
    ferrofmm_io::write_complex(&npy, Values::F32(&v32[..4]), &names[..2]).unwrap();
    let file = npyz::NpyFile::new(std::fs::File::open(&npy).unwrap()).unwrap();
    assert_eq!(file.shape(), &[2]);
    assert_eq!(file.dtype().descr(), "'<c8'");
    assert_eq!(
        ferrofmm_io::read(&npy, Contents::ComplexCharges).unwrap(),
        &v[..4]
    );
    // A complex output written in parts (MPI): its header, then the pairs.
    let mut bytes = npy::complex_header_bytes(2, 4);
    assert_eq!(bytes.len() % 64, 0);
    bytes.extend(v.iter().flat_map(|x| x.to_le_bytes()));
    std::fs::write(&npy, bytes).unwrap();
    let file = npyz::NpyFile::new(std::fs::File::open(&npy).unwrap()).unwrap();
    assert_eq!(file.shape(), &[2, 4]);
    let pairs: Vec<f64> = file
        .into_vec::<npyz::num_complex::Complex<f64>>()
        .unwrap()
        .iter()
        .flat_map(|c| [c.re, c.im])
        .collect();
    assert_eq!(pairs, v);
    let csv_path = dir.path("o.csv");
    ferrofmm_io::write_complex(&csv_path, Values::F64(&v), &names).unwrap();
    let text = std::fs::read_to_string(&csv_path).unwrap();
    assert!(
        text.starts_with("potential_re,potential_im,grad_x_re,"),
        "{text}"
    );
    assert_eq!(npy_or_csv_rows(&csv_path, 8), v);
    let e = ferrofmm_io::write(&dir.path("o.f64"), Values::F64(&v), &names)
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown file type for an output"), "{e}");
    let e = output::check(&dir.path("o.f64"), &[])
        .unwrap_err()
        .to_string();
    assert!(e.contains("unknown file type for an output"), "{e}");
    let e = ferrofmm_io::write_complex(&npy, Values::F64(&v[..3]), &names[..3])
        .unwrap_err()
        .to_string();
    assert!(e.contains("not re, im pairs"), "{e}");
}

/// Raw `.f64`: through a pipe too; a length that is not whole records, or
/// a stream beyond the limit, is refused.
#[cfg(unix)]
#[test]
fn raw_files_whole_and_through_a_pipe() {
    let dir = Scratch::new("raw");
    let v: Vec<f64> = (0..30).map(|i| f64::from(i) * 0.125).collect();
    let bytes: Vec<u8> = v.iter().flat_map(|x| x.to_le_bytes()).collect();
    let fifo = dir.path("pipe.f64");
    assert!(
        std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    let feeder = {
        let (fifo, bytes) = (fifo.clone(), bytes.clone());
        std::thread::spawn(move || {
            let mut f = std::fs::OpenOptions::new().write(true).open(fifo).unwrap();
            let _ = f.write_all(&bytes);
        })
    };
    let got = Reader::new().read_rows(&fifo, Contents::Points, |_| 2..4);
    feeder.join().unwrap();
    assert_eq!(got.unwrap(), (v[6..12].to_vec(), 10));
    let p = dir.path("q.f64");
    std::fs::write(&p, &bytes[..8 * 29]).unwrap();
    assert_eq!(
        ferrofmm_io::read(&p, Contents::Charges(1)).unwrap(),
        &v[..29]
    );
    let e = ferrofmm_io::read_points(&p).unwrap_err().to_string();
    assert!(
        e.contains("232 bytes are not a whole number of points"),
        "{e}"
    );
    let e = Reader::new()
        .memory_limit(Some(100))
        .read(&p, Contents::Charges(1))
        .unwrap_err();
    assert!(matches!(e, FileError::TooLarge { limit: 100, .. }), "{e}");
    let mut nan = bytes.clone();
    nan[8 * 7..8 * 8].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(&p, &nan).unwrap();
    let e = ferrofmm_io::read_points(&p).unwrap_err().to_string();
    assert!(e.contains("record 2, value 1 is not finite (NaN)"), "{e}");
}

/// The shared table of malformed files: the reader's message holds the
/// text every front end must print.
#[test]
fn malformed_files_get_the_shared_messages() {
    let dir = Scratch::new("malformed");
    let cases = ferrofmm_testing::files::malformed(&dir.0);
    assert!(cases.len() >= 15);
    for case in cases {
        let complex = case.kernel.starts_with("helmholtz");
        let contents = match case.what.as_str() {
            "points" => Contents::Points,
            _ => Contents::charges(if complex { 2 } else { 1 }, complex),
        };
        let e = Reader::new()
            .read(&case.path, contents)
            .expect_err(&case.message)
            .to_string();
        assert!(
            e.starts_with(&case.path.display().to_string()) && e.contains(&case.message),
            "{}: {e}",
            case.path.display()
        );
    }
}
