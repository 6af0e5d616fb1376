//! Tests of the records: write and read back, truncated files, foreign files.

use std::path::PathBuf;

use super::*;
use crate::config::Config;
use crate::error::Error;

/// A fresh directory under the system temp dir, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let p = std::env::temp_dir().join(format!("cdlab-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn row(k: u64) -> SeriesRow {
    let x = k as f64;
    SeriesRow {
        time_s: x * 5e-3,
        step: k * 10,
        phase: if k < 50 { "confinement" } else { "compression" }.into(),
        strain_axial: x * 1e-4,
        sigma1_pa: 8e6 + x * 1234.5678,
        sigma3_pa: 8e6,
        volumetric_strain: -x * 1e-5,
        n_contacts: 2000 + k,
        n_force: 1500 + k,
        n_rolling: 1400,
        n_sliding: 100 + k,
        n_zero_force: 500,
        coordination: 3.9 + x * 1e-3,
        isolated_fraction: 0.1 / (1.0 + x),
        overlap_mean_rel: 1e-4 * x.sin().abs(),
        overlap_max_rel: 3e-3,
        iterations: (100 + k % 7) as f64 + 0.25,
        iterations_max: 200 + k % 5,
        kinetic_energy_j: 1.0 / 3.0 * x,
        inertial_number: 1e-4,
        height_m: 97.0 - x * 1e-3,
        width_m: 39.0 + x * 1e-4,
        wall_s: 0.37 * x,
        deep_contacts: (k % 3) as f64 * 0.5,
        a_c: 0.01 * x.cos().abs(),
        theta_c_deg: 90.0 + x * 1e-2,
        a_n: 0.2 - x * 1e-4,
        a_t: 0.05 / (1.0 + x),
        strong_fraction: 0.37 + x * 1e-5,
        strong_q_share: 0.9 + 1.0 / (3.0 + x),
        lw_sigma1_pa: 1.2e7 + x * 987.654321,
        lw_sigma3_pa: 7.9e6 - x * 12.5,
        rose_max_dev: 0.08 + x * 1e-6,
    }
}

fn snapshot(k: usize, n: usize) -> Snapshot {
    Snapshot {
        time_s: k as f64,
        strain: k as f64 * 0.01,
        disks: (0..n)
            .map(|i| {
                let v = (i * 31 + k) as f64;
                DiskRecord {
                    x: v.sin(),
                    y: v.cos(),
                    theta: v * 0.1,
                    vx: -v,
                    vy: v * 1e-3,
                    w: 0.5,
                    r: 0.5 + (i % 4) as f64 * 0.5,
                    dx: v * 1e-6,
                    dy: -v * 1e-6,
                }
            })
            .collect(),
        contacts: (0..2 * n)
            .map(|i| ContactRecord {
                i: i as u32,
                j: (i + 1) as u32,
                nx: 0.6,
                ny: -0.8,
                f_n: 1e5 * i as f64,
                f_t: -3e4,
                class: (i % 4) as u8,
            })
            .collect(),
    }
}

/// Writes a run with many chunks; returns (file length after each checkpoint, its step),
/// the file length after the configuration, and the complete record.
fn write_run(dir: &std::path::Path) -> (Vec<(u64, u64)>, u64, RunRecord) {
    let config = Config::default();
    let mut rec = Recorder::create(dir, &config).unwrap();
    let len = || std::fs::metadata(dir.join(MCAP_FILE)).unwrap().len();
    let first = len();
    let mut marks = Vec::new();
    let mut expected = RunRecord {
        config_json: serde_json::to_string(&config).unwrap(),
        version: env!("CARGO_PKG_VERSION").into(),
        ..Default::default()
    };
    for k in 0..400 {
        let r = row(k);
        rec.series(&r).unwrap();
        expected.series.push(r);
        if k % 100 == 99 {
            let s = snapshot(k as usize, 50);
            rec.snapshot(&s).unwrap();
            expected.snapshots.push(s);
        }
        if k % 40 == 39 {
            let state: Vec<u8> = (0..1000u32).map(|b| (b * 7 + k as u32) as u8).collect();
            rec.checkpoint(k * 10, k as f64 * 5e-3, &state).unwrap();
            marks.push((len(), k * 10));
            expected.last_checkpoint = Some((k * 10, state));
        }
    }
    rec.finish().unwrap();
    (marks, first, expected)
}

