//! Sharded conversion (`convert --plan`, `--part`, `merge`): the merged output of N parts is
//! byte-identical (every file) to the single-machine conversion and valid, whatever the part
//! count, the parts' memory limits, re-runs of a part, variants or georeferencing; bad plans
//! and mismatched inputs and parts are refused with exit 2.

use crate::common::city::write_city_splat;
use crate::common::*;
use splat2tiles_core::splat::Splats;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn ok(o: Output) -> serde_json::Value {
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn refused(o: Output, what: &str) -> String {
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(what), "expected '{what}' in: {err}");
    err
}

fn os(s: &str) -> &std::ffi::OsStr {
    s.as_ref()
}

fn single(input: &Path, out: &Path, extra: &[&str]) {
    let mut a = vec![
        os("convert"),
        input.as_os_str(),
        os("-o"),
        out.as_os_str(),
        os("--json"),
    ];
    a.extend(extra.iter().map(|s| os(s)));
    ok(run(&a));
}

fn plan(input: &Path, plan: &Path, parts: usize, extra: &[&str]) -> serde_json::Value {
    let n = parts.to_string();
    let mut a = vec![
        os("convert"),
        input.as_os_str(),
        os("--plan"),
        plan.as_os_str(),
    ];
    a.extend([os("--parts"), os(&n), os("--json")]);
    a.extend(extra.iter().map(|s| os(s)));
    ok(run(&a))
}

fn part_args<'a>(
    input: &'a Path,
    plan: &'a Path,
    i: &'a str,
    out: &'a Path,
    extra: &[&'a str],
) -> Vec<&'a std::ffi::OsStr> {
    let mut a = vec![
        os("convert"),
        input.as_os_str(),
        os("--plan"),
        plan.as_os_str(),
    ];
    a.extend([os("--part"), os(i), os("-o"), out.as_os_str(), os("--json")]);
    a.extend(extra.iter().map(|s| os(s)));
    a
}

/// Routes chunk `c` of `chunks` of `input` into `dir`; returns the step's report.
fn route(input: &Path, plan: &Path, dir: &Path, c: usize, chunks: usize) -> serde_json::Value {
    let (c, k) = (c.to_string(), chunks.to_string());
    let mut a = vec![
        os("convert"),
        input.as_os_str(),
        os("--plan"),
        plan.as_os_str(),
        os("--route"),
        dir.as_os_str(),
    ];
    a.extend([os("--route-chunk"), os(&c), os("--route-chunks"), os(&k)]);
    a.push(os("--json"));
    ok(run(&a))
}

/// Runs every part (both phases) and the merge into `out`, after routing the input in
/// `chunks` chunks when given (the parts then read their routed files); returns the plan's,
/// the routing steps', the samples' and the builds' reports.
fn shard_steps(
    input: &Path,
    work: &Path,
    parts: usize,
    plan_extra: &[&str],
    part_limit: &str,
    chunks: Option<usize>,
    out: &Path,
) -> Vec<serde_json::Value> {
    let plan_path = work.join("plan.json");
    let p = plan(input, &plan_path, parts, plan_extra);
    assert_eq!(p["partSplats"].as_array().unwrap().len(), parts);
    let route_dir = work.join("route");
    let mut all = vec![p];
    for c in 0..chunks.unwrap_or(0) {
        all.push(route(input, &plan_path, &route_dir, c, chunks.unwrap()));
    }
    let mut common = vec!["--memory-limit", part_limit];
    let route_arg = route_dir.to_str().unwrap();
    if chunks.is_some() {
        common.extend(["--route", route_arg]);
    }
    let samples: Vec<PathBuf> = (0..parts).map(|i| work.join(format!("s{i}"))).collect();
    for (i, s) in samples.iter().enumerate() {
        let n = i.to_string();
        let mut a = part_args(input, &plan_path, &n, s, &["--phase", "samples"]);
        a.extend(common.iter().map(|s| os(s)));
        all.push(ok(run(&a)));
    }
    let dirs: Vec<PathBuf> = (0..parts).map(|i| work.join(format!("p{i}"))).collect();
    for (i, d) in dirs.iter().enumerate() {
        let n = i.to_string();
        let mut a = part_args(input, &plan_path, &n, d, &common);
        a.push(os("--samples"));
        a.extend(samples.iter().map(|s| s.as_os_str()));
        all.push(ok(run(&a)));
    }
    let mut a = vec![os("merge"), plan_path.as_os_str()];
    // Parts in any order.
    a.extend(dirs.iter().rev().map(|d| d.as_os_str()));
    a.extend([os("-o"), out.as_os_str(), os("--json")]);
    let m = ok(run(&a));
    assert_eq!(m["copiedBytes"], 0, "same file system: tiles hard-linked");
    all
}

