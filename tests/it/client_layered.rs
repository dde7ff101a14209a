//! The streaming client on a layered tileset (`spec/layered-content.md`): streamed through the
//! simulated transport it draws the reference renderer's layered selection (same layers, same
//! blend factors, same effective opacities), fetches Best only, and never draws a layer whose
//! ancestor layer is missing.

use crate::common;

use splat2tiles_build::convert::{ConvertOptions, SchemeChoice, convert};
use splat2tiles_core::camera::{Camera, auto_views_with};
use splat2tiles_lab::sim::transport::{NetModel, SimTransport};
use splat2tiles_stream::Level;
use splat2tiles_stream::client::{Action, ClientConfig, StreamClient};
use splat2tiles_tiles::geometry::{tileset_bounds, tileset_up};
use splat2tiles_tiles::layers::view::{layered_instances, select_layers};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{LoadedTileset, load_tileset};
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

/// A generated SH-1 scene (6000 splats, 400 per leaf, two levels per subtree file) converted
/// with `--layers`; returns the tileset folder.
fn layered(dir: &Path) -> PathBuf {
    let ply = dir.join("scene.ply");
    common::write_ply_file(&ply, &common::random_splats(6000, 1, 10.0, 7));
    let out = dir.join("layered");
    let opts = ConvertOptions {
        max_splats_per_tile: 400,
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    };
    convert(&ply, &out, &opts).expect("convert");
    out
}

fn config(max_sse: f64) -> ClientConfig {
    ClientConfig {
        width: 320,
        height: 180,
        max_sse,
        frustum_cull: false,
        ..ClientConfig::default()
    }
}

/// Runs the client with a fixed camera for `seconds` over a fast link; calls `each` after every
/// update (10 Hz).
fn stream(
    dir: &Path,
    cfg: ClientConfig,
    cam: &Camera,
    seconds: f64,
    mut each: impl FnMut(&StreamClient),
) -> (StreamClient, SimTransport) {
    let mut net = SimTransport::new(dir, NetModel::constant(50.0, 0.02));
    let mut client = StreamClient::new(&net.tileset_url(), cfg);
    let mut t = 0.0;
    while t <= seconds {
        while let Some(d) = net.next(t) {
            let input = d.into_input();
            let a: Vec<Action> = input.apply(&mut client);
            net.apply(&a);
        }
        let a = client.update(t, cam);
        net.apply(&a);
        each(&client);
        t += 0.1;
    }
    (client, net)
}

/// A camera and a threshold at which the reference selection is at least three levels deep
/// and blends some layer partly in.
fn interesting_view(ts: &LoadedTileset) -> (Camera, f64) {
    let (lo, hi) = tileset_bounds(ts).unwrap();
    for view in auto_views_with(lo, hi, tileset_up(ts), 320, 180, 50.0) {
        for max_sse in [40.0, 24.0, 16.0, 10.0, 6.0, 4.0] {
            let sel = select_layers(ts, &view, max_sse);
            let deep = sel.iter().any(|l| l.key.level >= 2);
            let partial = sel.iter().any(|l| l.blend > 0.0 && l.blend < 1.0);
            if deep && partial {
                return (view, max_sse);
            }
        }
    }
    panic!("no view blends a layer of level 2 in");
}

fn reference(ts: &LoadedTileset, cam: &Camera, max_sse: f64) -> BTreeSet<(TileKey, u32)> {
    select_layers(ts, cam, max_sse)
        .iter()
        .map(|l| (l.key, l.blend.to_bits()))
        .collect()
}

#[test]
fn streamed_layers_reach_the_reference_renderers_drawn_set() {
    let dir = tempfile::tempdir().unwrap();
    let out = layered(dir.path());
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let (cam, max_sse) = interesting_view(&ts);
    let want = reference(&ts, &cam, max_sse);
    let mut orphan = None;
    let (client, net) = stream(&out, config(max_sse), &cam, 20.0, |c| {
        // Every drawn layer's parent is drawn, before it.
        for (k, l) in c.layers().iter().enumerate() {
            if l.parent.is_none_or(|p| p >= k) && l.key != TileKey::ROOT {
                orphan = Some(l.key);
            }
        }
    });
    assert_eq!(orphan, None, "a layer was drawn without its parent");
    assert!(client.is_layered());
    assert_eq!(client.stats().errors, 0, "{:?}", client.stats().last_errors);
    let got: BTreeSet<(TileKey, u32)> = client
        .layers()
        .iter()
        .map(|l| (l.key, l.blend.to_bits()))
        .collect();
    assert_eq!(got, want);
    // Variants do not apply: every content request is for the Best file.
    for r in net.log() {
        if r.url.ends_with(".glb") {
            assert!(
                !r.url.contains("/low/") && !r.url.contains("/medium/"),
                "{}",
                r.url
            );
        }
    }
    assert!(client.resident().iter().all(|(_, l)| *l == Level::Best));
    // The effective opacities are the reference renderer's: the same splats survive the
    // occupancy rule, with the same opacities (in drawing order per layer).
    let ops = client.layer_opacities().unwrap();
    let mut mine: Vec<f32> = ops.iter().flat_map(|(_, o)| o.clone()).collect();
    mine.retain(|&o| o > 0.0);
    let mut theirs: Vec<f32> = layered_instances(&ts, &cam, max_sse)
        .unwrap()
        .iter()
        .flat_map(|(s, _)| s.opacities.clone())
        .collect();
    mine.sort_by(f32::total_cmp);
    theirs.sort_by(f32::total_cmp);
    assert_eq!(mine.len(), theirs.len());
    assert_eq!(mine, theirs);
    // A viewer's own blend factors (`layer_opacities_of`): the client's give the same result;
    // every child at 0 leaves the base at its stored opacities; a parent index that is not an
    // earlier layer, or an unknown drawable, is an error naming the tile, not a panic.
    let mut layers = client.layers();
    assert_eq!(client.layer_opacities_of(&layers).unwrap(), ops);
    for l in &mut layers[1..] {
        l.blend = 0.0;
    }
    let base = &client.layer_opacities_of(&layers).unwrap()[0];
    assert!(base.1.iter().any(|&o| o > 0.0));
    let mut bad = client.layers();
    let last = bad.len() - 1;
    bad[last].parent = Some(last + 5);
    let e = client.layer_opacities_of(&bad).unwrap_err();
    assert!(e.contains(&format!("{:?}", bad[last].key)), "{e}");
    bad[last].parent = Some(0);
    bad[last].scene_id = u64::MAX;
    assert!(
        client
            .layer_opacities_of(&bad)
            .unwrap_err()
            .contains("not decoded")
    );
}

