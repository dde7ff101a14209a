//! The utilities `convert --variants all` stores (estimated when each tile is written, at a grid
//! of viewing distances, and interpolated at its switching distance: `variants::curve`) against
//! the same estimate computed from the tiles read back at that distance, over every content tile
//! of the shared scenes (data/scenes, see its README.md) and the plant with generated SH1-3.

use crate::common::*;
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::variants::estimate::estimated_utilities;
use splat2tiles_build::variants::utility::ViewSetup;
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::storage_order::aligned_to_best;
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_tiles::variants::{
    ALL, VariantOptions, content_uri, content_variant_metadata, decode_variant, up_in_source,
};

/// Per (tile, variant) of `sc` converted with every variant: (stored utility, utility estimated
/// from the files read back at the tile's switching distance).
fn stored_and_read_back(
    name: &str,
    sc: splat2tiles_io::Scene,
    max_splats: usize,
) -> Vec<(f64, f64)> {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        max_splats_per_tile: max_splats,
        variants: VariantOptions {
            variants: ALL.to_vec(),
            ..Default::default()
        },
        ..Default::default()
    };
    convert_scene(sc, name, &out, &opts).unwrap();
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let meta = content_variant_metadata(&ts);
    let errors: std::collections::HashMap<_, _> = ts
        .tiles
        .iter()
        .map(|t| (t.key, t.geometric_error))
        .collect();
    let mut pairs = vec![];
    for t in ts.tiles.iter().filter(|t| t.content.is_some()) {
        let decoded: Vec<(Splats, [f64; 16])> = ALL
            .iter()
            .map(|&v| {
                let glb = std::fs::read(out.join(content_uri(ts.scheme, t.key, v))).unwrap();
                decode_variant(&glb).unwrap()
            })
            .collect();
        let error = if t.geometric_error > 0.0 {
            t.geometric_error
        } else {
            t.key
                .parent()
                .and_then(|p| errors.get(&p).copied())
                .unwrap_or(0.0)
        };
        let best = &decoded[0].0;
        let setup = ViewSetup::around(best, up_in_source(decoded[0].1), error).unwrap();
        // High and Medium are stored in Morton order: lined up with Best splat for splat.
        let aligned: Vec<Splats> = decoded[1..]
            .iter()
            .map(|d| aligned_to_best(&d.0, best).unwrap())
            .collect();
        let cands: Vec<&Splats> = aligned.iter().collect();
        let read_back = estimated_utilities(best, &cands, &setup);
        let stored = meta[&t.key].2;
        let x = setup.eye_distance() / splat2tiles_core::camera::box_radius(setup.lo, setup.hi);
        for (i, r) in read_back.iter().enumerate() {
            if std::env::var_os("CURVE_DEBUG").is_some() {
                eprintln!(
                    "x {x:.3} variant {} stored {} read back {r} splats {}",
                    i + 1,
                    stored[i + 1],
                    best.len()
                );
            }
            pairs.push((stored[i + 1] as f64, *r));
        }
    }
    pairs
}

#[test]
fn stored_utilities_match_the_read_back_estimate() {
    let inputs = [
        (
            "plant.splat",
            splat2tiles_io::read_path(&scene("plant.splat")).unwrap(),
        ),
        (
            "donut_fused_sh0.ply",
            splat2tiles_io::read_path(&scene("donut_fused_sh0.ply")).unwrap(),
        ),
        (
            "biker.spz",
            splat2tiles_io::read_path(&scene("biker.spz")).unwrap(),
        ),
        ("plant + SH1-3 (generated)", plant_sh3()),
    ];
    let mut failures = vec![];
    for (name, sc) in inputs {
        // The default tile size and a small one (more tiles, leaves far from their parents).
        for max_splats in [65536, 4096] {
            let pairs = stored_and_read_back(name, sc.clone(), max_splats);
            let (s, r): (Vec<f64>, Vec<f64>) = pairs.iter().copied().unzip();
            let rho = spearman(&s, &r);
            // Relative error of the loss (-ln u), where the loss is not negligible.
            let worst_loss = pairs
                .iter()
                .filter(|(_, r)| *r < 1.0 - 1e-6)
                .map(|(s, r)| (s.ln() / r.ln() - 1.0).abs())
                .fold(0.0, f64::max);
            let worst_abs = pairs.iter().map(|(s, r)| (s - r).abs()).fold(0.0, f64::max);
            eprintln!(
                "{name}, max {max_splats} splats/tile: {} pairs, Spearman {rho:.4}, worst |u - u_read_back| {worst_abs:.2e}, worst relative loss error {worst_loss:.3}",
                pairs.len()
            );
            if rho < 0.999 || worst_loss > 0.05 || worst_abs > 0.002 {
                failures.push(format!(
                    "{name} ({max_splats}): Spearman {rho:.4}, worst abs {worst_abs:.2e}, worst relative loss {worst_loss:.3}"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