#[test]
fn write_then_read_back_equal() {
    let tmp = TempDir::new("roundtrip");
    let (_, _, expected) = write_run(&tmp.0);
    let run = read_run(&tmp.0).unwrap();
    assert_eq!(run.truncated, None);
    assert_eq!(run.series, expected.series);
    assert_eq!(run.snapshots, expected.snapshots);
    assert_eq!(run.last_checkpoint, expected.last_checkpoint);
    assert_eq!(run.version, expected.version);
    assert_eq!(run.config().unwrap(), Config::default());
    // The file itself is a valid, complete MCAP with a summary (what Foxglove indexes).
    let bytes = std::fs::read(tmp.0.join(MCAP_FILE)).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("summary");
    let topics: Vec<_> = summary.channels.values().map(|c| c.topic.clone()).collect();
    for t in [TOPIC_CONFIG, TOPIC_SERIES, TOPIC_SNAPSHOT, TOPIC_CHECKPOINT] {
        assert!(topics.iter().any(|x| x == t), "{t} missing from {topics:?}");
    }
    // The CSV holds the same rows, same bits.
    let csv = std::fs::read_to_string(tmp.0.join(CSV_FILE)).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), csv_header());
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), expected.series.len());
    assert_eq!(rows[7], expected.series[7].csv_line());
}

/// `read_config` reads the configuration from the head of a record longer than the head it
/// reads (a sweep's check of finished tests), and equals what the whole read gives.
#[test]
fn configuration_alone_is_read_from_a_long_record() {
    let tmp = TempDir::new("config-only");
    let mut config = Config::default();
    config.solver.dt = crate::config::Duration(2.5e-4);
    config.test.mu = 6.0;
    let mut rec = Recorder::create(&tmp.0, &config).unwrap();
    for k in 0..4000 {
        rec.series(&row(k)).unwrap();
        if k % 400 == 0 {
            rec.snapshot(&snapshot(k as usize, 5000)).unwrap();
        }
    }
    rec.finish().unwrap();
    let len = std::fs::metadata(tmp.0.join(MCAP_FILE)).unwrap().len();
    assert!(
        len > 1 << 20,
        "the record ({len} bytes) must outgrow the 1 MiB head"
    );
    let head = read_config(&tmp.0).unwrap();
    assert_eq!(head, config);
    assert_eq!(head, read_run(&tmp.0).unwrap().config().unwrap());
}

#[test]
fn truncated_file_is_read_up_to_its_last_complete_chunk() {
    let tmp = TempDir::new("truncate");
    let (marks, first, full) = write_run(&tmp.0);
    let bytes = std::fs::read(tmp.0.join(MCAP_FILE)).unwrap();
    let n = bytes.len() as u64;
    // Evenly spread cuts, pseudo-random ones, the flush points themselves and the tail.
    let mut cuts: Vec<u64> = (0..60).map(|k| k * n / 60).collect();
    let mut s = 0x9e3779b97f4a7c15u64;
    for _ in 0..40 {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        cuts.push(s % n);
    }
    cuts.extend(marks.iter().flat_map(|&(l, _)| [l - 1, l, l + 1]));
    cuts.extend([0, 4, 8, 20, first - 1, first, n - 1, n - 8, n - 30]);
    for early in [0, 4, 8, 20] {
        std::fs::write(tmp.0.join("early.mcap"), &bytes[..early]).unwrap();
        assert!(read_run(tmp.0.join("early.mcap")).is_err(), "cut at {early}");
    }
    let cut_path = tmp.0.join("cut.mcap");
    for cut in cuts {
        std::fs::write(&cut_path, &bytes[..cut as usize]).unwrap();
        let result = read_run(&cut_path);
        if cut < first {
            // Cut inside the configuration's chunk (an error) or inside the message index
            // that follows it (the configuration alone).
            match result {
                Err(e) => assert!(e.to_string().contains("cut.mcap"), "{e}"),
                Ok(run) => assert!(run.series.is_empty() && run.truncated.is_some()),
            }
            continue;
        }
        let run = result.unwrap_or_else(|e| panic!("cut at {cut} of {n}: {e}"));
        assert!(run.truncated.is_some(), "cut at {cut} of {n}");
        assert_eq!(run.config().unwrap(), Config::default());
        assert_eq!(run.series[..], full.series[..run.series.len()]);
        assert_eq!(run.snapshots[..], full.snapshots[..run.snapshots.len()]);
        // Every checkpoint flushed before the cut is there, with its series rows.
        if let Some(&(_, step)) = marks.iter().rev().find(|(l, _)| *l <= cut) {
            let (got, _) = run.last_checkpoint.as_ref().expect("checkpoint");
            assert!(*got >= step, "cut at {cut}: checkpoint {got} < {step}");
            assert!(run.series.last().unwrap().step >= step);
        }
        if let Some((step, state)) = &run.last_checkpoint {
            assert_eq!(state.len(), 1000);
            assert_eq!(state[0], (step / 10) as u8);
        }
    }
}

