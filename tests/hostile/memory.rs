//! Resource exhaustion: declared sizes are checked against `--memory-limit` before anything is
//! allocated (exact-size decompression bombs, sparse huge files, devices), and overflowing or
//! oversized values are reported honestly.

use super::common::bin;
use super::inputs::{ply, record, spz_v2_data_len, spz_v2_header, write_zeros};
use super::{convert, hidden, stderr};
use std::io::Write;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs convert on `input` with `extra` arguments; asserts exit 2, one line naming the file and
/// containing every needle, and no output or hidden folder left.
fn assert_refused(input: &Path, extra: &[&str], needles: &[&str]) -> String {
    let dir = input.parent().unwrap();
    let out = dir.join("out");
    let mut args = vec![s(input), "-o", s(&out)];
    args.extend_from_slice(extra);
    let o = convert(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "exit code; stderr: {err}");
    assert!(err.contains(s(input)), "names the file: {err}");
    for n in needles {
        assert!(err.contains(n), "says '{n}': {err}");
    }
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(!out.exists());
    assert!(hidden(dir).is_empty(), "{:?}", hidden(dir));
    eprintln!("{}", err.trim());
    err
}

/// The exact-size zstd bomb of the report: a legacy SPZ payload declaring 2^26 points of SH
/// degree 3 (4.3 GB of arrays, all present) in about a hundred KB. Refused under the default
/// limit (at most 4 GiB) before decompressing.
#[test]
fn exact_size_zstd_bomb_is_refused_under_the_default_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("bomb.spz");
    let n = 1u32 << 26;
    let mut enc =
        zstd::stream::write::Encoder::new(std::fs::File::create(&input).unwrap(), 1).unwrap();
    enc.write_all(&spz_v2_header(n, 3)).unwrap();
    let data = spz_v2_data_len(n as u64, 3);
    write_zeros(&mut enc, data);
    let mut f = enc.finish().unwrap();
    // Exact-size: big enough for the reader's ratio check (32768:1) to let it through; a
    // skippable frame (which decoders pass over) makes up any shortfall.
    let len = std::fs::metadata(&input).unwrap().len();
    let need = data / 32768 + 1;
    if len < need {
        let pad = (need - len) as u32;
        f.write_all(&[0x50, 0x2a, 0x4d, 0x18]).unwrap();
        f.write_all(&pad.to_le_bytes()).unwrap();
        write_zeros(&mut f, pad as u64);
    }
    drop(f);
    let len = std::fs::metadata(&input).unwrap().len();
    assert!(len < 1 << 20, "{len}");
    assert_refused(&input, &[], &["67108864 declared splats", "memory limit"]);
}

/// The same as SPZ v4: six zstd streams whose TOC sizes match the declared count.
#[test]
fn exact_size_spz_v4_bomb_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("bomb4.spz");
    let n: u64 = 1 << 26;
    let sizes = [n * 9, n, n * 3, n * 3, n * 4, n * 45];
    let streams: Vec<Vec<u8>> = sizes
        .iter()
        .map(|&len| {
            let mut enc = zstd::stream::write::Encoder::new(Vec::new(), 1).unwrap();
            write_zeros(&mut enc, len);
            enc.finish().unwrap()
        })
        .collect();
    let mut b = b"NGSP".to_vec();
    b.extend_from_slice(&4u32.to_le_bytes());
    b.extend_from_slice(&(n as u32).to_le_bytes());
    b.extend_from_slice(&[3, 12, 0, 6]);
    b.extend_from_slice(&32u32.to_le_bytes());
    b.resize(32, 0);
    for (st, raw) in streams.iter().zip(sizes) {
        b.extend_from_slice(&(st.len() as u64).to_le_bytes());
        b.extend_from_slice(&raw.to_le_bytes());
    }
    for st in &streams {
        b.extend_from_slice(st);
    }
    std::fs::write(&input, &b).unwrap();
    assert_refused(&input, &[], &["67108864 declared splats", "memory limit"]);
}

/// An exact-size gzip bomb (SH0 and SH3) under a small explicit limit: `--memory-limit` is
/// honoured, and the message gives count, estimate and limit.
#[test]
fn exact_size_gzip_bombs_are_refused_under_an_explicit_limit() {
    let tmp = tempfile::tempdir().unwrap();
    for degree in [0u8, 3] {
        let input = tmp.path().join(format!("gz{degree}.spz"));
        let n: u32 = 4_000_000;
        let f = std::fs::File::create(&input).unwrap();
        let mut enc = flate2::write::GzEncoder::new(f, flate2::Compression::fast());
        enc.write_all(&spz_v2_header(n, degree)).unwrap();
        write_zeros(&mut enc, spz_v2_data_len(n as u64, degree));
        enc.finish().unwrap();
        let err = assert_refused(
            &input,
            &["--memory-limit", "64MiB"],
            &["4000000 declared splats", "64.0 MiB", "--memory-limit"],
        );
        assert!(err.contains("estimated"), "{err}");
    }
}

