//! The count-target LOD rule: every level of a generated city is a real reduction and the
//! coarsest holds more than a token handful; `build_parent` is deterministic whatever the thread
//! count; degenerate inputs give finite, sensible parents.

use crate::common;

use splat2tiles_build::convert::{ConvertOptions, convert_scene};
use splat2tiles_build::lod::eval::level_table;
use splat2tiles_build::lod::{
    ChildContent, MergeRule, ParentParams, ParentTile, build_parent, target_count,
};
use splat2tiles_core::frame::UpAxis;
use splat2tiles_core::splat::{Splat, Splats};
use splat2tiles_lab::city::{CityLayout, city_scene, generate_city, shared_sources};
use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::load_tileset;

fn params(budget: usize) -> ParentParams {
    ParentParams {
        leaf_radius: 0.01,
        levels_above_deepest: 1,
        budget,
        rule: MergeRule::Moment,
        // Single children cluster too: the degenerate-input checks exercise the clustering.
        pass_through: false,
    }
}

/// A deterministic pseudo-random cloud of `n` splats on a 10 x 10 x 1 slab.
fn cloud(n: usize, seed: u64) -> Splats {
    let mut s = Splats::new(0);
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut r = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..n {
        s.push(
            Splat {
                position: [r() * 10.0, r() * 10.0, r()],
                scale: [0.02 + r() as f32 * 0.05, 0.03, 0.01],
                rotation: [0.0, 0.0, (r() as f32 - 0.5), 1.0],
                opacity: r() as f32,
                sh0: [r() as f32, r() as f32, r() as f32],
            },
            &[],
        );
    }
    s
}

fn parent_of(children: &[Splats], budget: usize) -> ParentTile {
    let kids: Vec<ChildContent<'_>> = children
        .iter()
        .map(|s| ChildContent {
            splats: s,
            radius: 0.0,
        })
        .collect();
    build_parent(INNER, 0, &kids, &params(budget))
}

/// A parent below the root (the root aims at its cap instead of the target).
const INNER: TileKey = TileKey {
    level: 1,
    x: 0,
    y: 0,
    z: 0,
};

fn bits(s: &Splats) -> Vec<u64> {
    let mut v = Vec::new();
    for i in 0..s.len() {
        v.extend(s.positions[i].iter().map(|c| c.to_bits()));
        v.extend(s.scales[i].iter().map(|c| c.to_bits() as u64));
        v.extend(s.rotations[i].iter().map(|c| c.to_bits() as u64));
        v.push(s.opacities[i].to_bits() as u64);
        v.extend(s.sh0[i].iter().map(|c| c.to_bits() as u64));
    }
    v
}

fn assert_finite(p: &ParentTile, what: &str) {
    assert!(
        p.radius.is_finite() && p.radius > 0.0,
        "{what}: radius {}",
        p.radius
    );
    assert!(p.mean_displacement.is_finite(), "{what}");
    for i in 0..p.splats.len() {
        assert!(
            p.splats.is_finite(i),
            "{what}: splat {i} {:?}",
            p.splats.get(i)
        );
    }
}

#[test]
fn build_parent_hits_its_target_and_is_deterministic_across_thread_counts() {
    let children: Vec<Splats> = (0..4).map(|i| cloud(6000, i + 1)).collect();
    let budget = 4096;
    let a = parent_of(&children, budget);
    let target = target_count(24_000, budget);
    assert_eq!(target, 2048);
    assert_eq!(splat2tiles_build::lod::count_cap(24_000, budget), 4096);
    let n = a.splats.len();
    // One radius from the occupancy estimate (corrected once): near the target, within budget.
    assert!(
        n <= budget && n as f64 >= target as f64 / 2.0 && n as f64 <= target as f64 * 2.0,
        "{n} splats for a target of {target}"
    );
    assert_finite(&a, "cloud");
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| bits(&parent_of(&children, budget).splats))
    };
    let one = run(1);
    assert_eq!(one, bits(&a.splats));
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
    // The order of the children is part of the input; the content is still near the target.
    let mut rev = children.clone();
    rev.reverse();
    let b = parent_of(&rev, budget);
    assert!(b.splats.len() <= budget);
}

#[test]
fn the_root_aims_at_its_cap() {
    // Same input as above: an inner parent aims at 2048 splats, the root (the coarsest level,
    // shown from every distance beyond its switching distance) at its cap of 4096, so it is
    // finer and switches nearer.
    let children: Vec<Splats> = (0..4).map(|i| cloud(6000, i + 1)).collect();
    let kids: Vec<ChildContent<'_>> = children
        .iter()
        .map(|s| ChildContent {
            splats: s,
            radius: 0.0,
        })
        .collect();
    let budget = 4096;
    let cap = splat2tiles_build::lod::count_cap(24_000, budget);
    let root = build_parent(TileKey::ROOT, 0, &kids, &params(budget));
    let inner = build_parent(INNER, 0, &kids, &params(budget));
    let (r, i) = (root.splats.len(), inner.splats.len());
    assert!(
        r <= cap && r as f64 >= 0.75 * cap as f64,
        "root: {r} splats, cap {cap}"
    );
    assert!(2 * r > 3 * i, "root {r} splats, inner parent {i}");
    assert!(
        root.radius < inner.radius,
        "{} {}",
        root.radius,
        inner.radius
    );
    assert_finite(&root, "root");
}

