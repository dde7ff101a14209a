//! Fuzz target `samples`: a plan and a samples file (split at the first NUL byte, which JSON never
//! holds) through `convert::check_samples_bytes`, the build phase's checks of one part's samples.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let mut parts = data.splitn(2, |b| *b == 0);
    let plan = parts.next().unwrap_or_default();
    let samples = parts.next().unwrap_or_default();
    let _ = splat2tiles_build::convert::check_samples_bytes(plan, samples);
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
