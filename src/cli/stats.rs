//! `splat2tiles stats`: the per-level table of a tileset (tiles, splats, bytes, geometric error),
//! read from `tileset.json`, its subtrees and the content files' sizes only.

use clap::Args;
use splat2tiles_build::lod::eval::level_table;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::path::PathBuf;

/// Arguments of `stats`.
#[derive(Debug, Args)]
pub struct StatsArgs {
    /// The tileset's `tileset.json`, or the folder that holds it.
    pub tileset: PathBuf,
    /// Print the table as JSON on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Runs `stats`: prints the per-level table; returns the process exit code.
pub fn run(args: StatsArgs) -> i32 {
    match table(&args) {
        Ok(s) => {
            out!("{s}");
            0
        }
        Err(e) => {
            // The error names the file it could not read (and why) itself.
            eprintln!("splat2tiles: stats: {e}");
            super::EXIT_FAILURE
        }
    }
}

/// The text (or JSON) that `stats` prints.
pub fn table(args: &StatsArgs) -> anyhow::Result<String> {
    let path = if args.tileset.is_dir() {
        args.tileset.join("tileset.json")
    } else {
        args.tileset.clone()
    };
    let ts = load_tileset(&path)?;
    let rows = level_table(&ts)?;
    let vrows: Vec<_> = splat2tiles_tiles::variants::variant_table(&ts)
        .into_iter()
        .filter(|r| r.tiles > 0)
        .collect();
    let total: u64 = rows.iter().map(|r| r.splats).sum();
    let parents: std::collections::HashSet<_> =
        ts.tiles.iter().filter_map(|t| t.key.parent()).collect();
    let leaf_splats: u64 = ts
        .tiles
        .iter()
        .filter(|t| !parents.contains(&t.key))
        .filter_map(|t| t.splat_count)
        .map(u64::from)
        .sum();
    if args.json {
        let levels: Vec<serde_json::Value> = rows
            .iter()
            .map(|r| {
                serde_json::json!({
                    "level": r.level, "tiles": r.tiles, "leaves": r.leaves,
                    "splats": r.splats, "bytes": r.bytes,
                    "meanGeometricError": r.mean_geometric_error,
                })
            })
            .collect();
        let variants: Vec<serde_json::Value> = vrows
            .iter()
            .map(|r| {
                let num = |x: f64| {
                    if x.is_finite() {
                        serde_json::json!(x)
                    } else {
                        serde_json::Value::Null
                    }
                };
                serde_json::json!({
                    "variant": r.variant.name(), "tiles": r.tiles, "splats": r.splats,
                    "bytes": r.bytes, "bytesPerSplat": r.bytes_per_splat(),
                    "meanUtility": num(r.mean_utility), "worstUtility": num(r.worst_utility),
                })
            })
            .collect();
        let v = serde_json::json!({
            "levels": levels, "variants": variants, "splats": total, "leafSplats": leaf_splats,
        });
        return Ok(format!("{v}\n"));
    }
    let mut s = format!(
        "{:>5} {:>6} {:>6} {:>10} {:>8} {:>12} {:>14}\n",
        "level", "tiles", "leaves", "splats", "% leaves", "bytes", "mean geo error"
    );
    for r in &rows {
        s += &format!(
            "{:>5} {:>6} {:>6} {:>10} {:>7.2}% {:>12} {:>14.6}\n",
            r.level,
            r.tiles,
            r.leaves,
            r.splats,
            100.0 * r.splats as f64 / leaf_splats.max(1) as f64,
            r.bytes,
            r.mean_geometric_error
        );
    }
    s += &format!(
        "total: {total} splats in content tiles, {leaf_splats} in leaves, {} bytes\n",
        rows.iter().map(|r| r.bytes).sum::<u64>()
    );
    if !vrows.is_empty() {
        let util = |x: f64| {
            if x.is_finite() {
                format!("{x:.4}")
            } else {
                "-".into()
            }
        };
        s += &format!(
            "\n{:>8} {:>6} {:>10} {:>12} {:>8} {:>12} {:>13}\n",
            "variant", "tiles", "splats", "bytes", "B/splat", "mean utility", "worst utility"
        );
        for r in &vrows {
            s += &format!(
                "{:>8} {:>6} {:>10} {:>12} {:>8.2} {:>12} {:>13}\n",
                r.variant.name(),
                r.tiles,
                r.splats,
                r.bytes,
                r.bytes_per_splat(),
                util(r.mean_utility),
                util(r.worst_utility)
            );
        }
    }
    Ok(s)
}
