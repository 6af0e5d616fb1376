//! Hostile inputs through the command line (issue 23, classes 2, 5 and 8): damaged samples,
//! sizes beyond the machine, files that never end, bare numbers for quantities. Each is a
//! clear error naming what is wrong, given before any work, never a crash.

mod common;

use std::path::PathBuf;

use common::{cdlab, small_config};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-inputs-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A process a signal ended has no exit code: a failed allocation aborts (SIGABRT), which
/// is what these tests must never see.
fn exits_with_error(args: &[&str]) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(args)
        .output()
        .expect("cdlab runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(out.status.code(), Some(1), "{args:?} must fail cleanly: {text}");
    assert!(!text.contains("panicked"), "{args:?}: {text}");
    text
}

/// Sizes beyond the machine are refused by name before anything is allocated (the first
/// and third aborted on a failed allocation, the fourth read /dev/zero without end).
#[test]
fn huge_sizes_are_refused_before_allocating() {
    let base = scratch("huge");
    let out = base.join("run");
    let o = out.to_str().unwrap();
    let text = exits_with_error(&["biaxial", "--disks", "10000000000", "--out", o, "--quiet"]);
    assert!(
        text.contains("sample.disks") && text.contains("100000000"),
        "{text}"
    );
    let text = exits_with_error(&["prepare", "--disks", "10000000000", "-o", o]);
    assert!(text.contains("sample.disks"), "{text}");
    let png = base.join("a.png");
    let text = exits_with_error(&[
        "render",
        o,
        "--at",
        "0",
        "--height",
        "4000000000",
        "-o",
        png.to_str().unwrap(),
    ]);
    assert!(text.contains("--height") && text.contains("20000"), "{text}");
    let text = exits_with_error(&["config", "--check", "/dev/zero"]);
    assert!(text.contains("/dev/zero") && text.contains("1048576"), "{text}");
    let text = exits_with_error(&["fc2d", "/dev/zero"]);
    assert!(text.contains("/dev/zero"), "{text}");
    assert!(!out.exists(), "a refused run must leave no output");
    let _ = std::fs::remove_dir_all(&base);
}

/// A sample too small for the strips is refused up front, naming `sample.disks` and the
/// least disk count, before any deposition: it used to fail on `test.strip_thickness` after
/// minutes of compaction, having created its record.
#[test]
fn too_few_disks_for_the_strips_is_refused_up_front() {
    let base = scratch("few");
    for n in ["100", "150", "200"] {
        let out = base.join(n);
        let text = exits_with_error(&[
            "biaxial",
            "--disks",
            n,
            "--backend",
            "cpu",
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(
            text.contains("sample.disks") && text.contains("use more than"),
            "{n}: {text}"
        );
        assert!(!out.exists(), "{n}: the refused test started: {}", out.display());
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A prepared sample with one flipped bit, cut short, or in the old format without a
/// checksum is refused by `biaxial --sample` with the file's name, before the test starts
/// (a flipped bit in a position used to run the test with a 2.7% overlap).
#[test]
fn a_damaged_sample_is_refused_before_use() {
    let base = scratch("sample");
    let cfg = small_config(&base);
    let sample = base.join("sample.bin");
    let (ok, text) = cdlab(&[
        "prepare",
        "--config",
        cfg.to_str().unwrap(),
        "-o",
        sample.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let good = std::fs::read(&sample).unwrap();
    assert_eq!(&good[..8], b"CDLABSP2");
    // A bit in the middle of the disk data (a position or a velocity), the last byte, and
    // a cut in the middle.
    let mut flipped = good.clone();
    flipped[good.len() / 2] ^= 0x10;
    let mut last = good.clone();
    *last.last_mut().unwrap() ^= 1;
    let cut = good[..good.len() - 100].to_vec();
    let old = good[20..].to_vec(); // the bare checkpoint: the old format
    for (name, bytes, expect) in [
        ("flipped", flipped, "CRC-32"),
        ("last", last, "CRC-32"),
        ("cut", cut, "truncated"),
        ("old", old, "cdlab prepare"),
    ] {
        let path = base.join(format!("{name}.bin"));
        std::fs::write(&path, bytes).unwrap();
        let out = base.join(format!("run-{name}"));
        let text = exits_with_error(&[
            "biaxial",
            "--config",
            cfg.to_str().unwrap(),
            "--sample",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(
            text.contains(&format!("{name}.bin")) && text.contains(expect),
            "{name}: {text}"
        );
        assert!(!out.exists(), "{name}: a test started from a damaged sample");
    }
    // No temporary file is left beside the sample.
    let left: Vec<_> = std::fs::read_dir(&base)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    let _ = std::fs::remove_dir_all(&base);
}
