//! Reader for real throughput logs (`data/network-traces/`: HSDPA 3G and FCC broadband, in
//! Pensieve's `TIME_S THROUGHPUT_MBPS` format) into piecewise-constant bandwidth for the simulator.
//!
//! Sources (`data/network-traces/README.md`): HSDPA: Riiser, Vigmostad, Griwodz, Halvorsen,
//! "Commute Path Bandwidth Traces from 3G Networks", ACM MMSys 2013; FCC: "Measuring Broadband
//! America" 2016; both as prepared by Pensieve (Mao, Netravali, Alizadeh, SIGCOMM 2017).
//!
//! Output: `Vec<(start_s, bytes_per_s)>`, the type of `sim::client::NetModel.bandwidth`, times
//! shifted so the first piece starts at 0, each sample holding until the next. Rates are
//! `Mbit/s * 1e6 / 8 * scale`: `scale` is explicit (1 = as recorded) and must be reported next to
//! every number measured with it.

use std::path::{Path, PathBuf};

/// Largest log read (the largest shared one is about 30 KB).
pub const MAX_FILE_BYTES: u64 = 16 << 20;

/// Which collection a log comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Network {
    /// 3G/HSDPA mobile, Norway (`hsdpa/`).
    Hsdpa,
    /// FCC fixed broadband (`fcc/`).
    Fcc,
}

impl Network {
    /// Directory name under the shared `network-traces/`.
    pub fn dir(self) -> &'static str {
        match self {
            Network::Hsdpa => "hsdpa",
            Network::Fcc => "fcc",
        }
    }
}

/// A bandwidth log.
#[derive(Debug, Clone, PartialEq)]
pub struct NetTrace {
    /// File the log came from (for reports).
    pub name: String,
    /// `(start s, bytes/s)` pieces, sorted, the first at 0.
    pub pieces: Vec<(f64, f64)>,
    /// Seconds covered by the samples (time of the last sample after the shift).
    pub duration_s: f64,
    /// Scale applied to the recorded throughput.
    pub scale: f64,
}

impl NetTrace {
    /// Mean rate over the covered time, bytes/s (the last piece counts from its start to the end,
    /// i.e. not at all).
    pub fn mean_bytes_per_s(&self) -> f64 {
        if self.duration_s <= 0.0 {
            return self.pieces.first().map_or(0.0, |p| p.1);
        }
        let mut acc = 0.0;
        for w in self.pieces.windows(2) {
            acc += (w[1].0 - w[0].0) * w[0].1;
        }
        acc / self.duration_s
    }

    /// The pieces repeated end to end until `until_s` (a log shorter than a session loops; the
    /// last sample's own rate is not held past the end of the log).
    pub fn looped(&self, until_s: f64) -> Vec<(f64, f64)> {
        if self.duration_s <= 0.0 || self.pieces.len() < 2 {
            return self.pieces.clone();
        }
        let body = &self.pieces[..self.pieces.len() - 1];
        let mut out = vec![];
        let mut base = 0.0;
        // Bounded: a piece per sample per loop, until `until_s`.
        while base < until_s && out.len() < 50_000_000 {
            for &(t, r) in body {
                if base + t >= until_s {
                    break;
                }
                out.push((base + t, r));
            }
            base += self.duration_s;
        }
        out
    }
}

/// Parses a log; `name` is used in errors, which give the line. `scale` multiplies every rate.
pub fn parse_log(text: &str, name: &str, scale: f64) -> Result<NetTrace, String> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(format!("{name}: scale {scale} must be a positive number"));
    }
    let mut raw: Vec<(f64, f64)> = vec![];
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let ln = n + 1;
        let mut it = line.split_whitespace();
        let (Some(a), Some(b), None) = (it.next(), it.next(), it.next()) else {
            return Err(format!(
                "{name}: line {ln}: expected 'TIME_S THROUGHPUT_MBPS'"
            ));
        };
        let t: f64 = a
            .parse()
            .map_err(|e| format!("{name}: line {ln}: time '{a}': {e}"))?;
        let mbps: f64 = b
            .parse()
            .map_err(|e| format!("{name}: line {ln}: throughput '{b}': {e}"))?;
        if !t.is_finite() || !mbps.is_finite() || mbps < 0.0 {
            return Err(format!(
                "{name}: line {ln}: time and throughput must be finite, throughput >= 0"
            ));
        }
        if let Some(&(prev, _)) = raw.last()
            && t <= prev
        {
            return Err(format!("{name}: line {ln}: time does not increase"));
        }
        let rate = mbps * 1e6 / 8.0 * scale;
        if raw.first().is_some_and(|f| !(t - f.0).is_finite()) || !rate.is_finite() {
            return Err(format!(
                "{name}: line {ln}: time or throughput out of range"
            ));
        }
        raw.push((t, mbps));
    }
    let Some(&(t0, _)) = raw.first() else {
        return Err(format!("{name}: no samples"));
    };
    let duration_s = raw.last().map_or(0.0, |p| p.0 - t0);
    Ok(NetTrace {
        name: name.to_string(),
        pieces: raw
            .into_iter()
            .map(|(t, m)| (t - t0, m * 1e6 / 8.0 * scale))
            .collect(),
        duration_s,
        scale,
    })
}