#[test]
fn foreign_files_are_rejected_naming_the_file() {
    let tmp = TempDir::new("foreign");
    let text = tmp.0.join("notes.txt");
    std::fs::write(&text, "just some text, not a run\n").unwrap();
    let mut s = 12345u64;
    let random: Vec<u8> = (0..4096)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 33) as u8
        })
        .collect();
    let rnd = tmp.0.join("random.bin");
    std::fs::write(&rnd, &random).unwrap();
    let empty = tmp.0.join("empty.mcap");
    std::fs::write(&empty, b"").unwrap();
    // A valid MCAP that is not a cdlab run.
    let other = tmp.0.join("other.mcap");
    {
        let mut w =
            mcap::Writer::new(std::io::BufWriter::new(std::fs::File::create(&other).unwrap())).unwrap();
        let ch = w.add_channel(0, "/imu", "json", &Default::default()).unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: 1,
            publish_time: 1,
        };
        w.write_to_known_channel(&header, b"{}").unwrap();
        w.finish().unwrap();
    }
    for path in [&text, &rnd, &empty, &other, &tmp.0.join("missing.mcap")] {
        let name = path.file_name().unwrap().to_str().unwrap();
        let e = read_run(path).expect_err("foreign file").to_string();
        assert!(e.contains(name), "{e}");
        let e = read_config(path).expect_err("foreign file").to_string();
        assert!(e.contains(name), "{e}");
    }
    // Our own topic with a foreign schema is refused, not misread.
    let clash = tmp.0.join("clash.mcap");
    {
        let mut w =
            mcap::Writer::new(std::io::BufWriter::new(std::fs::File::create(&clash).unwrap())).unwrap();
        let ch = w
            .add_channel(0, TOPIC_CONFIG, "json", &Default::default())
            .unwrap();
        let header = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        w.write_to_known_channel(&header, b"{}").unwrap();
        w.finish().unwrap();
    }
    let e = read_run(&clash).unwrap_err().to_string();
    assert!(e.contains("clash.mcap") && e.contains(CONFIG_SCHEMA), "{e}");
}

#[test]
fn series_table_matches_the_struct() {
    let value = serde_json::to_value(row(3)).unwrap();
    let obj = value.as_object().unwrap();
    assert_eq!(obj.len(), SERIES_FIELDS.len());
    // The CSV line, read through its header, gives the JSON values back.
    let line = row(3).csv_line();
    let cells: Vec<&str> = line.split(',').collect();
    assert_eq!(cells.len(), SERIES_FIELDS.len());
    for ((name, ty, _), cell) in SERIES_FIELDS.iter().zip(cells) {
        let v = &obj[*name];
        match *ty {
            "string" => assert_eq!(v.as_str().unwrap(), cell, "{name}"),
            "integer" => assert_eq!(v.as_u64().unwrap(), cell.parse::<u64>().unwrap()),
            _ => assert_eq!(v.as_f64().unwrap(), cell.parse::<f64>().unwrap(), "{name}"),
        }
    }
    let schema: serde_json::Value = serde_json::from_str(&series_json_schema()).unwrap();
    assert_eq!(schema["properties"].as_object().unwrap().len(), obj.len());
}

/// Every column of [`SERIES_FIELDS`] read from the typed rows ([`series_column`]) is of
/// the table's type and holds, row by row, what the row's JSON holds under that name (NaN
/// for null): the Python package's DataFrame is built from these columns.
#[test]
fn series_columns_hold_the_rows_fields_by_name() {
    let mut rows: Vec<SeriesRow> = [1, 2, 7, 60].into_iter().map(row).collect();
    rows[2].a_t = f64::NAN;
    let json: Vec<serde_json::Value> = rows.iter().map(|r| serde_json::to_value(r).unwrap()).collect();
    for (name, ty, _) in SERIES_FIELDS {
        let column = series_column(&rows, name).unwrap_or_else(|| panic!("no column {name}"));
        let cells = json.iter().map(|v| &v[*name]);
        match (*ty, column) {
            ("string", SeriesColumn::Text(c)) => {
                assert!(
                    cells
                        .map(|v| v.as_str().unwrap())
                        .eq(c.iter().map(String::as_str)),
                    "{name}"
                )
            }
            ("integer", SeriesColumn::Integer(c)) => {
                assert!(cells.map(|v| v.as_u64().unwrap()).eq(c.iter().copied()), "{name}")
            }
            ("number", SeriesColumn::Number(c)) => {
                let bits = |x: f64| {
                    if x.is_nan() {
                        f64::NAN.to_bits()
                    } else {
                        x.to_bits()
                    }
                };
                let want = cells.map(|v| bits(v.as_f64().unwrap_or(f64::NAN)));
                assert!(want.eq(c.iter().map(|x| bits(*x))), "{name}");
            }
            (ty, c) => panic!("{name}: a {ty} column given as {c:?}"),
        }
    }
    assert!(series_column(&rows, "nothing").is_none());
}

