//! Fuzz target `limited`: scene bytes under a small memory limit, through `io::read_bytes_limited`
//! and (every other input) a file through `io::read_path_limited` (bounded prefix, declared-size
//! checks before the body is read). Byte 0 picks the extension and the path, byte 1 the limit.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let [pick, lim, body @ ..] = data else {
        return;
    };
    let name = ["fuzz.ply", "fuzz.splat", "fuzz.spz", "fuzz.bin"][(*pick & 3) as usize];
    // 4 KiB .. 128 MiB.
    let limit = 4096u64 << (*lim % 16);
    if pick & 0x80 == 0 {
        let _ = splat2tiles_io::read_bytes_limited(name, body, limit);
        return;
    }
    let dir = std::env::temp_dir().join(format!("s2t-fuzz-limited-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join(name);
    if std::fs::write(&path, body).is_ok() {
        let _ = splat2tiles_io::read_path_limited(&path, limit);
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
