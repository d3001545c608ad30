//! CSV text files.
//!
//! Reading rules:
//!
//! * one record per line: `x,y,z` for points, a single value for charges;
//! * fields are separated by commas (spaces around them are ignored), or,
//!   on a line without any comma, by whitespace (NumPy's `savetxt` default);
//! * blank lines and lines starting with `#` are ignored;
//! * the first remaining line is a header, and skipped, when none of its
//!   fields is a number (`x,y,z`, `charge`); any other line that is not
//!   all numbers is an error naming the line;
//! * every record must have exactly the expected number of fields, and
//!   every value must be finite;
//! * complex charges ([`Contents::ComplexCharges`]) are records of two
//!   values (`re, im`) or of one (a real charge: the imaginary part is
//!   zero), complex dipoles records of six or three; the first record
//!   decides, and every other record must have as many fields.
//!
//! Writing: a header line (`potential` or `potential,grad_x,grad_y,grad_z`),
//! then one record per line, each value in Rust's shortest round-trip
//! scientific notation (`1.2345e-3`), which NumPy, pandas and spreadsheets read.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use super::{Contents, Values};
use crate::error::{FileError, Result};

/// The longest line read (a record holds at most a few dozen numbers): a
/// binary file or an endless stream without line breaks stops here.
pub const MAX_LINE: u64 = 1 << 16;

/// Read `contents` from the CSV file `path` (interleaved values), line by
/// line: the memory taken is that of the values and of one line, and more
/// than `limit` bytes of them (an endless stream) is
/// [`FileError::TooLarge`]. `path` may be a pipe.
pub fn read(path: &Path, contents: Contents, limit: Option<u64>) -> Result<Vec<f64>> {
    let file = std::fs::File::open(path).map_err(|e| FileError::io(path, e))?;
    parse_reader(BufReader::new(file), contents, limit).map_err(|(line, error)| match error {
        ParseError::Message(message) => FileError::Csv {
            path: path.to_path_buf(),
            line,
            message,
        },
        ParseError::NonFinite { column, value } => FileError::NonFinite {
            path: path.to_path_buf(),
            location: if contents.columns() == 1 {
                format!("the value on line {line}")
            } else {
                format!("line {line}, column {column}")
            },
            value,
        },
        ParseError::TooLarge(limit) => FileError::TooLarge {
            path: path.to_path_buf(),
            limit,
        },
        ParseError::Io(source) => FileError::io(path, source),
    })
}

/// Why a line was rejected.
#[derive(Debug)]
pub enum ParseError {
    /// Malformed line.
    Message(String),
    /// A NaN or infinite value in 1-based `column`.
    NonFinite {
        /// 1-based column.
        column: usize,
        /// The value.
        value: f64,
    },
    /// The values and the line being read passed this many bytes.
    TooLarge(u64),
    /// Reading failed.
    Io(std::io::Error),
}

impl PartialEq for ParseError {
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (ParseError::Message(a), ParseError::Message(b)) => a == b,
            (
                ParseError::NonFinite { column, value },
                ParseError::NonFinite {
                    column: c,
                    value: v,
                },
            ) => column == c && value.to_bits() == v.to_bits(),
            (ParseError::TooLarge(a), ParseError::TooLarge(b)) => a == b,
            _ => false,
        }
    }
}

/// Parse CSV text; on error, the 1-based line number and what is wrong.
pub fn parse(text: &str, contents: Contents) -> Result<Vec<f64>, (usize, ParseError)> {
    parse_reader(text.as_bytes(), contents, None)
}

