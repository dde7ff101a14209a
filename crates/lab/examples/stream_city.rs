//! Generates and converts the issue-19 streaming city (`splat2tiles_lab::sim::stream_city`): real
//! content on a street grid, georeferenced, all four variants, reproducible from the seed.
//!
//! Run: `cargo run --release --example stream_city -- OUT_DIR [--origin LON,LAT,H] [--seed N]
//! [--splats N] [--stride N] [--scenes DIR]` (defaults: `sim::stream_city::DEFAULT_ORIGIN`, `CitySpec::default()`,
//! `data/scenes`). Prints splats, tiles, bytes per variant and seconds. Exit 2 on bad
//! arguments or a failed conversion (nothing is left at OUT_DIR then).

use splat2tiles_core::frame::geo::Geodetic;
use splat2tiles_lab::sim::stream_city::{CitySpec, DEFAULT_ORIGIN, build_city};
use std::path::PathBuf;

fn run() -> Result<(), String> {
    let mut args = std::env::args().skip(1);
    let mut out = None;
    let mut origin = DEFAULT_ORIGIN.to_string();
    let mut spec = CitySpec::default();
    let mut scenes =
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes");
    while let Some(a) = args.next() {
        let mut value = |name: &str| args.next().ok_or(format!("{name} needs a value"));
        match a.as_str() {
            "--origin" => origin = value("--origin")?,
            "--seed" => {
                let v = value("--seed")?;
                spec.seed = v.parse().map_err(|e| format!("--seed '{v}': {e}"))?;
            }
            "--splats" => {
                let v = value("--splats")?;
                spec.splats = v.parse().map_err(|e| format!("--splats '{v}': {e}"))?;
                if spec.splats == 0 || spec.splats > 50_000_000 {
                    return Err(format!("--splats {v}: expected 1..=50000000"));
                }
            }
            "--stride" => {
                let v = value("--stride")?;
                spec.stride = v.parse().map_err(|e| format!("--stride '{v}': {e}"))?;
                if spec.stride == 0 || spec.stride > 1000 {
                    return Err(format!("--stride {v}: expected 1..=1000"));
                }
            }
            "--scenes" => scenes = PathBuf::from(value("--scenes")?),
            _ if a.starts_with('-') => return Err(format!("unknown option '{a}'")),
            _ if out.is_none() => out = Some(PathBuf::from(&a)),
            _ => return Err(format!("unexpected argument '{a}'")),
        }
    }
    let out = out.ok_or(
        "usage: stream_city OUT_DIR [--origin LON,LAT,H] [--seed N] [--splats N] [--scenes DIR]",
    )?;
    let origin = Geodetic::parse(&origin)?;
    let c = build_city(&scenes, &out, &spec, Some(origin)).map_err(|e| e.to_string())?;
    println!("{}: {}", out.display(), c.summary());
    Ok(())
}

fn main() {
    if let Err(e) = run() {
        eprintln!("stream_city: {e}");
        std::process::exit(2);
    }
}
