//! City-scale conversion benchmark (not a test): generated cities of displaced, rotated and scaled
//! copies of the three shared scenes, converted with a memory limit while RSS is sampled.
//!
//! Run: `cargo bench --bench city` (all four sizes: 10M, 50M, 200M SH0 and 40M SH3) or
//! `cargo bench --bench city -- 10M:0 40M:3` (splats:SH degree; `plot` alone redraws the plot). `CITY_LIMIT` (default 2GiB) is
//! the `--memory-limit`; `CITY_DIR` (default `target/city-bench`) holds the generated inputs and
//! outputs, each deleted after its run (`CITY_KEEP=1` keeps the inputs and reuses them when
//! present, for repeated timing runs). Sizes whose in-memory conversion fits in 3/4 of the RAM
//! are also converted with a limit that large (the in-memory path) for comparison. Writes
//! `target/city-bench.md` (the table), `target/city-rss-*.csv` and `docs/city-rss.svg`.
//! SH0 cities are written as antimatter15 `.splat` (32 B/splat), SH3 cities as trainer PLY
//! (248 B/splat) with generated non-zero higher SH (the shared scenes carry none).

mod common;
use common::release_binary;
use splat2tiles_core::splat::{Splats, sh_rest_count};
use splat2tiles_io::limits::{MemoryLimit, human, in_memory_estimate, physical_memory};
use splat2tiles_io::{PlyWriter, read_path, write_splat_records};
use std::fmt::Write as _;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// A small deterministic generator (xorshift64*), so every run builds the same city.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// One source building block: a shared scene in the city frame (y down, like `.splat`/PLY
/// trainers), centred horizontally on the origin with its ground (largest y) at y = 0.
struct Block {
    splats: Splats,
    /// Robust horizontal half-size (98th percentile of |x| and |z|).
    half: f64,
}

fn percentile(mut v: Vec<f64>, q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q) as usize]
}

fn load_blocks(scenes: &Path) -> Vec<Block> {
    let mut out = Vec::new();
    for (name, y_up) in [
        ("plant.splat", false),
        ("donut_fused_sh0.ply", false),
        ("biker.spz", true),
    ] {
        let mut s = read_path(&scenes.join(name))
            .unwrap_or_else(|e| panic!("{e}"))
            .splats;
        s.drop_non_finite();
        if y_up {
            // SPZ is y-up: turn it over (180 degrees about x) so every block is y-down.
            for p in &mut s.positions {
                p[1] = -p[1];
                p[2] = -p[2];
            }
            for q in &mut s.rotations {
                // q' = (1,0,0,0)_xyz * q: a rotation by pi about x, composed on the left.
                let [x, y, z, w] = *q;
                *q = [w, -z, y, -x];
            }
        }
        let xs: Vec<f64> = s.positions.iter().map(|p| p[0]).collect();
        let zs: Vec<f64> = s.positions.iter().map(|p| p[2]).collect();
        let ys: Vec<f64> = s.positions.iter().map(|p| p[1]).collect();
        let cx = percentile(xs.clone(), 0.5);
        let cz = percentile(zs.clone(), 0.5);
        let ground = percentile(ys, 0.98);
        for p in &mut s.positions {
            p[0] -= cx;
            p[1] -= ground;
            p[2] -= cz;
        }
        let half = percentile(
            s.positions
                .iter()
                .map(|p| p[0].abs().max(p[2].abs()))
                .collect(),
            0.98,
        );
        out.push(Block { splats: s, half });
    }
    out
}

/// Where generated splats go: a trainer PLY (SH > 0) or `.splat` records.
enum Sink {
    Ply(PlyWriter<BufWriter<std::fs::File>>),
    Splat(BufWriter<std::fs::File>),
}

