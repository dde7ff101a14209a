//! Fuzz target `output_marker`: the marker file of an existing output folder (hostile JSON),
//! through `output::guard::check_target`, which decides whether `convert` may replace the folder.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let dir = std::env::temp_dir().join(format!("s2t-fuzz-marker-{}", std::process::id()));
    let out = dir.join("out");
    let _ = std::fs::create_dir_all(&out);
    let _ = std::fs::write(out.join("tileset.json"), b"{}");
    if std::fs::write(out.join(splat2tiles_build::output::marker::MARKER), data).is_ok() {
        let _ = splat2tiles_build::output::guard::check_target(&out);
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
