//! Fuzz target `http_head`: bytes a client sends to `serve`, through `serve::http::read_head`
//! (size limit, blank-line skipping, parsing) and, for a parsed head, keep-alive and body checks.
//! Under `cargo fuzz` libFuzzer drives it; a plain build replays one input from stdin.
#![cfg_attr(fuzzing, no_main)]

fn run(data: &[u8]) {
    let mut r = std::io::BufReader::with_capacity(7, data);
    // Several heads one after another, as on a keep-alive connection.
    for _ in 0..8 {
        match splat2tiles_serve::http::read_head(&mut r) {
            Ok(h) => {
                let _ = (h.keep_alive(), h.has_body(), h.header("Range"));
            }
            Err(_) => return,
        }
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