#[test]
fn non_finite_series_values_come_back_as_nan() {
    let mut r = row(1);
    r.inertial_number = f64::NAN;
    r.sigma1_pa = f64::INFINITY;
    let json = serde_json::to_string(&r).unwrap();
    let back: SeriesRow = serde_json::from_str(&json).unwrap();
    assert!(back.inertial_number.is_nan() && back.sigma1_pa.is_nan());
    assert_eq!(back.height_m, r.height_m);
}

#[test]
fn snapshot_codec_round_trips_and_rejects_bad_lengths() {
    let s = snapshot(3, 17);
    let b = s.encode().unwrap();
    assert_eq!(b.len(), 24 + 72 * 17 + 41 * 34);
    assert_eq!(Snapshot::decode(&b).unwrap(), s);
    assert!(Snapshot::decode(&b[..b.len() - 1]).is_err());
    assert!(Snapshot::decode(&b[..10]).is_err());
    assert_eq!(ContactClass::from_u8(3), Some(ContactClass::Sliding));
    assert_eq!(ContactClass::from_u8(4), None);
}

/// K / (sigma3 h w): 2e6 J/m over 1 MPa x 100 m x 20 m is 1e-3; a sample that has lost its
/// width or its confinement has no ratio (NaN), which no threshold accepts.
#[test]
fn kinetic_ratio_of_a_row() {
    let ok = SeriesRow {
        sigma3_pa: 1e6,
        height_m: 100.0,
        width_m: 20.0,
        kinetic_energy_j: 2e6,
        ..Default::default()
    };
    assert!(
        (ok.kinetic_ratio() - 1e-3).abs() < 1e-18,
        "{}",
        ok.kinetic_ratio()
    );
    for bad in [
        SeriesRow {
            width_m: -3.0,
            ..ok.clone()
        },
        SeriesRow {
            height_m: 0.0,
            ..ok.clone()
        },
        SeriesRow {
            sigma3_pa: 0.0,
            ..ok.clone()
        },
    ] {
        let r = bad.kinetic_ratio();
        assert!(r.is_nan() && r.partial_cmp(&1.0).is_none(), "{r}");
    }
}

/// A row of a record written before rows held the wall time reads back with it NaN (not
/// 0, which would pass for a measured time); the other fields as written.
#[test]
fn rows_without_wall_time_read_back_as_nan() {
    let mut v = serde_json::to_value(row(3)).unwrap();
    v.as_object_mut().unwrap().remove("wall_s");
    let back: SeriesRow = serde_json::from_value(v).unwrap();
    assert!(back.wall_s.is_nan());
    assert_eq!(back.sigma1_pa, row(3).sigma1_pa);
}

/// The CSV reads back to the rows written, bit for bit (Rust's shortest round-trip floats),
/// non-finite values as NaN, a quoted phase with its comma and quote.
#[test]
fn series_csv_reads_back_the_rows_written() {
    let mut rows: Vec<SeriesRow> = (0..60).map(row).collect();
    rows[3].inertial_number = f64::NAN;
    rows[4].kinetic_energy_j = f64::NEG_INFINITY;
    rows[5].phase = "odd, \"quoted\" phase".into();
    let text: String = std::iter::once(csv_header())
        .chain(rows.iter().map(SeriesRow::csv_line))
        .collect::<Vec<_>>()
        .join("\n");
    let back = parse_csv(&text).unwrap();
    assert_eq!(back.len(), rows.len());
    assert!(back[3].inertial_number.is_nan() && back[4].kinetic_energy_j.is_nan());
    assert_eq!(back[5].phase, rows[5].phase);
    for (k, (a, b)) in rows
        .iter()
        .zip(&back)
        .enumerate()
        .filter(|(k, _)| !(3..=4).contains(k))
    {
        assert_eq!(a, b, "row {k}");
    }
}