/// A sparse `.splat` (no bytes on disk: every splat at the origin) is read in chunks whatever
/// its size (the out-of-core converter spills what does not fit), but coincident splats cannot
/// be split into tiles: more of them than `--memory-limit` lets one tile hold is refused, with
/// nothing left behind.
#[test]
fn sparse_splat_file_of_coincident_splats_is_refused_at_the_memory_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("sparse.splat");
    let f = std::fs::File::create(&input).unwrap();
    f.set_len(16 << 20).unwrap();
    drop(f);
    assert_refused(
        &input,
        &["--memory-limit", "1MiB"],
        &["524288 splats share one cell", "memory limit"],
    );
}

/// `/dev/zero` named `x.ply`: refused on its first bytes (no `ply` line), never read to the end.
#[cfg(unix)]
#[test]
fn endless_device_named_ply_is_refused_on_its_magic() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("x.ply");
    std::os::unix::fs::symlink("/dev/zero", &input).unwrap();
    let out = tmp.path().join("out");
    let mut child = Command::new(bin())
        .args(["convert", s(&input), "-o", s(&out), "--quiet"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if t.elapsed() > Duration::from_secs(120) {
            let _ = child.kill();
            panic!("still reading /dev/zero after 2 minutes");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("x.ply") && err.contains("'ply'"), "{err}");
}

/// A device whose bytes look like a `.splat` is bounded by the limit, not read forever.
#[cfg(unix)]
#[test]
fn endless_device_named_splat_stops_at_the_memory_limit() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("zero.splat");
    std::os::unix::fs::symlink("/dev/zero", &input).unwrap();
    assert_refused(
        &input,
        &["--memory-limit", "8MiB"],
        &["larger than", "8.0 MiB"],
    );
}

/// Finite log-scales of 1e30 overflow `exp`: the report says so instead of blaming NaN/Inf in
/// the file.
#[test]
fn overflowing_log_scales_are_reported_as_such() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("huge_scales.ply");
    std::fs::write(
        &input,
        ply(1000, |i| {
            let mut r = record(i);
            r[7] = 1e30;
            r
        }),
    )
    .unwrap();
    assert_refused(
        &input,
        &[],
        &["1000 of them are finite", "log-scales too large"],
    );
    assert_refused(&input, &["--non-finite", "fail"], &["log-scales too large"]);
}

/// A gzip stream far longer than its valid header declares: called what it is.
#[test]
fn gzip_stream_longer_than_declared_is_named_a_bomb() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("long.spz");
    let f = std::fs::File::create(&input).unwrap();
    let mut enc = flate2::write::GzEncoder::new(f, flate2::Compression::fast());
    enc.write_all(&spz_v2_header(1000, 0)).unwrap();
    write_zeros(&mut enc, spz_v2_data_len(1000, 0) + (256 << 20));
    enc.finish().unwrap();
    let err = assert_refused(&input, &[], &["decompression bomb", "19000 bytes"]);
    assert!(!err.contains("unexpected bytes"), "{err}");
}

/// A header of 44k properties parses in linear time (the duplicate check was quadratic).
#[test]
fn header_with_tens_of_thousands_of_properties_is_parsed_quickly() {
    let mut h = String::from("ply\nformat binary_little_endian 1.0\nelement vertex 1\n");
    for p in super::inputs::PROPS {
        h.push_str(&format!("property float {p}\n"));
    }
    for i in 0..44_000 {
        h.push_str(&format!("property uchar e{i}\n"));
    }
    h.push_str("end_header\n");
    let mut bytes = h.into_bytes();
    bytes.extend(std::iter::repeat_n(0u8, 14 * 4 + 44_000));
    let t = Instant::now();
    let scene = splat2tiles_io::read_bytes("wide.ply", &bytes).expect("a valid wide PLY");
    assert_eq!(scene.splats.len(), 1);
    // Quadratic took 6.5 s in release (and far longer here); linear takes milliseconds.
    assert!(t.elapsed() < Duration::from_secs(30), "{:?}", t.elapsed());
    // A duplicate among them is still found, at its line.
    let dup = String::from_utf8_lossy(&bytes)
        .replacen("property uchar e43999\n", "property uchar e7\n", 1)
        .into_bytes();
    let e = splat2tiles_io::read_bytes("wide.ply", &dup).unwrap_err();
    assert!(e.to_string().contains("duplicate property 'e7'"), "{e}");
}