/// [`shard_steps`] without routing; returns the build reports.
fn shard(
    input: &Path,
    work: &Path,
    parts: usize,
    plan_extra: &[&str],
    part_limit: &str,
    out: &Path,
) -> Vec<serde_json::Value> {
    let all = shard_steps(input, work, parts, plan_extra, part_limit, None, out);
    all[all.len() - parts..].to_vec()
}

/// A city converted in 4 and in 16 parts with the input routed (in 4 and 3 chunks) gives the
/// single-machine bytes, and the whole sharded run reads at most 3 times the input's bytes
/// from the input file (the steps' own count: the plan's two passes, the routing's one; the
/// parts read only their routed files), where a part that reads the input reads it whole.
#[test]
fn routed_parts_read_the_input_at_most_three_times() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    let n = 200_000u64;
    write_city_splat(&input, n as usize, 41);
    let size = std::fs::metadata(&input).unwrap().len();
    let extra = ["--max-splats", "2048", "--no-utility"];
    let base = tmp.path().join("base");
    single(&input, &base, &extra);
    for (parts, chunks) in [(4, 4), (16, 3)] {
        let work = tmp.path().join(format!("w{parts}"));
        let out = tmp.path().join(format!("out{parts}"));
        let all = shard_steps(&input, &work, parts, &extra, "256MiB", Some(chunks), &out);
        assert_same_files(&base, &out);
        let read: Vec<u64> = all
            .iter()
            .map(|r| r["inputReadBytes"].as_u64().expect("inputReadBytes"))
            .collect();
        let total: u64 = read.iter().sum();
        let routed: u64 = all[1..=chunks]
            .iter()
            .map(|r| r["splats"].as_u64().unwrap())
            .sum();
        assert_eq!(routed, n);
        assert!(read[1..=chunks].iter().sum::<u64>() >= size, "{read:?}");
        assert!(read[chunks + 1..].iter().all(|&b| b == 0), "{read:?}");
        assert!(
            total <= 3 * size,
            "{parts} parts read {total} bytes of a {size}-byte input: {read:?}"
        );
        eprintln!(
            "{parts} parts, {chunks} routing chunks: {total} bytes read of {size} ({:.3}x)",
            total as f64 / size as f64
        );
        // Without routing, a part reads the input whole.
        let p0 = work.join("unrouted");
        let plan_path = work.join("plan.json");
        let r = ok(run(&part_args(
            &input,
            &plan_path,
            "0",
            &p0,
            &["--phase", "samples"],
        )));
        assert!(r["inputReadBytes"].as_u64().unwrap() >= size, "{r}");
        std::fs::remove_dir_all(&work).unwrap();
        std::fs::remove_dir_all(&out).unwrap();
    }
}

/// An SPZ input (gzipped, read whole) is routed in one chunk, and gives the single-machine
/// bytes; several chunks are refused.
#[test]
fn an_spz_input_is_routed_in_one_chunk() {
    let tmp = tempfile::tempdir().unwrap();
    let input = scene("biker.spz");
    let extra = ["--max-splats", "4096", "--no-utility"];
    let base = tmp.path().join("base");
    single(&input, &base, &extra);
    let (work, out) = (tmp.path().join("w"), tmp.path().join("out"));
    let all = shard_steps(&input, &work, 3, &extra, "256MiB", Some(1), &out);
    assert_same_files(&base, &out);
    assert!(all[2..].iter().all(|r| r["inputReadBytes"] == 0));
    let err = refused(
        run(&[
            os("convert"),
            input.as_os_str(),
            os("--plan"),
            work.join("plan.json").as_os_str(),
            os("--route"),
            work.join("r2").as_os_str(),
            os("--route-chunks"),
            os("2"),
        ]),
        "route it in one chunk",
    );
    assert!(err.contains("biker.spz"), "{err}");
}