/// A CSV written before the `wall_s` and `deep_contacts` columns (35 of the 5000-disk
/// archive's tests) reads with their defaults, NaN and 0; a column cdlab never wrote, a
/// short line or a value that is not a number is an error naming the column or line.
#[test]
fn series_csv_of_older_and_bad_files() {
    // The first `m` columns of the current header and of a line.
    let first = |text: &str, m: usize| text.split(',').take(m).collect::<Vec<_>>().join(",");
    let at = |name: &str| csv_header().split(',').position(|c| c == name).unwrap();
    let old_header = first(&csv_header(), at("wall_s"));
    let line = row(7).csv_line();
    let old_line = first(&line, at("wall_s"));
    let back = parse_csv(&format!("{old_header}\n{old_line}\n")).unwrap();
    assert!(back[0].wall_s.is_nan() && back[0].deep_contacts == 0.0);
    assert_eq!(back[0].sigma1_pa, row(7).sigma1_pa);
    // Written before the micromechanical columns: they read as NaN (not measured), the
    // columns before them as written.
    let pre_micro = parse_csv(&format!(
        "{}\n{}\n",
        first(&csv_header(), at("a_c")),
        first(&line, at("a_c"))
    ))
    .unwrap();
    assert_eq!(pre_micro[0].deep_contacts, row(7).deep_contacts);
    assert!(
        pre_micro[0].a_c.is_nan() && pre_micro[0].lw_sigma1_pa.is_nan() && pre_micro[0].rose_max_dev.is_nan()
    );
    let e = parse_csv(&format!("{},sigma2_pa\n{line},1\n", csv_header())).unwrap_err();
    assert!(e.contains("sigma2_pa"), "{e}");
    let e = parse_csv(&format!("{}\n{old_line}\n", csv_header())).unwrap_err();
    assert!(e.contains("line 2"), "{e}");
    let bad_step = line.replacen(",70,", ",7x0,", 1);
    assert_ne!(bad_step, line);
    let e = parse_csv(&format!("{}\n{line}\n{bad_step}\n", csv_header())).unwrap_err();
    assert!(e.contains("line 3") && e.contains("step"), "{e}");
    // The phase has no default: a file without it cannot give rows, and serde names it.
    let no_phase = csv_header().replace("phase,", "");
    let e = parse_csv(&format!("{no_phase}\n{}\n", line.replacen(",confinement", "", 1))).unwrap_err();
    assert!(e.contains("phase"), "{e}");
    assert!(parse_csv("").is_err());
}

/// An archived test (configuration and thinned series, no record): `read_series` reads the
/// thinned series and `read_config` the configuration, while `read_run` says what the
/// directory is instead of "no such file".
#[test]
fn archived_test_gives_its_series_and_says_it_has_no_record() {
    let tmp = TempDir::new("archived-series");
    let rows: Vec<SeriesRow> = (0..20).map(row).collect();
    let text: String = std::iter::once(csv_header())
        .chain(rows.iter().map(SeriesRow::csv_line))
        .map(|l| l + "\n")
        .collect();
    std::fs::write(tmp.0.join(THINNED_SERIES_FILE), text).unwrap();
    std::fs::write(
        tmp.0.join(ARCHIVED_CONFIG_FILE),
        Config::default().to_toml_string().unwrap(),
    )
    .unwrap();
    let (read, config) = read_series(&tmp.0).unwrap();
    assert_eq!(read, rows);
    assert_eq!(config.unwrap(), Config::default());
    assert_eq!(read_config(&tmp.0).unwrap(), Config::default());
    let e = read_run(&tmp.0).unwrap_err();
    let text = e.to_string();
    assert!(
        text.contains("archived test") && text.contains("thinned series"),
        "{text}"
    );
    assert_eq!(
        e.remedy(),
        Some(crate::error::Remedy::UseThinnedSeries(tmp.0.clone()))
    );
}

/// Every single-bit flip in a record, wherever it lands, gives either an error naming the
/// file or a record whose rows are a prefix of those written and whose checkpoint is one
/// of those written, byte for byte: damaged content is never handed out. A flip inside the
/// last checkpoint's chunk falls back to the checkpoint before it, flagged as damage.
#[test]
fn bit_flips_never_hand_out_damaged_content() {
    let tmp = TempDir::new("bitflip");
    let (marks, first, full) = write_run(&tmp.0);
    let bytes = std::fs::read(tmp.0.join(MCAP_FILE)).unwrap();
    let written: Vec<(u64, Vec<u8>)> = marks
        .iter()
        .map(|&(_, step)| {
            let k = step / 10;
            (step, (0..1000u32).map(|b| (b * 7 + k as u32) as u8).collect())
        })
        .collect();
    assert_eq!(written.last(), full.last_checkpoint.as_ref());
    // The last checkpoint's chunk lies between the flushes of the last two checkpoints.
    let (lo, hi) = (
        marks[marks.len() - 2].0 as usize,
        marks[marks.len() - 1].0 as usize,
    );
    let mut offsets: Vec<usize> = (lo..hi).step_by(5).collect();
    // The first chunk's opcode, each of its bits: a chunk whose opcode is damaged is
    // skipped by the MCAP reader without an error, and the rows after it were once handed
    // out as the run's (the sequence numbers now stop the read there).
    offsets.extend(std::iter::repeat_n(first as usize, 8));
    let mut s = 0x2545f4914f6cdd1du64;
    for _ in 0..300 {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        offsets.push((s % bytes.len() as u64) as usize);
    }
    let path = tmp.0.join("flipped.mcap");
    let mut fell_back = 0;
    for (n, &at) in offsets.iter().enumerate() {
        let mut b = bytes.clone();
        b[at] ^= 1 << (n % 8);
        std::fs::write(&path, &b).unwrap();
        let run = match read_run(&path) {
            Ok(run) => run,
            Err(e) => {
                assert!(e.to_string().contains("flipped.mcap"), "{e}");
                assert!((at as u64) < first, "flip at {at}: {e}");
                continue;
            }
        };
        assert_eq!(run.series[..], full.series[..run.series.len()], "flip at {at}");
        assert_eq!(
            run.snapshots[..],
            full.snapshots[..run.snapshots.len()],
            "flip at {at}"
        );
        if let Some(ck) = &run.last_checkpoint {
            assert!(written.contains(ck), "flip at {at}: a checkpoint never written");
        }
        if (lo..hi).contains(&at) && run.last_checkpoint != full.last_checkpoint {
            fell_back += 1;
            assert_eq!(
                run.last_checkpoint.as_ref().map(|c| c.0),
                written.get(written.len() - 2).map(|c| c.0),
                "flip at {at} in {lo}..{hi}: {:?} {:?}",
                run.truncated,
                run.damaged
            );
            assert!(
                run.damaged.is_some() || run.truncated.is_some(),
                "flip at {at} in {lo}..{hi}: {:?} {:?} {:?}",
                run.last_checkpoint.as_ref().map(|c| c.0),
                run.truncated,
                run.damaged
            );
        }
    }
    // Most flips in the last checkpoint's chunk hit its compressed content.
    assert!(
        fell_back > (hi - lo) / 10,
        "{fell_back} of {} flips fell back",
        (hi - lo) / 5
    );
}

