//! The user guide cannot drift from the code: the configuration reference
//! (`docs/configuration.md`) lists exactly the keys of the configuration with the defaults
//! of `cdlab config --print-default`; the Python example of `docs/outputs.md` is the file
//! `examples/read_run.py` and reads a real run; the example commands marked ```` ```sh test
//! ```` in the README and the guide run and succeed.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(rel: &str) -> String {
    std::fs::read_to_string(root().join(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("cdlab_docs_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A key's default in the default file: set (`key = value`) or unset (a commented-out
/// `# key = value` line showing an example value).
#[derive(Debug, PartialEq)]
enum DefaultValue {
    Set(String),
    Unset(String),
}

/// `section.key -> default as written` from the default file's text: `key = value` lines
/// under `[section]` headers, and `# key = value` lines for keys that are unset by default.
fn default_file_keys(text: &str) -> BTreeMap<String, DefaultValue> {
    let mut out = BTreeMap::new();
    let mut section = String::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(s) = line.strip_prefix('[').and_then(|s| s.strip_suffix(']')) {
            section = s.to_string();
            continue;
        }
        let (commented, body) = match line.strip_prefix('#') {
            Some(rest) => (true, rest.trim()),
            None => (false, line),
        };
        let Some((key, value)) = body.split_once(" = ") else {
            continue;
        };
        if section.is_empty()
            || !key
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
        {
            continue;
        }
        let (k, v) = (format!("{section}.{key}"), value.trim().to_string());
        if commented {
            out.entry(k).or_insert(DefaultValue::Unset(v));
        } else {
            out.insert(k, DefaultValue::Set(v));
        }
    }
    out
}

/// `section.key -> (unit, default)` from the reference's tables: rows
/// `` | `key` | unit | `default` | meaning | `` under `## [section]` headings.
fn reference_keys(text: &str) -> BTreeMap<String, (String, String)> {
    let mut out = BTreeMap::new();
    let mut section = None;
    for line in text.lines() {
        if let Some(h) = line.strip_prefix("## ") {
            section = h
                .trim()
                .strip_prefix("`[")
                .and_then(|s| s.strip_suffix("]`"))
                .map(str::to_string);
            continue;
        }
        let (Some(sec), Some(row)) = (&section, line.strip_prefix("| `")) else {
            continue;
        };
        let cells: Vec<&str> = row.split(" | ").map(str::trim).collect();
        let key = cells[0].trim_end_matches('`');
        let unit = cells.get(1).copied().unwrap_or("").to_string();
        let default = cells.get(2).copied().unwrap_or("").trim_matches('`').to_string();
        out.insert(format!("{sec}.{key}"), (unit, default));
    }
    out
}

/// Every key of the configuration, from the code: the serialized default configuration,
/// and the keys unset by default (not serialized) that the default file shows commented out,
/// each accepted by the configuration reader (which refuses unknown keys).
fn code_keys(defaults: &BTreeMap<String, DefaultValue>) -> Vec<String> {
    let value = serde_json::to_value(cdlab::config::Config::default()).unwrap();
    let mut keys = Vec::new();
    for (section, table) in value.as_object().unwrap() {
        for key in table.as_object().unwrap().keys() {
            keys.push(format!("{section}.{key}"));
        }
    }
    for (key, d) in defaults {
        if let DefaultValue::Unset(v) = d {
            let (section, name) = key.split_once('.').unwrap();
            if cdlab::config::Config::from_toml_str(&format!("[{section}]\n{name} = {v}\n")).is_ok() {
                keys.push(key.clone());
            }
        }
    }
    keys.sort();
    keys.dedup();
    keys
}

#[test]
fn configuration_reference_lists_every_key_with_its_default() {
    let out = Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["config", "--print-default"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let defaults = default_file_keys(&String::from_utf8(out.stdout).unwrap());
    let reference = reference_keys(&read("docs/configuration.md"));
    let code = code_keys(&defaults);
    assert!(
        reference.len() > 30,
        "docs/configuration.md: expected a table per section (`## `[section]``), found {} keys",
        reference.len()
    );
    let mut faults = Vec::new();
    for key in &code {
        if !reference.contains_key(key) {
            faults.push(format!(
                "{key}: a configuration key missing from docs/configuration.md; add a row \
                 to its section's table"
            ));
        }
        if !defaults.contains_key(key) {
            faults.push(format!(
                "{key}: a configuration key missing from assets/default.toml (`cdlab config \
                 --print-default`); add it with its comment"
            ));
        }
    }
    for (key, (unit, default)) in &reference {
        if !code.contains(key) {
            faults.push(format!(
                "{key}: in docs/configuration.md but not a configuration key; remove or \
                 rename its row"
            ));
            continue;
        }
        if unit.is_empty() {
            faults.push(format!(
                "{key}: docs/configuration.md gives no unit (write - for none)"
            ));
        }
        match defaults.get(key) {
            Some(DefaultValue::Set(d)) if d != default => faults.push(format!(
                "{key}: docs/configuration.md says the default is `{default}`, \
                 assets/default.toml says `{d}`; make the reference's default `{d}`"
            )),
            Some(DefaultValue::Unset(_)) if default != "unset" => faults.push(format!(
                "{key}: unset in assets/default.toml (commented out); its default in \
                 docs/configuration.md must read `unset`, not `{default}`"
            )),
            _ => {}
        }
    }
    assert!(faults.is_empty(), "{}", faults.join("\n"));
}

#[test]
fn the_reference_parsers_find_what_they_look_for() {
    let file = "[a]\n# x is a comment, = not a key\nb_c = \"2 m\"\n# wall_mu = 0.3\n[d]\ne = 3e-4\n";
    let keys = default_file_keys(file);
    assert_eq!(keys.get("a.b_c"), Some(&DefaultValue::Set("\"2 m\"".to_string())));
    assert_eq!(
        keys.get("a.wall_mu"),
        Some(&DefaultValue::Unset("0.3".to_string()))
    );
    assert_eq!(keys.get("d.e"), Some(&DefaultValue::Set("3e-4".to_string())));
    assert_eq!(keys.len(), 3, "{keys:?}");
    let doc = "## `[a]`\n\n| key | unit | default | meaning |\n| --- | --- | --- | --- |\n\
               | `b_c` | m | `\"2 m\"` | a length |\n## Units\n| `z` | - | `1` | not a key |\n";
    let refs = reference_keys(doc);
    assert_eq!(refs.len(), 1, "{refs:?}");
    assert_eq!(refs["a.b_c"], ("m".to_string(), "\"2 m\"".to_string()));
}

/// Whether `python3` can import the `mcap` package; `None` when it can, else why not.
fn python_with_mcap() -> Option<String> {
    match Command::new("python3").args(["-c", "import mcap"]).output() {
        Err(e) => Some(format!("python3 not found: {e}")),
        Ok(o) if !o.status.success() => Some(format!(
            "python3 cannot import mcap ({}); install it with `python3 -m pip install mcap`",
            String::from_utf8_lossy(&o.stderr)
                .trim()
                .lines()
                .last()
                .unwrap_or("")
        )),
        Ok(_) => None,
    }
}

/// The value after `prefix` on the line of `out` that starts with it, up to a space.
fn field<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines()
        .find_map(|l| l.strip_prefix(prefix))
        .and_then(|rest| rest.split_whitespace().next())
        .unwrap_or_else(|| panic!("no line starting {prefix:?} in:\n{out}"))
}

#[test]
fn python_example_reads_a_run_as_its_csv_says() {
    // The guide quotes the script whole, so that what a reader copies is what runs here.
    let script = read("examples/read_run.py");
    let guide = read("docs/outputs.md");
    assert!(
        guide.contains(&format!("```python\n{script}```")),
        "docs/outputs.md must quote examples/read_run.py whole in a ```python block; copy \
         the file into it again"
    );
    if let Some(why) = python_with_mcap() {
        if std::env::var_os("CDLAB_REQUIRE_PYTHON").is_some() {
            panic!("CDLAB_REQUIRE_PYTHON is set but {why}");
        }
        // Written past the test harness's capture, so the skip shows in a plain `cargo test`.
        let line = format!("SKIPPED (python example: {why})\n");
        let _ = std::io::Write::write_all(&mut std::io::stderr(), line.as_bytes());
        return;
    }
    // A tiny run: 300 disks to axial strain 0.003, loose tolerance (seconds).
    let dir = scratch("python");
    let cfg = dir.join("tiny.toml");
    std::fs::write(
        &cfg,
        "[sample]\ndisks = 300\n[solver]\ntol = 1e-3\nbackend = \"cpu\"\n[test]\n\
         strip_thickness = \"3 m\"\nstrain_end = 0.003\n[output]\nsnapshot_every = 0.001\n",
    )
    .unwrap();
    let run = dir.join("run");
    let status = Command::new(env!("CARGO_BIN_EXE_cdlab"))
        .args(["biaxial", "--quiet", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&run)
        .output()
        .unwrap();
    assert!(
        status.status.success(),
        "{}",
        String::from_utf8_lossy(&status.stderr)
    );
    let out = Command::new("python3")
        .arg(root().join("examples/read_run.py"))
        .arg(run.join("run.mcap"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "examples/read_run.py failed:\n{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Against the CSV the run wrote: the same rows, the same last sigma_1 to the bit.
    let csv = std::fs::read_to_string(run.join("series.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "sigma1_pa").unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert!(rows.len() > 20, "{} rows", rows.len());
    let rows_py: usize = field(&text, "series rows ").parse().unwrap();
    assert_eq!(rows_py, rows.len(), "{text}");
    let last_csv: f64 = rows.last().unwrap().split(',').nth(col).unwrap().parse().unwrap();
    let last_py: f64 = field(&text, "last sigma_1 ").parse().unwrap();
    assert_eq!(last_py, last_csv, "{text}");
    // Confining stress 8 MPa: sigma_1 of a compressed sample lies above it.
    assert!(last_py > 8e6, "{text}");
    assert_eq!(field(&text, "friction "), "0.3,", "{text}");
    assert_eq!(field(&text, "last snapshot: "), "300", "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The commands of the ```` ```sh test ```` blocks of a Markdown text, one per line
/// (comments and blank lines dropped).
fn tested_commands(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut inside = false;
    for line in text.lines() {
        let t = line.trim();
        if !inside {
            inside = t == "```sh test";
            continue;
        }
        if t.starts_with("```") {
            inside = false;
            continue;
        }
        let cmd = t.split(" #").next().unwrap().trim();
        if !cmd.is_empty() && !cmd.starts_with('#') {
            out.push(cmd.to_string());
        }
    }
    out
}

fn markdown_files() -> Vec<PathBuf> {
    let mut files = vec![root().join("README.md")];
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root().join("docs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "md"))
        .collect();
    docs.sort();
    files.extend(docs);
    files
}

#[test]
#[cfg(unix)] // symbolic links and `sh`
fn documented_example_commands_run() {
    // Run from an empty directory holding links to the repository's inputs, so that the
    // commands' outputs land there and not in the repository.
    let dir = scratch("commands");
    for input in ["assets", "tests"] {
        std::os::unix::fs::symlink(root().join(input), dir.join(input)).unwrap();
    }
    let bin = dir.join("bin");
    std::fs::create_dir_all(&bin).unwrap();
    std::os::unix::fs::symlink(env!("CARGO_BIN_EXE_cdlab"), bin.join("cdlab")).unwrap();
    let path = format!("{}:{}", bin.display(), std::env::var("PATH").unwrap_or_default());
    let mut ran = Vec::new();
    for file in markdown_files() {
        let name = file.strip_prefix(root()).unwrap().display().to_string();
        for cmd in tested_commands(&std::fs::read_to_string(&file).unwrap()) {
            assert!(
                cmd.starts_with("cdlab "),
                "{name}: `{cmd}` in a ```sh test block: only cdlab commands belong there \
                 (they run in the test suite); use a plain ```sh block"
            );
            let out = Command::new("sh")
                .args(["-c", &cmd])
                .current_dir(&dir)
                .env("PATH", &path)
                .output()
                .unwrap();
            let text = format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(
                out.status.success(),
                "{name}: `{cmd}` failed (fix the command in {name} or the code):\n{text}"
            );
            assert!(!text.trim().is_empty(), "{name}: `{cmd}` printed nothing");
            ran.push(format!("{name}: {cmd}"));
        }
    }
    // The README's and the guide's quick examples are all marked, so the test has work.
    assert!(
        ran.iter().any(|c| c.starts_with("README.md")) && ran.iter().any(|c| c.starts_with("docs/")),
        "no ```sh test block in README.md or docs/: {ran:?}"
    );
    assert!(ran.len() >= 5, "{ran:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn tested_blocks_are_found() {
    let text = "x\n```sh test\ncdlab --help   # help\n\n# note\ncdlab info\n```\n```sh\nno\n```\n";
    assert_eq!(tested_commands(text), vec!["cdlab --help", "cdlab info"]);
}

/// GitHub's anchor of a heading: lower case, spaces to hyphens, other punctuation dropped.
fn anchor(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

#[test]
fn links_between_pages_point_to_existing_headings() {
    let mut broken = Vec::new();
    for file in markdown_files() {
        let text = std::fs::read_to_string(&file).unwrap();
        let dir = file.parent().unwrap();
        let name = file.strip_prefix(root()).unwrap().display().to_string();
        let mut rest = text.as_str();
        // Links `](target)` whose target is a Markdown page of the repository, with or
        // without an anchor, or an anchor of the same page.
        while let Some(k) = rest.find("](") {
            rest = &rest[k + 2..];
            let target = &rest[..rest.find(')').unwrap_or(0)];
            let (page, frag) = target.split_once('#').unwrap_or((target, ""));
            if target.starts_with("http") || !(page.ends_with(".md") || page.is_empty()) {
                continue;
            }
            let path = if page.is_empty() {
                file.clone()
            } else {
                dir.join(page)
            };
            let Ok(linked) = std::fs::read_to_string(&path) else {
                // A missing page is tests/self_contained.rs's to report.
                continue;
            };
            if frag.is_empty() {
                continue;
            }
            let found = linked
                .lines()
                .filter_map(|l| {
                    l.trim_start_matches('#')
                        .strip_prefix(' ')
                        .filter(|_| l.starts_with('#'))
                })
                .any(|h| anchor(h) == frag);
            if !found {
                broken.push(format!("{name}: ({target}) names no heading of {page}"));
            }
        }
    }
    assert!(
        broken.is_empty(),
        "links to headings that do not exist (fix the anchor or the heading):\n{}",
        broken.join("\n")
    );
}

#[test]
fn anchors_follow_github() {
    assert_eq!(
        anchor("Low contact friction: the strips"),
        "low-contact-friction-the-strips"
    );
    assert_eq!(anchor("The 5000-disk campaign"), "the-5000-disk-campaign");
}

/// The README's command table has a row for every subcommand the binary has (issue 36,
/// item 18: `cdlab fabric` was missing).
#[test]
fn the_readme_lists_every_command() {
    use clap::CommandFactory;
    let readme = read("README.md");
    let table = &readme[readme.find("## Commands").expect("a Commands section")..];
    let names: Vec<String> = cdlab::cli::Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .collect();
    assert!(
        names.len() > 10 && names.contains(&"fabric".to_string()),
        "{names:?}"
    );
    for name in names {
        assert!(
            table.contains(&format!("| `cdlab {name}")) || table.contains(&format!("`cdlab {name} ")),
            "README.md's command table has no row for `cdlab {name}`"
        );
    }
}