#[test]
fn a_layer_whose_ancestor_is_missing_is_never_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let out = layered(dir.path());
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let (cam, max_sse) = interesting_view(&ts);
    let sel = select_layers(&ts, &cam, max_sse);
    // A level-1 layer with drawn children: its file goes missing (404).
    let gone = sel
        .iter()
        .find(|l| l.key.level == 1 && sel.iter().any(|c| c.key.parent() == Some(l.key)))
        .expect("a level-1 layer with children in the selection")
        .clone();
    std::fs::remove_file(&gone.path).unwrap();
    let below = |k: TileKey| {
        let mut a = k.parent();
        while let Some(p) = a {
            if p == gone.key {
                return true;
            }
            a = p.parent();
        }
        false
    };
    let mut drawn_below = 0;
    let mut resident_below = 0;
    let (client, _) = stream(&out, config(max_sse), &cam, 20.0, |c| {
        drawn_below += c
            .layers()
            .iter()
            .filter(|l| l.key == gone.key || below(l.key))
            .count();
        resident_below += c.resident().iter().filter(|(k, _)| below(*k)).count();
    });
    assert!(
        resident_below > 0,
        "no descendant of the missing layer was ever held: the test would prove nothing"
    );
    assert_eq!(drawn_below, 0, "a layer was drawn over a missing ancestor");
    // The rest of the selection is drawn.
    let drawn: BTreeSet<TileKey> = client.layers().iter().map(|l| l.key).collect();
    for l in &sel {
        if l.key != gone.key && !below(l.key) {
            assert!(drawn.contains(&l.key), "{:?} not drawn", l.key);
        }
    }
    assert!(client.stats().errors > 0);
}

/// A LapisGS import (format v2: ancestor deltas, sparse accessors, positive deltas) streamed
/// through the client: the same layers as the reference selection, the same effective
/// opacities as the CPU reference (`layered_instances`), and fully refined, every splat of the
/// last level's file at its opacity there.
#[test]
fn a_lapisgs_import_streams_with_the_reference_opacities() {
    use splat2tiles_build::convert::import_lapisgs;
    let dir = tempfile::tempdir().unwrap();
    let (lv, files) = common::lapis::dense(dir.path());
    let out = dir.path().join("lapis");
    let opts = ConvertOptions {
        scheme: SchemeChoice::Octree,
        subtree_levels: Some(2),
        layers: true,
        progress: None,
        ..ConvertOptions::default()
    };
    import_lapisgs(&files, &out, &opts).unwrap();
    let ts = load_tileset(&out.join("tileset.json")).unwrap();
    let (cam, max_sse) = interesting_view(&ts);
    let sorted = |mut v: Vec<f32>| {
        v.retain(|&o| o > 0.0);
        v.sort_by(f32::total_cmp);
        v
    };
    for (max_sse, full) in [(max_sse, false), (1e-9, true)] {
        let (client, _) = stream(&out, config(max_sse), &cam, 20.0, |_| {});
        assert_eq!(client.stats().errors, 0, "{:?}", client.stats().last_errors);
        let got: BTreeSet<(TileKey, u32)> = client
            .layers()
            .iter()
            .map(|l| (l.key, l.blend.to_bits()))
            .collect();
        assert_eq!(got, reference(&ts, &cam, max_sse));
        let mine = sorted(
            client
                .layer_opacities()
                .unwrap()
                .into_iter()
                .flat_map(|(_, o)| o)
                .collect(),
        );
        let theirs = sorted(
            layered_instances(&ts, &cam, max_sse)
                .unwrap()
                .iter()
                .flat_map(|(s, _)| s.opacities.clone())
                .collect(),
        );
        assert_eq!(mine, theirs);
        if full {
            // Every layer drawn at blend 1: the last level's opacities (occupancy rule applied).
            assert_eq!(
                client.layers().len(),
                ts.tiles.iter().filter(|t| t.content.is_some()).count()
            );
            let want = sorted(
                lv[2]
                    .opacities
                    .iter()
                    .map(|&o| {
                        if o < splat2tiles_tiles::layers::OCCUPANCY_THRESHOLD {
                            0.0
                        } else {
                            o
                        }
                    })
                    .collect(),
            );
            assert_eq!(mine.len(), want.len());
            for (a, b) in mine.iter().zip(&want) {
                assert!((a - b).abs() <= 1e-5, "{a} vs {b}");
            }
        }
    }
}
