//! Quality variants: bytes per splat before and after gzip, mean and worst utility (SSIM vs
//! Best), encode time per variant, for the shared scenes and the plant with synthetic SH1-3.
//!
//! Run: `cargo bench --bench variants` (prints a Markdown table, writes
//! `docs/variants_ssim_bytes.svg`).

mod common;
use common::plant_sh3;
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_io::{Scene, read_path};
use splat2tiles_tiles::encode::spz2::{SpzOptions, encode_spz_v2, encode_spz_v2_raw, gzip};
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_tiles::variants::{ALL, VariantOptions, content_uri, variant_table};
use std::fmt::Write as _;
use std::path::Path;

struct Point {
    scene: String,
    variant: &'static str,
    bytes_per_splat: f64,
    mean: f64,
}

/// The plant scene with [`plant_sh3`]'s splats.
fn plant_sh3_scene(plant: &Scene) -> Scene {
    let mut sc = plant.clone();
    sc.splats = plant_sh3(&plant.splats);
    sc
}

/// SPZ v2 arrays with each attribute stream zstd-compressed separately (how SPZ v4 stores them;
/// an estimate of v4's size, not upstream's v4 writer: v4 also packs rotations in 4 bytes).
fn zstd_streams(raw: &[u8], n: usize, degree: u8) -> usize {
    let k = splat2tiles_core::splat::sh_rest_count(degree);
    let sizes = [9 * n, n, 3 * n, 3 * n, 3 * n, 3 * k * n];
    let mut at = 16;
    let mut total = 32 + 16 * sizes.len();
    for s in sizes {
        total += zstd::bulk::compress(&raw[at..at + s], 12).unwrap().len();
        at += s;
    }
    total
}

fn main() {
    let scenes_dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    let plant = read_path(&scenes_dir.join("plant.splat")).unwrap();
    let inputs = vec![
        ("plant.splat (SH0)".to_string(), plant.clone()),
        (
            "donut_fused_sh0.ply (SH0)".to_string(),
            read_path(&scenes_dir.join("donut_fused_sh0.ply")).unwrap(),
        ),
        (
            "biker.spz (SH0)".to_string(),
            read_path(&scenes_dir.join("biker.spz")).unwrap(),
        ),
        (
            "plant + synthetic SH1-3".to_string(),
            plant_sh3_scene(&plant),
        ),
    ];
    let mut table = String::from(
        "| scene | variant | tiles | B/splat (file) | B/splat raw | B/splat gzip -9 | mean SSIM | worst SSIM | encode s |\n|---|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    let mut spz_table = String::from(
        "| scene | splats | Low raw (SPZ v2, SH<=1) | Low gzip | SPZ v2 full SH gzip | SPZ v2 arrays, zstd per stream (v4-style) |\n|---|---:|---:|---:|---:|---:|\n",
    );
    let mut points = vec![];
    for (name, scene) in inputs {
        let s = scene.splats.clone();
        let n = s.len();
        let low_raw = encode_spz_v2_raw(&s, [0.0; 3], &splat2tiles_tiles::variants::LOW_SPZ);
        let low_gz = gzip(&low_raw);
        let full = SpzOptions::default();
        let full_raw = encode_spz_v2_raw(&s, [0.0; 3], &full);
        let full_gz = encode_spz_v2(&s, [0.0; 3], &full);
        let zs = zstd_streams(&full_raw, n, s.sh_degree);
        let per = |b: usize| b as f64 / n as f64;
        writeln!(
            spz_table,
            "| {name} | {n} | {:.2} | {:.2} | {:.2} | {:.2} |",
            per(low_raw.len()),
            per(low_gz.len()),
            per(full_gz.len()),
            per(zs)
        )
        .unwrap();

        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("ts");
        let opts = ConvertOptions {
            variants: VariantOptions {
                variants: ALL.to_vec(),
                ..Default::default()
            },
            ..Default::default()
        };
        let report = convert_scene(scene, &name, &out, &opts).unwrap();
        let ts = load_tileset(&out.join("tileset.json")).unwrap();
        for row in variant_table(&ts) {
            let v = row.variant;
            let i = v.index();
            let (mut raw, mut gz) = (0usize, 0usize);
            for t in ts.tiles.iter().filter(|t| t.content.is_some()) {
                let glb = std::fs::read(out.join(content_uri(ts.scheme, t.key, v))).unwrap();
                gz += gzip(&glb).len();
                raw += raw_size(&glb);
            }
            let secs: f64 = report
                .contents
                .iter()
                .map(|(_, f)| f.encode_seconds[i])
                .sum();
            writeln!(
                table,
                "| {name} | {} | {} | {:.2} | {:.2} | {:.2} | {:.4} | {:.4} | {:.3} |",
                v.name(),
                row.tiles,
                row.bytes_per_splat(),
                raw as f64 / row.splats as f64,
                gz as f64 / row.splats as f64,
                row.mean_utility,
                row.worst_utility,
                secs
            )
            .unwrap();
            points.push(Point {
                scene: name.clone(),
                variant: v.name(),
                bytes_per_splat: row.bytes_per_splat(),
                mean: row.mean_utility,
            });
        }
    }
    println!("{table}\n{spz_table}");
    let svg = plot(&points);
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."))
        .join("docs/variants_ssim_bytes.svg");
    std::fs::write(&path, svg).unwrap();
    println!("wrote {}", path.display());
}