/// A checkpoint message whose CRC does not match is recognised; an intact one, and one of
/// the layout without CRC (older records), are read.
#[test]
fn checkpoint_crc_is_checked() {
    let tmp = TempDir::new("ckcrc");
    let mut rec = Recorder::create(&tmp.0, &Config::default()).unwrap();
    rec.checkpoint(7, 0.5, b"first state").unwrap();
    rec.checkpoint(9, 0.6, b"second state").unwrap();
    rec.finish().unwrap();
    let run = read_run(&tmp.0).unwrap();
    assert_eq!(run.last_checkpoint, Some((9, b"second state".to_vec())));
    assert!(run.damaged.is_none() && run.run_id.as_deref().is_some_and(|id| id.len() == 32));
    let mut data = 9u64.to_le_bytes().to_vec();
    data.extend_from_slice(b"state");
    let crc = crc32fast::hash(&data);
    data.extend_from_slice(&crc.to_le_bytes());
    assert_eq!(
        super::reader::checkpoint_message(&data, false),
        Ok((9, b"state".to_vec()))
    );
    for k in 0..data.len() * 8 {
        let mut d = data.clone();
        d[k / 8] ^= 1 << (k % 8);
        assert!(super::reader::checkpoint_message(&d, false).is_err(), "bit {k}");
    }
    assert_eq!(
        super::reader::checkpoint_message(&data[..13], true),
        Ok((9, b"state".to_vec()))
    );
    assert!(super::reader::checkpoint_message(&data[..11], false).is_err());
}

/// A staged recorder leaves the files of the real names alone until it commits, then
/// replaces them whole; an atomic write replaces a file whole or not at all.
#[test]
fn staged_record_replaces_the_old_only_at_commit() {
    let tmp = TempDir::new("staged");
    let (_, _, full) = write_run(&tmp.0);
    let before = std::fs::read(tmp.0.join(MCAP_FILE)).unwrap();
    let head = RecordHead {
        run_id: "0123".into(),
        backend: Some("test".into()),
        earlier_backends: Vec::new(),
    };
    let mut rec = Recorder::stage(&tmp.0, &Config::default(), &head).unwrap();
    rec.series(&row(0)).unwrap();
    rec.checkpoint(0, 0.0, b"new").unwrap();
    assert_eq!(before, std::fs::read(tmp.0.join(MCAP_FILE)).unwrap());
    assert_eq!(read_run(&tmp.0).unwrap().series, full.series);
    rec.commit().unwrap();
    assert!(!tmp.0.join("run.mcap.tmp").exists() && !tmp.0.join("series.csv.tmp").exists());
    rec.series(&row(1)).unwrap();
    rec.checkpoint(10, 0.1, b"newer").unwrap();
    // Read while the recorder is still open: no footer, the chunks so far.
    let run = read_run(&tmp.0).unwrap();
    assert_eq!(run.series, vec![row(0), row(1)]);
    assert_eq!(run.last_checkpoint, Some((10, b"newer".to_vec())));
    assert_eq!(
        (run.run_id.as_deref(), run.backend.as_deref()),
        (Some("0123"), Some("test"))
    );
    rec.finish().unwrap();
    let csv = std::fs::read_to_string(tmp.0.join(CSV_FILE)).unwrap();
    assert_eq!(csv.lines().count(), 3);

    let f = tmp.0.join("summary.json");
    atomic::write_file(&f, b"old").unwrap();
    atomic::write_file(&f, b"new").unwrap();
    assert_eq!(std::fs::read(&f).unwrap(), b"new");
    assert!(!tmp.0.join("summary.json.tmp").exists());
    atomic::remove_file(&f).unwrap();
    atomic::remove_file(&f).unwrap();
    assert!(!f.exists());
}