/// Streams a city of `n` splats of SH degree `degree` to `path`; returns its side length.
fn generate(path: &Path, n: u64, degree: u8, blocks: &[Block]) -> f64 {
    // Blocks are scaled so each covers about a 20 m lot; copies sit on a square grid of lots.
    let lot = 20.0;
    let per_copy = blocks.iter().map(|b| b.splats.len() as u64).sum::<u64>() / 3;
    let copies = n.div_ceil(per_copy);
    let cols = (copies as f64).sqrt().ceil() as u64;
    let file = std::fs::File::create(path).unwrap();
    let w = BufWriter::with_capacity(1 << 22, file);
    let mut sink = if degree > 0 {
        Sink::Ply(PlyWriter::new(w, n, degree).unwrap())
    } else {
        Sink::Splat(w)
    };
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let rest_n = sh_rest_count(degree);
    let mut left = n;
    let mut c = 0u64;
    while left > 0 {
        let b = &blocks[(c % 3) as usize];
        let (gx, gz) = ((c % cols) as f64, (c / cols) as f64);
        let yaw = rng.next() * std::f64::consts::TAU;
        let scale = lot / 2.0 / b.half.max(1e-6) * (0.6 + 0.8 * rng.next());
        let off = [
            (gx + 0.5) * lot + (rng.next() - 0.5) * lot * 0.2,
            0.0,
            (gz + 0.5) * lot + (rng.next() - 0.5) * lot * 0.2,
        ];
        let (sin, cos) = yaw.sin_cos();
        // The yaw is about the (vertical) y axis: quaternion (0, sin(yaw/2), 0, cos(yaw/2)).
        let (hs, hc) = ((yaw / 2.0).sin() as f32, (yaw / 2.0).cos() as f32);
        let take = left.min(b.splats.len() as u64) as usize;
        let mut chunk = Splats::with_capacity(degree, take.min(1 << 16));
        for i in 0..take {
            let p = b.splats.positions[i];
            let x = (cos * p[0] + sin * p[2]) * scale + off[0];
            let z = (-sin * p[0] + cos * p[2]) * scale + off[2];
            chunk.positions.push([x, p[1] * scale, z]);
            let s = b.splats.scales[i];
            chunk.scales.push([
                s[0] * scale as f32,
                s[1] * scale as f32,
                s[2] * scale as f32,
            ]);
            let [qx, qy, qz, qw] = b.splats.rotations[i];
            // (0, hs, 0, hc) * q
            chunk.rotations.push([
                hc * qx + hs * qz,
                hc * qy + hs * qw,
                hc * qz - hs * qx,
                hc * qw - hs * qy,
            ]);
            chunk.opacities.push(b.splats.opacities[i]);
            chunk.sh0.push(b.splats.sh0[i]);
            for _ in 0..rest_n {
                let v = (rng.next() - 0.5) as f32 * 0.1;
                chunk.sh_rest.push([v, -v * 0.5, v * 0.25]);
            }
            if chunk.len() == 1 << 16 || i + 1 == take {
                match &mut sink {
                    Sink::Ply(p) => p.write(&chunk).unwrap(),
                    Sink::Splat(w) => write_splat_records(&chunk, w).unwrap(),
                }
                chunk = Splats::with_capacity(degree, 1 << 16);
            }
        }
        left -= take as u64;
        c += 1;
    }
    match sink {
        Sink::Ply(p) => p.finish().unwrap(),
        Sink::Splat(mut w) => w.flush().unwrap(),
    }
    cols as f64 * lot
}

/// One sampled conversion.
struct Run {
    seconds: f64,
    peak_rss: u64,
    /// (seconds, RSS bytes) samples.
    rss: Vec<(f64, u64)>,
    spill_peak: u64,
    summary: serde_json::Value,
}

fn status_kib(pid: u32, key: &str) -> Option<u64> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = s.lines().find(|l| l.starts_with(key))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Bytes under `dir` in files whose path mentions "spill" (the converter's spill files).
fn spill_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    for e in rd.flatten() {
        let p = e.path();
        let Ok(t) = e.file_type() else { continue };
        let spilly = p.to_string_lossy().contains("spill");
        if t.is_dir()
            && (spilly
                || p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with('.')))
        {
            total += spill_bytes(&p);
        } else if t.is_file() && spilly {
            total += e.metadata().map(|m| m.len()).unwrap_or(0);
        }
    }
    total
}