/// Parse CSV from `reader` line by line, keeping at most `limit` bytes (of
/// values, plus the line being read); on error, the 1-based line number
/// and what is wrong.
pub fn parse_reader(
    mut reader: impl BufRead,
    contents: Contents,
    limit: Option<u64>,
) -> Result<Vec<f64>, (usize, ParseError)> {
    let columns = contents.columns();
    // Fields per record: fixed, except for complex contents, where the
    // first record chooses both parts or the real parts alone.
    let mut width: Option<usize> = None;
    let limit_bytes = limit.unwrap_or(u64::MAX);
    let mut values: Vec<f64> = Vec::new();
    let mut first_record = true;
    let mut buf = Vec::new();
    let mut line_no = 0;
    loop {
        line_no += 1;
        buf.clear();
        let held = 8 * values.len() as u64;
        let budget = limit_bytes.saturating_sub(held);
        let n = (&mut reader)
            .take(budget.min(MAX_LINE).saturating_add(1))
            .read_until(b'\n', &mut buf)
            .map_err(|e| (line_no, ParseError::Io(e)))?;
        if n == 0 {
            break;
        }
        if n as u64 > budget {
            return Err((line_no, ParseError::TooLarge(limit_bytes)));
        }
        if n as u64 > MAX_LINE {
            return Err((
                line_no,
                ParseError::Message(format!(
                    "longer than {MAX_LINE} bytes without a line break: not a CSV file of numbers"
                )),
            ));
        }
        let mut bytes = &buf[..];
        if line_no == 1 {
            bytes = bytes.strip_prefix("\u{feff}".as_bytes()).unwrap_or(bytes);
        }
        let Ok(line) = std::str::from_utf8(bytes) else {
            return Err((
                line_no,
                ParseError::Message(
                    "not UTF-8 text (a binary file? NumPy arrays need the .npy extension)".into(),
                ),
            ));
        };
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields = split(line);
        let parsed: Vec<Option<f64>> = fields.iter().map(|f| f.parse::<f64>().ok()).collect();
        if first_record {
            first_record = false;
            if parsed.iter().all(Option::is_none) {
                continue; // header
            }
        }
        let real_parts = contents.real_parts();
        let fits = match width {
            Some(w) => fields.len() == w,
            None => fields.len() == columns || Some(fields.len()) == real_parts,
        };
        if !fits {
            let expected = match (contents, width) {
                (Contents::Points, _) => "3 values (x, y, z)".to_string(),
                (Contents::Charges(1), _) => "1 value (the charge)".to_string(),
                (Contents::Charges(c), _) => format!("{c} values (the charge's components)"),
                (Contents::Dipoles(1), _) => "3 values (the dipole's nx, ny, nz)".to_string(),
                (Contents::Dipoles(c), _) => {
                    format!(
                        "{} values (the dipole's nx, ny, nz, {c} components each)",
                        3 * c
                    )
                }
                (Contents::ComplexCharges, None) => {
                    "2 values (the charge's re, im) or 1 (a real charge)".to_string()
                }
                (Contents::ComplexDipoles, None) => {
                    "6 values (the dipole's nx_re, nx_im, ny_re, ny_im, nz_re, nz_im) or 3 \
                     (a real dipole's nx, ny, nz)"
                        .to_string()
                }
                (_, Some(w)) => format!(
                    "{w} value{} per record, as in the first one",
                    if w == 1 { "" } else { "s" }
                ),
            };
            return Err((
                line_no,
                ParseError::Message(format!("expected {expected}, found {}", fields.len())),
            ));
        }
        let widen = fields.len() != columns;
        width = Some(fields.len());
        for (column, (field, value)) in fields.iter().zip(&parsed).enumerate() {
            match value {
                None if field.is_empty() => {
                    return Err((
                        line_no,
                        ParseError::Message(format!("field {} is empty", column + 1)),
                    ));
                }
                None => {
                    return Err((
                        line_no,
                        ParseError::Message(format!("'{field}' is not a number")),
                    ));
                }
                Some(v) if !v.is_finite() => {
                    return Err((
                        line_no,
                        ParseError::NonFinite {
                            column: column + 1,
                            value: *v,
                        },
                    ));
                }
                Some(v) => {
                    values.push(*v);
                    if widen {
                        values.push(0.0); // a real value: no imaginary part
                    }
                }
            }
        }
        if 8 * values.len() as u64 > limit_bytes {
            return Err((line_no, ParseError::TooLarge(limit_bytes)));
        }
    }
    Ok(values)
}

/// Fields of a non-empty, trimmed line.
fn split(line: &str) -> Vec<&str> {
    if line.contains(',') {
        line.split(',').map(str::trim).collect()
    } else {
        line.split_whitespace().collect()
    }
}