/// The record's errors a caller can act on come back as their own variants, naming the
/// directory or file: a run held by another process (wait), an archived test (use its
/// thinned series), a file that is not a record.
#[test]
fn record_errors_are_variants_naming_the_place() {
    let tmp = TempDir::new("variants");
    let run = tmp.0.join("run");
    let held = RunLock::acquire(&run).unwrap();
    match RunLock::acquire(&run) {
        Err(Error::InUse { dir, lock }) => {
            assert_eq!(dir, run);
            assert_eq!(lock, run.join(LOCK_FILE));
        }
        other => panic!("expected the run to be in use, got {:?}", other.map(|_| ())),
    }
    drop(held);
    assert!(RunLock::acquire(&run).is_ok());

    let archived = tmp.0.join("archived");
    std::fs::create_dir_all(&archived).unwrap();
    std::fs::write(archived.join(THINNED_SERIES_FILE), csv_header() + "\n").unwrap();
    std::fs::write(
        archived.join(ARCHIVED_CONFIG_FILE),
        Config::default().to_toml_string().unwrap(),
    )
    .unwrap();
    match read_run(&archived) {
        Err(Error::Archived { dir, .. }) => assert_eq!(dir, archived),
        other => panic!("expected an archived test, got {:?}", other.map(|_| ())),
    }

    let text = tmp.0.join("notes.mcap");
    std::fs::write(&text, "not a record\n").unwrap();
    match read_run(&text) {
        Err(Error::BadRecord { path, message }) => {
            assert_eq!(path.as_deref(), Some(text.as_path()));
            assert!(!message.is_empty());
        }
        other => panic!("expected a bad record, got {:?}", other.map(|_| ())),
    }
    assert!(matches!(
        parse_run(b"not a record"),
        Err(Error::BadRecord { path: None, .. })
    ));
}

/// Two touching disks of radius 1 on the x axis pressed by 1e5 N/m, and one in contact
/// with a wall.
fn pressed_pair(time_s: f64, strain: f64) -> Snapshot {
    let disk = |x: f64| DiskRecord {
        x,
        r: 1.0,
        ..Default::default()
    };
    let contact = |i, j, f_n| ContactRecord {
        i,
        j,
        nx: 1.0,
        ny: 0.0,
        f_n,
        f_t: 0.0,
        class: ContactClass::Rolling as u8,
    };
    Snapshot {
        time_s,
        strain,
        disks: vec![disk(0.0), disk(2.0)],
        contacts: vec![contact(1, 0, 1e5), contact(0, 2, 1e5)],
    }
}

#[test]
fn snapshot_fabric_takes_the_nearest_rows_area_and_names_what_is_missing() {
    use crate::error::SnapshotFault;
    use crate::measure::micro::Analysis;
    let src = std::path::Path::new("runs/t1");
    // Rows at t = 0, 5, 10 ms ...: the snapshot at t = 12 ms takes the row at 10 ms.
    let series: Vec<SeriesRow> = (0..10).map(row).collect();
    let snap = pressed_pair(0.012, 0.02);
    let f = snap.fabric(&series, src).unwrap();
    assert_eq!(f.row.time_s, series[2].time_s);
    let area = series[2].height_m * series[2].width_m;
    let radius = [1.0, 1.0];
    assert_eq!(f.analysis, Analysis::of(&snap.micro_contacts(), &radius, area));
    // One force-carrying disk-disk contact of 1e5 N/m along x, branch 2 m: the Love-Weber
    // sigma_xx has the wall contact's share too (1e5 N/m x 1 m), so (2e5 + 1e5) / area.
    assert_eq!(f.analysis.sums.n_force, 1);
    let sxx = 3e5 / area;
    assert!(
        (f.analysis.sigma1_pa - sxx).abs() <= 1e-9 * sxx,
        "{} Pa against {sxx} Pa",
        f.analysis.sigma1_pa
    );
    let fault_of = |r: crate::Result<super::SnapshotFabric<'_>>| match r {
        Err(Error::Snapshot { path, fault, message }) => {
            assert_eq!(path, src);
            assert!(message.starts_with("runs/t1: "), "{message}");
            fault
        }
        other => panic!("{other:?}"),
    };
    assert_eq!(fault_of(snap.fabric(&[], src)), SnapshotFault::NoSeriesRow);
    let mut flat = series.clone();
    flat[2].height_m = 0.0;
    assert_eq!(fault_of(snap.fabric(&flat, src)), SnapshotFault::NoArea);
    flat[2].height_m = f64::NAN;
    assert_eq!(fault_of(snap.fabric(&flat, src)), SnapshotFault::NoArea);
    let mut idle = snap.clone();
    idle.contacts.iter_mut().for_each(|c| c.f_n = 0.0);
    assert_eq!(fault_of(idle.fabric(&series, src)), SnapshotFault::NoForce);
}

