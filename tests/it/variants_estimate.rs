//! The utility estimate (`variants::estimate`, no renders) against the rendered utility it is
//! calibrated to (`variants::utility`): over every content tile and variant of the shared scenes
//! (data/scenes, see its README.md) and the plant with generated SH1-3.

use crate::common::*;
use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::variants::estimate::{FEATURE_NAMES, WEIGHTS, features, predicted_loss};
use splat2tiles_build::variants::utility::{Score, ViewSetup, scores, utility_of};
use splat2tiles_core::splat::Splats;
use splat2tiles_tiles::encode::storage_order::aligned_to_best;
use splat2tiles_tiles::tiling::load::load_tileset;
use splat2tiles_tiles::variants::{ALL, VariantOptions, content_uri, decode_variant, up_in_source};

/// One (tile, variant) pair: the estimate's features and the rendered utility.
#[derive(Debug, Clone)]
struct Row {
    scene: String,
    tile: String,
    variant: usize,
    features: [f64; 5],
    rendered: f64,
    /// The rendered score behind it.
    score: Score,
}

/// Every content tile of `sc` converted with all variants at `max_splats` per tile: the rows.
fn rows(name: &str, sc: splat2tiles_io::Scene, max_splats: usize) -> Vec<Row> {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ts");
    let opts = ConvertOptions {
        max_splats_per_tile: max_splats,
        variants: VariantOptions {
            variants: ALL.to_vec(),
            measure_utility: false,
            ..Default::default()
        },
        ..Default::default()
    };
    convert_scene(sc, name, &out, &opts).unwrap();
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let errors: std::collections::HashMap<_, _> = ts
        .tiles
        .iter()
        .map(|t| (t.key, t.geometric_error))
        .collect();
    let mut rows = vec![];
    for t in ts.tiles.iter().filter(|t| t.content.is_some()) {
        let decoded: Vec<(Splats, [f64; 16])> = ALL
            .iter()
            .map(|&v| {
                let glb = std::fs::read(out.join(content_uri(ts.scheme, t.key, v))).unwrap();
                decode_variant(&glb).unwrap()
            })
            .collect();
        let best = &decoded[0].0;
        // Viewed where the converter views it: at its own error, a leaf at its parent's.
        let error = if t.geometric_error > 0.0 {
            t.geometric_error
        } else {
            t.key
                .parent()
                .and_then(|p| errors.get(&p).copied())
                .unwrap_or(0.0)
        };
        let up = up_in_source(decoded[0].1);
        let Some(setup) = ViewSetup::around(best, up, error) else {
            continue;
        };
        // High and Medium are stored in Morton order: lined up with Best splat for splat.
        let aligned: Vec<Splats> = decoded[1..]
            .iter()
            .map(|d| aligned_to_best(&d.0, best).unwrap())
            .collect();
        let cands: Vec<&Splats> = aligned.iter().collect();
        let sc = scores(best, &cands, &setup.windows());
        for (i, c) in cands.iter().enumerate() {
            rows.push(Row {
                scene: name.to_string(),
                tile: format!("{}/{}/{}/{}", t.key.level, t.key.x, t.key.y, t.key.z),
                variant: i + 1,
                features: features(best, c, &setup).unwrap().to_array(),
                rendered: utility_of(sc[i]),
                score: sc[i],
            });
        }
    }
    rows
}

/// Loss (`-ln utility`, as [`predicted_loss`] predicts it; a utility below 1e-9 counts as 1e-9).
fn loss(r: &Row) -> f64 {
    -r.rendered.max(1e-9).ln()
}

/// Least squares `x` of `a x = b` over the columns in `cols` (normal equations, Gaussian
/// elimination with partial pivoting); `None` if singular.
fn least_squares(a: &[[f64; 5]], b: &[f64], cols: &[usize]) -> Option<Vec<f64>> {
    let k = cols.len();
    let mut m = vec![vec![0.0; k + 1]; k];
    for (row, &y) in a.iter().zip(b) {
        for i in 0..k {
            for j in 0..k {
                m[i][j] += row[cols[i]] * row[cols[j]];
            }
            m[i][k] += row[cols[i]] * y;
        }
    }
    for c in 0..k {
        let p = (c..k).max_by(|&i, &j| m[i][c].abs().total_cmp(&m[j][c].abs()))?;
        m.swap(c, p);
        if m[c][c].abs() < 1e-300 {
            return None;
        }
        let pivot = m[c].clone();
        for (r, row) in m.iter_mut().enumerate() {
            if r != c {
                let f = row[c] / pivot[c];
                for (v, p) in row.iter_mut().zip(&pivot).skip(c) {
                    *v -= f * p;
                }
            }
        }
    }
    Some((0..k).map(|i| m[i][k] / m[i][i]).collect())
}

