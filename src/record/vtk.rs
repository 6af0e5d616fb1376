//! VTK export of snapshots for ParaView: one PolyData file (`.vtp`, XML, ASCII) per snapshot
//! with the disks as vertices and the contacts as lines, and a `.pvd` series indexing them
//! by simulated time.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::Snapshot;
use crate::error::Result;

/// Formats one disk's value of a point-data array.
type DiskField = dyn Fn(&super::DiskRecord) -> String;

/// Writes `snap` as a `.vtp` file: points = disk centres (z = 0) with point data `radius`,
/// `velocity`, `spin`, `rotation`, `displacement`; vertices = one per disk; lines = one per
/// disk-disk contact with cell data `normal_force`, `tangential_force`, `class`. Contacts
/// with walls are left out (a wall is not a point).
pub fn write_vtp(snap: &Snapshot, path: &Path) -> Result<()> {
    let nd = snap.disks.len();
    let lines: Vec<_> = snap.contacts.iter().filter(|c| (c.j as usize) < nd).collect();
    let mut s = String::new();
    let w = &mut s;
    let _ = writeln!(w, "<?xml version=\"1.0\"?>");
    let _ = writeln!(
        w,
        "<VTKFile type=\"PolyData\" version=\"0.1\" byte_order=\"LittleEndian\">"
    );
    let _ = writeln!(w, "<PolyData>");
    let _ = writeln!(
        w,
        "<Piece NumberOfPoints=\"{nd}\" NumberOfVerts=\"{nd}\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">",
        lines.len()
    );
    let _ = writeln!(
        w,
        "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">"
    );
    for d in &snap.disks {
        let _ = writeln!(w, "{} {} 0", d.x, d.y);
    }
    let _ = writeln!(w, "</DataArray></Points>");
    let _ = writeln!(w, "<PointData Scalars=\"radius\" Vectors=\"velocity\">");
    let arrays: [(&str, usize, &DiskField); 5] = [
        ("radius", 1, &|d| format!("{}", d.r)),
        ("velocity", 3, &|d| format!("{} {} 0", d.vx, d.vy)),
        ("spin", 1, &|d| format!("{}", d.w)),
        ("rotation", 1, &|d| format!("{}", d.theta)),
        ("displacement", 3, &|d| format!("{} {} 0", d.dx, d.dy)),
    ];
    for (name, comps, f) in arrays {
        let _ = writeln!(
            w,
            "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"ascii\">"
        );
        for d in &snap.disks {
            let _ = writeln!(w, "{}", f(d));
        }
        let _ = writeln!(w, "</DataArray>");
    }
    let _ = writeln!(w, "</PointData>");
    let _ = writeln!(w, "<CellData Scalars=\"normal_force\">");
    // Vertices come first among the cells, then lines: both need values.
    for (name, ty, f) in [
        (
            "normal_force",
            "Float64",
            &(|c: &super::ContactRecord| format!("{}", c.f_n)) as &dyn Fn(&super::ContactRecord) -> String,
        ),
        ("tangential_force", "Float64", &|c| format!("{}", c.f_t)),
        ("class", "Int32", &|c| format!("{}", c.class)),
    ] {
        let _ = writeln!(w, "<DataArray type=\"{ty}\" Name=\"{name}\" format=\"ascii\">");
        for _ in 0..nd {
            let _ = writeln!(w, "0");
        }
        for c in &lines {
            let _ = writeln!(w, "{}", f(c));
        }
        let _ = writeln!(w, "</DataArray>");
    }
    let _ = writeln!(w, "</CellData>");
    let _ = writeln!(
        w,
        "<Verts><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
    );
    for k in 0..nd {
        let _ = writeln!(w, "{k}");
    }
    let _ = writeln!(
        w,
        "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
    );
    for k in 0..nd {
        let _ = writeln!(w, "{}", k + 1);
    }
    let _ = writeln!(w, "</DataArray></Verts>");
    let _ = writeln!(
        w,
        "<Lines><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">"
    );
    for c in &lines {
        let _ = writeln!(w, "{} {}", c.i, c.j);
    }
    let _ = writeln!(
        w,
        "</DataArray><DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">"
    );
    for k in 0..lines.len() {
        let _ = writeln!(w, "{}", 2 * (k + 1));
    }
    let _ = writeln!(w, "</DataArray></Lines>");
    let _ = writeln!(w, "</Piece>\n</PolyData>\n</VTKFile>");
    crate::fsio::write_file(path, s.as_bytes())
}

/// Writes every snapshot as `snapshot_NNNN.vtp` into `dir` and the series `snapshots.pvd`
/// (time = simulated time in s); returns the files written.
pub fn write_series(snaps: &[Snapshot], dir: &Path) -> Result<Vec<PathBuf>> {
    crate::fsio::create_dir_all(dir)?;
    let mut files = Vec::new();
    let mut pvd = String::from(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n",
    );
    for (k, s) in snaps.iter().enumerate() {
        let name = format!("snapshot_{k:04}.vtp");
        let path = dir.join(&name);
        write_vtp(s, &path)?;
        let _ = writeln!(
            pvd,
            "<DataSet timestep=\"{}\" part=\"0\" file=\"{name}\"/>",
            s.time_s
        );
        files.push(path);
    }
    pvd.push_str("</Collection>\n</VTKFile>\n");
    let p = dir.join("snapshots.pvd");
    crate::fsio::write_file(&p, pvd.as_bytes())?;
    files.push(p);
    Ok(files)
}
