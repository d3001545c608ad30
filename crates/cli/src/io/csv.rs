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
//!   every value must be finite.
//!
//! Writing: a header line (`potential` or `potential,grad_x,grad_y,grad_z`),
//! then one record per line, each value in Rust's shortest round-trip
//! scientific notation (`1.2345e-3`), which NumPy, pandas and spreadsheets read.

use std::io::Write;
use std::path::Path;

use super::{Contents, Values};
use crate::error::{CliError, Result};

/// Read `contents` from the CSV file `path` (interleaved values).
pub fn read(path: &Path, contents: Contents) -> Result<Vec<f64>> {
    let text = std::fs::read_to_string(path).map_err(|e| CliError::io(path, e))?;
    parse(&text, contents).map_err(|(line, message)| match message {
        ParseError::Message(message) => CliError::Csv {
            path: path.to_path_buf(),
            line,
            message,
        },
        ParseError::NonFinite { column, value } => CliError::NonFinite {
            path: path.to_path_buf(),
            location: if contents.columns() == 1 {
                format!("the value on line {line}")
            } else {
                format!("line {line}, column {column}")
            },
            value,
        },
    })
}

/// Why a line was rejected.
#[derive(Debug, PartialEq)]
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
}

/// Parse CSV text; on error, the 1-based line number and what is wrong.
pub fn parse(text: &str, contents: Contents) -> Result<Vec<f64>, (usize, ParseError)> {
    let columns = contents.columns();
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut values = Vec::new();
    let mut first_record = true;
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
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
        if fields.len() != columns {
            let expected = match contents {
                Contents::Points => "3 values (x, y, z)".to_string(),
                Contents::Charges(1) => "1 value (the charge)".to_string(),
                Contents::Charges(c) => format!("{c} values (the charge's components)"),
                Contents::Dipoles(1) => "3 values (the dipole's nx, ny, nz)".to_string(),
                Contents::Dipoles(c) => {
                    format!(
                        "{} values (the dipole's nx, ny, nz, {c} components each)",
                        3 * c
                    )
                }
            };
            return Err((
                line_no,
                ParseError::Message(format!("expected {expected}, found {}", fields.len())),
            ));
        }
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
                Some(v) => values.push(*v),
            }
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
    super::output::write_atomically(path, |out| match values {
        Values::F64(v) => write_records(out, v, names),
        Values::F32(v) => write_records(out, v, names),
    })
}

fn write_records<T: std::fmt::LowerExp>(
    out: &mut impl Write,
    values: &[T],
    names: &[&str],
) -> std::io::Result<()> {
    writeln!(out, "{}", names.join(","))?;
    for record in values.chunks_exact(names.len()) {
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