/// Non-negative least squares by enumerating the column subsets (5 columns: 31 subsets).
fn nnls(a: &[[f64; 5]], b: &[f64]) -> [f64; 5] {
    let mut best = ([0.0; 5], b.iter().map(|y| y * y).sum::<f64>());
    for mask in 1u32..32 {
        let cols: Vec<usize> = (0..5).filter(|c| mask & (1 << c) != 0).collect();
        let Some(x) = least_squares(a, b, &cols) else {
            continue;
        };
        if x.iter().any(|v| *v < 0.0 || !v.is_finite()) {
            continue;
        }
        let mut w = [0.0; 5];
        for (c, v) in cols.iter().zip(x) {
            w[*c] = v;
        }
        let sse: f64 = a
            .iter()
            .zip(b)
            .map(|(r, y)| (r.iter().zip(&w).map(|(f, w)| f * w).sum::<f64>() - y).powi(2))
            .sum();
        if sse < best.1 {
            best = (w, sse);
        }
    }
    best.0
}

/// The fit's design matrix: the features (as `predicted_loss` uses them), each row divided by
/// its loss, so the fit minimises the relative error: losses span three orders of magnitude
/// (High about 1e-3, Low up to 1), and plain least squares fitted the largest ones only
/// (pooled Spearman 0.892 against the rendered utility).
fn design(rows: &[&Row]) -> (Vec<[f64; 5]>, Vec<f64>) {
    let a = rows
        .iter()
        .map(|r| {
            let y = loss(r).max(1e-9);
            r.features.map(|f| f.max(0.0) / y)
        })
        .collect();
    let b = rows.iter().map(|_| 1.0).collect();
    (a, b)
}

/// Estimated utility of a row under `w`.
fn estimate(r: &Row, w: &[f64; 5]) -> f64 {
    let f = splat2tiles_build::variants::estimate::Features {
        colour: r.features[0],
        opacity: r.features[1],
        position: r.features[2],
        scale: r.features[3],
        rotation: r.features[4],
    };
    (-predicted_loss(&f, w)).exp().clamp(0.0, 1.0)
}

/// (Spearman, mean absolute error, share of tiles in order High >= Medium >= Low) of the
/// estimate under `w` against the rendered utility over `rows`.
fn agreement(rows: &[&Row], w: &[f64; 5]) -> (f64, f64, f64) {
    let est: Vec<f64> = rows.iter().map(|r| estimate(r, w)).collect();
    let ren: Vec<f64> = rows.iter().map(|r| r.rendered).collect();
    let mae = est
        .iter()
        .zip(&ren)
        .map(|(a, b)| (a - b).abs())
        .sum::<f64>()
        / rows.len() as f64;
    let (mut tiles, mut ordered) = (0, 0);
    for chunk in est.chunks(3) {
        tiles += 1;
        ordered += (chunk[0] >= chunk[1] && chunk[1] >= chunk[2]) as usize;
    }
    (
        spearman(&est, &ren),
        mae,
        ordered as f64 / tiles.max(1) as f64,
    )
}

fn all_rows(max_splats: usize) -> Vec<Row> {
    let mut out = vec![];
    for name in ["plant.splat", "donut_fused_sh0.ply", "biker.spz"] {
        out.extend(rows(
            name,
            splat2tiles_io::read_path(&scene(name)).unwrap(),
            max_splats,
        ));
    }
    out.extend(rows("plant + SH1-3 (generated)", plant_sh3(), max_splats));
    out
}

