//! Minimal SVG line plots for the experiment and benchmark figures (no plotting crate): line
//! charts, optionally with a dot per point, and several charts side by side in one document.

use std::fmt::Write as _;

/// One line: label and points.
pub type Series = (String, Vec<(f64, f64)>);

const COLOURS: [&str; 6] = [
    "#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf",
];

/// A line chart of `series` with axis labels; y from `y_range` (auto when `None`).
pub fn line_chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    y_range: Option<(f64, f64)>,
) -> String {
    chart(title, x_label, y_label, series, y_range, false)
}

/// [`line_chart`] with a dot on every point (a series of one point shows).
pub fn marked_chart(title: &str, x_label: &str, y_label: &str, series: &[Series]) -> String {
    chart(title, x_label, y_label, series, None, true)
}

/// Charts (each a whole `<svg>` of [`line_chart`]'s size) side by side, `cols` per row, in
/// one SVG document.
pub fn panels(charts: &[String], cols: usize) -> String {
    let (w, h) = (640.0, 360.0);
    let cols = cols.max(1);
    let rows = charts.len().div_ceil(cols).max(1);
    let mut s = format!(
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{}" height="{}"><rect width="100%" height="100%" fill="white"/>"#,
        w * cols.min(charts.len().max(1)) as f64,
        h * rows as f64
    );
    for (i, c) in charts.iter().enumerate() {
        let (x, y) = ((i % cols) as f64 * w, (i / cols) as f64 * h);
        let inner = c
            .trim_end()
            .replacen("<svg ", &format!(r#"<svg x="{x}" y="{y}" "#), 1);
        s.push_str(&inner);
    }
    s.push_str("</svg>\n");
    s
}

fn chart(
    title: &str,
    x_label: &str,
    y_label: &str,
    series: &[Series],
    y_range: Option<(f64, f64)>,
    markers: bool,
) -> String {
    let (w, h, ml, mr, mt, mb) = (640.0, 360.0, 60.0, 150.0, 30.0, 45.0);
    let pts = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if let Some((a, b)) = y_range {
        (y0, y1) = (a, b);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    if y1 <= y0 {
        y1 = y0 + 1.0;
    }
    let sx = |x: f64| ml + (x - x0) / (x1 - x0) * (w - ml - mr);
    let sy = |y: f64| h - mb - (y - y0) / (y1 - y0) * (h - mt - mb);
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12"><rect width="100%" height="100%" fill="white"/><text x="{}" y="18" text-anchor="middle" font-size="14">{title}</text>"#,
        (w - mr + ml) / 2.0
    );
    let _ = write!(
        s,
        r#"<line x1="{ml}" y1="{}" x2="{}" y2="{}" stroke="black"/><line x1="{ml}" y1="{mt}" x2="{ml}" y2="{}" stroke="black"/>"#,
        h - mb,
        w - mr,
        h - mb,
        h - mb
    );
    for i in 0..=4 {
        let fx = x0 + (x1 - x0) * i as f64 / 4.0;
        let fy = y0 + (y1 - y0) * i as f64 / 4.0;
        let _ = write!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text><text x="{}" y="{}" text-anchor="end">{}</text>"#,
            sx(fx),
            h - mb + 16.0,
            fmt_num(fx),
            ml - 5.0,
            sy(fy) + 4.0,
            fmt_num(fy)
        );
    }
    let _ = write!(
        s,
        r#"<text x="{}" y="{}" text-anchor="middle">{x_label}</text><text x="14" y="{}" transform="rotate(-90 14 {})" text-anchor="middle">{y_label}</text>"#,
        (w - mr + ml) / 2.0,
        h - 8.0,
        (h - mb + mt) / 2.0,
        (h - mb + mt) / 2.0
    );
    for (k, (label, p)) in series.iter().enumerate() {
        let c = COLOURS[k % COLOURS.len()];
        let path: Vec<String> = p
            .iter()
            .map(|&(x, y)| format!("{:.1},{:.1}", sx(x), sy(y.clamp(y0, y1))))
            .collect();
        let _ = write!(
            s,
            r#"<polyline fill="none" stroke="{c}" stroke-width="1.6" points="{}"/><text x="{}" y="{}" fill="{c}">{label}</text>"#,
            path.join(" "),
            w - mr + 8.0,
            mt + 16.0 * (k as f64 + 1.0)
        );
        if markers {
            for &(x, y) in p {
                let _ = write!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{c}"/>"#,
                    sx(x),
                    sy(y.clamp(y0, y1))
                );
            }
        }
    }
    s.push_str("</svg>\n");
    s
}

fn fmt_num(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 1.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}

/// Writes `{stem}_quality.svg` (SSIM over time, 0..1) and `{stem}_bytes.svg` (MB received over
/// time) into `dir`, titled "`label`: `quality_what`" and "`label`: bytes received".
pub fn write_time_plots(
    dir: &std::path::Path,
    stem: &str,
    label: &str,
    quality_what: &str,
    quality: &[Series],
    bytes: &[Series],
) -> std::io::Result<()> {
    std::fs::write(
        dir.join(format!("{stem}_quality.svg")),
        line_chart(
            &format!("{label}: {quality_what}"),
            "time (s)",
            "SSIM",
            quality,
            Some((0.0, 1.0)),
        ),
    )?;
    std::fs::write(
        dir.join(format!("{stem}_bytes.svg")),
        line_chart(
            &format!("{label}: bytes received"),
            "time (s)",
            "MB",
            bytes,
            None,
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_and_panels() {
        let series: Vec<Series> = vec![
            ("a".into(), vec![(1.0, 2.0), (2.0, 3.0)]),
            ("b".into(), vec![(1.5, 2.5)]),
        ];
        let plain = line_chart("t", "x", "y", &series, None);
        let marked = marked_chart("t", "x", "y", &series);
        assert_eq!(plain.matches("<circle").count(), 0);
        assert_eq!(marked.matches("<circle").count(), 3);
        let doc = panels(&[plain, marked], 2);
        assert!(doc.starts_with(
            "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"1280\" height=\"360\""
        ));
        assert_eq!(doc.matches("<svg ").count(), 3);
        assert!(doc.contains(r#"<svg x="640" y="0" xmlns"#));
        assert!(doc.trim_end().ends_with("</svg></svg>"));
    }
}