fn convert(bin: &Path, input: &Path, out: &Path, limit: &str) -> Run {
    let t0 = Instant::now();
    let mut child = Command::new(bin)
        .args([
            "convert",
            "--json",
            "--quiet",
            "--memory-limit",
            limit,
            "-o",
        ])
        .arg(out)
        .arg(input)
        .stdout(Stdio::piped())
        .spawn()
        .expect("spawn convert");
    let pid = child.id();
    let parent = out.parent().unwrap().to_path_buf();
    let mut rss = Vec::new();
    let mut spill_peak = 0u64;
    let mut k = 0u64;
    loop {
        if let Some(kib) = status_kib(pid, "VmRSS:") {
            rss.push((t0.elapsed().as_secs_f64(), kib * 1024));
        }
        if k.is_multiple_of(10) {
            spill_peak = spill_peak.max(spill_bytes(&parent));
        }
        k += 1;
        if child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let seconds = t0.elapsed().as_secs_f64();
    let mut stdout = String::new();
    std::io::Read::read_to_string(child.stdout.as_mut().unwrap(), &mut stdout).unwrap();
    let st = child.wait().unwrap();
    assert!(st.success(), "convert {} failed: {st}", input.display());
    let summary: serde_json::Value = serde_json::from_str(stdout.trim()).expect("summary JSON");
    // The converter reports its spill bytes; the sampled size of files named "spill" is the fallback.
    let spill_peak = summary["spillBytes"].as_u64().unwrap_or(spill_peak);
    let peak_rss = summary["peakRssMiB"]
        .as_f64()
        .map(|m| (m * 1024.0 * 1024.0) as u64)
        .unwrap_or_else(|| rss.iter().map(|r| r.1).max().unwrap_or(0));
    Run {
        seconds,
        peak_rss,
        rss,
        spill_peak,
        summary,
    }
}

fn dir_bytes(dir: &Path) -> u64 {
    let mut total = 0;
    if let Ok(rd) = std::fs::read_dir(dir) {
        for e in rd.flatten() {
            match e.file_type() {
                Ok(t) if t.is_dir() => total += dir_bytes(&e.path()),
                Ok(_) => total += e.metadata().map(|m| m.len()).unwrap_or(0),
                Err(_) => {}
            }
        }
    }
    total
}

fn extent_warnings(bin: &Path, out: &Path) -> String {
    let o = Command::new(bin)
        .args(["validate", "--check-extent"])
        .arg(out)
        .output()
        .expect("validate");
    let text = String::from_utf8_lossy(&o.stdout).to_string() + &String::from_utf8_lossy(&o.stderr);
    let n = text.lines().filter(|l| l.contains("EXTENT")).count();
    format!("exit {}, {n} extent lines", o.status.code().unwrap_or(-1))
}

fn parse_spec(s: &str) -> (u64, u8) {
    let (n, d) = s.split_once(':').unwrap_or((s, "0"));
    let n = n.trim_end_matches(['M', 'm']);
    (
        (n.parse::<f64>().expect("size in millions") * 1e6) as u64,
        d.parse().expect("SH degree"),
    )
}

/// An SVG line plot of RSS over time, one line per run, and the limit as a dashed line.
fn svg(runs: &[(String, Vec<(f64, u64)>)], limit: u64) -> String {
    let (w, h, m) = (760.0, 360.0, 50.0);
    let tmax = runs
        .iter()
        .flat_map(|r| r.1.iter().map(|s| s.0))
        .fold(1.0f64, f64::max);
    let ymax = runs
        .iter()
        .flat_map(|r| r.1.iter().map(|s| s.1 as f64))
        .fold(limit as f64 * 1.2, f64::max)
        / (1u64 << 30) as f64;
    let x = |t: f64| m + t / tmax * (w - 2.0 * m);
    let y = |g: f64| h - m - g / ymax * (h - 2.0 * m);
    let colours = [
        "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b",
    ];
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{h}\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    );
    let _ = writeln!(
        s,
        "<line x1=\"{m}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/><line x1=\"{m}\" y1=\"{m}\" x2=\"{m}\" y2=\"{}\" stroke=\"black\"/>",
        h - m,
        w - m,
        h - m,
        h - m
    );
    for i in 0..=4 {
        let g = ymax * i as f64 / 4.0;
        let _ = writeln!(s, "<text x=\"4\" y=\"{:.1}\">{g:.1} GiB</text>", y(g) + 4.0);
        let t = tmax * i as f64 / 4.0;
        let _ = writeln!(
            s,
            "<text x=\"{:.1}\" y=\"{}\">{t:.0} s</text>",
            x(t) - 10.0,
            h - m + 18.0
        );
    }
    let gl = limit as f64 / (1u64 << 30) as f64;
    let _ = writeln!(
        s,
        "<line x1=\"{m}\" y1=\"{:.1}\" x2=\"{}\" y2=\"{:.1}\" stroke=\"grey\" stroke-dasharray=\"6,4\"/><text x=\"{}\" y=\"{:.1}\">limit {}</text>",
        y(gl),
        w - m,
        y(gl),
        w - m - 90.0,
        y(gl) - 4.0,
        human(limit)
    );
    for (i, (name, pts)) in runs.iter().enumerate() {
        let c = colours[i % colours.len()];
        let path: Vec<String> = pts
            .iter()
            .map(|(t, b)| format!("{:.1},{:.1}", x(*t), y(*b as f64 / (1u64 << 30) as f64)))
            .collect();
        let _ = writeln!(
            s,
            "<polyline fill=\"none\" stroke=\"{c}\" stroke-width=\"1.5\" points=\"{}\"/>",
            path.join(" ")
        );
        let _ = writeln!(
            s,
            "<text x=\"{}\" y=\"{}\" fill=\"{c}\">{name}</text>",
            m + 10.0,
            m + 14.0 * (i as f64 + 1.0)
        );
    }
    s + "</svg>\n"
}