#[test]
fn parent_radius_grows_over_its_children() {
    let children: Vec<Splats> = (0..4).map(|i| cloud(500, i + 7)).collect();
    let kids: Vec<ChildContent<'_>> = children
        .iter()
        .map(|s| ChildContent {
            splats: s,
            radius: 0.3,
        })
        .collect();
    let p = build_parent(TileKey::ROOT, 0, &kids, &params(32_768));
    assert!(
        p.radius >= 0.375,
        "error {} under 1.25 x the children's",
        p.radius
    );
    // At most a quarter of the input (lod::MAX_KEEP) whatever the budget.
    assert!(p.splats.len() <= 500, "{}", p.splats.len());
}

#[test]
fn degenerate_inputs_give_finite_sensible_parents() {
    let one = |position: [f64; 3], scale: [f32; 3], opacity: f32| Splat {
        position,
        scale,
        rotation: [0.0, 0.0, 0.0, 1.0],
        opacity,
        sh0: [0.5, 0.25, 0.0],
    };
    let mut coincident = Splats::new(0);
    for _ in 0..5000 {
        coincident.push(one([3.0, 4.0, 5.0], [0.1, 0.1, 0.1], 0.7), &[]);
    }
    let p = parent_of(&[coincident.clone(), coincident], 1024);
    assert_finite(&p, "coincident");
    assert_eq!(p.splats.len(), 1, "coincident splats merge into one");
    assert_eq!(p.splats.positions[0], [3.0, 4.0, 5.0]);

    let mut single = Splats::new(0);
    single.push(one([1.0, 2.0, 3.0], [0.1, 0.2, 0.3], 0.5), &[]);
    let p = parent_of(&[single.clone()], 1024);
    assert_finite(&p, "one splat");
    assert_eq!(p.splats, single);

    let mut scales = Splats::new(0);
    for i in 0..400 {
        let s = if i % 2 == 0 { 1e30 } else { 1e-30 };
        scales.push(one([i as f64 * 0.01, 0.0, 0.0], [s, s, s], 0.5), &[]);
    }
    let p = parent_of(&[scales], 1024);
    assert_finite(&p, "huge and tiny scales");
    assert!(p.splats.len() <= 200);

    let mut transparent = cloud(3000, 99);
    transparent.opacities.iter_mut().for_each(|a| *a = 0.0);
    let p = parent_of(&[transparent], 1024);
    assert_finite(&p, "opacity 0");
    assert!(!p.splats.is_empty() && p.splats.len() <= 1024);
    assert!(p.splats.opacities.iter().all(|&a| a == 0.0));

    let p = parent_of(&[Splats::new(0)], 1024);
    assert!(p.splats.is_empty());
}

#[test]
fn every_level_of_a_generated_city_is_a_real_reduction() {
    // 600,000 splats of displaced, rotated, scaled copies of the shared scenes
    // (data/scenes/README.md), 8192 splats per tile.
    let sources = shared_sources(&common::scenes()).unwrap();
    let n = 600_000;
    let city = generate_city(
        &sources,
        &CityLayout {
            splats: n,
            ..CityLayout::default()
        },
    );
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("city");
    let opts = ConvertOptions {
        max_splats_per_tile: 8192,
        up_axis: Some(UpAxis::PosZ),
        ..ConvertOptions::default()
    };
    let r = convert_scene(city_scene(city), "city", &out, &opts).unwrap();
    let rows = level_table(&load_tileset(&out.join("tileset.json")).unwrap()).unwrap();
    for row in &rows {
        println!(
            "level {}: {} tiles ({} leaves), {} splats ({:.2}%)",
            row.level,
            row.tiles,
            row.leaves,
            row.splats,
            100.0 * row.splats as f64 / n as f64
        );
    }
    let coarsest = &rows[0];
    assert_eq!(coarsest.level, 0, "the root holds a level of detail");
    assert!(
        coarsest.splats >= 1000,
        "the coarsest level holds a token {} splats",
        coarsest.splats
    );
    assert!(
        (coarsest.splats as f64) < 0.02 * n as f64,
        "the coarsest level holds {} of {n}",
        coarsest.splats
    );
    // Every level's parents hold at most 30% of their children's splats, and every level with
    // parents holds less than the next finer one.
    for w in rows.windows(2) {
        if w[0].parent_tiles > 0 {
            assert!(
                w[0].parent_splats as f64 <= 0.3 * w[0].children_splats as f64,
                "level {}: parents {} of their children's {}",
                w[0].level,
                w[0].parent_splats,
                w[0].children_splats
            );
            if w[0].leaves == 0 {
                assert!(w[0].splats < w[1].splats, "level {} grows", w[0].level);
            }
        }
    }
    // Parent splats are a bounded share of the input.
    assert!(
        (r.parent_splats as f64) < 0.5 * n as f64,
        "parents hold {} of {n}",
        r.parent_splats
    );
}

#[test]
fn a_single_child_below_the_root_passes_through_unless_layered() {
    let child = cloud(3000, 7);
    let kids = [ChildContent {
        splats: &child,
        radius: 0.5,
    }];
    let passing = ParentParams {
        pass_through: true,
        ..params(1024)
    };
    let p = build_parent(INNER, 0, &kids, &passing);
    assert_eq!(p.splats, child, "content goes up unchanged");
    assert_eq!(
        (p.radius, p.passed_through),
        (0.5, true),
        "and so does the error"
    );
    let q = build_parent(INNER, 0, &kids, &params(1024));
    assert!(
        q.splats.len() < child.len() && q.radius > 0.5,
        "a layer of its own"
    );
    // The root always clusters (it is written whatever its children).
    let r = build_parent(TileKey::ROOT, 0, &kids, &passing);
    assert!(r.splats.len() < child.len());
}
