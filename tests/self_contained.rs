//! The project stands on its own: no source, test, bench, shader, script or document reads a
//! path beside the repository, and every Markdown file they cite is in the repository.
//! (`.ci/run` also runs the suite from a fresh clone with nothing beside it.)

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Text files of the project that code, tests and readers follow.
fn project_files() -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack: Vec<PathBuf> = [
        "src", "tests", "benches", "shaders", "examples", "docs", ".ci", "python",
    ]
    .iter()
    .map(|d| root().join(d))
    .filter(|d| d.exists())
    .collect();
    for f in ["README.md", "CHANGELOG.md", "Cargo.toml"] {
        if root().join(f).exists() {
            out.push(root().join(f));
        }
    }
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let p = entry.unwrap().path();
            let name = p.file_name().unwrap().to_string_lossy().to_string();
            if p.is_dir() {
                // Shipped test data is third-party text, not the project's prose.
                if name != "data" && name != "target" && !name.starts_with('.') {
                    stack.push(p);
                }
            } else if [".rs", ".wgsl", ".md", ".toml", ".py", ".pyi", ".sh", "run"]
                .iter()
                .any(|ext| name.ends_with(ext))
            {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Path-like words ending in `.md` in a text.
fn markdown_mentions(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let bytes = text.as_bytes();
    let is_path = |c: u8| c.is_ascii_alphanumeric() || b"_./-".contains(&c);
    let mut i = 0;
    while let Some(k) = text[i..].find(".md") {
        let end = i + k + 3;
        // A word boundary after ".md" (not ".mdx", not "x.mdbook").
        let after_ok = end >= bytes.len() || !bytes[end].is_ascii_alphanumeric();
        let mut start = i + k;
        while start > 0 && is_path(bytes[start - 1]) {
            start -= 1;
        }
        if after_ok && start < i + k {
            out.push(text[start..end].trim_start_matches("./").to_string());
        }
        i = end;
    }
    out
}

/// Files cdlab and its hardware check (benches/hardware_check.sh) write under these names:
/// a mention of them is not a citation.
const OUTPUT_NAMES: &[&str] = &["bench.md", "report.md", "OUT/report.md"];

#[test]
fn every_cited_markdown_file_is_in_the_repository() {
    let mut missing = Vec::new();
    for file in project_files() {
        // This file's own examples are not citations.
        if file.ends_with("tests/self_contained.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        let dir = file.parent().unwrap();
        for m in markdown_mentions(&text) {
            if OUTPUT_NAMES.contains(&m.as_str()) || m.starts_with("http") {
                continue;
            }
            // A citation is a path from the repository's root, or from the citing file's
            // own directory (links inside docs/).
            if !(root().join(&m).is_file() || dir.join(&m).is_file()) {
                missing.push(format!("{}: {m}", file.strip_prefix(root()).unwrap().display()));
            }
        }
    }
    assert!(
        missing.is_empty(),
        "cited Markdown files that are not in the repository:\n{}",
        missing.join("\n")
    );
}

#[test]
fn no_file_reads_a_path_beside_the_repository() {
    let mut found = Vec::new();
    for file in project_files() {
        // This file names the pattern it looks for.
        if file.ends_with("tests/self_contained.rs") {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        let dir = file.parent().unwrap();
        for (n, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(k) = rest.find("../") {
                // The relative path starting here, up to a quote, space or bracket.
                let tail = &rest[k..];
                let end = tail
                    .find(|c: char| "\"'` )]>,;".contains(c))
                    .unwrap_or(tail.len());
                let rel = &tail[..end];
                // Resolved from the file's directory (include_str!, links in docs) and from
                // the root (paths joined to CARGO_MANIFEST_DIR), it must stay inside.
                let from_dir = normalize(&dir.join(rel));
                let from_root = normalize(&root().join(rel));
                let inside = |p: &Path| p.starts_with(root());
                if !inside(&from_dir) && !inside(&from_root) || rel.contains("shared/") {
                    found.push(format!(
                        "{}:{}: {rel}",
                        file.strip_prefix(root()).unwrap().display(),
                        n + 1
                    ));
                }
                rest = &tail[end.max(3)..];
            }
        }
    }
    assert!(
        found.is_empty(),
        "paths outside the repository:\n{}",
        found.join("\n")
    );
}

/// `a/b/../c` as `a/c`, without touching the file system.
fn normalize(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            std::path::Component::ParentDir => {
                out.pop();
            }
            std::path::Component::CurDir => {}
            other => out.push(other),
        }
    }
    out
}

#[test]
fn the_checks_find_what_they_look_for() {
    // The scanners themselves, on texts with and without citations.
    assert_eq!(
        markdown_mentions("see docs/method.md, and `bench.md`; not x.mdx"),
        vec!["docs/method.md", "bench.md"]
    );
    assert!(markdown_mentions("no citation here (.md alone)").is_empty());
    assert_eq!(normalize(Path::new("/a/b/../../c/./d")), PathBuf::from("/c/d"));
}
