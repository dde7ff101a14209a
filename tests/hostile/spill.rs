//! The out-of-core converter's spill files live in the staging folder: a run killed while
//! spilling (as by the kernel's OOM killer) leaves the earlier result intact, and the next run
//! removes the dead run's staging folder, spill files and all, before it starts.

use super::common::bin;
use super::inputs::{ply, record, write_splat};
use super::{assert_valid, convert, hidden, stderr};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Bytes of the spill files under a staging folder (0 when absent).
fn spill_bytes(staging: &Path) -> u64 {
    std::fs::read_dir(staging.join(".spill"))
        .map(|rd| {
            rd.flatten()
                .filter_map(|e| e.metadata().ok())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

#[cfg(unix)]
#[test]
fn a_run_killed_while_spilling_leaves_the_earlier_result_and_the_next_run_cleans_up() {
    let tmp = tempfile::tempdir().unwrap();
    let small = tmp.path().join("small.ply");
    std::fs::write(&small, ply(50, record)).unwrap();
    let big = tmp.path().join("big.splat");
    write_splat(&big, 1_000_000);
    let out = tmp.path().join("out");
    let o = convert(&[s(&small), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let earlier = std::fs::read(out.join("tileset.json")).unwrap();

    // A spilling run (64 MiB for a million splats), killed with SIGKILL once spill files exist.
    let mut child = Command::new(bin())
        .args(["convert", s(&big), "-o", s(&out)])
        .args(["--quiet", "--no-utility", "--memory-limit", "64MiB"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t = Instant::now();
    let mut spilling = None;
    while t.elapsed() < Duration::from_secs(300) && child.try_wait().unwrap().is_none() {
        if let Some(st) = hidden(tmp.path())
            .into_iter()
            .find(|h| h.starts_with(".out.s2t-tmp-"))
            && spill_bytes(&tmp.path().join(&st)) > 1 << 20
        {
            spilling = Some(st);
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let staging = spilling.expect("the run spilled to its staging folder");
    assert!(
        tmp.path().join(&staging).is_dir(),
        "a SIGKILL cleans nothing"
    );
    assert_eq!(
        std::fs::read(out.join("tileset.json")).unwrap(),
        earlier,
        "the earlier result is intact"
    );
    assert_valid(&out.join("tileset.json"));

    // The next run removes the dead run's staging folder (spill files included) and its lock.
    let o = convert(&[s(&small), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
    assert_valid(&out.join("tileset.json"));
}