/// Routing refuses another input of the same size and splat count, and a part refuses routed
/// files that are missing, truncated or of another plan, naming the file (exit 2); a routing
/// step run again gives the same files.
#[test]
fn routing_refuses_foreign_inputs_and_broken_files() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 60_000, 13);
    let extra = [
        "--max-splats",
        "2048",
        "--no-utility",
        "--lod-radius",
        "0.5",
    ];
    let plan_path = tmp.path().join("plan.json");
    plan(&input, &plan_path, 2, &extra);
    let dir = tmp.path().join("route");
    let route_args = |input: &Path, c: &str| -> Vec<std::ffi::OsString> {
        let mut a: Vec<std::ffi::OsString> = vec![
            "convert".into(),
            input.into(),
            "--plan".into(),
            plan_path.clone().into(),
            "--route".into(),
            dir.clone().into(),
        ];
        a.extend(["--route-chunk", c, "--route-chunks", "2", "--json"].map(Into::into));
        a
    };
    let go = |a: Vec<std::ffi::OsString>| Command::new(bin()).args(a).output().unwrap();
    // The same records in another order: same size and count, other content.
    let other = tmp.path().join("other.splat");
    let mut bytes = std::fs::read(&input).unwrap();
    bytes.reverse();
    let recs: Vec<u8> = bytes
        .chunks(32)
        .flat_map(|r| r.iter().rev().copied().collect::<Vec<_>>())
        .collect();
    std::fs::write(&other, &recs).unwrap();
    refused(go(route_args(&other, "1")), "not the input of plan");
    assert!(!dir.join("chunk-1").exists(), "no partial output");
    // Chunk 1 only: the part misses chunk 0.
    ok(go(route_args(&input, "1")));
    let out = tmp.path().join("p0");
    let part = |out: &Path| {
        let mut a = part_args(&input, &plan_path, "0", out, &[]);
        a.extend([os("--route"), dir.as_os_str()]);
        run(&a)
    };
    refused(part(&out), "chunk-0/route.json: missing");
    ok(go(route_args(&input, "0")));
    let before = tree_files(&dir);
    ok(go(route_args(&input, "0")));
    assert_eq!(tree_files(&dir), before, "a rerun gives the same files");
    // A truncated routed file.
    let f = dir.join("chunk-1/part-0.spill");
    let len = std::fs::metadata(&f).unwrap().len();
    let file = std::fs::OpenOptions::new().write(true).open(&f).unwrap();
    file.set_len(len - 7).unwrap();
    refused(part(&out), "chunk-1/part-0.spill: byte ");
    assert!(!out.exists(), "no partial output");
    // Routed for another plan.
    ok(go(route_args(&input, "1")));
    plan(&input, &plan_path, 3, &extra);
    refused(part(&out), "routed for another plan");
}

/// 400k splats of a city in 4 parts (parts spilling at 64 MiB) and in 1 and 3 parts give the
/// single-machine bytes, and validate; each part's peak RSS stays under its memory limit.
#[test]
fn four_parts_give_the_single_machine_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 400_000, 17);
    let extra = ["--max-splats", "4096", "--no-utility"];
    let base = tmp.path().join("base");
    single(&input, &base, &extra);
    for (parts, limit) in [(4, "64MiB"), (1, "1GiB"), (3, "1GiB")] {
        let work = tmp.path().join(format!("w{parts}"));
        let out = tmp.path().join(format!("out{parts}"));
        let reports = shard(&input, &work, parts, &extra, limit, &out);
        assert_same_files(&base, &out);
        let splats: u64 = reports.iter().map(|r| r["splats"].as_u64().unwrap()).sum();
        assert_eq!(splats, 400_000);
        for r in &reports {
            let rss = r["peakRssMiB"].as_f64().unwrap();
            if limit == "64MiB" {
                assert!(r["spillBytes"].as_u64().unwrap() > 0, "{r}");
                assert!(rss < 64.0, "part over its memory limit: {r}");
            }
        }
        if parts == 4 {
            assert_valid_with_extents(&out);
            // A part run again (a retried task) gives the same bytes.
            let again = tmp.path().join("again");
            std::fs::create_dir(&again).unwrap();
            let plan_path = work.join("plan.json");
            let samples: Vec<PathBuf> = (0..4).map(|i| work.join(format!("s{i}"))).collect();
            let p2 = work.join("p2");
            let before = tree_files(&p2);
            let mut a = part_args(&input, &plan_path, "2", &p2, &[]);
            a.push(os("--samples"));
            a.extend(samples.iter().map(|s| s.as_os_str()));
            ok(run(&a));
            let after = tree_files(&p2);
            assert_eq!(
                after.keys().collect::<Vec<_>>(),
                before.keys().collect::<Vec<_>>()
            );
            for (k, v) in &before {
                assert!(v == &after[k], "{} differs after a rerun", k.display());
            }
        }
        std::fs::remove_dir_all(&work).unwrap();
        std::fs::remove_dir_all(&out).unwrap();
    }
}

