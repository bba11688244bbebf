//! Records the source tree's `git describe` at build time (`JOINTFIT_GIT_DESCRIBE`), so that
//! `jointfit reproduce` names the sources of the binary without needing them at run time.
//! Nothing is recorded when the sources are not a git checkout or git is missing.

use std::path::PathBuf;
use std::process::Command;

fn git(dir: &str, args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .arg("-C")
        .arg(dir)
        .args(args)
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout).trim().to_string();
    (out.status.success() && !text.is_empty()).then_some(text)
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into());
    // Rebuilt when the checked-out commit moves: HEAD, and the branch it points at.
    if let Some(git_dir) = git(&dir, &["rev-parse", "--absolute-git-dir"]) {
        println!(
            "cargo:rerun-if-changed={}",
            PathBuf::from(&git_dir).join("HEAD").display()
        );
        let common = git(&dir, &["rev-parse", "--git-common-dir"]).map(|c| {
            let c = PathBuf::from(c);
            if c.is_absolute() {
                c
            } else {
                PathBuf::from(&dir).join(c)
            }
        });
        if let (Some(common), Some(head)) = (common, git(&dir, &["symbolic-ref", "-q", "HEAD"])) {
            println!("cargo:rerun-if-changed={}", common.join(head).display());
        }
    }
    if let Some(describe) = git(&dir, &["describe", "--always", "--tags"]) {
        println!("cargo:rustc-env=JOINTFIT_GIT_DESCRIBE={describe}");
    }
}
