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
    exits_with(args, 1)
}

/// Runs cdlab with `args`, expecting exit status `code` (1 for an error, 2 for clap's
/// usage errors) and no panic; returns stdout and stderr.
fn exits_with(args: &[&str], code: i32) -> String {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(args)
        .output()
        .expect("cdlab runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        out.status.code(),
        Some(code),
        "{args:?} must fail cleanly: {text}"
    );
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
    // The benchmark builds its samples too: the same bound, named by its flag.
    let text = exits_with_error(&["bench", "--disks", "10000000000", "--steps", "1"]);
    assert!(text.contains("--disks") && text.contains("100000000"), "{text}");
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
/// (a flipped bit in a position used to run the test with a 2.7% overlap); so is one whose
/// checksum is right but whose values are not, with the file's name and the field.
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
    // Valid CRCs over bad values (issue 36, item 10): the sample re-encoded with a scene
    // edited into one the engine cannot run, and a `glued_to` patched to 2^32, which the
    // scene's 32-bit field cannot hold, with the CRC computed again. The first panicked
    // with an index out of bounds in the engine; the second was read as wall 0.
    let ck = cdlab::protocol::checkpoint::decode(&good[20..]).unwrap();
    let edited = |edit: &dyn Fn(&mut cdlab::model::Scene)| {
        let mut scene = ck.scene.clone();
        edit(&mut scene);
        cdlab::protocol::sample_file::encode_sample(&ck.state, &scene)
    };
    let walls = ck.scene.walls.len() as u32;
    let glued = edited(&|s| s.disks.glued_to[5] = walls + 3);
    let radius = edited(&|s| s.disks.radius[7] = -0.5);
    let mass = edited(&|s| s.disks.mass[9] = f64::NAN);
    let velocity = edited(&|s| s.disks.vel[11].x = f64::INFINITY);
    let wide = {
        let mut payload = good[20..].to_vec();
        let json = u64::from_le_bytes(payload[8..16].try_into().unwrap()) as usize;
        // Disk 0's `glued_to`, its 15th word (the layout of `checkpoint::encode`).
        let at = 16 + json + 8 + 8 * 14;
        payload[at..at + 8].copy_from_slice(&(1u64 << 32).to_le_bytes());
        let mut b = good[..8].to_vec();
        b.extend_from_slice(&(payload.len() as u64).to_le_bytes());
        b.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        b.extend_from_slice(&payload);
        b
    };
    let glued_what = format!("disk 5 glued_to = {}", walls + 3);
    for (name, bytes, expect) in [
        ("flipped", flipped, "CRC-32"),
        ("last", last, "CRC-32"),
        ("cut", cut, "truncated"),
        ("old", old, "cdlab prepare"),
        ("glued", glued, glued_what.as_str()),
        ("radius", radius, "disk 7 radius = -0.5"),
        ("mass", mass, "disk 9 mass = NaN"),
        ("velocity", velocity, "disk 11 velocity = inf"),
        ("wide", wide, "disk 0 glued_to = 4294967296"),
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

/// Quantities on the command line need their unit: `--sigma3 8` was taken as 8 Pa and
/// failed only after a long confinement, with a hint about strips.
#[test]
fn a_flag_quantity_without_unit_is_refused() {
    let base = scratch("unit");
    let out = base.join("run");
    let text = exits_with_error(&["biaxial", "--sigma3", "8", "--out", out.to_str().unwrap()]);
    assert!(
        text.contains("--sigma3") && text.contains("needs a unit") && text.contains("8MPa"),
        "{text}"
    );
    assert!(!out.exists());
    let _ = std::fs::remove_dir_all(&base);
}

/// Configuration values absurd for their quantity name their own key: a 1e-320 s step
/// was blamed on solver.velocity_tol (derived from r_min / dt), and `sigma3 = 8` (8 Pa)
/// was accepted.
#[test]
fn absurd_configuration_values_name_their_key() {
    let base = scratch("absurd");
    for (text, key) in [
        ("[solver]\ndt = \"1e-320 s\"\n", "solver.dt"),
        ("[test]\nsigma3 = 8\n", "test.sigma3"),
        ("[test]\nsigma3 = \"1e400 MPa\"\n", "test.sigma3"),
    ] {
        let path = base.join("c.toml");
        std::fs::write(&path, text).unwrap();
        let out = exits_with_error(&["config", "--check", path.to_str().unwrap()]);
        assert!(out.contains(key) && out.contains("c.toml"), "{text}: {out}");
        if text.contains("1e400") {
            assert!(!out.contains("inf"), "{out}");
        }
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A WGPU_BACKEND that names no backend is reported by name with the valid values, not
/// as a missing driver.
#[test]
fn a_bad_wgpu_backend_is_named() {
    let base = scratch("wgpu");
    let cfg = small_config(&base);
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args([
            "biaxial",
            "--config",
            cfg.to_str().unwrap(),
            "--backend",
            "gpu",
            "--out",
            base.join("run").to_str().unwrap(),
            "--quiet",
        ])
        .env("WGPU_BACKEND", "vulkn")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.contains("WGPU_BACKEND") && text.contains("vulkn") && text.contains("vulkan"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&base);
}

/// A sweep's grid is checked before a dry run lists what it would start: frictions
/// finite and >= 0, pressures with units.
#[test]
fn a_sweep_grid_is_validated_before_a_dry_run() {
    let base = scratch("grid");
    for (grid, key) in [
        ("mu = [0.3, -1]\nsigma3 = [\"1 MPa\"]", "`mu` = -1"),
        ("mu = [nan]\nsigma3 = [\"1 MPa\"]", "`mu` = NaN"),
        ("mu = [0.3]\nsigma3 = [8]", "`sigma3`"),
        ("mu = [0.3]\nsigma3 = [\"8\"]", "needs a unit"),
        ("mu = [0.3]\nsigma3 = [\"-1 MPa\"]", "`sigma3`"),
    ] {
        let file = base.join("sweep.toml");
        std::fs::write(
            &file,
            format!("out = \"{}\"\n{grid}\n", base.join("campaign").display()),
        )
        .unwrap();
        let text = exits_with_error(&["sweep", file.to_str().unwrap(), "--dry-run"]);
        assert!(
            text.contains(key) && !text.contains("would start"),
            "{grid}: {text}"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A sweep file that is not valid TOML for a sweep names the line and the key where it is
/// wrong; the message said "line 0:" before the parser's own line.
#[test]
fn a_sweep_file_error_names_its_line() {
    let base = scratch("sweep-lines");
    for (grid, line, key) in [
        ("mu = [0.3]\nseeds = [-1]", 3, "seeds"),
        ("mu = \"0.3\"", 2, "mu"),
        ("mu = [0.3]\nfriction = [0.3]", 3, "friction"),
        ("mu = [0.3]\nsigma3 = [\"1 MPa\"]\nmu = [0.4]", 4, "mu"),
    ] {
        let file = base.join("sweep.toml");
        std::fs::write(
            &file,
            format!("out = \"{}\"\n{grid}\n", base.join("campaign").display()),
        )
        .unwrap();
        let text = exits_with_error(&["sweep", file.to_str().unwrap(), "--dry-run"]);
        assert!(
            text.contains(&format!("{}: line {line}:", file.display()))
                && text.contains(key)
                && !text.contains("line 0"),
            "{grid}: {text}"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A sweep whose `out` is a looping link, a FIFO or a regular file is refused up front,
/// naming the path and what it is, by a dry run too (which said "would start" for each
/// test; a real sweep warned "File exists", then failed every test with "Too many levels
/// of symbolic links").
#[cfg(unix)]
#[test]
fn a_sweep_whose_out_is_no_directory_is_refused_naming_it() {
    let base = scratch("sweep-out");
    let looped = base.join("loop");
    std::os::unix::fs::symlink(&looped, &looped).unwrap();
    let fifo = base.join("fifo");
    mkfifo(&fifo);
    let file = base.join("file");
    std::fs::write(&file, "not a campaign").unwrap();
    for (out, what) in [
        (&looped, "symbolic link that loops"),
        (&fifo, "FIFO"),
        (&file, "regular file"),
    ] {
        let sweep = base.join("sweep.toml");
        std::fs::write(
            &sweep,
            format!("out = \"{}\"\nmu = [0.3]\nsigma3 = [\"1 MPa\"]\n", out.display()),
        )
        .unwrap();
        for dry in [true, false] {
            let mut args = vec!["sweep", sweep.to_str().unwrap()];
            if dry {
                args.push("--dry-run");
            }
            let text = exits_with_error(&args);
            assert!(
                text.contains(out.to_str().unwrap())
                    && text.contains(what)
                    && !text.contains("would start")
                    && !text.contains("FAILED"),
                "{args:?}: {text}"
            );
        }
        assert_eq!(std::fs::read(&file).unwrap(), b"not a campaign");
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A `--sample` that is no sample file of a size this machine can run is refused before it
/// is read, naming the file: a character device (`/dev/zero` was read without end, until
/// the memory ran out) and a sparse file one byte larger than the largest sample this
/// machine can run (it was read whole into memory).
#[cfg(unix)]
#[test]
fn a_sample_that_cannot_be_one_is_not_read() {
    use std::time::{Duration, Instant};
    let base = scratch("huge-sample");
    let sparse = base.join("sparse.bin");
    let limit = cdlab::protocol::sample_file::max_sample_bytes();
    std::fs::File::create(&sparse)
        .unwrap()
        .set_len(limit + 1)
        .unwrap();
    for (path, what) in [
        (std::path::Path::new("/dev/zero"), "character device"),
        (sparse.as_path(), "more than"),
    ] {
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
            .args(["biaxial", "--out"])
            .arg(base.join("run"))
            .arg("--sample")
            .arg(path)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let t0 = Instant::now();
        let status = loop {
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            if t0.elapsed() > Duration::from_secs(60) {
                let _ = child.kill();
                let _ = child.wait();
                panic!("{}: still reading after 60 s", path.display());
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        let mut err = String::new();
        std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
        assert_eq!(status.code(), Some(1), "{}: {err}", path.display());
        assert!(
            err.contains(path.to_str().unwrap()) && err.contains(what),
            "{}: {err}",
            path.display()
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

/// A full disk under the terminal: with stdout and stderr on `/dev/full` (every write fails
/// with ENOSPC) an error still ends with exit code 1, and a command that succeeds but
/// cannot print ends with 1 too, never with a panic's 101.
#[cfg(target_os = "linux")]
#[test]
fn output_to_a_full_device_ends_cleanly() {
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    for args in [
        vec!["biaxial", "--resume", "/nonexistent-cdlab-run"],
        vec!["config", "--print-default"],
    ] {
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_cdlab"))
            .args(&args)
            .stdout(full())
            .stderr(full())
            .status()
            .expect("cdlab runs");
        assert_eq!(status.code(), Some(1), "{args:?}");
    }
}

/// Makes a FIFO at `path`.
#[cfg(unix)]
fn mkfifo(path: &std::path::Path) {
    let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
    // SAFETY: a valid NUL-terminated path and mode.
    assert_eq!(
        unsafe { libc::mkfifo(c.as_ptr(), 0o600) },
        0,
        "{}",
        path.display()
    );
}

/// An output that exists and is not a regular file is refused up front, with or without
/// --force, naming the path and what it is, and left as it was (issue 36, item 3: `prepare
/// -o X --force` renamed over a link, a FIFO or a device node, and as root replaced a
/// device of the system): `prepare -o` a link (to a file, or dangling) or a FIFO, and a
/// run directory whose record or summary is one.
#[cfg(unix)]
#[test]
fn outputs_that_are_not_regular_files_are_refused() {
    use std::os::unix::fs::symlink;
    let base = scratch("special");
    let cfg = small_config(&base);
    let c = cfg.to_str().unwrap();
    let victim = base.join("victim.bin");
    std::fs::write(&victim, b"not cdlab's").unwrap();
    let link = base.join("link.bin");
    symlink(&victim, &link).unwrap();
    let dangling = base.join("dangling.bin");
    symlink(base.join("nowhere.bin"), &dangling).unwrap();
    let fifo = base.join("fifo.bin");
    mkfifo(&fifo);
    for (path, what, force) in [
        (&link, "is a symbolic link", true),
        (&dangling, "is a symbolic link", false),
        (&fifo, "is a FIFO", true),
    ] {
        let mut args = vec!["prepare", "--config", c, "-o", path.to_str().unwrap()];
        if force {
            args.push("--force");
        }
        let text = exits_with_error(&args);
        assert!(
            text.contains(&format!("{} {what}", path.display())) && text.contains("not a regular file"),
            "{args:?}: {text}"
        );
        assert!(!path.symlink_metadata().unwrap().file_type().is_file());
    }
    assert_eq!(std::fs::read(&victim).unwrap(), b"not cdlab's");
    assert!(!base.join("nowhere.bin").exists());

    // A run directory: its record a FIFO, then its summary a link.
    let out = base.join("run");
    std::fs::create_dir_all(&out).unwrap();
    mkfifo(&out.join("run.mcap"));
    let o = out.to_str().unwrap();
    let text = exits_with_error(&["biaxial", "--config", c, "--out", o, "--force", "--quiet"]);
    assert!(
        text.contains(&format!("{} is a FIFO", out.join("run.mcap").display())),
        "{text}"
    );
    std::fs::remove_file(out.join("run.mcap")).unwrap();
    symlink(&victim, out.join("summary.json")).unwrap();
    let text = exits_with_error(&["biaxial", "--config", c, "--out", o, "--force", "--quiet"]);
    assert!(
        text.contains(&format!(
            "{} is a symbolic link",
            out.join("summary.json").display()
        )),
        "{text}"
    );
    assert!(
        out.join("summary.json")
            .symlink_metadata()
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(!out.join("run.mcap").exists() && !out.join("series.csv").exists());
    assert_eq!(std::fs::read(&victim).unwrap(), b"not cdlab's");
    let _ = std::fs::remove_dir_all(&base);
}

/// `--resume` continues a run with the settings it was recorded with: a flag that would
/// change them, `--force` included, is refused naming it instead of being ignored (the
/// probe of issue 36 found `--resume DIR --force` silently ignoring `--force`).
#[test]
fn resume_refuses_the_flags_it_would_ignore() {
    for flag in [&["--force"][..], &["--disks", "200"], &["--out", "elsewhere"]] {
        let mut args = vec!["biaxial", "--resume", "no-such-run"];
        args.extend_from_slice(flag);
        // A usage error (clap's exit status 2), before the directory is looked at.
        let text = exits_with(&args, 2);
        assert!(
            text.contains(flag[0]) && text.contains("cannot be used with"),
            "{flag:?}: {text}"
        );
    }
}
