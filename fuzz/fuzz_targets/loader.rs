//! Fuzz target `loader`: a `tileset.json` and a root subtree file (split at the first NUL byte,
//! which JSON never holds) through the tileset loader of `render` and `stats`
//! (`tiling::load::parse_tileset_json`, then `parse_subtree_tiles` for the root subtree).
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

use splat2tiles_tiles::tiling::TileKey;
use splat2tiles_tiles::tiling::load::{parse_subtree_tiles, parse_tileset_json};

fn run(data: &[u8]) {
    let mut parts = data.splitn(2, |b| *b == 0);
    let json = parts.next().unwrap_or_default();
    let subtree = parts.next().unwrap_or_default();
    if let Ok(root) = parse_tileset_json(json) {
        let _ = parse_subtree_tiles(&root, TileKey::ROOT, subtree);
    }
}

#[cfg(fuzzing)]
libfuzzer_sys::fuzz_target!(|data: &[u8]| run(data));

#[cfg(not(fuzzing))]
fn main() {
    use std::io::Read;
    let mut data = Vec::new();
    std::io::stdin().read_to_end(&mut data).expect("read stdin");
    run(&data);
    println!("ok: {} bytes replayed without a crash", data.len());
}
