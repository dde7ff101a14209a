//! The fewest first-time entries after the warm-up that any client can miss when it draws its
//! first view first, on the city experiment's traces of a split (the bound behind the oracle's
//! validation figure in BENCHMARKS.md, "Robust planning"): the link carries the first cut at Low
//! until the warm-up ends (`sim::score::link_warm_up`, by its definition), then, with perfect
//! foresight, no round trips and every tile at Low, Moore-Hodgson over the later first-time
//! entries (each due at its entry tick) gives the fewest late ones.
//! `STREAM_CITY_DIR=DIR cargo run --release -p splat2tiles-lab --example warm_bound -- test|val`
//! (DIR from `cargo run --release -p splat2tiles-lab --example stream_city -- DIR`).
//! `FROM0=1`: the link free from the first tick (no first view at all); `COVER_UP=N`: the first
//! view drawn by the ancestors N levels above the first cut's tiles (at Low) before anything
//! else, the bound for a client that covers its first view coarsely first.

use splat2tiles_lab::experiments::simulate_city::{label, pick_traces, table4_traces};
use splat2tiles_lab::sim::score::Truth;
use splat2tiles_lab::sim::stream_city::{
    CitySpec, NAVIGATION_DIR, StreetGrid, city_sources, evaluation_set, trace_set,
};
use splat2tiles_stream::client::ClientConfig;
use splat2tiles_stream::split::Split;
use std::collections::{BinaryHeap, HashSet};
use std::path::{Path, PathBuf};

/// 10 Mbit/s and 40 ms, as the experiment's link.
const RATE: f64 = 1.25e6;
const RTT: f64 = 0.04;

fn main() {
    let dir = PathBuf::from(std::env::var("STREAM_CITY_DIR").expect("STREAM_CITY_DIR"));
    let spec = CitySpec::default();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/scenes");
    let sources = city_sources(&scenes, spec.stride).expect("scenes");
    let grid = StreetGrid::of(&sources, &spec.layout());
    let truth = Truth::load(&dir.join("tileset.json")).expect("city");
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json")).unwrap();
    let meta = splat2tiles_tiles::variants::content_variant_metadata(&ts);
    let low = |k: &splat2tiles_tiles::tiling::TileKey| meta.get(k).map_or(0, |m| m.1[3] as u64);
    let nav = Path::new(NAVIGATION_DIR);
    let traces = match std::env::args().nth(1).as_deref() {
        Some("val") => pick_traces(&trace_set(&grid, nav, Split::Val).unwrap()),
        Some("test") => table4_traces(&evaluation_set(&grid, nav).unwrap()),
        _ => {
            eprintln!("usage: warm_bound test|val (with STREAM_CITY_DIR set)");
            std::process::exit(2);
        }
    };
    let cfg = ClientConfig::default();
    println!("| trace | warm-up (s) | first-time entries after it | fewest late | at most held |");
    println!("|---|---:|---:|---:|---:|");
    let (mut all_n, mut all_late) = (0usize, 0usize);
    for tr in traces {
        let needed: Vec<Vec<_>> = tr.poses.iter().map(|p| truth.needed_at(&cfg, p)).collect();
        let Some(first) = needed.iter().position(|n| !n.is_empty()) else {
            continue;
        };
        let cut_bytes: u64 = needed[first].iter().map(&low).sum();
        let warm = tr.poses[first].t + RTT + cut_bytes as f64 / RATE;
        // Later first-time entries: (due, Low bytes).
        let mut ever: HashSet<_> = needed[first].iter().copied().collect();
        let mut jobs = vec![];
        for (p, cut) in tr.poses.iter().zip(&needed).skip(first + 1) {
            for k in cut {
                if ever.insert(*k) && p.t > warm {
                    jobs.push((p.t, low(k)));
                }
            }
        }
        // Moore-Hodgson: earliest due first; whenever the kept jobs miss the current due, the
        // largest kept one is dropped (late).
        jobs.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut kept = BinaryHeap::new();
        let (mut load, mut late) = (0u64, 0usize);
        for &(due, bytes) in &jobs {
            kept.push(bytes);
            load += bytes;
            let from = if std::env::var("FROM0").is_ok() {
                tr.poses[first].t
            } else if let Ok(up) = std::env::var("COVER_UP") {
                let up: u32 = up.parse().unwrap();
                let cover: HashSet<_> = needed[first]
                    .iter()
                    .map(|k| {
                        let mut c = *k;
                        for _ in 0..up {
                            c = c.parent().unwrap_or(c);
                        }
                        c
                    })
                    .collect();
                let b: u64 = cover.iter().map(&low).sum();
                tr.poses[first].t + RTT + b as f64 / RATE
            } else {
                warm
            };
            let cap = ((due - from).max(0.0) * RATE) as u64;
            while load > cap {
                load -= kept.pop().unwrap_or(0);
                late += 1;
            }
        }
        all_n += jobs.len();
        all_late += late;
        println!(
            "| {} | {warm:.2} | {} | {late} | {:.1}% |",
            label(&tr),
            jobs.len(),
            100.0 * (jobs.len() - late) as f64 / jobs.len().max(1) as f64
        );
    }
    println!(
        "| all | | {all_n} | {all_late} | {:.1}% |",
        100.0 * (all_n - all_late) as f64 / all_n.max(1) as f64
    );
}
