//! The LOD hierarchy on the shared scenes: a small root, every input splat kept in the leaves,
//! importance order inside tiles, monotone geometric errors, a root of about half the tile
//! budget, and every level's cut rendering with SSIM >= 0.85 against the full scene from the level's switching distance.

use crate::common;

use crate::common::*;
use splat2tiles_build::convert::{ConvertOptions, convert};
use splat2tiles_build::lod::eval::{EvalOptions, evaluate};
use splat2tiles_core::splat::importance::{importance_scores, reference_volume};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;
use std::collections::{HashMap, HashSet};

const BUDGET: usize = 16_384;

#[test]
fn shared_scenes_hierarchy_and_quality() {
    let tmp = tempfile::tempdir().unwrap();
    for name in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        let out = tmp.path().join(name.replace('.', "_"));
        let opts = ConvertOptions {
            max_splats_per_tile: BUDGET,
            ..Default::default()
        };
        let report = convert(&scene(name), &out, &opts).expect("convert");
        let ts_path = out.join("tileset.json");
        let ts = load_tileset(&ts_path).unwrap();
        let parents: HashSet<TileKey> = ts.tiles.iter().filter_map(|t| t.key.parent()).collect();
        let count: HashMap<TileKey, u32> = ts
            .tiles
            .iter()
            .filter_map(|t| t.splat_count.map(|n| (t.key, n)))
            .collect();
        let error: HashMap<TileKey, f64> = ts
            .tiles
            .iter()
            .map(|t| (t.key, t.geometric_error))
            .collect();

        // Leaves keep every input splat; parents add their own.
        let leaf_total: u64 = count
            .iter()
            .filter(|(k, _)| !parents.contains(k))
            .map(|(_, n)| *n as u64)
            .sum();
        assert_eq!(leaf_total as usize, report.splats_in, "{name}: leaf splats");
        assert_eq!(report.splats_out, report.splats_in);
        // A parent with content is a level of detail within the budget and with a geometric
        // error above its children's, but for a pass-through child (no content, one child),
        // which carries its parent's (spec/georeferencing.md "Levels").
        common::assert_levels_complete(&ts);
        let mut lod_parents = 0;
        for p in &parents {
            let with_content = count.get(p).copied();
            if let Some(n) = with_content {
                lod_parents += 1;
                assert!(
                    n >= 1 && n as usize <= BUDGET,
                    "{name}: parent {p:?} holds {n}"
                );
            }
            for t in ts.tiles.iter().filter(|t| t.key.parent() == Some(*p)) {
                assert!(
                    error[p] > t.geometric_error
                        || (t.content.is_none() && error[p] == t.geometric_error),
                    "{name}: {p:?} error {} <= child {:?} {}",
                    error[p],
                    t.key,
                    t.geometric_error
                );
            }
        }
        assert!(lod_parents > 0, "{name}: no LOD level at all");
        // The coarsest content holds a small part of the input.
        let coarsest = ts
            .tiles
            .iter()
            .filter(|t| t.splat_count.is_some())
            .min_by_key(|t| t.key.level)
            .unwrap();
        let root = coarsest.splat_count.unwrap() as f64 / report.splats_in as f64;
        println!(
            "{name}: coarsest content {:?} holds {} of {} splats ({:.2}%), r = {:.4}",
            coarsest.key,
            coarsest.splat_count.unwrap(),
            report.splats_in,
            100.0 * root,
            report.lod_radius
        );
        // The count-target rule aims an inner parent at min(half the tile budget, 0.8 x a quarter
        // of its input) (lod::target_count) and the root at its cap, min(budget, a quarter of its
        // input) (lod::count_cap): its input is the content of the nearest content descendants
        // (whose nearest content ancestor it is).
        let kept = coarsest.splat_count.unwrap() as usize;
        let has_content: std::collections::HashMap<_, _> = ts
            .tiles
            .iter()
            .filter_map(|t| t.splat_count.map(|n| (t.key, n as usize)))
            .collect();
        let input: usize = has_content
            .iter()
            .filter(|(k, _)| {
                let mut a = k.parent();
                while let Some(p) = a {
                    if has_content.contains_key(&p) {
                        return p == coarsest.key;
                    }
                    a = p.parent();
                }
                false
            })
            .map(|(_, n)| *n)
            .sum();
        // It may hold fewer than its aim (its radius is at least 1.25x its children's, so errors
        // grow upwards), never more than the cap, and more than a token handful.
        let aim = splat2tiles_build::lod::target_count(input, BUDGET);
        let cap = splat2tiles_build::lod::count_cap(input, BUDGET);
        assert!(
            (1000..=cap).contains(&kept),
            "{name}: the coarsest content holds {kept} splats of {input} input (aim {aim}, cap {cap})"
        );
        // A root directly over the leaves holds up to a quarter of the input (its cap; the donut
        // measured 23.76%; it was under 20% while the root aimed at 0.8 of the cap).
        assert!(
            root <= splat2tiles_build::lod::MAX_KEEP + 1.0 / report.splats_in as f64,
            "{name}: the coarsest content holds {:.2}% of the input",
            100.0 * root
        );

        // Importance order inside every tile (leaves and parents).
        for (key, leaf) in decode_tileset(&ts_path) {
            let s = &leaf.splats;
            let sc = importance_scores(s, reference_volume(s));
            assert!(
                sc.windows(2).all(|w| w[0] >= w[1]),
                "{name}: tile {key:?} not in descending importance"
            );
        }

        // Every level's cut against all leaves, from the level's switching distance.
        let opts = EvalOptions {
            parent_pairs: false,
            ..EvalOptions::default()
        };
        let q = evaluate(&ts_path, &opts).expect("evaluate");
        let mut levels = 0;
        for l in &q {
            let Some(s) = l.cut_ssim_min else { continue };
            levels += 1;
            println!(
                "{name}: level {} ({} splats): cut SSIM mean {:.4} min {s:.4} at {:.3}",
                l.row.level,
                l.row.splats,
                l.cut_ssim.unwrap(),
                l.cut_distance.unwrap()
            );
            assert!(s >= 0.85, "{name}: level {} cut SSIM {s}", l.row.level);
        }
        assert!(levels >= 1, "{name}: at least one LOD level measured");
    }
}

