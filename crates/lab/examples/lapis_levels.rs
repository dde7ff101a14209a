//! Writes LapisGS-shaped level files from one scene, for `import-lapisgs` measurements: the
//! splats in a seeded random order, level k = the first n/2^(L-1-k) of them (the last level is
//! the whole scene); at each level half of the earlier splats (drawn at random) get a new
//! opacity, the stored one times a factor in [0.5, 1.5] (clamped to [0.005, 0.99]), as
//! LapisGS's opacity fine-tuning does (not trained: the geometry is the scene's, the changes random).
//!
//! Run: `cargo run --example lapis_levels -- SCENE OUT_DIR [LEVELS (default 4)]`, then
//! `splat2tiles import-lapisgs OUT_DIR/level0.ply ... -o lapis/`.

use splat2tiles_core::rng::SplitMix64;
use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some(scene), Some(out)) = (args.first(), args.get(1)) else {
        anyhow::bail!("usage: lapis_levels SCENE OUT_DIR [LEVELS]");
    };
    let levels: usize = match args.get(2) {
        Some(l) => l
            .parse()
            .map_err(|e| anyhow::anyhow!("LEVELS '{l}': {e}"))?,
        None => 4,
    };
    anyhow::ensure!((1..=8).contains(&levels), "LEVELS must be 1..=8");
    let s = splat2tiles_io::read_path(&PathBuf::from(scene))?.splats;
    let n = s.len();
    let mut rng = SplitMix64::new(21);
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        order.swap(i, rng.below(i + 1));
    }
    let all = s.select(&order);
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out)?;
    let mut prev: Option<splat2tiles_core::splat::Splats> = None;
    for k in 0..levels {
        let size = (n >> (levels - 1 - k)).max(1);
        let mut lv = all.select(&(0..size).collect::<Vec<_>>());
        if let Some(p) = &prev {
            for i in 0..p.len() {
                lv.opacities[i] = if rng.f64() < 0.5 {
                    (p.opacities[i] * rng.range(0.5, 1.5) as f32).clamp(0.005, 0.99)
                } else {
                    p.opacities[i]
                };
            }
        }
        let path = out.join(format!("level{k}.ply"));
        let f = std::fs::File::create(&path)?;
        splat2tiles_io::write_ply(&lv, std::io::BufWriter::new(f))?;
        println!("{}: {} splats", path.display(), lv.len());
        prev = Some(lv);
    }
    Ok(())
}
