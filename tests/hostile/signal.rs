//! SIGINT in the middle of a multi-million-splat conversion: exit 130, and nothing left behind
//! (the staging folder is removed only after the worker threads stopped writing tiles).

use super::common::bin;
use super::hidden;
use super::inputs::write_splat;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Files under `dir`, recursively (0 when it vanished meanwhile).
fn count_files(dir: &Path) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    rd.flatten()
        .map(|e| {
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                count_files(&e.path())
            } else {
                1
            }
        })
        .sum()
}

#[cfg(unix)]
#[test]
fn sigint_while_tiles_are_written_leaves_nothing_behind() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("big.splat");
    write_splat(&input, 2_000_000);
    // Interrupt at different moments after the workers began writing tiles.
    for (round, delay_ms) in [0u64, 150, 600].into_iter().enumerate() {
        let out = tmp.path().join("out");
        let mut child = Command::new(bin())
            .args([
                "convert",
                input.to_str().unwrap(),
                "-o",
                out.to_str().unwrap(),
            ])
            .args(["--quiet", "--no-utility", "--max-splats", "2000"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let t = Instant::now();
        let mut writing = false;
        while t.elapsed() < Duration::from_secs(300) && child.try_wait().unwrap().is_none() {
            let staging = hidden(tmp.path())
                .into_iter()
                .find(|h| h.starts_with(".out.s2t-tmp-"));
            if let Some(st) = staging
                && count_files(&tmp.path().join(st)) >= 20
            {
                writing = true;
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        std::thread::sleep(Duration::from_millis(delay_ms));
        let sent = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let o = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            writing,
            "round {round}: never saw tiles being written; {err}"
        );
        let left = hidden(tmp.path());
        if o.status.success() {
            // Finished before the signal landed: the output must then be whole.
            assert!(out.join("tileset.json").is_file());
            std::fs::remove_dir_all(&out).unwrap();
        } else {
            assert_eq!(o.status.code(), Some(130), "round {round}: {err}");
            assert!(!out.exists(), "round {round}: partial output");
        }
        assert!(
            left.is_empty(),
            "round {round}: left behind {left:?}; {err}"
        );
    }
}