/// Write `values` as CSV with a header line of `names` (one column each).
pub fn write(path: &Path, values: Values<'_>, names: &[&str]) -> Result<()> {
    super::output::write_atomically(path, |out| {
        write_header(out, names)?;
        match values {
            Values::F64(v) => write_records(out, v, names.len()),
            Values::F32(v) => write_records(out, v, names.len()),
        }
    })
}

/// The header line: `names`, comma-separated.
pub fn write_header(out: &mut impl Write, names: &[&str]) -> std::io::Result<()> {
    writeln!(out, "{}", names.join(","))
}

/// `values` as records of `columns` values, one per line, each value in
/// Rust's shortest round-trip scientific notation.
pub fn write_records<T: std::fmt::LowerExp>(
    out: &mut impl Write,
    values: &[T],
    columns: usize,
) -> std::io::Result<()> {
    for record in values.chunks_exact(columns) {
        for (k, v) in record.iter().enumerate() {
            if k > 0 {
                out.write_all(b",")?;
            }
            write!(out, "{v:e}")?;
        }
        out.write_all(b"\n")?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_comments_blank_lines_and_separators() {
        let text = "\u{feff}x, y ,z\n\n# a comment\n1,2,3\r\n 4.5 , -6e-1 ,7\n8 9 10\n";
        assert_eq!(
            parse(text, Contents::Points).unwrap(),
            vec![1.0, 2.0, 3.0, 4.5, -0.6, 7.0, 8.0, 9.0, 10.0]
        );
        assert_eq!(
            parse("charge\n1\n2.5\n", Contents::Charges(1)).unwrap(),
            vec![1.0, 2.5]
        );
        assert_eq!(parse("", Contents::Charges(1)).unwrap(), Vec::<f64>::new());
        assert_eq!(
            parse("q\n\n", Contents::Charges(1)).unwrap(),
            Vec::<f64>::new()
        );
    }

    #[test]
    fn complex_records_take_both_parts_or_the_real_part() {
        assert_eq!(
            parse("re,im\n1,2\n3,-4\n", Contents::ComplexCharges).unwrap(),
            vec![1.0, 2.0, 3.0, -4.0]
        );
        assert_eq!(
            parse("charge\n1\n3\n", Contents::ComplexCharges).unwrap(),
            vec![1.0, 0.0, 3.0, 0.0]
        );
        assert_eq!(
            parse("1 2 3\n", Contents::ComplexDipoles).unwrap(),
            vec![1.0, 0.0, 2.0, 0.0, 3.0, 0.0]
        );
        let e = parse("1\n2,3\n", Contents::ComplexCharges).unwrap_err();
        assert_eq!(
            e,
            (
                2,
                ParseError::Message(
                    "expected 1 value per record, as in the first one, found 2".into()
                )
            )
        );
        let e = parse("1,2,3\n", Contents::ComplexCharges).unwrap_err();
        assert!(
            matches!(&e, (1, ParseError::Message(m)) if m.contains("or 1 (a real charge)")),
            "{e:?}"
        );
    }

    #[test]
    fn malformed_lines_name_the_line() {
        let err = |t: &str, c| parse(t, c).unwrap_err();
        assert_eq!(
            err("1,2,3\n4,5\n", Contents::Points),
            (
                2,
                ParseError::Message("expected 3 values (x, y, z), found 2".into())
            )
        );
        assert_eq!(
            err("1\n2,3\n", Contents::Charges(1)),
            (
                2,
                ParseError::Message("expected 1 value (the charge), found 2".into())
            )
        );
        assert_eq!(
            err("1,2,3\n4,abc,6\n", Contents::Points),
            (2, ParseError::Message("'abc' is not a number".into()))
        );
        assert_eq!(
            err("1,,3\n", Contents::Points),
            (1, ParseError::Message("field 2 is empty".into()))
        );
        // Only the first record may be a header.
        assert_eq!(err("1,2,3\nx,y,z\n", Contents::Points).0, 2);
        assert!(matches!(
            err("x,y,z\n1,2,nan\n", Contents::Points),
            (2, ParseError::NonFinite { column: 3, .. })
        ));
        assert!(matches!(
            err("inf\n", Contents::Charges(1)),
            (1, ParseError::NonFinite { column: 1, .. })
        ));
    }
}
