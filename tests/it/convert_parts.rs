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

/// Runs every part (both phases) and the merge into `out`; returns the build reports.
fn shard(
    input: &Path,
    work: &Path,
    parts: usize,
    plan_extra: &[&str],
    part_limit: &str,
    out: &Path,
) -> Vec<serde_json::Value> {
    let plan_path = work.join("plan.json");
    let p = plan(input, &plan_path, parts, plan_extra);
    assert_eq!(p["partSplats"].as_array().unwrap().len(), parts);
    let samples: Vec<PathBuf> = (0..parts).map(|i| work.join(format!("s{i}"))).collect();
    for (i, s) in samples.iter().enumerate() {
        let n = i.to_string();
        let mut a = part_args(input, &plan_path, &n, s, &["--phase", "samples"]);
        a.extend([os("--memory-limit"), os(part_limit)]);
        ok(run(&a));
    }
    let mut reports = Vec::new();
    let dirs: Vec<PathBuf> = (0..parts).map(|i| work.join(format!("p{i}"))).collect();
    for (i, d) in dirs.iter().enumerate() {
        let n = i.to_string();
        let mut a = part_args(input, &plan_path, &n, d, &["--memory-limit", part_limit]);
        a.push(os("--samples"));
        a.extend(samples.iter().map(|s| s.as_os_str()));
        reports.push(ok(run(&a)));
    }
    let mut a = vec![os("merge"), plan_path.as_os_str()];
    // Parts in any order.
    a.extend(dirs.iter().rev().map(|d| d.as_os_str()));
    a.extend([os("-o"), out.as_os_str(), os("--json")]);
    let m = ok(run(&a));
    assert_eq!(m["copiedBytes"], 0, "same file system: tiles hard-linked");
    reports
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
