//! Build information for the service's metrics (`riskplan_build_info`, proto/README.md
//! "Metrics"): the git commit the binary was built from, as `RISKPLAN_GIT_COMMIT`.
//!
//! `RISKPLAN_GIT_COMMIT` set in the build's environment wins (a packager building from a
//! tarball); otherwise `git rev-parse HEAD` in the source tree; otherwise "unknown" (no
//! git, no repository). The commit is HEAD's: uncommitted changes are not marked.

use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=RISKPLAN_GIT_COMMIT");
    let given = std::env::var("RISKPLAN_GIT_COMMIT").ok().filter(|c| valid(c));
    let commit = given.or_else(git_head).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=RISKPLAN_GIT_COMMIT={commit}");
}

/// A commit as a label value: 1 to 64 hex digits (or a short name of the same
/// characters a packager may give).
fn valid(c: &str) -> bool {
    !c.is_empty() && c.len() <= 64 && c.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'.')
}

/// HEAD's commit, and the files whose change moves it watched (HEAD, the branch it
/// points to, the packed refs), so that a new commit rebuilds with its hash.
fn git_head() -> Option<String> {
    let git = |args: &[&str]| -> Option<String> {
        let out = Command::new("git").args(args).output().ok()?;
        out.status.success().then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    let dir = PathBuf::from(git(&["rev-parse", "--git-dir"])?);
    let common = git(&["rev-parse", "--git-common-dir"]).map(PathBuf::from).unwrap_or_else(|| dir.clone());
    let watch = |p: &Path| {
        if p.exists() {
            println!("cargo:rerun-if-changed={}", p.display());
        }
    };
    watch(&dir.join("HEAD"));
    if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
        // a worktree keeps its HEAD in its own directory, the branches in the common one
        watch(&if dir.join(&branch).exists() { dir.join(&branch) } else { common.join(&branch) });
    }
    watch(&common.join("packed-refs"));
    git(&["rev-parse", "HEAD"]).filter(|c| valid(c))
}
