//! The main job draws its figures: `cdlab biaxial` writes the stress-strain and contact-count
//! figures beside its summary, names them in its last lines, and leaves them out with
//! `--no-figures`.

mod common;

use common::{biaxial, small_config};
use std::path::{Path, PathBuf};

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-main-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

fn run(cfg: &Path, out: &Path, extra: &[&str]) -> String {
    let (ok, text) = biaxial(cfg, out, extra);
    assert!(ok, "{text}");
    text
}

/// Width and height of a PNG file, decoded (a truncated or empty file fails here).
fn png_size(p: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(p).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    (info.width, info.height)
}

#[test]
fn the_biaxial_test_draws_its_curves_unless_asked_not_to() {
    let base = scratch("figs");
    let cfg = small_config(&base);
    let out = base.join("run");
    let text = run(&cfg, &out, &[]);
    let figures_line = text
        .lines()
        .find(|l| l.starts_with("figures: "))
        .unwrap_or_else(|| panic!("no figures line in:\n{text}"));
    for stem in ["stress_strain", "contacts"] {
        let png = out.join(format!("{stem}.png"));
        let svg = out.join(format!("{stem}.svg"));
        // Named in the final lines, where the user looks for them.
        assert!(
            figures_line.contains(&png.display().to_string()),
            "{figures_line}"
        );
        assert!(
            figures_line.contains(&svg.display().to_string()),
            "{figures_line}"
        );
        // The figures' page size (src/figures/curves.rs, CURVE_SIZE).
        assert_eq!(png_size(&png), (900, 600), "{}", png.display());
        let svg_text = std::fs::read_to_string(&svg).unwrap();
        let doc = roxmltree::Document::parse(&svg_text).unwrap();
        // The curves themselves: one polyline per series with a point per compression row
        // (0.6% strain at series_every 10 gives far more than 20 rows).
        let longest = doc
            .descendants()
            .filter(|n| n.has_tag_name("polyline"))
            .map(|n| n.attribute("points").unwrap_or("").split_whitespace().count())
            .max()
            .unwrap_or(0);
        assert!(longest > 20, "{stem}: longest polyline has {longest} points");
        let words: String = doc
            .descendants()
            .filter_map(|n| n.text())
            .collect::<Vec<_>>()
            .join(" ");
        assert!(words.contains("axial strain"), "{stem}: no axis title");
    }
    // The contact counts' axis labels whole numbers without a decimal point.
    let svg_text = std::fs::read_to_string(out.join("contacts.svg")).unwrap();
    let doc = roxmltree::Document::parse(&svg_text).unwrap();
    let ticks: Vec<&str> = doc
        .descendants()
        .filter(|n| n.has_tag_name("text"))
        .filter_map(|n| n.text())
        .filter(|t| t.trim().parse::<f64>().is_ok_and(|v| v >= 100.0))
        .collect();
    assert!(!ticks.is_empty(), "no count tick labels");
    assert!(
        ticks.iter().all(|t| !t.contains('.')),
        "count ticks with a decimal point: {ticks:?}"
    );

    let bare = base.join("bare");
    let text = run(&cfg, &bare, &["--no-figures"]);
    assert!(!text.contains("figures: "), "{text}");
    assert!(bare.join("summary.json").is_file());
    for f in ["stress_strain.png", "contacts.svg"] {
        assert!(!bare.join(f).exists(), "{f} drawn with --no-figures");
    }
    let _ = std::fs::remove_dir_all(&base);
}