/// Every variant with utilities measured at the final switching distances (parts measure their
/// tiles, the merge the tiles above them and the units' root leaves) on an SH1 PLY (wide spill
/// records), and a georeferenced scene, give the single-machine bytes.
#[test]
fn variants_and_georeferenced_scenes_merge_identically() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("scene.ply");
    let mut s: Splats = random_splats(30_000, 1, 30.0, 5);
    s.positions
        .iter_mut()
        .step_by(3)
        .for_each(|p| *p = [p[0] * 0.05, p[1] * 0.05, p[2] * 0.05]);
    write_ply_file(&input, &s);
    for (name, extra) in [
        (
            "variants",
            &["--max-splats", "1024", "--variants", "all"][..],
        ),
        (
            "geo",
            &[
                "--max-splats",
                "1024",
                "--no-utility",
                "--origin",
                "7.44,46.95,550",
            ][..],
        ),
        (
            "radius",
            &[
                "--max-splats",
                "1024",
                "--no-utility",
                "--lod-radius",
                "0.5",
            ][..],
        ),
        (
            "nolod",
            &["--max-splats", "1024", "--no-utility", "--no-lod"][..],
        ),
    ] {
        let base = tmp.path().join(format!("base-{name}"));
        single(&input, &base, extra);
        let work = tmp.path().join(format!("w-{name}"));
        let out = tmp.path().join(format!("out-{name}"));
        shard(&input, &work, 4, extra, "256MiB", &out);
        assert_same_files(&base, &out);
        // Routed in 2 chunks (wide records, decoded whole), the same bytes.
        let (work, out) = (work.join("routed"), out.join("routed"));
        shard_steps(&input, &work, 4, extra, "256MiB", Some(2), &out);
        assert_same_files(&base, &out);
    }
}

/// Splats with NaN/Inf are dropped by the plan's count and skipped by every part (whole chunks
/// decoded, indices among the finite splats), and the output is the single machine's.
#[test]
fn non_finite_splats_are_dropped_alike() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 120_000, 29);
    let mut bytes = std::fs::read(&input).unwrap();
    for i in (0..120_000).step_by(997) {
        bytes[i * 32..i * 32 + 4].copy_from_slice(&f32::NAN.to_le_bytes());
    }
    std::fs::write(&input, &bytes).unwrap();
    let extra = ["--max-splats", "2048", "--no-utility"];
    let base = tmp.path().join("base");
    single(&input, &base, &extra);
    let out = tmp.path().join("out");
    let reports = shard(&input, &tmp.path().join("w"), 3, &extra, "64MiB", &out);
    let splats: u64 = reports.iter().map(|r| r["splats"].as_u64().unwrap()).sum();
    assert_eq!(splats, 120_000 - 121);
    assert_same_files(&base, &out);
    // Routed in one chunk (several are refused with NaN/Inf splats), the same bytes.
    let w = tmp.path().join("wr");
    let routed = tmp.path().join("routed");
    shard_steps(&input, &w, 3, &extra, "64MiB", Some(1), &routed);
    assert_same_files(&base, &routed);
    let err = refused(
        run(&[
            os("convert"),
            input.as_os_str(),
            os("--plan"),
            w.join("plan.json").as_os_str(),
            os("--route"),
            w.join("r2").as_os_str(),
            os("--route-chunks"),
            os("2"),
        ]),
        "route it in one chunk",
    );
    assert!(err.contains("city.splat"), "{err}");
}

/// A scene that fits one leaf is one unit (the root) in the first part; the other parts are
/// empty, and the merge still gives the single-machine bytes.
#[test]
fn a_single_tile_scene_is_one_part() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("small.splat");
    write_city_splat(&input, 2_000, 3);
    let base = tmp.path().join("base");
    single(&input, &base, &["--variants", "all"]);
    let out = tmp.path().join("out");
    shard(
        &input,
        &tmp.path().join("w"),
        3,
        &["--variants", "all"],
        "256MiB",
        &out,
    );
    assert_same_files(&base, &out);
}

