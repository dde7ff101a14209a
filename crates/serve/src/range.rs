//! HTTP `Range: bytes=…` parsing (RFC 9110 sec. 14) for one file of known length: which bytes a
//! request asks for, or that the whole file is answered (invalid, foreign or multiple ranges).

/// What a `Range` header selects from a representation of `len` bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RangeRequest {
    /// No usable single range: answer the whole representation with 200. This covers a missing
    /// header, another unit, a syntactically invalid spec (`bytes=5-2`, `bytes=x-`) and several
    /// ranges, all of which RFC 9110 lets a server ignore.
    Whole,
    /// Bytes `start..end` (end exclusive, `start < end <= len`): answer 206 with Content-Range.
    Part {
        /// First byte.
        start: u64,
        /// One past the last byte.
        end: u64,
    },
    /// A valid range that selects no byte of this representation: answer 416 with
    /// `Content-Range: bytes */len`.
    Unsatisfiable,
}

/// Digits only (no sign, no space), saturating at `u64::MAX`: a huge position is simply past
/// the end, never an overflow. `None` when empty or not all ASCII digits.
fn digits(s: &str) -> Option<u64> {
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some(s.bytes().fold(0u64, |n, b| {
        n.saturating_mul(10).saturating_add(u64::from(b - b'0'))
    }))
}

/// Parses a `Range` header value against a representation of `len` bytes.
pub fn parse_range(header: &str, len: u64) -> RangeRequest {
    let header = header.trim();
    let Some((unit, set)) = header.split_once('=') else {
        return RangeRequest::Whole;
    };
    if !unit.trim().eq_ignore_ascii_case("bytes") {
        return RangeRequest::Whole;
    }
    // Empty list elements are allowed by the list syntax; more than one range gets the whole body.
    let mut specs = set.split(',').map(str::trim).filter(|s| !s.is_empty());
    let (Some(spec), None) = (specs.next(), specs.next()) else {
        return RangeRequest::Whole;
    };
    let Some((first, last)) = spec.split_once('-') else {
        return RangeRequest::Whole;
    };
    if first.is_empty() {
        // Suffix range: the last n bytes.
        let Some(n) = digits(last) else {
            return RangeRequest::Whole;
        };
        if n == 0 || len == 0 {
            return RangeRequest::Unsatisfiable;
        }
        return RangeRequest::Part {
            start: len - n.min(len),
            end: len,
        };
    }
    let Some(start) = digits(first) else {
        return RangeRequest::Whole;
    };
    let end = if last.is_empty() {
        len
    } else {
        let Some(last) = digits(last) else {
            return RangeRequest::Whole;
        };
        if last < start {
            return RangeRequest::Whole;
        }
        last.saturating_add(1).min(len)
    };
    if start >= len {
        return RangeRequest::Unsatisfiable;
    }
    RangeRequest::Part { start, end }
}

#[cfg(test)]
mod tests {
    use super::RangeRequest::{Part, Unsatisfiable, Whole};
    use super::*;

    #[test]
    fn single_ranges_of_each_form() {
        assert_eq!(parse_range("bytes=0-9", 100), Part { start: 0, end: 10 });
        assert_eq!(
            parse_range("bytes=10-", 100),
            Part {
                start: 10,
                end: 100
            }
        );
        assert_eq!(
            parse_range("bytes=-10", 100),
            Part {
                start: 90,
                end: 100
            }
        );
        assert_eq!(
            parse_range("bytes=99-99", 100),
            Part {
                start: 99,
                end: 100
            }
        );
        assert_eq!(
            parse_range(" Bytes = 5 - 7 ", 100),
            Whole,
            "no space inside numbers"
        );
        assert_eq!(parse_range("BYTES=5-7", 100), Part { start: 5, end: 8 });
        assert_eq!(parse_range("bytes= 5-7 ,", 100), Part { start: 5, end: 8 });
    }

    #[test]
    fn ranges_past_the_end_are_clamped_or_unsatisfiable() {
        assert_eq!(
            parse_range("bytes=50-500", 100),
            Part {
                start: 50,
                end: 100
            }
        );
        assert_eq!(parse_range("bytes=-500", 100), Part { start: 0, end: 100 });
        assert_eq!(parse_range("bytes=100-", 100), Unsatisfiable);
        assert_eq!(parse_range("bytes=100-200", 100), Unsatisfiable);
        assert_eq!(parse_range("bytes=-0", 100), Unsatisfiable);
        assert_eq!(parse_range("bytes=0-", 0), Unsatisfiable);
        assert_eq!(parse_range("bytes=-5", 0), Unsatisfiable);
    }

    #[test]
    fn absurd_and_overflowing_values_never_panic() {
        let huge = "99999999999999999999999999999999";
        assert_eq!(parse_range(&format!("bytes={huge}-"), 100), Unsatisfiable);
        assert_eq!(
            parse_range(&format!("bytes=0-{huge}"), 100),
            Part { start: 0, end: 100 }
        );
        assert_eq!(
            parse_range(&format!("bytes=-{huge}"), 100),
            Part { start: 0, end: 100 }
        );
        let max = u64::MAX;
        assert_eq!(
            parse_range(&format!("bytes={max}-{max}"), max),
            Unsatisfiable
        );
        assert_eq!(
            parse_range(&format!("bytes=0-{max}"), max),
            Part { start: 0, end: max }
        );
        assert_eq!(parse_range("bytes=--5", 100), Whole);
        assert_eq!(parse_range("bytes=+1-2", 100), Whole);
        assert_eq!(parse_range("bytes=0x10-", 100), Whole);
        assert_eq!(parse_range("bytes=1-2-3", 100), Whole);
        assert_eq!(parse_range("bytes=١-٢", 100), Whole, "non-ASCII digits");
    }

    #[test]
    fn invalid_foreign_and_multiple_ranges_get_the_whole_body() {
        assert_eq!(parse_range("bytes=5-2", 100), Whole, "last before first");
        assert_eq!(parse_range("5-7", 100), Whole, "missing bytes=");
        assert_eq!(parse_range("items=0-1", 100), Whole);
        assert_eq!(parse_range("bytes=", 100), Whole);
        assert_eq!(parse_range("bytes=-", 100), Whole);
        assert_eq!(parse_range("bytes=abc", 100), Whole);
        assert_eq!(parse_range("", 100), Whole);
        assert_eq!(parse_range("bytes=0-1,5-6", 100), Whole);
        assert_eq!(parse_range("bytes=0-1, -5", 100), Whole);
    }
}