#[test]
fn stats_prints_the_per_level_table() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("g.ply");
    write_ply_file(&ply, &random_splats(6000, 1, 10.0, 5));
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        max_splats_per_tile: 500,
        ..Default::default()
    };
    let r = convert(&ply, &out, &opts).unwrap();
    assert!(r.parent_splats > 0);
    let o = std::process::Command::new(bin())
        .args([
            "stats",
            out.join("tileset.json").to_str().unwrap(),
            "--json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["leafSplats"], 6000);
    let levels = v["levels"].as_array().unwrap();
    assert_eq!(levels.len() as u32, r.levels);
    assert_eq!(levels[0]["tiles"], 1);
    let total: u64 = levels.iter().map(|l| l["splats"].as_u64().unwrap()).sum();
    assert_eq!(total as usize, 6000 + r.parent_splats);
    let text = std::process::Command::new(bin())
        .args(["stats", out.join("tileset.json").to_str().unwrap()])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&text.stdout);
    let (level_part, variant_part) = text.split_once("\n\n").expect("two tables");
    assert!(
        level_part.contains("mean geo error") && level_part.lines().count() == levels.len() + 2
    );
    // The default conversion writes the Best variant only: one row after the header.
    assert!(variant_part.contains("mean utility") && variant_part.lines().count() == 2);
    let variants = v["variants"].as_array().unwrap();
    assert_eq!(variants.len(), 1);
    assert_eq!(variants[0]["variant"], "best");
    assert_eq!(
        variants[0]["splats"].as_u64().unwrap() as usize,
        6000 + r.parent_splats
    );
    // The output folder names its tileset.json; a missing file is named once, with the reason.
    let dir = std::process::Command::new(bin())
        .args(["stats", out.to_str().unwrap(), "--json"])
        .output()
        .unwrap();
    assert_eq!(dir.stdout, o.stdout);
    let missing = out.join("nothing.json");
    let m = std::process::Command::new(bin())
        .args(["stats", missing.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!m.status.success() && m.stdout.is_empty());
    let err = String::from_utf8_lossy(&m.stderr);
    assert_eq!(err.matches("nothing.json").count(), 1, "{err}");
}

#[test]
fn no_lod_keeps_parents_empty_and_merge_rules_are_selectable() {
    let tmp = tempfile::tempdir().unwrap();
    let ply = tmp.path().join("g.ply");
    write_ply_file(&ply, &random_splats(3000, 0, 10.0, 9));
    for (args, expect_parents) in [
        (vec!["--no-lod"], false),
        (vec!["--lod-merge", "axis"], true),
        (vec!["--lod-merge", "moment", "--lod-radius", "0.5"], true),
    ] {
        let out = tmp.path().join(format!("o{}", args.len()));
        let mut cmd = std::process::Command::new(bin());
        cmd.args([
            "convert",
            ply.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ])
        .args(["--max-splats", "400", "--json"])
        .args(&args);
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(v["splatsOut"], 3000);
        assert_eq!(
            v["parentSplats"].as_u64().unwrap() > 0,
            expect_parents,
            "{args:?}"
        );
        if args.contains(&"--lod-radius") {
            assert_eq!(v["lodRadius"], 0.5);
        }
    }
}
