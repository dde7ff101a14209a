//! Level of detail on generated cities (not a test): LOD build seconds per million splats at
//! several sizes, and for the first size the per-level table (tiles, splats, share, bytes) with
//! each level's cut SSIM against all leaves from street-level and aerial cameras.
//!
//! Run: `cargo bench --bench lod_city` (release). `LOD_CITY_SIZES` (comma-separated splat counts,
//! default `5000000`), `LOD_MAX_SPLATS` (tile budget, default 32768), `LOD_CITY_PICTURES` (a
//! folder for each level's street and aerial picture), `LOD_CITY_DAMAGE` (a level measured again
//! with half its splats dropped), `LOD_CITY_VIEWS=0` (timing only), `LOD_CITY_WIDTH` (image
//! frame width, default the viewer's pixel scale, 960), `LOD_CITY_ERROR_SCALES` (SSIM again with
//! every error scaled), `LOD_CITY_BYTES_SCALES` (bytes a viewer loads with every error scaled).
//! Cities: displaced, rotated, scaled copies of the three shared scenes
//! (`data/scenes/README.md`), built in memory. Writes `target/lod_city.md`.

use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::lod::eval::level_table;
use splat2tiles_build::lod::views::{ViewKind, ViewOptions, evaluate_views, viewer_bytes};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_lab::city::{CityLayout, city_scene, generate_city, shared_sources};
use splat2tiles_tiles::tiling::load::load_tileset;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

