//! The measured time series ([`SeriesRow`], defined in `measure`) as records hold it: the
//! `/series` channel and `series.csv`.
//!
//! Field names carry their SI unit (`sigma1_pa`, `height_m`); fields without a suffix are
//! dimensionless or counts. The JSON schema that Foxglove reads and the CSV header are built
//! from one table ([`SERIES_FIELDS`]), and a test checks that the table matches the struct.

use crate::measure::SeriesRow;

/// Every field of [`SeriesRow`] in declaration order: (name, JSON type, description).
pub const SERIES_FIELDS: &[(&str, &str, &str)] = &[
    ("time_s", "number", "simulated time (s)"),
    ("step", "integer", "step index"),
    ("phase", "string", "phase: compaction, confinement or compression"),
    (
        "strain_axial",
        "number",
        "axial strain dz/h0 (compression positive)",
    ),
    ("sigma1_pa", "number", "axial stress on the top wall (Pa)"),
    ("sigma3_pa", "number", "confining stress of the strips (Pa)"),
    ("volumetric_strain", "number", "dV/V0, positive = dilation"),
    ("n_contacts", "integer", "candidate contacts"),
    ("n_force", "integer", "force-carrying contacts"),
    ("n_rolling", "integer", "force-carrying non-slipping contacts"),
    ("n_sliding", "integer", "force-carrying slipping contacts"),
    ("n_zero_force", "integer", "geometric contacts without force"),
    ("coordination", "number", "coordination number 2 Nc / N'"),
    (
        "isolated_fraction",
        "number",
        "fraction of free disks with < 2 force contacts",
    ),
    ("overlap_mean_rel", "number", "mean overlap / r_min"),
    ("overlap_max_rel", "number", "maximum overlap / r_min"),
    (
        "iterations",
        "number",
        "mean solver iterations per step over the interval",
    ),
    (
        "iterations_max",
        "integer",
        "largest solver iteration count of a step in the interval",
    ),
    (
        "kinetic_energy_j",
        "number",
        "kinetic energy of the free disks (J/m)",
    ),
    ("inertial_number", "number", "inertial number I"),
    ("height_m", "number", "sample height (m)"),
    ("width_m", "number", "sample width (m)"),
    (
        "wall_s",
        "number",
        "wall-clock time since the run started, over its resumed parts (s)",
    ),
    (
        "deep_contacts",
        "number",
        "mean contacts per step given local updates (solver.deep_overlap)",
    ),
    (
        "a_c",
        "number",
        "fabric anisotropy of the force-carrying contacts",
    ),
    (
        "theta_c_deg",
        "number",
        "principal direction of the fabric (degrees from x)",
    ),
    ("a_n", "number", "normal force anisotropy"),
    ("a_t", "number", "tangential force anisotropy"),
    (
        "strong_fraction",
        "number",
        "fraction of force-carrying contacts with f_n > <f_n>",
    ),
    (
        "strong_q_share",
        "number",
        "share of the deviatoric stress carried by the strong network",
    ),
    (
        "lw_sigma1_pa",
        "number",
        "major principal Love-Weber stress over h w (Pa)",
    ),
    (
        "lw_sigma3_pa",
        "number",
        "minor principal Love-Weber stress over h w (Pa)",
    ),
    (
        "rose_max_dev",
        "number",
        "largest deviation of the 18-bin orientation histogram from its mean / mean",
    ),
];

/// One column of a series, typed as [`SERIES_FIELDS`] says ([`series_column`]).
#[derive(Clone, Debug, PartialEq)]
pub enum SeriesColumn {
    /// A "number" column (NaN where a row holds none).
    Number(Vec<f64>),
    /// An "integer" column.
    Integer(Vec<u64>),
    /// A "string" column (the phase).
    Text(Vec<String>),
}

