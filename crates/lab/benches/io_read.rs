//! Times `io::read_bytes` on an in-memory trainer PLY of 1M SH-degree-3 splats (about 248 MB):
//! header parse, bulk record decode and the exp/sigmoid/normalise conversions, not disk reads.
//!
//! That size is a mid-size real capture, far beyond the caches, and big enough to amortise thread
//! start-up, yet fits a developer machine. The file is written once to the temp folder (never
//! committed). Throughput is reported on one thread (the per-core figure) and on all threads.
//! Run: `cargo bench --bench io_read` (set S2T_BENCH_SPLATS to change the size).

use std::time::Instant;

use splat2tiles_core::splat::{Splat, Splats, normalize_quat};
use splat2tiles_io::{read_bytes, write_ply};

fn scene(n: usize) -> Splats {
    let mut state = 0x1234_5678_9abc_def1u64;
    let mut r = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f32 / (1u64 << 53) as f32
    };
    let mut s = Splats::with_capacity(3, n);
    let mut rest = vec![[0.0f32; 3]; 15];
    for _ in 0..n {
        let splat = Splat {
            position: [0; 3].map(|_| (r() as f64 - 0.5) * 100.0),
            scale: [0; 3].map(|_| (r() * 5.0 - 6.0).exp()),
            rotation: normalize_quat([0; 4].map(|_| r() - 0.5)),
            opacity: r(),
            sh0: [0; 3].map(|_| r() - 0.5),
        };
        rest.iter_mut()
            .flatten()
            .for_each(|v| *v = (r() - 0.5) * 0.2);
        s.push(splat, &rest);
    }
    s
}

fn main() {
    let n: usize = std::env::var("S2T_BENCH_SPLATS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1_000_000);
    let path = std::env::temp_dir().join(format!("s2t_io_bench_{n}_sh3.ply"));
    if !path.exists() {
        let f = std::fs::File::create(&path).expect("create bench file");
        write_ply(&scene(n), std::io::BufWriter::new(f)).expect("write bench file");
    }
    let bytes = std::fs::read(&path).expect("read bench file");
    let mb = bytes.len() as f64 / 1e6;
    for threads in [
        1,
        std::thread::available_parallelism().map_or(1, |t| t.get()),
    ] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("thread pool");
        let mut best = f64::MAX;
        for _ in 0..5 {
            let t = Instant::now();
            let scene = pool
                .install(|| read_bytes("bench.ply", &bytes))
                .expect("decode");
            best = best.min(t.elapsed().as_secs_f64());
            assert_eq!(scene.splats.len(), n);
        }
        println!(
            "read_bytes PLY {n} splats SH3 ({mb:.0} MB), {threads} thread(s): best {:.3} s, {:.0} MB/s, {:.1} M splats/s",
            best,
            mb / best,
            n as f64 / best / 1e6
        );
    }
}
