//! VTK export parsed back: the numbers ParaView reads are the snapshot's.

use cdlab::record::{ContactRecord, DiskRecord, Snapshot, vtk};

/// The whitespace-separated values of the DataArray named `name` (first match after `after`).
fn array(text: &str, after: &str, name: &str) -> Vec<f64> {
    let start = text.find(after).expect("section");
    let tag = format!("Name=\"{name}\"");
    let at = start + text[start..].find(&tag).expect("array");
    let body_start = at + text[at..].find('>').expect("tag end") + 1;
    let body_end = body_start + text[body_start..].find("</DataArray>").expect("array end");
    text[body_start..body_end]
        .split_whitespace()
        .map(|t| t.parse().expect("number"))
        .collect()
}

#[test]
fn vtp_files_hold_the_snapshot() {
    let snap = Snapshot {
        time_s: 1.5,
        strain: 0.01,
        disks: (0..3)
            .map(|k| DiskRecord {
                x: k as f64,
                y: 2.0 * k as f64,
                r: 0.5 + 0.1 * k as f64,
                vx: 1.0,
                dx: 0.25,
                ..Default::default()
            })
            .collect(),
        contacts: vec![
            ContactRecord {
                i: 0,
                j: 1,
                nx: 1.0,
                ny: 0.0,
                f_n: 10.0,
                f_t: -2.0,
                class: 2,
            },
            ContactRecord {
                i: 1,
                j: 2,
                nx: 0.0,
                ny: 1.0,
                f_n: 5.0,
                f_t: 1.0,
                class: 3,
            },
            // A wall contact (j >= n_disks) is not a line.
            ContactRecord {
                i: 2,
                j: 3,
                nx: 0.0,
                ny: 1.0,
                f_n: 7.0,
                f_t: 0.0,
                class: 2,
            },
        ],
    };
    let dir = std::env::temp_dir().join(format!("cdlab-vtk-{}", std::process::id()));
    let files = vtk::write_series(&[snap.clone(), snap.clone()], &dir).unwrap();
    assert_eq!(files.len(), 3);
    let text = std::fs::read_to_string(&files[0]).unwrap();
    assert!(text.contains("NumberOfPoints=\"3\"") && text.contains("NumberOfLines=\"2\""));
    assert_eq!(array(&text, "<PointData", "radius"), vec![0.5, 0.6, 0.7]);
    assert_eq!(
        array(&text, "<PointData", "displacement"),
        vec![0.25, 0.0, 0.0, 0.25, 0.0, 0.0, 0.25, 0.0, 0.0]
    );
    // Cell data: three vertices (0) then the two disk-disk contacts.
    assert_eq!(
        array(&text, "<CellData", "normal_force"),
        vec![0.0, 0.0, 0.0, 10.0, 5.0]
    );
    assert_eq!(array(&text, "<Lines", "connectivity"), vec![0.0, 1.0, 1.0, 2.0]);
    let pvd = std::fs::read_to_string(dir.join("snapshots.pvd")).unwrap();
    assert_eq!(pvd.matches("<DataSet timestep=\"1.5\"").count(), 2);
    let _ = std::fs::remove_dir_all(&dir);
}
