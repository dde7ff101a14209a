//! Writes a generated city (`splat2tiles_lab::city`, copies of the three shared scenes of
//! `data/scenes/`) as a z-up binary PLY: the input of the viewers' city checks.
//!
//! Run: `cargo run --example city -- SPLATS OUT.ply [SCENES_DIR]`, then
//! `splat2tiles convert OUT.ply -o city/ --up-axis +z [--origin LON,LAT,H]`.

use std::path::PathBuf;

use splat2tiles_lab::city::{CityLayout, generate_city, shared_sources};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(n), Some(out)) = (args.first(), args.get(1)) else {
        anyhow::bail!("usage: city SPLATS OUT.ply [SCENES_DIR (default data/scenes)]");
    };
    let splats: usize = n
        .parse()
        .map_err(|e| anyhow::anyhow!("SPLATS '{n}': {e}"))?;
    let scenes = args.get(2).map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("data/scenes")
    });
    let city = generate_city(
        &shared_sources(&scenes)?,
        &CityLayout {
            splats,
            ..CityLayout::default()
        },
    );
    let f = std::fs::File::create(out).map_err(|e| anyhow::anyhow!("{out}: {e}"))?;
    splat2tiles_io::write_ply(&city, std::io::BufWriter::new(f))?;
    eprintln!("city: {} splats -> {out}", city.len());
    Ok(())
}
