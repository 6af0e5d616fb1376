//! The report of the hardware check (`benches/hardware_report.py`) turns the crossover's
//! tests (`CDLAB_HW_CROSSOVER` in `benches/hardware_check.sh`) into one row per sample: the
//! compression's time per step and iterations on each backend, from the series the tests
//! wrote, and each part's wall time, marked where the part was stopped at its limit.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Writes a series of compression rows, 100 steps apart, `ms` ms of wall time per step and
/// `iterations` per step; the first row only starts the clock.
fn series(dir: &Path, file: &str, ms: f64, iterations: f64, rows: u32) {
    std::fs::create_dir_all(dir).unwrap();
    let mut text =
        String::from("step,phase,strain_axial,sigma1_pa,iterations,overlap_max_rel,n_contacts,wall_s\n");
    for k in 0..rows {
        let step = 1000 + 100 * k;
        let wall = 2.0 + k as f64 * 100.0 * ms / 1e3;
        text += &format!(
            "{step},compression,{:.4},1.6e7,{iterations},0.002,9000,{wall}\n",
            1e-4 * k as f64
        );
    }
    std::fs::write(dir.join(file), text).unwrap();
}

#[test]
fn the_crossover_table_gives_each_backends_compression_and_wall_time() {
    let out: PathBuf = std::env::temp_dir().join(format!("cdlab-hw-report-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).unwrap();
    // Two samples; the 20,000-disk CPU test on two threads was stopped at its limit (exit
    // status 124 of `timeout`) and left only its series' temporary file.
    series(&out.join("test_x_s10000_gpu"), "series.csv", 2.5, 11.0, 5);
    series(&out.join("test_x_s10000_cpu2"), "series.csv", 4.0, 9.0, 5);
    series(&out.join("test_x_s10000_cpu"), "series.csv", 3.25, 9.0, 5);
    series(&out.join("test_x_s20000_gpu"), "series.csv", 2.75, 9.0, 5);
    series(&out.join("test_x_s20000_cpu2"), "series.csv.tmp", 7.0, 6.0, 3);
    std::fs::write(
        out.join("parts.tsv"),
        "part\trc\tseconds\tlimit_s\n\
         test_x_s10000_gpu\t0\t17.500\t55\n\
         test_x_s10000_cpu2\t0\t28.500\t55\n\
         test_x_s10000_cpu\t0\t23.400\t55\n\
         test_x_s20000_gpu\t0\t29.100\t55\n\
         test_x_s20000_cpu2\t124\t55.087\t55\n",
    )
    .unwrap();
    let run = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/hardware_report.py"))
        .arg(&out)
        .output()
        .expect("python3 runs (the CI installs it)");
    let text = String::from_utf8_lossy(&run.stdout).into_owned() + &String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{text}");
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    // ms per step: the wall time between the first and last rows over their steps.
    assert!(
        md.contains("| s10000 | 2.50 (11.0), 17.5 s | 4.00 (9.0), 28.5 s | 3.25 (9.0), 23.4 s |"),
        "{md}"
    );
    // The smaller sample first; a stopped part is marked, a part never run is a dash.
    assert!(
        md.contains("| s20000 | 2.75 (9.0), 29.1 s | 7.00 (6.0), 55.1 s (stopped) | - |"),
        "{md}"
    );
    assert!(md.find("| s10000 |").unwrap() < md.find("| s20000 |").unwrap());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(json["tests"].as_object().unwrap().len(), 5, "{json}");
    let _ = std::fs::remove_dir_all(&out);
}