/// Bytes before entropy coding: the SPZ v2 arrays for SPZ_2 tiles, the decoded (quantized,
/// filtered) bufferViews for meshopt tiles, the file for plain tiles.
fn raw_size(glb: &[u8]) -> usize {
    if let Ok(Some(p)) = splat2tiles_tiles::encode::spz2::spz2_payload(glb) {
        let mut d = flate2::read::GzDecoder::new(&p[..]);
        let mut v = vec![];
        std::io::Read::read_to_end(&mut d, &mut v).unwrap();
        return v.len();
    }
    if splat2tiles_tiles::variants::is_meshopt(glb) {
        return splat2tiles_tiles::encode::meshopt::decompress_meshopt_glb(glb)
            .unwrap()
            .len();
    }
    glb.len()
}

/// SSIM against bytes per splat (log x), one polyline per scene.
fn plot(points: &[Point]) -> String {
    let (w, h, l, r, t, b) = (720.0, 440.0, 70.0, 200.0, 30.0, 50.0);
    let xs: Vec<f64> = points.iter().map(|p| p.bytes_per_splat.log10()).collect();
    let (x0, x1) = (
        xs.iter().copied().fold(f64::MAX, f64::min).floor(),
        xs.iter().copied().fold(f64::MIN, f64::max).ceil(),
    );
    let y0 = points
        .iter()
        .map(|p| p.mean)
        .fold(1.0f64, f64::min)
        .min(0.995);
    let (y0, y1) = ((y0 * 1000.0).floor() / 1000.0, 1.0005);
    let px = |x: f64| l + (x.log10() - x0) / (x1 - x0) * (w - l - r);
    let py = |y: f64| t + (y1 - y) / (y1 - y0) * (h - t - b);
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    writeln!(s, "<text x=\"{l}\" y=\"18\" font-size=\"14\">Quality variants: utility (mean SSIM vs Best, 8 views) against bytes/splat</text>").unwrap();
    let mut dec = x0;
    while dec <= x1 {
        for m in [1.0, 2.0, 5.0] {
            let v = 10f64.powf(dec) * m;
            if v.log10() > x1 + 1e-9 {
                break;
            }
            let x = px(v);
            writeln!(s, "<line x1=\"{x:.1}\" y1=\"{t}\" x2=\"{x:.1}\" y2=\"{}\" stroke=\"#ddd\"/><text x=\"{x:.1}\" y=\"{}\" text-anchor=\"middle\">{v}</text>", h - b, h - b + 16.0).unwrap();
        }
        dec += 1.0;
    }
    let mut y = y0;
    while y <= 1.0 + 1e-9 {
        let yy = py(y);
        writeln!(s, "<line x1=\"{l}\" y1=\"{yy:.1}\" x2=\"{}\" y2=\"{yy:.1}\" stroke=\"#ddd\"/><text x=\"{}\" y=\"{:.1}\" text-anchor=\"end\">{y:.3}</text>", w - r, l - 6.0, yy + 4.0).unwrap();
        y += ((1.0 - y0) / 5.0).max(0.001);
    }
    writeln!(
        s,
        "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">bytes per splat (file, log scale)</text>",
        (l + w - r) / 2.0,
        h - 12.0
    )
    .unwrap();
    let mut scenes: Vec<&str> = points.iter().map(|p| p.scene.as_str()).collect();
    scenes.dedup();
    for (si, scene) in scenes.iter().enumerate() {
        let c = colours[si % colours.len()];
        let pts: Vec<&Point> = points.iter().filter(|p| p.scene == *scene).collect();
        let path: Vec<String> = pts
            .iter()
            .map(|p| format!("{:.1},{:.1}", px(p.bytes_per_splat), py(p.mean)))
            .collect();
        writeln!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"1.5\"/>",
            path.join(" ")
        )
        .unwrap();
        for p in &pts {
            let (x, y) = (px(p.bytes_per_splat), py(p.mean));
            writeln!(s, "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"3.5\" fill=\"{c}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" fill=\"{c}\">{}</text>", x + 4.0, y - 5.0, p.variant).unwrap();
        }
        let ly = t + 20.0 + si as f64 * 18.0;
        writeln!(s, "<rect x=\"{}\" y=\"{:.1}\" width=\"12\" height=\"12\" fill=\"{c}\"/><text x=\"{}\" y=\"{:.1}\">{scene}</text>", w - r + 10.0, ly - 10.0, w - r + 28.0, ly).unwrap();
    }
    s.push_str("</svg>\n");
    s
}
