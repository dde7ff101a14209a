//! Viewer benchmarks (not timed tests): the CPU radix sort of depth keys at 1M and 4M splats on
//! one core, software (lavapipe) frame time at 1280x720 for 100k and 1M resident splats (SH0 and
//! SH3, warm-up frames first, median of N), and memory per resident splat (GPU and CPU).
//!
//! Sizes: 1M is a city block at full detail, 4M is the page budget's order of magnitude (256
//! pages of 16,384 splats); the frame sizes bracket what a streaming client keeps resident.
//! Run with `cargo bench -p splat2tiles-viewer`; prints a markdown table.

use glam::{DMat4, DVec3};
use splat2tiles_core::camera::Camera;
use splat2tiles_core::splat::{Splat, Splats, normalize_quat};
use splat2tiles_viewer::gpu::{OFFSCREEN_FORMAT, Offscreen};
use splat2tiles_viewer::sort::{RadixSorter, back_to_front_key};
use splat2tiles_viewer::{RendererConfig, SplatRenderer};

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Median ms of sorting `n` pairs with keys from `key(i)`.
fn time_sort(n: usize, runs: usize, mut key: impl FnMut(usize) -> u32) -> f64 {
    let keys: Vec<u32> = (0..n).map(&mut key).collect();
    let mut sorter = RadixSorter::new();
    let mut pairs: Vec<u64> = Vec::with_capacity(n);
    let mut times = Vec::new();
    for _ in 0..runs + 1 {
        pairs.clear();
        pairs.extend(
            keys.iter()
                .enumerate()
                .map(|(i, &k)| ((k as u64) << 32) | i as u64),
        );
        let t0 = std::time::Instant::now();
        sorter.sort_packed(&mut pairs);
        times.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    assert!(pairs.windows(2).all(|w| w[0] >> 32 <= w[1] >> 32));
    times.remove(0);
    median(times)
}

/// `n` splats of degree `deg` in a 40 x 40 x 8 m block (a street scene's density).
fn scene(n: usize, deg: u8, seed: u64) -> Splats {
    let mut r = Lcg(seed);
    let mut s = Splats::with_capacity(deg, n);
    let k = s.rest_per_splat();
    let mut rest = vec![[0f32; 3]; k];
    for _ in 0..n {
        let q = [r.next(), r.next(), r.next(), r.next()].map(|v| (v - 0.5) as f32);
        for c in rest.iter_mut() {
            *c = [r.next(), r.next(), r.next()].map(|v| (0.2 * v - 0.1) as f32);
        }
        s.push(
            Splat {
                position: [
                    40.0 * r.next() - 20.0,
                    40.0 * r.next() - 20.0,
                    8.0 * r.next(),
                ],
                scale: [0.02, 0.05, 0.01].map(|b| (b * (0.5 + r.next())) as f32),
                rotation: normalize_quat(q),
                opacity: (0.05 + 0.9 * r.next()) as f32,
                sh0: [r.next(), r.next(), r.next()].map(|v| (2.0 * v - 1.0) as f32),
            },
            &rest,
        );
    }
    s
}

fn main() {
    let mut rows: Vec<String> = Vec::new();
    // 1. Sort, one core (the worker thread is one core; nothing else runs here).
    for n in [1_000_000usize, 4_000_000] {
        let mut r = Lcg(1);
        let rand = time_sort(n, 5, |_| (r.next() * 4294967296.0) as u32);
        let mut r = Lcg(2);
        // Realistic depths: a camera inside the block sees 0.2..60 m, denser nearby.
        let depth = time_sort(n, 5, |_| {
            back_to_front_key((0.2 + 60.0 * r.next() * r.next()) as f32)
        });
        for (what, ms) in [("random u32 keys", rand), ("view depths (f32)", depth)] {
            rows.push(format!(
                "| sort {} pairs, {what} | {ms:.1} ms | {:.1} M pairs/s |",
                n / 1_000_000 * 1_000_000,
                n as f64 / ms / 1e3
            ));
        }
    }
    // 2. Frames on the software adapter.
    let g = splat2tiles_viewer::gpu::headless().expect("no wgpu adapter (install lavapipe)");
    let adapter = g.adapter_name();
    let cam = Camera::look_at(
        1280,
        720,
        60.0,
        DVec3::new(-25.0, -25.0, 6.0),
        DVec3::new(0.0, 0.0, 2.0),
        DVec3::Z,
    );
    let target = Offscreen::new(&g.device, 1280, 720).unwrap();
    let mut mem_rows = Vec::new();
    for (n, deg, frames) in [
        (100_000usize, 0u8, 7usize),
        (100_000, 3, 7),
        (1_000_000, 0, 3),
        (1_000_000, 3, 3),
    ] {
        let s = scene(n, deg, 7 + n as u64);
        let cfg = RendererConfig {
            blocking_sort: true,
            ..Default::default()
        };
        let mut r = SplatRenderer::new(&g.device, &g.queue, OFFSCREEN_FORMAT, cfg);
        // As tiles of 32,768 (the converter's default leaf size).
        let t_up = std::time::Instant::now();
        for (id, start) in (0..n).step_by(32_768).enumerate() {
            let idx: Vec<usize> = (start..(start + 32_768).min(n)).collect();
            r.insert_tile(
                &g.device,
                &g.queue,
                id as u64,
                &s.select(&idx),
                DMat4::IDENTITY,
                0.0,
            );
        }
        let upload_ms = t_up.elapsed().as_secs_f64() * 1e3;
        // Warm-up (pipeline JIT, first sort), then frames that wait for the GPU.
        for _ in 0..2 {
            r.render(&g.device, &g.queue, &target.view, &cam, 1.0);
            g.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
        }
        let mut times = Vec::new();
        for _ in 0..frames {
            let t0 = std::time::Instant::now();
            let st = r.render(&g.device, &g.queue, &target.view, &cam, 1.0);
            g.device.poll(wgpu::PollType::wait_indefinitely()).unwrap();
            times.push(t0.elapsed().as_secs_f64() * 1e3);
            assert_eq!(st.drawn, n);
        }
        let ms = median(times);
        rows.push(format!(
            "| frame 1280x720, {}k splats SH{deg} (lavapipe) | {ms:.0} ms median of {frames} | {:.1} fps (upload {upload_ms:.0} ms) |",
            n / 1000,
            1e3 / ms
        ));
        mem_rows.push(format!(
            "| memory, {}k splats SH{deg} | GPU {:.1} B/splat ({:.0} B/slot textures) | CPU {:.1} B/splat |",
            n / 1000,
            r.gpu_bytes() as f64 / n as f64,
            r.texture_bytes_per_slot(),
            r.cpu_bytes() as f64 / n as f64
        ));
    }
    rows.extend(mem_rows);
    println!(
        "\nsplat2tiles-viewer benchmarks ({adapter}, {} cores)\n",
        std::thread::available_parallelism()
            .map(|n| n.get())
            .unwrap_or(1)
    );
    println!("| measurement | time / size | rate |");
    println!("|---|---|---|");
    for r in rows {
        println!("{r}");
    }
}