#[expect(
    clippy::too_many_lines,
    reason = "a measurement run by hand: one straight script that prints its table"
)]
fn main() {
    let sizes: Vec<usize> = std::env::var("LOD_CITY_SIZES")
        .unwrap_or_else(|_| "5000000".into())
        .split(',')
        .filter_map(|v| v.trim().parse().ok())
        .collect();
    let budget: usize = env_or("LOD_MAX_SPLATS", 32_768);
    let pictures = std::env::var("LOD_CITY_PICTURES").ok().map(PathBuf::from);
    let damage: Option<u32> = std::env::var("LOD_CITY_DAMAGE")
        .ok()
        .and_then(|v| v.parse().ok());
    let base = ViewOptions {
        width: env_or("LOD_CITY_WIDTH", ViewOptions::default().width),
        ..ViewOptions::default()
    };
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let sources = shared_sources(&root.join("data/scenes")).expect("shared scenes");
    let tmp = root.join("target/tmp-big");
    let mut md = String::new();
    let _ = writeln!(
        md,
        "max splats per tile {budget}\n\n| city splats | convert s | LOD s | LOD s per M splats | parent splats (% of input) | levels |\n|---|---|---|---|---|---|"
    );
    let mut tables = String::new();
    for (i, &n) in sizes.iter().enumerate() {
        let t0 = Instant::now();
        let city = generate_city(
            &sources,
            &CityLayout {
                splats: n,
                ..CityLayout::default()
            },
        );
        eprintln!(
            "city of {n} generated in {:.1} s",
            t0.elapsed().as_secs_f64()
        );
        let out = tmp.join(format!("lod-city-{n}"));
        let _ = std::fs::remove_dir_all(&out);
        let opts = ConvertOptions {
            max_splats_per_tile: budget,
            up_axis: Some(UpAxis::PosZ),
            ..ConvertOptions::default()
        };
        let r = convert_scene(city_scene(city), "city", &out, &opts).expect("convert");
        let _ = writeln!(
            md,
            "| {n} | {:.1} | {:.2} | {:.3} | {} ({:.1}%) | {} |",
            r.seconds,
            r.lod_seconds,
            r.lod_seconds / (n as f64 / 1e6),
            r.parent_splats,
            100.0 * r.parent_splats as f64 / n as f64,
            r.levels
        );
        eprint!("{md}");
        if i == 0 && env_or("LOD_CITY_VIEWS", 1) != 0 {
            let ts_path = out.join("tileset.json");
            let ts = load_tileset(&ts_path).expect("load");
            let rows = level_table(&ts).expect("table");
            let t1 = Instant::now();
            let views = evaluate_views(
                &ts_path,
                &ViewOptions {
                    pictures: pictures.clone(),
                    ..base.clone()
                },
            )
            .expect("views");
            eprintln!("views measured in {:.1} s", t1.elapsed().as_secs_f64());
            let _ = writeln!(
                tables,
                "\ncity of {n} splats; SSIM: lowest of 2 azimuths, pixel scale of a {}x{} frame, cut vs all leaves, cameras at the level's switching distance (viewer 1280x720, 50 deg, 16 px SSE)\n\n| level | tiles (leaves) | splats | share of input | bytes | geometric error (mean) | cut splats | SSIM street | SSIM aerial |\n|---|---|---|---|---|---|---|---|---|",
                base.width,
                base.width * 3 / 4
            );
            for row in &rows {
                let v = views.iter().find(|v| v.level == row.level);
                let f = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.3}"));
                let _ = writeln!(
                    tables,
                    "| {} | {} ({}) | {} | {:.3}% | {} | {:.3} | {} | {} | {} |",
                    row.level,
                    row.tiles,
                    row.leaves,
                    row.splats,
                    100.0 * row.splats as f64 / n as f64,
                    row.bytes,
                    row.mean_geometric_error,
                    v.map_or("-".to_string(), |v| v.cut_splats.to_string()),
                    f(v.map(|v| v.street_ssim)),
                    f(v.map(|v| v.aerial_ssim)),
                );
            }
            for scale in std::env::var("LOD_CITY_ERROR_SCALES")
                .unwrap_or_default()
                .split(',')
                .filter_map(|v| v.trim().parse::<f64>().ok())
            {
                let d = evaluate_views(
                    &ts_path,
                    &ViewOptions {
                        error_scale: scale,
                        ..base.clone()
                    },
                )
                .expect("scaled views");
                for v in d {
                    let _ = writeln!(
                        tables,
                        "errors x{scale}: level {} SSIM street {:.3} aerial {:.3}",
                        v.level, v.street_ssim, v.aerial_ssim
                    );
                }
            }
            let byte_scales: Vec<f64> = std::env::var("LOD_CITY_BYTES_SCALES")
                .unwrap_or_default()
                .split(',')
                .filter_map(|v| v.trim().parse::<f64>().ok())
                .collect();
            if !byte_scales.is_empty() {
                let distances = [0.25, 0.5, 1.0, 2.0, 4.0];
                let cols: Vec<Vec<(ViewKind, f64, u64)>> = byte_scales
                    .iter()
                    .map(|&k| viewer_bytes(&ts_path, &distances, k).expect("viewer bytes"))
                    .collect();
                let _ = write!(
                    tables,
                    "\nbytes the viewer (1280x720, 16 px SSE) loads, every geometric error times k\n\n| camera | distance / scene radius |"
                );
                for k in &byte_scales {
                    let _ = write!(tables, " k = {k} |");
                }
                let _ = write!(tables, "\n|---|---|");
                for _ in &byte_scales {
                    let _ = write!(tables, "---|");
                }
                let _ = writeln!(tables);
                for (i, (kind, m, _)) in cols[0].iter().enumerate() {
                    let _ = write!(tables, "| {} | {m} |", kind.as_str());
                    for c in &cols {
                        let _ = write!(tables, " {} |", c[i].2);
                    }
                    let _ = writeln!(tables);
                }
            }
            if let Some(level) = damage {
                let d = evaluate_views(
                    &ts_path,
                    &ViewOptions {
                        damage_level: Some(level),
                        ..base.clone()
                    },
                )
                .expect("damaged views");
                if let (Some(a), Some(b)) = (
                    views.iter().find(|v| v.level == level),
                    d.iter().find(|v| v.level == level),
                ) {
                    let _ = writeln!(
                        tables,
                        "\nlevel {level} with every second splat of its tiles dropped: SSIM street {:.3} (intact {:.3}), aerial {:.3} (intact {:.3})",
                        b.street_ssim, a.street_ssim, b.aerial_ssim, a.aerial_ssim
                    );
                }
            }
            eprint!("{tables}");
        }
        let _ = std::fs::remove_dir_all(&out);
    }
    md.push_str(&tables);
    print!("{md}");
    let path = root.join("target/lod_city.md");
    std::fs::write(&path, &md).expect("write target/lod_city.md");
    eprintln!("wrote {}", path.display());
}
