//! Fuzz target `subtree`: `.subtree` bytes through `tiling::subtree::read_subtree` and the validator's subtree walk.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let _ = splat2tiles_tiles::tiling::subtree::read_subtree(data);
    let opts = splat2tiles_validate::ValidateOptions::default();
    let octree = data.first().is_some_and(|b| b & 1 == 1);
    let levels = 1 + u32::from(data.get(1).copied().unwrap_or(0) % 4);
    let _ = splat2tiles_validate::validate_subtree_bytes(data, octree, levels, &opts);
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
