//! The option values of `simulate --tileset`: link rates (`10Mbit`), durations (`40ms`), memory
//! sizes (`256MiB`), viewports (`1280x720`) and points (`x,y,z`); errors name the option.

use glam::DVec3;

/// Splits `s` into its leading number and the rest (trimmed).
fn number_and_unit<'a>(s: &'a str, opt: &str, example: &str) -> Result<(f64, &'a str), String> {
    let s = s.trim();
    let end = s
        .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == '+' || c == 'e'))
        .unwrap_or(s.len());
    // An 'e' that starts the unit (none of ours does) would be eaten above; units here start
    // with k, m, g, b or s.
    let (num, unit) = s.split_at(end);
    let v: f64 = num
        .parse()
        .map_err(|_| format!("{opt} '{s}': expected a number with a unit, e.g. {example}"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(format!("{opt} '{s}': must be a finite number >= 0"));
    }
    Ok((v, unit.trim()))
}

/// A link rate in megabits per second from `10Mbit`, `10 Mbit/s`, `10Mbps`, `500kbit`,
/// `1Gbit` (case-insensitive; a bare number is refused as ambiguous).
pub fn parse_rate_mbps(s: &str, opt: &str) -> Result<f64, String> {
    let (v, unit) = number_and_unit(s, opt, "10Mbit")?;
    let u = unit.to_ascii_lowercase();
    let u = u.strip_suffix("/s").unwrap_or(&u);
    let scale = match u {
        "kbit" | "kbps" | "kb" => 1e-3,
        "mbit" | "mbps" | "mb" => 1.0,
        "gbit" | "gbps" | "gb" => 1e3,
        "bit" | "bps" => 1e-6,
        _ => {
            return Err(format!(
                "{opt} '{s}': unknown unit '{unit}' (use kbit, Mbit or Gbit, e.g. 10Mbit)"
            ));
        }
    };
    let mbps = v * scale;
    if mbps <= 0.0 {
        return Err(format!("{opt} '{s}': must be above 0"));
    }
    Ok(mbps)
}

/// A duration in seconds from `40ms`, `0.04s`, `1.5 s` (a bare number is refused).
pub fn parse_duration_s(s: &str, opt: &str) -> Result<f64, String> {
    let (v, unit) = number_and_unit(s, opt, "40ms")?;
    match unit.to_ascii_lowercase().as_str() {
        "ms" => Ok(v / 1e3),
        "s" => Ok(v),
        _ => Err(format!(
            "{opt} '{s}': unknown unit '{unit}' (use ms or s, e.g. 40ms)"
        )),
    }
}

/// A memory size in bytes from `256MiB`, `32 MiB`, `1GB` (`parse-size`: decimal and binary
/// prefixes; a bare number is bytes).
pub fn parse_bytes(s: &str, opt: &str) -> Result<u64, String> {
    let b =
        parse_size::parse_size(s.trim()).map_err(|e| format!("{opt} '{s}': {e} (e.g. 256MiB)"))?;
    if b == 0 {
        return Err(format!("{opt} '{s}': must be above 0"));
    }
    Ok(b)
}

/// A viewport `WIDTHxHEIGHT` in pixels (each 1..=16384).
pub fn parse_viewport(s: &str, opt: &str) -> Result<(u32, u32), String> {
    let bad = || format!("{opt} '{s}': expected WIDTHxHEIGHT, e.g. 1280x720");
    let (w, h) = s.trim().split_once(['x', 'X']).ok_or_else(bad)?;
    let w: u32 = w.trim().parse().map_err(|_| bad())?;
    let h: u32 = h.trim().parse().map_err(|_| bad())?;
    if !(1..=16384).contains(&w) || !(1..=16384).contains(&h) {
        return Err(format!("{opt} '{s}': each side must be 1..=16384 pixels"));
    }
    Ok((w, h))
}

/// A point `x,y,z` of finite numbers.
pub fn parse_point(s: &str, opt: &str) -> Result<DVec3, String> {
    let v: Result<Vec<f64>, _> = s.split(',').map(|f| f.trim().parse::<f64>()).collect();
    match v {
        Ok(v) if v.len() == 3 && v.iter().all(|x| x.is_finite()) => {
            Ok(DVec3::new(v[0], v[1], v[2]))
        }
        _ => Err(format!("{opt} '{s}': expected three numbers x,y,z")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates() {
        assert_eq!(parse_rate_mbps("10Mbit", "--bandwidth"), Ok(10.0));
        assert_eq!(parse_rate_mbps("10 Mbit/s", "--bandwidth"), Ok(10.0));
        assert_eq!(parse_rate_mbps("2.5mbps", "--bandwidth"), Ok(2.5));
        assert_eq!(parse_rate_mbps("500kbit", "--bandwidth"), Ok(0.5));
        assert_eq!(parse_rate_mbps("1Gbit", "--bandwidth"), Ok(1000.0));
        for bad in ["10", "fast", "10 furlongs", "0Mbit", "-3Mbit", "Mbit", ""] {
            let e = parse_rate_mbps(bad, "--bandwidth").unwrap_err();
            assert!(e.starts_with("--bandwidth"), "{bad}: {e}");
        }
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration_s("40ms", "--rtt"), Ok(0.04));
        assert_eq!(parse_duration_s("0.1 s", "--rtt"), Ok(0.1));
        assert_eq!(parse_duration_s("0ms", "--rtt"), Ok(0.0));
        for bad in ["40", "40 min", "x", "-1ms"] {
            assert!(
                parse_duration_s(bad, "--rtt")
                    .unwrap_err()
                    .contains("--rtt")
            );
        }
    }

    #[test]
    fn sizes_viewports_points() {
        assert_eq!(parse_bytes("256MiB", "--budget"), Ok(256 << 20));
        assert_eq!(parse_bytes("32 MiB", "--budget"), Ok(32 << 20));
        assert_eq!(parse_bytes("1GB", "--budget"), Ok(1_000_000_000));
        assert!(
            parse_bytes("lots", "--budget")
                .unwrap_err()
                .contains("--budget")
        );
        assert!(parse_bytes("0", "--budget").is_err());
        assert_eq!(parse_viewport("1280x720", "--viewport"), Ok((1280, 720)));
        for bad in ["1280", "0x720", "axb", "1280x720x3", "99999x10"] {
            assert!(parse_viewport(bad, "--viewport").is_err(), "{bad}");
        }
        assert_eq!(
            parse_point("1, -2.5,3", "--anchor"),
            Ok(DVec3::new(1.0, -2.5, 3.0))
        );
        assert!(parse_point("1,2", "--anchor").is_err());
        assert!(parse_point("1,2,nan", "--anchor").is_err());
    }
}