/// The column `name` of [`SERIES_FIELDS`] over `rows`, read from the typed rows (no JSON
/// per cell: what the Python package hands to NumPy); `None` for a name that is no column.
pub fn series_column(rows: &[SeriesRow], name: &str) -> Option<SeriesColumn> {
    let number = |f: fn(&SeriesRow) -> f64| SeriesColumn::Number(rows.iter().map(f).collect());
    let integer = |f: fn(&SeriesRow) -> u64| SeriesColumn::Integer(rows.iter().map(f).collect());
    Some(match name {
        "time_s" => number(|r| r.time_s),
        "step" => integer(|r| r.step),
        "phase" => SeriesColumn::Text(rows.iter().map(|r| r.phase.clone()).collect()),
        "strain_axial" => number(|r| r.strain_axial),
        "sigma1_pa" => number(|r| r.sigma1_pa),
        "sigma3_pa" => number(|r| r.sigma3_pa),
        "volumetric_strain" => number(|r| r.volumetric_strain),
        "n_contacts" => integer(|r| r.n_contacts),
        "n_force" => integer(|r| r.n_force),
        "n_rolling" => integer(|r| r.n_rolling),
        "n_sliding" => integer(|r| r.n_sliding),
        "n_zero_force" => integer(|r| r.n_zero_force),
        "coordination" => number(|r| r.coordination),
        "isolated_fraction" => number(|r| r.isolated_fraction),
        "overlap_mean_rel" => number(|r| r.overlap_mean_rel),
        "overlap_max_rel" => number(|r| r.overlap_max_rel),
        "iterations" => number(|r| r.iterations),
        "iterations_max" => integer(|r| r.iterations_max),
        "kinetic_energy_j" => number(|r| r.kinetic_energy_j),
        "inertial_number" => number(|r| r.inertial_number),
        "height_m" => number(|r| r.height_m),
        "width_m" => number(|r| r.width_m),
        "wall_s" => number(|r| r.wall_s),
        "deep_contacts" => number(|r| r.deep_contacts),
        "a_c" => number(|r| r.a_c),
        "theta_c_deg" => number(|r| r.theta_c_deg),
        "a_n" => number(|r| r.a_n),
        "a_t" => number(|r| r.a_t),
        "strong_fraction" => number(|r| r.strong_fraction),
        "strong_q_share" => number(|r| r.strong_q_share),
        "lw_sigma1_pa" => number(|r| r.lw_sigma1_pa),
        "lw_sigma3_pa" => number(|r| r.lw_sigma3_pa),
        "rose_max_dev" => number(|r| r.rose_max_dev),
        _ => return None,
    })
}

/// The JSON schema of `/series` messages (Foxglove uses it to offer the fields in plots).
pub fn series_json_schema() -> String {
    let props: serde_json::Map<String, serde_json::Value> = SERIES_FIELDS
        .iter()
        .map(|(name, ty, desc)| {
            // Numbers may be null: non-finite values have no JSON representation.
            let ty = if *ty == "number" {
                serde_json::json!(["number", "null"])
            } else {
                serde_json::json!(ty)
            };
            (
                name.to_string(),
                serde_json::json!({ "type": ty, "description": desc }),
            )
        })
        .collect();
    let names: Vec<&str> = SERIES_FIELDS.iter().map(|f| f.0).collect();
    serde_json::json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": "cdlab.SeriesRow",
        "description": "Macroscopic measurements of a cdlab run at one step (SI units)",
        "type": "object",
        "properties": props,
        "required": names,
    })
    .to_string()
}

/// The CSV header line (field names with their units, as in [`SERIES_FIELDS`]).
pub fn csv_header() -> String {
    let names: Vec<&str> = SERIES_FIELDS.iter().map(|f| f.0).collect();
    names.join(",")
}

