//! Output safety: only absent, empty or earlier splat2tiles folders are written; concurrent runs
//! refuse; dead runs' leftovers are cleaned; errors name the user's path.

use super::common::bin;
use super::inputs::{ply, record, write_splat};
use super::{assert_valid, convert, hidden, set_immutable, stderr};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime};

fn small_input(dir: &Path) -> PathBuf {
    let p = dir.join("small.ply");
    std::fs::write(&p, ply(50, record)).unwrap();
    p
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_folder_with_a_tileset_json_and_user_files_is_refused_and_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("mine");
    std::fs::create_dir_all(out.join("photos")).unwrap();
    std::fs::write(out.join("tileset.json"), "{}").unwrap();
    std::fs::write(out.join("notes.txt"), "keep me").unwrap();
    std::fs::write(out.join("photos/a.jpg"), "jpeg").unwrap();
    let o = convert(&[s(&input), "-o", s(&out)]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(s(&out)), "names the folder: {err}");
    assert!(
        err.contains("notes.txt") && err.contains("photos/"),
        "says what is in it: {err}"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "keep me"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("photos/a.jpg")).unwrap(),
        "jpeg"
    );
    assert_eq!(
        std::fs::read_to_string(out.join("tileset.json")).unwrap(),
        "{}"
    );
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
}

#[test]
fn an_earlier_output_is_replaced_but_not_when_it_holds_user_files() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("out");
    let o = convert(&[s(&input), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join(".splat2tiles-output.json").is_file());
    // Ours: replaced.
    std::fs::write(out.join("tileset.json"), "{\"stale\":1}").unwrap();
    let o = convert(&[s(&input), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !std::fs::read_to_string(out.join("tileset.json"))
            .unwrap()
            .contains("stale")
    );
    // A file of the user's put into it: refused, kept.
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let o = convert(&[s(&input), "-o", s(&out)]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("notes.txt") && err.contains(s(&out)), "{err}");
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "mine"
    );
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
}

/// Sets a file's modification time `secs` seconds into the past.
fn age(path: &Path, secs: u64) {
    let f = File::options().write(true).open(path).unwrap();
    f.set_modified(SystemTime::now() - Duration::from_secs(secs))
        .unwrap();
}

#[test]
fn a_live_runs_lock_refuses_a_second_run_which_leaves_its_staging_alone() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("out");
    // What a live run into `out` holds: its locked lock file and its staging folder.
    let lock_path = tmp.path().join(".out.s2t-lock-999999-0");
    let lock = File::create(&lock_path).unwrap();
    lock.lock().unwrap();
    age(&lock_path, 3600);
    let staging = tmp.path().join(".out.s2t-tmp-999999-0");
    std::fs::create_dir_all(staging.join("tiles")).unwrap();
    std::fs::write(staging.join("tiles/a.glb"), "in progress").unwrap();
    let o = convert(&[s(&input), "-o", s(&out)]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("another splat2tiles run") && err.contains(s(&out)),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(staging.join("tiles/a.glb")).unwrap(),
        "in progress"
    );
    assert!(!out.exists());
    // Once that run is gone (its lock released), the next run cleans up after it.
    drop(lock);
    let o = convert(&[s(&input), "-o", s(&out)]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("interrupted run"),
        "says what it cleaned: {err}"
    );
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
    assert!(out.join("tileset.json").is_file());
}

#[test]
fn leftovers_of_a_killed_run_are_cleaned_by_the_next_run() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("out");
    // An out-of-memory kill leaves the staging folder and an unlocked lock file.
    let staging = tmp.path().join(".out.s2t-tmp-424242-0");
    std::fs::create_dir_all(staging.join("tiles/best/3")).unwrap();
    std::fs::write(staging.join("tiles/best/3/0.glb"), vec![7u8; 4096]).unwrap();
    let lock_path = tmp.path().join(".out.s2t-lock-424242-0");
    File::create(&lock_path).unwrap();
    age(&lock_path, 3600);
    // A staging folder whose lock file is gone entirely (killed while cleaning up).
    std::fs::create_dir_all(tmp.path().join(".out.s2t-tmp-424243-0")).unwrap();
    // A run killed a moment ago (its lock file is fresh, but its process is gone).
    std::fs::create_dir_all(tmp.path().join(".out.s2t-tmp-3999999-0")).unwrap();
    File::create(tmp.path().join(".out.s2t-lock-3999999-0")).unwrap();
    // Another output's leftovers are not ours to touch.
    let other = tmp.path().join(".other.s2t-tmp-424242-0");
    std::fs::create_dir_all(&other).unwrap();
    let o = convert(&[s(&input), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        hidden(tmp.path()),
        vec![".other.s2t-tmp-424242-0".to_string()]
    );
}