#[test]
fn nearest_snapshot_takes_the_last_of_equal_strains() {
    use crate::error::SnapshotFault;
    let snaps: Vec<Snapshot> = [0.0, 0.0, 0.01, 0.03]
        .iter()
        .enumerate()
        .map(|(k, &e)| pressed_pair(k as f64, e))
        .collect();
    // The snapshots at strain 0 end the preparation's phases: the last is the compression's start.
    assert_eq!(nearest_snapshot(&snaps, 0.0), Some(1));
    assert_eq!(nearest_snapshot(&snaps, 0.018), Some(2));
    assert_eq!(nearest_snapshot(&snaps, 1.0), Some(3));
    assert_eq!(nearest_snapshot(&[], 0.0), None);
    let src = std::path::Path::new("t");
    assert_eq!(pick_snapshot(&snaps, None, src).unwrap().time_s, 3.0);
    assert_eq!(pick_snapshot(&snaps, Some(0.011), src).unwrap().time_s, 2.0);
    assert!(matches!(
        pick_snapshot(&[], None, src),
        Err(Error::Snapshot {
            fault: SnapshotFault::NoSnapshot,
            ..
        })
    ));
    // Rotations of snapshot 3 count from the least strain before it, the last of equals.
    assert_eq!(rotation_reference(&snaps, 3).unwrap().time_s, 1.0);
    assert!(rotation_reference(&snaps, 0).is_none());
}

/// Damage to the summary section of a finished record (the chunk indexes that other
/// readers seek through) is found by the footer's summary CRC (issue 36, item 11): every
/// byte from the summary's start to the CRC field, flipped in turn, makes the record read
/// as damaged; the intact file reads complete.
#[test]
fn a_damaged_summary_section_is_found_by_its_crc() {
    let tmp = TempDir::new("summary-crc");
    write_run(&tmp.0);
    let bytes = std::fs::read(tmp.0.join(MCAP_FILE)).unwrap();
    let rec = parse_run(&bytes).unwrap();
    assert!(
        rec.truncated.is_none() && rec.damaged.is_none(),
        "{:?}",
        rec.truncated
    );
    // Footer: opcode, length, summary_start, summary_offset_start, summary_crc; then magic.
    let n = bytes.len();
    let start = u64::from_le_bytes(bytes[n - 28..n - 20].try_into().unwrap()) as usize;
    let crc = u32::from_le_bytes(bytes[n - 12..n - 8].try_into().unwrap());
    assert!(
        start > 8 && start < n - 37 && crc != 0,
        "start {start}, crc {crc:08x}"
    );
    let missed: Vec<usize> = (start..n - 12)
        .filter(|&at| {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x10;
            parse_run(&damaged).is_ok_and(|r| r.damaged.is_none())
        })
        .collect();
    assert!(
        missed.is_empty(),
        "{} of {} flips in the summary section went unnoticed, first at byte {}",
        missed.len(),
        n - 12 - start,
        missed[0]
    );
}

/// A resumed record names the backends of the run's earlier parts with its own (issue 36,
/// item 15: a GPU run resumed on the CPU said only `backend: cpu`); parts on one backend in
/// a row are named once, and a record that names none has none.
#[test]
fn a_resumed_record_lists_the_backends_of_its_parts() {
    let tmp = TempDir::new("backends");
    let head = RecordHead {
        run_id: "01".into(),
        backend: Some("gpu (test adapter)".into()),
        earlier_backends: Vec::new(),
    };
    let config = Config::default();
    let mut rec = Recorder::stage(&tmp.0, &config, &head).unwrap();
    rec.checkpoint(1, 0.0, b"state").unwrap();
    rec.finish().unwrap();
    let first = read_run(&tmp.0).unwrap();
    assert_eq!(first.backends, ["gpu (test adapter)"]);
    for (backend, want) in [
        ("cpu (1 thread)", vec!["gpu (test adapter)", "cpu (1 thread)"]),
        ("cpu (1 thread)", vec!["gpu (test adapter)", "cpu (1 thread)"]),
    ] {
        let before = read_run(&tmp.0).unwrap();
        let head = RecordHead::resumed(&before, backend.into());
        assert_eq!(head.run_id, "01");
        let mut rec = Recorder::stage(&tmp.0, &config, &head).unwrap();
        rec.checkpoint(2, 0.0, b"state").unwrap();
        rec.finish().unwrap();
        let after = read_run(&tmp.0).unwrap();
        assert_eq!(after.backends, want);
        assert_eq!(after.backend.as_deref(), Some(backend));
    }
    drop(Recorder::create(&tmp.0, &config).unwrap());
    assert!(read_run(&tmp.0).unwrap().backends.is_empty());
}
