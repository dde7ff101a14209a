//! Level-of-detail benchmark (not a test): per-level splats, reduction, bytes and SSIM at the
//! switching distance for the three shared scenes, both merge rules, and the LOD build time.
//!
//! Run: `cargo bench --bench lod` (release; `LOD_MAX_SPLATS` sets the tile budget, default
//! 16384). Writes `target/lod_bench.md` (the tables pasted into BENCHMARKS.md).

use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_build::lod::eval::{EvalOptions, evaluate};
use splat2tiles_build::lod::{LodOptions, MergeRule};
use std::fmt::Write as _;
use std::path::Path;

fn main() {
    let budget: usize = std::env::var("LOD_MAX_SPLATS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(16_384);
    let scenes = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    let tmp = std::env::temp_dir().join(format!("s2t-lod-bench-{}", std::process::id()));
    let mut md = String::new();
    let _ = writeln!(
        md,
        "max splats per tile {budget}; SSIM: 256x192 images, 4 views, viewer 1280x720 / 50 deg / 16 px SSE\n"
    );
    let _ = writeln!(
        md,
        "| scene | merge | level | tiles | splats | % of input | parents: splats / children's splats (kept) | bytes | mean geo. error | parent vs children SSIM (mean / min) | cut vs leaves SSIM (mean / min) |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|");
    let mut timing = String::new();
    for name in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        for merge in [MergeRule::Moment, MergeRule::Axis] {
            let out = tmp.join(format!("{name}-{}", merge.as_str()));
            let opts = ConvertOptions {
                max_splats_per_tile: budget,
                lod: LodOptions {
                    merge,
                    ..LodOptions::default()
                },
                ..ConvertOptions::default()
            };
            let r = convert(&scenes.join(name), &out, &opts).expect("convert");
            let _ = writeln!(
                timing,
                "| {name} | {} | {} | {:.3} | {:.2} | {:.2} | {} |",
                merge.as_str(),
                r.splats_in,
                r.lod_radius,
                r.seconds,
                r.lod_seconds,
                r.parent_splats
            );
            let q = evaluate(&out.join("tileset.json"), &EvalOptions::default()).expect("eval");
            let input = r.splats_in as f64;
            for l in q.iter().rev() {
                let f = |v: Option<f64>, m: Option<f64>| match (v, m) {
                    (Some(v), Some(m)) => format!("{v:.3} / {m:.3}"),
                    _ => "-".into(),
                };
                let _ = writeln!(
                    md,
                    "| {name} | {} | {} | {} ({} leaves) | {} | {:.2}% | {} | {} | {:.4} | {} | {} |",
                    merge.as_str(),
                    l.row.level,
                    l.row.tiles,
                    l.row.leaves,
                    l.row.splats,
                    100.0 * l.row.splats as f64 / input,
                    if l.row.parent_tiles > 0 {
                        format!(
                            "{} / {} ({:.2}%)",
                            l.row.parent_splats,
                            l.row.children_splats,
                            100.0 * l.row.parent_splats as f64
                                / l.row.children_splats.max(1) as f64
                        )
                    } else {
                        "-".into()
                    },
                    l.row.bytes,
                    l.row.mean_geometric_error,
                    f(l.parent_ssim, l.parent_ssim_min),
                    f(l.cut_ssim, l.cut_ssim_min),
                );
            }
            let _ = std::fs::remove_dir_all(&out);
        }
    }
    let _ = writeln!(
        md,
        "\n| scene | merge | splats in | leaf radius r | convert s (total) | LOD build s | parent splats |\n|---|---|---|---|---|---|---|\n{timing}"
    );
    print!("{md}");
    let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("target/lod_bench.md");
    std::fs::write(&path, &md).expect("write target/lod_bench.md");
    eprintln!("wrote {}", path.display());
}
