//! Build information for `cdlab version`: the git commit the binary was built from (when
//! built in a git checkout; "-dirty" after it when its sources had uncommitted changes),
//! the wgpu version of Cargo.lock, the target, the profile and the compiler.
//! Everything is optional: a build from a source archive without git or Cargo.lock says
//! "unknown" rather than failing.

use std::path::Path;
use std::process::Command;

/// `git ARGS` in the package directory, its trimmed output when it succeeds.
fn git(args: &[&str]) -> Option<String> {
    let out = Command::new("git")
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .ok()?;
    let text = String::from_utf8(out.stdout).ok()?.trim().to_string();
    (out.status.success() && !text.is_empty()).then_some(text)
}

/// The version of package `name` in the lock file's text.
fn locked_version(lock: &str, name: &str) -> Option<String> {
    let mut lines = lock.lines();
    while let Some(line) = lines.next() {
        if line.trim() == format!("name = \"{name}\"") {
            let next = lines.next()?.trim();
            return next
                .strip_prefix("version = \"")?
                .strip_suffix('"')
                .map(str::to_string);
        }
    }
    None
}

/// What the binary is built from: where a change makes the build differ from its commit.
/// The build script reruns when any of them changes (cargo scans a directory's files), so
/// the "-dirty" marker follows edits made after the last build.
const SOURCES: &[&str] = &["src", "shaders", "build.rs", "Cargo.toml", "Cargo.lock"];

fn main() {
    let unknown = || "unknown".to_string();
    // The commit changes with HEAD or with the branch it points to (loose or packed): the
    // paths git names for them, so that worktrees and submodules are followed too. (A new
    // branch packed away later is missed until the next change of HEAD.)
    let mut commit = git(&["rev-parse", "--short=12", "HEAD"]);
    if let Some(hash) = &mut commit {
        // Sources that differ from the commit, staged or not, or new ones: the build is
        // not that commit's, and says so (a binary built from a tree with a merge not yet
        // committed named the commit before it). `--no-optional-locks`: git status would
        // otherwise refresh the index, a change that ran this script again on every build.
        let mut status = vec!["--no-optional-locks", "status", "--porcelain", "--"];
        status.extend(SOURCES);
        if git(&status).is_some() {
            hash.push_str("-dirty");
        }
        for source in SOURCES {
            println!(
                "cargo:rerun-if-changed={}",
                Path::new(env!("CARGO_MANIFEST_DIR")).join(source).display()
            );
        }
        // The index changes with every `git add` and commit.
        let mut watched = vec!["HEAD".to_string(), "packed-refs".to_string(), "index".to_string()];
        if let Some(branch) = git(&["symbolic-ref", "-q", "HEAD"]) {
            watched.push(branch);
        }
        for w in watched {
            if let Some(path) = git(&["rev-parse", "--git-path", &w]) {
                let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(path);
                // A path that does not exist would make every build run this again.
                if path.exists() {
                    println!("cargo:rerun-if-changed={}", path.display());
                }
            }
        }
    }
    let lock_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.lock");
    println!("cargo:rerun-if-changed={}", lock_path.display());
    println!("cargo:rerun-if-changed=build.rs");
    let wgpu = std::fs::read_to_string(&lock_path)
        .ok()
        .and_then(|lock| locked_version(&lock, "wgpu"));
    let env = |k: &str| std::env::var(k).unwrap_or_else(|_| unknown());
    println!(
        "cargo:rustc-env=CDLAB_GIT_COMMIT={}",
        commit.unwrap_or_else(unknown)
    );
    println!(
        "cargo:rustc-env=CDLAB_WGPU_VERSION={}",
        wgpu.unwrap_or_else(unknown)
    );
    println!("cargo:rustc-env=CDLAB_TARGET={}", env("TARGET"));
    println!("cargo:rustc-env=CDLAB_PROFILE={}", env("PROFILE"));
    let rustc = Command::new(env("RUSTC"))
        .arg("-V")
        .output()
        .ok()
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|v| v.trim().to_string())
        .filter(|v| !v.is_empty());
    println!("cargo:rustc-env=CDLAB_RUSTC={}", rustc.unwrap_or_else(unknown));
}