/// Fits the weights (prints them for `WEIGHTS`), reports the stored weights' agreement with the
/// rendered utility per scene, pooled, leave-one-scene-out and at another tile size
/// (BENCHMARKS.md "Quality variants"). Run:
/// `cargo test --release --test variants_estimate -- --ignored --nocapture calibrate`.
#[test]
#[ignore = "slow (renders every tile); produces WEIGHTS and the BENCHMARKS.md table"]
fn calibrate() {
    use std::fmt::Write as _;
    let rows = all_rows(ConvertOptions::default().max_splats_per_tile);
    let refs: Vec<&Row> = rows.iter().collect();
    let (a, b) = design(&refs);
    let fitted = nnls(&a, &b);
    eprintln!("fitted weights ({FEATURE_NAMES:?}): {fitted:?}");
    let mut csv = String::from(
        "scene,tile,variant,rendered,estimated,ssim,rmse,ssim_footprint,rmse_footprint",
    );
    for n in FEATURE_NAMES {
        write!(csv, ",{n}").unwrap();
    }
    csv.push('\n');
    for r in &rows {
        write!(
            csv,
            "{},{},{},{},{},{},{},{},{}",
            r.scene,
            r.tile,
            r.variant,
            r.rendered,
            estimate(r, &WEIGHTS),
            r.score.ssim,
            r.score.rmse,
            r.score.ssim_footprint,
            r.score.rmse_footprint
        )
        .unwrap();
        for f in r.features {
            write!(csv, ",{f}").unwrap();
        }
        csv.push('\n');
    }
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    std::fs::write(dir.join("variants_estimate.csv"), &csv).unwrap();
    let mut table = String::from(
        "| rows | pairs | Spearman (estimate vs rendered) | mean abs error | tiles in order (estimate) |\n|---|---:|---:|---:|---:|\n",
    );
    let mut failures = vec![];
    let scenes: Vec<String> = {
        let mut s: Vec<String> = rows.iter().map(|r| r.scene.clone()).collect();
        s.dedup();
        s
    };
    let mut line = |label: &str, sel: &[&Row], w: &[f64; 5], check: bool| {
        let (rho, mae, ord) = agreement(sel, w);
        writeln!(
            table,
            "| {label} | {} | {rho:.3} | {mae:.4} | {:.0}% |",
            sel.len(),
            100.0 * ord
        )
        .unwrap();
        if check && (rho.is_nan() || rho < 0.9) {
            failures.push(format!("{label}: Spearman {rho:.3}"));
        }
    };
    for s in &scenes {
        let sel: Vec<&Row> = rows.iter().filter(|r| &r.scene == s).collect();
        line(s, &sel, &WEIGHTS, true);
    }
    line("all (stored WEIGHTS)", &refs, &WEIGHTS, true);
    line("all (weights refitted now)", &refs, &fitted, false);
    // Leave one scene out: fit on the others, score the one left out.
    for s in &scenes {
        let train: Vec<&Row> = rows.iter().filter(|r| &r.scene != s).collect();
        let test: Vec<&Row> = rows.iter().filter(|r| &r.scene == s).collect();
        let (a, b) = design(&train);
        let w = nnls(&a, &b);
        line(&format!("{s}, fitted without it"), &test, &w, false);
    }
    // Another tile size than the one calibrated on.
    let small = all_rows(8192);
    let small_refs: Vec<&Row> = small.iter().collect();
    line("all, tiles of <= 8192 splats", &small_refs, &WEIGHTS, true);
    std::fs::write(dir.join("variants_estimate.md"), &table).unwrap();
    eprintln!("{table}");
    assert!(failures.is_empty(), "{failures:?}");
}

/// The estimate on the donut's tiles (stored weights) ranks the variants as the renders do and
/// stays within 0.1 of the rendered utility on average.
#[test]
fn estimate_follows_the_renders_on_the_donut() {
    let name = "donut_fused_sh0.ply";
    let rows = rows(
        name,
        splat2tiles_io::read_path(&scene(name)).unwrap(),
        16384,
    );
    let refs: Vec<&Row> = rows.iter().collect();
    let (rho, mae, ord) = agreement(&refs, &WEIGHTS);
    eprintln!("donut: Spearman {rho:.3}, mean abs error {mae:.4}, in order {ord:.2}");
    assert!(rho >= 0.9 && mae <= 0.1 && ord >= 0.95, "{rho} {mae} {ord}");
}

#[test]
fn nnls_recovers_non_negative_weights() {
    let mut r = Rng(3);
    let a: Vec<[f64; 5]> = (0..40).map(|_| [0; 5].map(|_| r.range(0.0, 1.0))).collect();
    let w = [0.5, 0.0, 2.0, 0.0, 1.0];
    let b: Vec<f64> = a
        .iter()
        .map(|x| x.iter().zip(&w).map(|(f, w)| f * w).sum())
        .collect();
    let got = nnls(&a, &b);
    for (g, w) in got.iter().zip(&w) {
        assert!((g - w).abs() < 1e-9, "{got:?}");
    }
}

/// With every variant and estimated utilities, the out-of-core path (many spilled regions, one
/// thread) writes the same bytes as the in-memory one (two threads).
#[test]
fn variants_and_estimates_are_the_same_out_of_core() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("scene.ply");
    write_ply_file(&input, &random_splats(20_000, 2, 30.0, 11));
    let run = |out: &std::path::Path, threads: usize, limit: u64| {
        let opts = ConvertOptions {
            max_splats_per_tile: 2048,
            memory_limit: limit,
            variants: VariantOptions {
                variants: ALL.to_vec(),
                ..Default::default()
            },
            ..Default::default()
        };
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| splat2tiles_build::convert::convert(&input, out, &opts))
            .unwrap()
    };
    let (mem, ooc) = (tmp.path().join("mem"), tmp.path().join("ooc"));
    let a = run(&mem, 2, 4 << 30);
    let b = run(&ooc, 1, 1 << 20);
    assert_eq!(a.regions, 1);
    assert!(b.regions > 1, "{}", b.regions);
    let (fa, fb) = (tree_files(&mem), tree_files(&ooc));
    assert_eq!(fa.keys().collect::<Vec<_>>(), fb.keys().collect::<Vec<_>>());
    for (k, v) in &fa {
        assert!(v == &fb[k], "{} differs", k.display());
    }
    let ts = load_tileset(&mem.join("tileset.json")).unwrap();
    let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
    assert!(meta.values().all(|(_, _, u)| u[1] > 0.0 && u[1] < 1.0));
}
