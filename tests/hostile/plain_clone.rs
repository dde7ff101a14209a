//! A plain clone works: the README's first command converts the sample shipped in the
//! repository, with no `../shared` beside the clone (the already-built binary stands in for
//! `cargo run --release`, whose build would be too slow here).

use super::assert_valid;
use super::common::bin;
use std::path::Path;
use std::process::Command;

/// The first command block of README.md's "Two commands on a fresh machine" section.
fn readme_first_command(readme: &str) -> String {
    let section = readme
        .split("## Two commands on a fresh machine")
        .nth(1)
        .expect("README has the 'Two commands on a fresh machine' section");
    let block = section
        .split("```sh\n")
        .nth(1)
        .and_then(|b| b.split("```").next())
        .expect("a sh code block in that section");
    block.trim().to_string()
}

#[test]
fn readme_first_command_converts_in_a_plain_clone() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().unwrap();
    let clone = tmp.path().join("splat2tiles");
    let o = Command::new("git")
        .args(["clone", "--quiet", "--no-hardlinks"])
        .arg(repo)
        .arg(&clone)
        .output()
        .expect("git is installed");
    assert!(
        o.status.success(),
        "git clone: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!tmp.path().join("shared").exists());
    let readme = std::fs::read_to_string(clone.join("README.md")).unwrap();
    let command = readme_first_command(&readme);
    // The convert step: `cargo run --release -- convert ARGS... && ...`.
    let convert = command.split("&&").next().unwrap().trim();
    let args = convert
        .strip_prefix("cargo run --release -- ")
        .unwrap_or_else(|| {
            panic!("README's first command is not `cargo run --release -- ...`: {convert}")
        });
    let args: Vec<&str> = args.split_whitespace().collect();
    assert_eq!(args.first(), Some(&"convert"), "{convert}");
    let input = clone.join(args[1]);
    assert!(input.is_file(), "{} is in the clone", args[1]);
    assert!(!args[1].contains("shared"), "{convert}");
    let o = Command::new(bin())
        .args(&args)
        .arg("--quiet")
        .current_dir(&clone)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "`{convert}` in a clone: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let out_flag = args
        .iter()
        .position(|a| *a == "-o")
        .expect("-o in the command");
    let tileset = clone.join(args[out_flag + 1]).join("tileset.json");
    assert_valid(&tileset);
    // The sample ships with its licence.
    let lic = std::fs::read_to_string(clone.join("samples/README.md")).unwrap();
    assert!(lic.contains("CC-BY-4.0") && lic.contains("Marcel Padilla"));
}