fn main() {
    let specs: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let specs = if specs.is_empty() {
        ["10M:0", "50M:0", "200M:0", "40M:3"]
            .map(String::from)
            .to_vec()
    } else {
        specs
    };
    let limit_s = std::env::var("CITY_LIMIT").unwrap_or_else(|_| "2GiB".into());
    let limit = MemoryLimit::parse(&limit_s).expect("CITY_LIMIT").bytes();
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../.."));
    let dir = std::env::var_os("CITY_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/city-bench"));
    std::fs::create_dir_all(&dir).unwrap();
    let bin = release_binary();
    let blocks = load_blocks(&root.join("data/scenes"));
    let ram = physical_memory().unwrap_or(0);
    let mut md = format!(
        "memory limit {}; machine RAM {}; {} cores\n\n| city | SH | path | seconds | splats/s | peak RSS | RSS / limit | spill | output | tiles | levels | parent splats | LOD s |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        human(limit),
        human(ram),
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    // `plot` alone redraws docs/city-rss.svg from the samples already in target/.
    for spec in specs.iter().filter(|s| *s != "plot") {
        let (n, degree) = parse_spec(spec);
        let ext = if degree == 0 { "splat" } else { "ply" };
        let input = dir.join(format!("city-{n}-sh{degree}.{ext}"));
        let keep = std::env::var_os("CITY_KEEP").is_some_and(|v| v == "1");
        let t0 = Instant::now();
        let side = if keep && input.exists() {
            f64::NAN
        } else {
            generate(&input, n, degree, &blocks)
        };
        let gen_s = t0.elapsed().as_secs_f64();
        let in_bytes = std::fs::metadata(&input).map(|m| m.len()).unwrap_or(0);
        eprintln!(
            "{spec}: generated {} ({}, {side:.0} m square) in {gen_s:.1} s",
            input.display(),
            human(in_bytes)
        );
        let fits = in_memory_estimate(n, degree, 0) < ram / 4 * 3;
        let mut paths = vec![("out of core", limit)];
        if fits {
            paths.push(("in memory", ram / 4 * 3));
        }
        for (path, lim_bytes) in paths {
            let lim = human(lim_bytes);
            let out = dir.join(format!("out-{n}-sh{degree}"));
            let r = convert(&bin, &input, &out, &lim_bytes.to_string());
            let out_bytes = dir_bytes(&out);
            let extent = if n <= 10_000_000 && path == "out of core" {
                format!(" ({})", extent_warnings(&bin, &out))
            } else {
                String::new()
            };
            let s = &r.summary;
            let _ = writeln!(
                md,
                "| {}M, {} input | {degree} | {path} (limit {lim}) | {:.1} | {:.2}M | {} | {:.2} | {} | {}{extent} | {} | {} | {} | {:.1} |",
                n as f64 / 1e6,
                human(in_bytes),
                r.seconds,
                n as f64 / r.seconds / 1e6,
                human(r.peak_rss),
                r.peak_rss as f64 / lim_bytes as f64,
                human(r.spill_peak),
                human(out_bytes),
                s["tiles"],
                s["levels"],
                s["parentSplats"],
                s["lodSeconds"].as_f64().unwrap_or(f64::NAN),
            );
            let csv: String = r.rss.iter().map(|(t, b)| format!("{t:.2},{b}\n")).collect();
            let _ = std::fs::write(
                root.join(
                    format!("target/city-rss-{spec}-{}.csv", path.replace(' ', "-"))
                        .replace(':', "-sh"),
                ),
                format!("seconds,rss_bytes\n{csv}"),
            );
            eprintln!("{}", md.lines().last().unwrap_or(""));
            std::fs::remove_dir_all(&out).unwrap();
        }
        if !keep {
            std::fs::remove_file(&input).unwrap();
        }
    }
    std::fs::write(root.join("target/city-bench.md"), &md).unwrap();
    // The plot shows every out-of-core run whose samples are in target/ (earlier invocations'
    // too, so sizes may be run one at a time).
    let mut plots = Vec::new();
    let mut files: Vec<PathBuf> = std::fs::read_dir(root.join("target"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy();
            n.starts_with("city-rss-") && n.ends_with("-out-of-core.csv")
        })
        .collect();
    files.sort();
    for f in files {
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        let label = name
            .trim_start_matches("city-rss-")
            .trim_end_matches("-out-of-core.csv")
            .replace("-sh", " SH");
        let pts: Vec<(f64, u64)> = std::fs::read_to_string(&f)
            .unwrap()
            .lines()
            .skip(1)
            .filter_map(|l| {
                let (t, b) = l.split_once(',')?;
                Some((t.parse().ok()?, b.parse().ok()?))
            })
            .collect();
        plots.push((label, pts));
    }
    std::fs::write(root.join("docs/city-rss.svg"), svg(&plots, limit)).unwrap();
    println!("{md}");
}