/// Reads one log file (bounded) with `scale`.
pub fn read_log(path: &Path, scale: f64) -> Result<NetTrace, String> {
    let text = splat2tiles_stream::eyenav::read_bounded(path, MAX_FILE_BYTES)?;
    let name = path
        .file_name()
        .and_then(|s| s.to_str())
        .unwrap_or("")
        .to_string();
    parse_log(&text, &name, scale).map_err(|e| format!("{}/{e}", dir_of(path)))
}

fn dir_of(path: &Path) -> String {
    path.parent()
        .map(|p| p.display().to_string())
        .unwrap_or_default()
}

/// Log files of `net` under `root` (the shared `network-traces/`), sorted by name.
pub fn log_files(root: &Path, net: Network) -> Result<Vec<PathBuf>, String> {
    let dir = root.join(net.dir());
    let rd = std::fs::read_dir(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let mut out = vec![];
    for e in rd {
        let p = e.map_err(|e| format!("{}: {e}", dir.display()))?.path();
        if p.is_file() {
            out.push(p);
        }
        if out.len() > 10_000 {
            return Err(format!("{}: more than 10000 files", dir.display()));
        }
    }
    out.sort();
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pieces_are_shifted_scaled_bytes_per_second() {
        let t = parse_log("5.0\t8.0\n6.0 16\n\n8.0   0\n", "x.log", 1.0).unwrap();
        assert_eq!(t.pieces, vec![(0.0, 1e6), (1.0, 2e6), (3.0, 0.0)]);
        assert_eq!(t.duration_s, 3.0);
        // (1 s x 1 MB/s + 2 s x 2 MB/s) / 3 s.
        assert!((t.mean_bytes_per_s() - 5e6 / 3.0).abs() < 1e-6);
        let x10 = parse_log("5.0\t8.0\n6.0 16\n\n8.0   0\n", "x.log", 10.0).unwrap();
        assert_eq!(x10.pieces[1], (1.0, 2e7));
        assert_eq!(x10.scale, 10.0);
    }

    #[test]
    fn looped_repeats_the_log_without_the_last_sample() {
        let t = parse_log("0 8\n1 16\n2 0\n", "x", 1.0).unwrap();
        let l = t.looped(5.0);
        assert_eq!(
            l,
            vec![(0.0, 1e6), (1.0, 2e6), (2.0, 1e6), (3.0, 2e6), (4.0, 1e6)]
        );
    }

    #[test]
    fn hostile_logs_are_errors_naming_the_line() {
        for (text, want) in [
            ("", "no samples"),
            ("0 1\n1\n", "line 2"),
            ("0 1\n1 2 3\n", "line 2"),
            ("0 1\n1 x\n", "line 2"),
            ("0 1\nNaN 1\n", "line 2"),
            ("0 1\n1 -1\n", "line 2"),
            ("0 1\n1 inf\n", "line 2"),
            ("0 1\n0 1\n", "does not increase"),
            ("1 1\n0 1\n", "line 2"),
            ("-1e308 1\n1e308 1\n", "out of range"),
            ("0 1e308\n", "out of range"),
        ] {
            let e = parse_log(text, "bad.log", 1.0).unwrap_err();
            assert!(
                e.starts_with("bad.log") && e.contains(want),
                "{text:?}: {e}"
            );
        }
        for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(parse_log("0 1\n", "s.log", s).is_err());
        }
    }

    /// Random text never panics: it parses or names a line.
    #[test]
    fn random_logs_never_panic() {
        let mut rng = splat2tiles_core::rng::SplitMix64::new(9);
        let alphabet = b"0123456789.-+eEnaNifINF \t\n#x";
        for _ in 0..3000 {
            let len = rng.below(120);
            let text: String = (0..len)
                .map(|_| alphabet[rng.below(alphabet.len())] as char)
                .collect();
            match parse_log(&text, "r.log", 1.0) {
                Ok(t) => {
                    assert!(t.pieces[0].0 == 0.0 && t.duration_s >= 0.0);
                    assert!(t.pieces.windows(2).all(|w| w[1].0 > w[0].0));
                    assert!(t.pieces.iter().all(|p| p.1 >= 0.0 && p.1.is_finite()));
                    let _ = t.looped(50.0);
                }
                Err(e) => assert!(e.starts_with("r.log"), "{e}"),
            }
        }
    }

    /// Every shared log reads (`data/network-traces/README.md`); the median of the HSDPA
    /// means is near the README's ~1 Mbit/s.
    #[test]
    fn shared_logs_read() {
        let root =
            Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/network-traces");
        if !root.exists() {
            eprintln!("skipped: {} missing", root.display());
            return;
        }
        for (net, n) in [(Network::Hsdpa, 68), (Network::Fcc, 59)] {
            let files = log_files(&root, net).unwrap();
            assert_eq!(files.len(), n);
            let mut means: Vec<f64> = files
                .iter()
                .map(|f| read_log(f, 1.0).unwrap().mean_bytes_per_s() * 8.0 / 1e6)
                .collect();
            means.sort_by(f64::total_cmp);
            let med = means[means.len() / 2];
            assert!((0.2..5.0).contains(&med), "{net:?}: median {med} Mbit/s");
        }
    }
}