/// Rows from the text of a series CSV (`series.csv`, or an archive's `series_thinned.csv`),
/// columns found by the header's names: a file written before `wall_s`, `deep_contacts` or
/// the micromechanical columns (`a_c` to `rose_max_dev`) existed reads with their defaults, as its MCAP does. `NaN` and infinities (how
/// [`SeriesRow::csv_line`] writes non-finite values) read as NaN. An unknown column, a
/// missing one that has no default, or a value that does not parse is an error naming its
/// line.
pub fn parse_csv(text: &str) -> std::result::Result<Vec<SeriesRow>, String> {
    let mut lines = text.lines().enumerate();
    let header: Vec<&str> = match lines.next() {
        Some((_, h)) => h.split(',').map(str::trim).collect(),
        None => return Err("empty file: no header".into()),
    };
    let kinds: Vec<&str> = header
        .iter()
        .map(|name| {
            SERIES_FIELDS
                .iter()
                .find(|f| f.0 == *name)
                .map(|f| f.1)
                .ok_or_else(|| format!("unknown column `{name}` in the header"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let mut rows = Vec::new();
    for (k, line) in lines {
        if line.trim().is_empty() {
            continue;
        }
        let cells = split_csv_line(line);
        if cells.len() != header.len() {
            return Err(format!(
                "line {}: {} values for {} columns",
                k + 1,
                cells.len(),
                header.len()
            ));
        }
        let mut obj = serde_json::Map::new();
        for ((name, kind), cell) in header.iter().zip(&kinds).zip(cells) {
            let bad = |e: &dyn std::fmt::Display| format!("line {}, column {name}: `{cell}`: {e}", k + 1);
            let value = match *kind {
                "string" => serde_json::Value::from(cell),
                "integer" => serde_json::Value::from(cell.parse::<u64>().map_err(|e| bad(&e))?),
                _ => {
                    let v = cell.parse::<f64>().map_err(|e| bad(&e))?;
                    // serde_json has no NaN: null is what the MCAP holds for it.
                    serde_json::Number::from_f64(v).map_or(serde_json::Value::Null, serde_json::Value::Number)
                }
            };
            obj.insert(name.to_string(), value);
        }
        rows.push(
            serde_json::from_value(serde_json::Value::Object(obj))
                .map_err(|e| format!("line {}: {e}", k + 1))?,
        );
    }
    Ok(rows)
}

/// The cells of one CSV line; a cell in double quotes may hold commas and doubled quotes
/// (how [`SeriesRow::csv_line`] writes a phase name that needs it).
fn split_csv_line(line: &str) -> Vec<String> {
    let mut cells = Vec::new();
    let mut cell = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                cell.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => cells.push(std::mem::take(&mut cell)),
            _ => cell.push(c),
        }
    }
    cells.push(cell);
    cells
}

impl SeriesRow {
    /// The row as one CSV line (no newline), in the order of [`csv_header`]. Floats use
    /// Rust's shortest round-trip form, so the CSV holds the same bits as the MCAP.
    pub fn csv_line(&self) -> String {
        // The phase is the only text; quote it if it ever holds a comma or a quote.
        let phase = if self.phase.contains([',', '"', '\n']) {
            format!("\"{}\"", self.phase.replace('"', "\"\""))
        } else {
            self.phase.clone()
        };
        format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            self.time_s,
            self.step,
            phase,
            self.strain_axial,
            self.sigma1_pa,
            self.sigma3_pa,
            self.volumetric_strain,
            self.n_contacts,
            self.n_force,
            self.n_rolling,
            self.n_sliding,
            self.n_zero_force,
            self.coordination,
            self.isolated_fraction,
            self.overlap_mean_rel,
            self.overlap_max_rel,
            self.iterations,
            self.iterations_max,
            self.kinetic_energy_j,
            self.inertial_number,
            self.height_m,
            self.width_m,
            self.wall_s,
            self.deep_contacts,
            self.a_c,
            self.theta_c_deg,
            self.a_n,
            self.a_t,
            self.strong_fraction,
            self.strong_q_share,
            self.lw_sigma1_pa,
            self.lw_sigma3_pa,
            self.rose_max_dev,
        )
    }
}