#[test]
fn a_result_moved_aside_by_a_killed_commit_is_put_back() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("out");
    let o = convert(&[s(&input), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Killed between moving the earlier result aside and moving the new one in.
    let aside = tmp.path().join(".out.s2t-old-515151-0");
    std::fs::rename(&out, &aside).unwrap();
    // A failing run (bad input) must not lose it: it is restored, then the run refuses.
    let bad = tmp.path().join("bad.ply");
    std::fs::write(&bad, b"ply\nformat ascii 1.0\nend_header\n").unwrap();
    let o = convert(&[s(&bad), "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    // The reader fails before the output is touched; the next good run restores and replaces.
    let o = convert(&[s(&input), "-o", s(&out)]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("restored"), "{err}");
    assert!(out.join("tileset.json").is_file());
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
}

#[test]
fn a_failed_delete_of_the_earlier_result_is_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let out = tmp.path().join("out");
    let o = convert(&[s(&input), "-o", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    // An undeletable file inside the earlier result (immutable: root ignores permissions).
    let stuck = out.join("subtrees");
    if !set_immutable(&stuck, true) {
        eprintln!("chattr +i unsupported here; cannot make a deletion fail");
        return;
    }
    let o = convert(&[s(&input), "-o", s(&out)]);
    set_immutable(&stuck, false);
    let err = stderr(&o);
    for h in hidden(tmp.path()) {
        set_immutable(&tmp.path().join(&h).join("subtrees"), false);
    }
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("earlier result could not be deleted") && err.contains(".out.s2t-old-"),
        "not silent: {err}"
    );
}

#[test]
fn an_unwritable_parent_folder_is_reported_with_the_users_path() {
    let tmp = tempfile::tempdir().unwrap();
    let input = small_input(tmp.path());
    let parent = tmp.path().join("ro");
    std::fs::create_dir(&parent).unwrap();
    let out = parent.join("x");
    if !set_immutable(&parent, true) {
        eprintln!("chattr +i unsupported here");
        return;
    }
    let o = convert(&[s(&input), "-o", s(&out)]);
    set_immutable(&parent, false);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let first = err.lines().next().unwrap_or("");
    assert!(
        first.contains(&format!("{}:", out.display())),
        "names -o: {err}"
    );
    assert!(
        !err.contains("s2t-tmp") && !err.contains("s2t-lock"),
        "{err}"
    );
}

#[test]
fn two_real_runs_into_one_folder_the_second_refuses_the_first_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("big.splat");
    write_splat(&input, 1_500_000);
    let small = small_input(tmp.path());
    let out = tmp.path().join("out");
    let mut first = Command::new(bin())
        .args([
            "convert",
            s(&input),
            "-o",
            s(&out),
            "--quiet",
            "--no-utility",
        ])
        .args(["--max-splats", "4000"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t = Instant::now();
    while !hidden(tmp.path())
        .iter()
        .any(|h| h.starts_with(".out.s2t-tmp-"))
    {
        assert!(
            t.elapsed() < Duration::from_secs(300),
            "first run never staged"
        );
        assert!(first.try_wait().unwrap().is_none(), "first run ended early");
        std::thread::sleep(Duration::from_millis(5));
    }
    // A quick second run into the same folder while the first writes: it must refuse. (It used
    // to delete the first's staging folder as leftovers and finish first; the first then
    // renamed a half-written folder into place and exited 0.)
    let second = convert(&[s(&small), "-o", s(&out)]);
    let err = stderr(&second);
    assert_eq!(second.status.code(), Some(2), "{err}");
    assert!(err.contains("another splat2tiles run"), "{err}");
    let first = first.wait_with_output().unwrap();
    assert!(first.status.success(), "first run: {}", stderr(&first));
    assert_valid(&out.join("tileset.json"));
    let ts = std::fs::read_to_string(out.join("tileset.json")).unwrap();
    assert!(ts.contains("\"splats\": 1500000"), "the first run's output");
    assert!(hidden(tmp.path()).is_empty(), "{:?}", hidden(tmp.path()));
}

/// A sharded conversion whose output names one of its own inputs: `convert --part` into a
/// samples folder it reads, `merge` into one of its parts. Both are refused with exit 2 and the
/// input is kept; the same steps into fresh folders then succeed.
#[test]
fn a_sharded_step_into_one_of_its_inputs_is_refused_and_the_input_kept() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in.splat");
    write_splat(&input, 20_000);
    let plan = tmp.path().join("plan.json");
    let run = |args: &[&str]| {
        Command::new(bin())
            .args(args)
            .arg("--quiet")
            .output()
            .unwrap()
    };
    let o = run(&["convert", s(&input), "--plan", s(&plan), "--parts", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let samples: Vec<PathBuf> = (0..2).map(|i| tmp.path().join(format!("s{i}"))).collect();
    for (i, dir) in samples.iter().enumerate() {
        let i = i.to_string();
        let o = run(&[
            "convert",
            s(&input),
            "--plan",
            s(&plan),
            "--part",
            &i,
            "--phase",
            "samples",
            "-o",
            s(dir),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let before = super::common::tree_files(&samples[0]);
    let part = |i: &str, out: &Path| {
        run(&[
            "convert",
            s(&input),
            "--plan",
            s(&plan),
            "--part",
            i,
            "-o",
            s(out),
            "--samples",
            s(&samples[0]),
            s(&samples[1]),
        ])
    };
    let o = part("0", &samples[0]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("which this run reads"),
        "{}",
        stderr(&o)
    );
    assert_eq!(super::common::tree_files(&samples[0]), before);
    let parts: Vec<PathBuf> = (0..2).map(|i| tmp.path().join(format!("p{i}"))).collect();
    for (i, out) in parts.iter().enumerate() {
        let o = part(&i.to_string(), out);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let kept = super::common::tree_files(&parts[0]);
    let o = run(&[
        "merge",
        s(&plan),
        s(&parts[0]),
        s(&parts[1]),
        "-o",
        s(&parts[0]),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("which this run reads"),
        "{}",
        stderr(&o)
    );
    assert_eq!(super::common::tree_files(&parts[0]), kept);
    let merged = tmp.path().join("merged");
    let o = run(&[
        "merge",
        s(&plan),
        s(&parts[0]),
        s(&parts[1]),
        "-o",
        s(&merged),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_valid(&merged);
}
