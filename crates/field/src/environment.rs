//! The environment variables the precomputation reads:
//! [`MEMORY_LIMIT_ENV`] (`FERROFMM_MEMORY_LIMIT`, the cache's variables
//! are read in `cache_location`), a byte count
//! `x [K|M|G|T][i][B]` meaning `x * 1024^e` bytes (`e = 0..4` for no
//! suffix, `K`, `M`, `G`, `T`), or `unlimited` / `off`.
//!
//! Uses only [`FieldError`].

use crate::FieldError;

/// Name of the environment variable read by [`MemoryLimit::Auto`](crate::MemoryLimit::Auto).
pub const MEMORY_LIMIT_ENV: &str = "FERROFMM_MEMORY_LIMIT";

/// The limit set by [`MEMORY_LIMIT_ENV`]: `None` when the variable is not
/// set, `Some(Ok(None))` for `unlimited`, `Some(Ok(Some(bytes)))`, or
/// `Some(Err(FieldError::InvalidParams))` when it is not a byte count.
pub(crate) fn memory_limit_from_env() -> Option<Result<Option<u64>, FieldError>> {
    let s = std::env::var(MEMORY_LIMIT_ENV).ok()?;
    Some(parse_bytes(&s).ok_or_else(|| {
        FieldError::InvalidParams(format!(
            "{MEMORY_LIMIT_ENV}={s:?} is not a byte count (e.g. 512M, 8G, unlimited)"
        ))
    }))
}

/// `"123"`, `"64K"`, `"512M"`, `"8G"`, `"1T"` (powers of 1024, optional
/// trailing `B`/`iB`), or `"unlimited"` (`Some(None)`).
pub(crate) fn parse_bytes(s: &str) -> Option<Option<u64>> {
    let s = s.trim();
    if s.eq_ignore_ascii_case("unlimited") || s.eq_ignore_ascii_case("off") {
        return Some(None);
    }
    let s = s
        .trim_end_matches(['B', 'b'])
        .trim_end_matches(['i', 'I'])
        .trim();
    let (num, mult) = match s.chars().last()? {
        'k' | 'K' => (&s[..s.len() - 1], 1u64 << 10),
        'm' | 'M' => (&s[..s.len() - 1], 1 << 20),
        'g' | 'G' => (&s[..s.len() - 1], 1 << 30),
        't' | 'T' => (&s[..s.len() - 1], 1 << 40),
        _ => (s, 1),
    };
    let x: f64 = num.trim().parse().ok()?;
    (x.is_finite() && x >= 0.0).then_some(Some((x * mult as f64) as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_byte_counts() {
        assert_eq!(parse_bytes("1000"), Some(Some(1000)));
        assert_eq!(parse_bytes("1K"), Some(Some(1024)));
        assert_eq!(parse_bytes("2M"), Some(Some(2 << 20)));
        assert_eq!(parse_bytes("1.5GiB"), Some(Some(3 << 29)));
        assert_eq!(parse_bytes("unlimited"), Some(None));
        assert_eq!(parse_bytes("lots"), None);
        assert_eq!(parse_bytes("-1"), None);
    }
}
