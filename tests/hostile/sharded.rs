//! Sharded conversion against tampered inputs: part tiles deleted, truncated or changed after
//! the part was built, files the part never wrote, a huge unit content claimed over a sparse
//! `roots.bin`, an oversized `part.json`, and a plan used with another scene of the same size.
//! Each refusal exits 2, names the file and leaves no output, lock or staging folder; every
//! command runs under a 512 MiB data limit.

use super::common::bin;
use super::inputs::write_splat;
use super::{assert_valid, hidden, stderr};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs `splat2tiles ARGS... --quiet` under a 512 MiB data limit (`prlimit`, where it exists):
/// an allocation past it aborts the command, which the exit-code checks catch.
fn run(args: &[&str]) -> Output {
    let mut cmd = if Path::new("/usr/bin/prlimit").exists() {
        let mut c = Command::new("/usr/bin/prlimit");
        c.arg("--data=536870912").arg(bin());
        c
    } else {
        Command::new(bin())
    };
    cmd.args(args).arg("--quiet").output().unwrap()
}

/// A plan of `DIR/in.splat` (20,000 splats, tiles of at most 1024) in two parts and both parts
/// built: `(plan, parts)`.
fn built_parts(dir: &Path) -> (PathBuf, Vec<PathBuf>) {
    let input = dir.join("in.splat");
    write_splat(&input, 20_000);
    let plan = dir.join("plan.json");
    let o = run(&[
        "convert",
        s(&input),
        "--plan",
        s(&plan),
        "--parts",
        "2",
        "--max-splats",
        "1024",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let samples: Vec<PathBuf> = (0..2).map(|i| dir.join(format!("s{i}"))).collect();
    for (i, out) in samples.iter().enumerate() {
        let i = i.to_string();
        let phase = ["--phase", "samples", "-o", s(out)];
        let o = run(&[
            &["convert", s(&input), "--plan", s(&plan), "--part", &i],
            &phase[..],
        ]
        .concat());
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let parts: Vec<PathBuf> = (0..2).map(|i| dir.join(format!("p{i}"))).collect();
    for (i, out) in parts.iter().enumerate() {
        let i = i.to_string();
        let o = run(&[
            "convert",
            s(&input),
            "--plan",
            s(&plan),
            "--part",
            &i,
            "-o",
            s(out),
            "--samples",
            s(&samples[0]),
            s(&samples[1]),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    (plan, parts)
}

/// `merge PLAN PARTS -o DIR/merged EXTRA...`.
fn merge(dir: &Path, plan: &Path, parts: &[PathBuf], extra: &[&str]) -> (Output, PathBuf) {
    let out = dir.join("merged");
    let mut args = vec!["merge", s(plan), s(&parts[0]), s(&parts[1]), "-o", s(&out)];
    args.extend_from_slice(extra);
    (run(&args), out)
}

/// The merge exited 2 with a message naming `file` and holding `needle`, and left nothing.
fn assert_merge_refused(dir: &Path, o: &Output, out: &Path, file: &Path, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(s(file)), "names {}: {err}", file.display());
    assert!(err.contains(needle), "says '{needle}': {err}");
    assert!(!out.exists(), "an output was left");
    assert!(hidden(dir).is_empty(), "{:?}", hidden(dir));
}

/// The first tile file of a part, in path order.
fn first_tile(part: &Path) -> PathBuf {
    let mut tiles = super::common::files_under(&part.join("tiles"), "glb");
    tiles.sort();
    tiles.remove(0)
}

#[test]
fn merge_checks_every_listed_tile_and_carries_nothing_else() {
    let tmp = tempfile::tempdir().unwrap();
    let (plan, parts) = built_parts(tmp.path());
    // A file the part did not write is not carried over.
    std::fs::write(parts[0].join("tiles/notes.txt"), "mine").unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !out.join("tiles/notes.txt").exists(),
        "an unlisted file was carried over"
    );
    assert_valid(&out);
    std::fs::remove_dir_all(&out).unwrap();

    // A tile changed (same size), truncated, then deleted.
    let tile = first_tile(&parts[1]);
    let original = std::fs::read(&tile).unwrap();
    let mut changed = original.clone();
    let last = changed.len() - 1;
    changed[last] ^= 0x5a;
    std::fs::write(&tile, &changed).unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &[]);
    assert_merge_refused(tmp.path(), &o, &out, &tile, "CRC-32");
    std::fs::write(&tile, &original[..original.len() / 2]).unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &[]);
    assert_merge_refused(tmp.path(), &o, &out, &tile, "bytes where");
    std::fs::remove_file(&tile).unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &[]);
    assert_merge_refused(tmp.path(), &o, &out, &tile, "No such file");
}

#[test]
fn a_huge_unit_content_over_a_sparse_roots_file_is_refused_before_it_is_allocated() {
    let tmp = tempfile::tempdir().unwrap();
    let (plan, parts) = built_parts(tmp.path());
    let part_json = parts[0].join("part.json");
    let mut v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&part_json).unwrap()).unwrap();
    let roots = parts[0].join("roots.bin");
    let len = std::fs::metadata(&roots).unwrap().len();
    let units = v["units"].as_array_mut().unwrap();
    let total: u64 = units.iter().map(|u| u["content"].as_u64().unwrap()).sum();
    assert!(
        total > 0 && len % total == 0,
        "{len} bytes for {total} splats"
    );
    let record = len / total;
    // 64 GiB of content claimed by the first unit, and a roots file (sparse) that long.
    let huge = (64u64 << 30) / record;
    let before = units[0]["content"].as_u64().unwrap();
    units[0]["content"] = huge.into();
    std::fs::write(&part_json, serde_json::to_vec(&v).unwrap()).unwrap();
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&roots)
        .unwrap();
    f.set_len(len + (huge - before) * record).unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &[]);
    assert_merge_refused(tmp.path(), &o, &out, &roots, "memory limit");
}

#[test]
fn a_part_file_larger_than_a_quarter_of_the_memory_limit_is_not_read() {
    let tmp = tempfile::tempdir().unwrap();
    let (plan, parts) = built_parts(tmp.path());
    let part_json = parts[0].join("part.json");
    // 2.5 GB, sparse: trailing zeros after the JSON.
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(&part_json)
        .unwrap();
    f.set_len(2_500_000_000).unwrap();
    let (o, out) = merge(tmp.path(), &plan, &parts, &["--memory-limit", "256MiB"]);
    assert_merge_refused(tmp.path(), &o, &out, &part_json, "more than the 67108864");
}

#[test]
fn a_plan_made_for_another_scene_of_the_same_size_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 20_000);
    let plan = tmp.path().join("plan.json");
    let o = run(&["convert", s(&input), "--plan", s(&plan), "--parts", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The scene mirrored in x: the same size and splat count, other splats.
    let mut bytes = std::fs::read(&input).unwrap();
    for rec in bytes.chunks_exact_mut(32) {
        let x = f32::from_le_bytes(rec[0..4].try_into().unwrap());
        rec[0..4].copy_from_slice(&(-x).to_le_bytes());
    }
    let mirrored = tmp.path().join("mirrored.splat");
    std::fs::write(&mirrored, &bytes).unwrap();
    let out = tmp.path().join("s0");
    let o = run(&[
        "convert",
        s(&mirrored),
        "--plan",
        s(&plan),
        "--part",
        "0",
        "--phase",
        "samples",
        "-o",
        s(&out),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(s(&mirrored)) && err.contains("other content"),
        "{err}"
    );
    assert!(!out.exists());
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
}
