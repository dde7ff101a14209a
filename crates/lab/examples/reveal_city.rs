//! How many tiles the test split's street walks and human traces see for the first time after
//! 30 s on a converted full city (every 5th trace; a measurement for BENCHMARKS.md):
//! `STREAM_CITY_DIR=DIR cargo run --profile test -p splat2tiles-lab --example reveal_city`, with
//! DIR built by the `stream_city` example. Reads `data/scenes` and
//! the human traces under `data/` (read through `sim::split`).

use splat2tiles_lab::sim::stream_city::{CitySpec, StreetGrid, city_sources, revealed, trace_set};
use splat2tiles_stream::TileCatalog;
use splat2tiles_stream::split::Split;
use std::path::PathBuf;

fn main() -> Result<(), String> {
    let root = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let dir = PathBuf::from(std::env::var("STREAM_CITY_DIR").map_err(|_| "set STREAM_CITY_DIR")?);
    let ts = splat2tiles_tiles::tiling::load::load_tileset(&dir.join("tileset.json"))
        .map_err(|e| e.to_string())?;
    let cat = TileCatalog::from_loaded(&ts.tiles, |_| Some(1));
    let spec = CitySpec::default();
    let sources =
        city_sources(&root.join("data/scenes"), spec.stride).map_err(|e| e.to_string())?;
    let g = StreetGrid::of(&sources, &spec.layout());
    println!("{} tiles, grid {g:?}", cat.tiles.len());
    let nav = root.join(splat2tiles_lab::sim::stream_city::NAVIGATION_DIR);
    for t in trace_set(&g, &nav, Split::Test)?.iter().step_by(5) {
        let (late, all) = revealed(&cat, t, 30.0);
        println!(
            "{} {}: {late} of {all} tiles first seen after 30 s ({:.0} s)",
            t.header("kind").unwrap_or(""),
            t.header("source").or(t.header("seed")).unwrap_or(""),
            t.duration()
        );
    }
    Ok(())
}