/// Bad plans, parts out of range, another input, missing samples or parts, and parts of
/// another plan are refused (exit 2) naming the file; nothing is written.
#[test]
fn bad_plans_and_parts_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("city.splat");
    write_city_splat(&input, 50_000, 9);
    let plan_path = tmp.path().join("plan.json");
    plan(
        &input,
        &plan_path,
        2,
        &["--max-splats", "2048", "--no-utility"],
    );
    let text = std::fs::read_to_string(&plan_path).unwrap();
    let out = tmp.path().join("p0");

    // Truncated JSON: the byte offset is named.
    let bad = tmp.path().join("bad.json");
    std::fs::write(&bad, &text[..text.len() / 2]).unwrap();
    let err = refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "bad.json: byte ",
    );
    assert!(!err.contains("panicked"));
    // Another version, a unit moved out of order, splats not adding up.
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["splat2tilesPlan"] = 9.into();
    std::fs::write(&bad, v.to_string()).unwrap();
    refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "plan version 9",
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["units"][0]["splats"] = 1.into();
    std::fs::write(&bad, v.to_string()).unwrap();
    refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "splats where the histogram has",
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["histogram"][0][1] = (v["histogram"][0][1].as_u64().unwrap() + 1).into();
    std::fs::write(&bad, v.to_string()).unwrap();
    refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "the histogram holds",
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["units"].as_array_mut().unwrap().reverse();
    std::fs::write(&bad, v.to_string()).unwrap();
    refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "invalid plan",
    );
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["layout"]["size"][0] = "7ff0000000000000".into();
    std::fs::write(&bad, v.to_string()).unwrap();
    refused(
        run(&part_args(&input, &bad, "0", &out, &[])),
        "layout.min/size",
    );
    // Part out of range; another input; build without the samples.
    refused(
        run(&part_args(&input, &plan_path, "2", &out, &[])),
        "parts 0 to 1",
    );
    let other = tmp.path().join("other.splat");
    write_city_splat(&other, 50_001, 9);
    refused(
        run(&part_args(
            &other,
            &plan_path,
            "0",
            &out,
            &["--phase", "samples"],
        )),
        "not the input of plan",
    );
    refused(
        run(&part_args(&input, &plan_path, "0", &out, &[])),
        "samples of all 2 parts",
    );
    assert!(!out.exists());
    // A plan never replaces a file that is not one.
    let mine = tmp.path().join("notes.json");
    std::fs::write(&mine, "{\"mine\": 1}").unwrap();
    let o = run(&[
        os("convert"),
        input.as_os_str(),
        os("--plan"),
        mine.as_os_str(),
        os("--parts"),
        os("2"),
    ]);
    refused(o, "not a splat2tiles plan");
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "{\"mine\": 1}");

    // Merge: too few parts, and a part of another plan.
    let s: Vec<PathBuf> = (0..2).map(|i| tmp.path().join(format!("s{i}"))).collect();
    let p: Vec<PathBuf> = (0..2).map(|i| tmp.path().join(format!("p{i}"))).collect();
    for (i, si) in s.iter().enumerate() {
        let n = i.to_string();
        ok(run(&part_args(
            &input,
            &plan_path,
            &n,
            si,
            &["--phase", "samples"],
        )));
    }
    for (i, pi) in p.iter().enumerate() {
        let n = i.to_string();
        let mut a = part_args(&input, &plan_path, &n, pi, &["--samples"]);
        a.extend(s.iter().map(|d| d.as_os_str()));
        ok(run(&a));
    }
    let merged = tmp.path().join("merged");
    let o = run(&[
        os("merge"),
        plan_path.as_os_str(),
        p[0].as_os_str(),
        os("-o"),
        merged.as_os_str(),
    ]);
    refused(o, "2 parts; 1 part folders");
    let plan2 = tmp.path().join("plan2.json");
    plan(&input, &plan2, 2, &["--max-splats", "1024", "--no-utility"]);
    let o = run(&[
        os("merge"),
        plan2.as_os_str(),
        p[0].as_os_str(),
        p[1].as_os_str(),
        os("-o"),
        merged.as_os_str(),
    ]);
    refused(o, "another plan");
    assert!(!merged.exists());
    let o = run(&[
        os("merge"),
        plan_path.as_os_str(),
        p[0].as_os_str(),
        p[0].as_os_str(),
        os("-o"),
        merged.as_os_str(),
    ]);
    refused(o, "each of the parts 0 to 1 once");
    ok(run(&[
        os("merge"),
        plan_path.as_os_str(),
        p[1].as_os_str(),
        p[0].as_os_str(),
        os("-o"),
        merged.as_os_str(),
        os("--json"),
    ]));
    assert_valid_with_extents(&merged);
}
