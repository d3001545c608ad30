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
