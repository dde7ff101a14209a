//! Fuzz target `tileset`: a tileset JSON, an external tileset and one content file (split at the
//! first two NUL bytes) written to a scratch folder and validated: external tilesets, metadata
//! values, tile rules, declarations, b3dm / i3dm / pnts / cmpt headers.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

use std::path::PathBuf;
use std::sync::OnceLock;

/// One scratch folder per process; the files are rewritten for every input.
fn scratch() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("s2t-fuzz-tileset-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("scratch folder");
        d
    })
}

fn run(data: &[u8]) {
    let mut parts = data.splitn(3, |b| *b == 0);
    let main = parts.next().unwrap_or_default();
    let external = parts.next().unwrap_or_default();
    let content = parts.next().unwrap_or_default();
    let dir = scratch();
    // The seeds name these files: `e.json` (external tileset) and `c.bin` (any content).
    let _ = std::fs::write(dir.join("e.json"), external);
    let _ = std::fs::write(dir.join("c.bin"), content);
    let opts = splat2tiles_validate::ValidateOptions {
        max_decompressed_bytes: 16 << 20,
        ..Default::default()
    };
    let _ = splat2tiles_validate::validate_tileset_bytes(main, dir, &opts);
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
