//! Fuzz target `glb`: glb bytes through `encode::read_tile_glb`, the layer extension reader
//! (`layers::glb::read_layer`, sparse and ancestor deltas) and the validator's glb checks.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let _ = splat2tiles_tiles::encode::read_tile_glb(data);
    let _ = splat2tiles_tiles::layers::glb::read_layer(data);
    let opts = splat2tiles_validate::ValidateOptions::default();
    let _ = splat2tiles_validate::validate_glb_bytes(data, &opts);
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
