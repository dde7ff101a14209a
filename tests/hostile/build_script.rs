//! `viewer/web/build.sh` on a copy of the script with stub tools on PATH (no wasm build): it
//! honours `CARGO_TARGET_DIR`, and a failed `rustup target add` stops it with a message.

use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::process::Command;

fn script(dir: &Path, name: &str, body: &str) {
    let p = dir.join(name);
    std::fs::write(&p, format!("#!/usr/bin/env bash\n{body}\n")).unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// A fake repository root holding build.sh and a Cargo.lock, plus stub rustc/rustup/cargo;
/// `wasm_target` says whether the stub sysroot has the wasm32 target, `rustup_ok` whether
/// `rustup target add` succeeds. Returns (root, bin dir, log file).
fn setup(tmp: &Path, wasm_target: bool, rustup_ok: bool) -> (PathBuf, PathBuf, PathBuf) {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let root = tmp.join("repo");
    std::fs::create_dir_all(root.join("viewer/web")).unwrap();
    std::fs::copy(
        repo.join("viewer/web/build.sh"),
        root.join("viewer/web/build.sh"),
    )
    .unwrap();
    std::fs::write(
        root.join("Cargo.lock"),
        "[[package]]\nname = \"wasm-bindgen\"\nversion = \"0.2.99\"\n",
    )
    .unwrap();
    let sysroot = tmp.join("sysroot");
    std::fs::create_dir_all(sysroot.join("lib/rustlib")).unwrap();
    if wasm_target {
        std::fs::create_dir_all(sysroot.join("lib/rustlib/wasm32-unknown-unknown")).unwrap();
    }
    let bin = tmp.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    let log = tmp.join("log");
    let log_s = log.display();
    script(&bin, "rustc", &format!("echo {}", sysroot.display()));
    script(
        &bin,
        "rustup",
        &format!(
            "echo \"rustup $*\" >> {log_s}; exit {}",
            if rustup_ok { 0 } else { 1 }
        ),
    );
    // `cargo install` puts a wasm-bindgen stub into --root; `cargo build` does nothing.
    script(
        &bin,
        "cargo",
        &format!(
            "echo \"cargo $*\" >> {log_s}\n\
             if [ \"$1\" = install ]; then\n\
               r=\"${{@: -1}}\"; mkdir -p \"$r/bin\"\n\
               printf '#!/usr/bin/env bash\\nif [ \"$1\" = --version ]; then echo \"wasm-bindgen 0.2.99\"; exit 0; fi\\necho \"wasm-bindgen $*\" >> {log_s}\\nfor a in \"$@\"; do [ \"$p\" = --out-dir ] && mkdir -p \"$a\"; p=\"$a\"; done\\n' > \"$r/bin/wasm-bindgen\"\n\
               chmod +x \"$r/bin/wasm-bindgen\"\n\
             fi"
        ),
    );
    (root, bin, log)
}

fn run(root: &Path, bin: &Path, target_dir: Option<&Path>) -> std::process::Output {
    let path = format!(
        "{}:{}",
        bin.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut c = Command::new("bash");
    c.arg(root.join("viewer/web/build.sh")).env("PATH", path);
    match target_dir {
        Some(t) => c.env("CARGO_TARGET_DIR", t),
        None => c.env_remove("CARGO_TARGET_DIR"),
    };
    c.output().unwrap()
}

#[test]
fn build_script_honours_cargo_target_dir() {
    let tmp = tempfile::tempdir().unwrap();
    let (root, bin, log) = setup(tmp.path(), true, true);
    let target = tmp.path().join("elsewhere");
    let o = run(&root, &bin, Some(&target));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let log = std::fs::read_to_string(log).unwrap();
    let wasm = target.join("wasm32-unknown-unknown/release/splat2tiles_web.wasm");
    assert!(log.contains(&wasm.display().to_string()), "{log}");
    assert!(target.join("tools/bin/wasm-bindgen").is_file());
    assert!(
        !root.join("target").exists(),
        "nothing under the default target/"
    );
    assert!(root.join("viewer/web/pkg").is_dir());
}

#[test]
fn build_script_stops_when_the_wasm_target_cannot_be_added() {
    let tmp = tempfile::tempdir().unwrap();
    let (root, bin, log) = setup(tmp.path(), false, false);
    let o = run(&root, &bin, None);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success(),
        "a failed rustup target add must fail the build"
    );
    assert!(
        err.contains("rustup target add wasm32-unknown-unknown"),
        "{err}"
    );
    let log = std::fs::read_to_string(log).unwrap_or_default();
    assert!(
        !log.contains("cargo build"),
        "stopped before building: {log}"
    );
}
