//! The validation report as data: `{date, numErrors, numWarnings, numInfos, issues}` shaped like
//! CesiumGS/3d-tiles-validator's JSON report; the human text is rendered from the same data.
//!
//! ## Wire format
//! ```json
//! {"date": "2026-11-22T05:00:00Z", "numErrors": 1, "numWarnings": 0, "numInfos": 0,
//!  "issues": [{"type": "BOUNDING_VOLUME_INVALID", "path": "tileset.json#/root/boundingVolume/box",
//!              "message": "...", "severity": "ERROR"}]}
//! ```

use super::issues::{Issue, Severity};
use serde::{Deserialize, Serialize};

/// Outcome of validating one tileset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Report {
    /// When the validation ran (UTC, RFC 3339).
    pub date: String,
    /// Number of ERROR issues.
    pub num_errors: usize,
    /// Number of WARNING issues.
    pub num_warnings: usize,
    /// Number of INFO issues.
    pub num_infos: usize,
    /// Every issue, in the order found.
    pub issues: Vec<Issue>,
    /// The tileset file itself could not be read as JSON (not JSON, a bad compressed stream;
    /// not a file refused for its size or depth): nothing of it was checked. Not in the JSON.
    #[serde(skip)]
    pub unreadable: bool,
}

impl Report {
    /// A report over `issues`, dated now.
    pub fn new(issues: Vec<Issue>) -> Report {
        let count = |s: Severity| issues.iter().filter(|i| i.severity == s).count();
        Report {
            date: now_rfc3339(),
            num_errors: count(Severity::Error),
            num_warnings: count(Severity::Warning),
            num_infos: count(Severity::Info),
            issues,
            unreadable: false,
        }
    }

    /// True when no ERROR was found.
    pub fn is_valid(&self) -> bool {
        self.num_errors == 0
    }

    /// Codes of the ERROR and WARNING issues, sorted (a multiset, for tests); the ERROR and
    /// WARNING causes of an issue follow as `CODE>CAUSE` (and `CODE>CAUSE>CAUSE` when nested).
    pub fn codes(&self) -> Vec<String> {
        fn walk(prefix: &str, issues: &[Issue], out: &mut Vec<String>) {
            for i in issues.iter().filter(|i| i.severity != Severity::Info) {
                let code = format!("{prefix}{}", i.code);
                walk(&format!("{code}>"), &i.causes, out);
                out.push(code);
            }
        }
        let mut v = Vec::new();
        walk("", &self.issues, &mut v);
        v.sort();
        v
    }

    /// The JSON report, pretty-printed.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("report serialises")
    }

    /// Human-readable text: one line per issue, then a summary line.
    pub fn to_text(&self, input: &str) -> String {
        fn lines(issues: &[Issue], indent: usize, out: &mut String) {
            for i in issues {
                out.push_str(&format!(
                    "{:indent$}{:<7} {} {}: {}\n",
                    "",
                    i.severity.to_string(),
                    i.code,
                    i.path,
                    i.message
                ));
                lines(&i.causes, indent + 2, out);
            }
        }
        let mut out = String::new();
        lines(&self.issues, 0, &mut out);
        out.push_str(&format!(
            "{input}: {} ({} errors, {} warnings, {} infos)\n",
            if self.is_valid() { "valid" } else { "INVALID" },
            self.num_errors,
            self.num_warnings,
            self.num_infos
        ));
        out
    }
}

/// Current UTC time as `YYYY-MM-DDTHH:MM:SSZ` (no date crate needed).
fn now_rfc3339() -> String {
    let secs = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs() as i64)
        .unwrap_or(0);
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serde_round_trip_and_counts() {
        let r = Report::new(vec![
            Issue::BOUNDING_VOLUME_INVALID("tileset.json#/root/boundingVolume", "no volume"),
            Issue::TILE_GEOMETRIC_ERRORS_INCONSISTENT("x", "y"),
            Issue::CONTENT_DATA_NOT_CHECKED("t.glb", "spz"),
        ]);
        assert_eq!((r.num_errors, r.num_warnings, r.num_infos), (1, 1, 1));
        let text = r.to_json();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(v["issues"][0]["type"], "BOUNDING_VOLUME_INVALID");
        assert_eq!(v["issues"][0]["severity"], "ERROR");
        assert_eq!(v["numWarnings"], 1);
        let back: Report = serde_json::from_str(&text).unwrap();
        assert_eq!(back, r);
        assert!(r.to_text("ts").contains("INVALID (1 errors"));
        assert_eq!(r.date.len(), 20);
    }
}
