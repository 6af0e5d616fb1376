//! Figures drawn from small synthetic runs whose content is known, then read back: PNGs are
//! decoded and probed at the pixels where a disk, a bar or a curve must be; SVGs are parsed
//! and their elements counted. The CLI is run end to end on a synthetic record.

mod common;

use std::path::{Path, PathBuf};

use cdlab::analysis::report::{Report, TestPoint, analyse};
use cdlab::figures::colormap::{DIVERGING, SEQUENTIAL};
use cdlab::figures::envelope::friction_color;
use cdlab::figures::network::{ARROW, DISK_BACKGROUND, ROLLING, SLIDING};
use cdlab::figures::{
    CompareFigure, ContactsFigure, EnvelopeFigure, Field, Figure, Format, LINE_COLORS, MuMacroFigure,
    ShearField, SnapshotFigure, StressStrainFigure, render_png, render_svg, save,
};
use cdlab::record::{ContactRecord, DiskRecord, SeriesRow, Snapshot};
use common::cdlab;
use plotters::style::RGBColor;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-figures-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A decoded 8-bit RGB image.
struct Img {
    w: u32,
    h: u32,
    rgb: Vec<u8>,
}

impl Img {
    fn decode(bytes: &[u8]) -> Img {
        let mut dec = png::Decoder::new(std::io::Cursor::new(bytes))
            .read_info()
            .expect("a PNG");
        let mut buf = vec![0; dec.output_buffer_size().expect("size")];
        let info = dec.next_frame(&mut buf).expect("one frame");
        assert_eq!(
            info.color_type,
            png::ColorType::Rgb,
            "figures are written as 8-bit RGB"
        );
        buf.truncate(info.buffer_size());
        Img {
            w: info.width,
            h: info.height,
            rgb: buf,
        }
    }
    fn at(&self, x: f64, y: f64) -> RGBColor {
        let (x, y) = (x.round() as usize, y.round() as usize);
        let i = 3 * (y * self.w as usize + x);
        RGBColor(self.rgb[i], self.rgb[i + 1], self.rgb[i + 2])
    }
    /// Pixels of exactly `c` in columns [x0, x1) and rows [y0, y1).
    fn count_in(&self, c: RGBColor, (x0, x1): (u32, u32), (y0, y1): (u32, u32)) -> usize {
        let mut n = 0;
        for y in y0..y1.min(self.h) {
            for x in x0..x1.min(self.w) {
                if self.at(x as f64, y as f64) == c {
                    n += 1;
                }
            }
        }
        n
    }
    fn count(&self, c: RGBColor) -> usize {
        self.count_in(c, (0, self.w), (0, self.h))
    }
    /// Pixels darker than mid-grey in the given rows: text and axes are black.
    fn dark_in_rows(&self, y0: u32, y1: u32) -> usize {
        (y0..y1)
            .flat_map(|y| (0..self.w).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let c = self.at(x as f64, y as f64);
                (c.0 as u32 + c.1 as u32 + c.2 as u32) < 3 * 100
            })
            .count()
    }
    fn distinct_colors(&self) -> usize {
        let mut v: Vec<&[u8]> = self.rgb.chunks(3).collect();
        v.sort();
        v.dedup();
        v.len()
    }
}

fn hex(c: RGBColor) -> String {
    format!("#{:02X}{:02X}{:02X}", c.0, c.1, c.2)
}

/// The elements of an SVG named `tag` whose attribute `attr` equals `value` (any when None).
fn svg_elements<'a>(
    doc: &'a roxmltree::Document,
    tag: &str,
    attr: Option<(&str, &str)>,
) -> Vec<roxmltree::Node<'a, 'a>> {
    doc.descendants()
        .filter(|n| n.has_tag_name(tag))
        .filter(|n| attr.is_none_or(|(a, v)| n.attribute(a) == Some(v)))
        .collect()
}

fn points(node: &roxmltree::Node) -> Vec<(f64, f64)> {
    node.attribute("points")
        .expect("points")
        .split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').expect("x,y");
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// Series with a confinement row (not drawn) then 101 compression rows: sigma_1 rising to
/// a peak of 15 MPa at strain 0.01 then settling at 12 MPa; volumetric strain growing to 0.02.
fn series() -> Vec<SeriesRow> {
    let mut rows = vec![SeriesRow {
        phase: "confinement".into(),
        sigma1_pa: 8e6,
        n_rolling: 999,
        ..Default::default()
    }];
    for k in 0..=100 {
        let e = 0.001 * k as f64;
        rows.push(SeriesRow {
            phase: "compression".into(),
            strain_axial: e,
            sigma1_pa: if e < 0.01 {
                8e6 + 7e8 * e
            } else {
                12e6 + 3e6 * (-(e - 0.01) / 0.005).exp()
            },
            volumetric_strain: 0.2 * e,
            n_rolling: 2000 - 5 * k as u64,
            n_sliding: 200 + 3 * k as u64,
            n_zero_force: 100,
            ..Default::default()
        });
    }
    rows
}

#[test]
fn stress_strain_curve_shows_both_axes_and_its_text() {
    let rows = series();
    let fig = StressStrainFigure {
        rows: &rows,
        title: "synthetic".into(),
    };
    let (png, ()) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    assert_eq!(
        (img.w, img.h),
        fig.size(),
        "the PNG has the figure's declared size"
    );
    // Each curve spans the plot width (about 700 px) with a 2 px pen: hundreds of pixels.
    for (c, what) in [(LINE_COLORS[0], "sigma_1"), (LINE_COLORS[1], "volumetric strain")] {
        let n = img.count(c);
        assert!(n > 500, "{what} curve color {c:?}: {n} pixels, expected > 500");
    }
    // Text renders with the embedded font: the x-axis title is alone in the bottom 35 rows
    // and the caption alone in the top 30; blank text would leave them white.
    let bottom = img.dark_in_rows(img.h - 35, img.h);
    let top = img.dark_in_rows(0, 30);
    assert!(bottom > 100, "x-axis title: {bottom} dark pixels, expected > 100");
    assert!(top > 50, "caption: {top} dark pixels, expected > 50");

    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    // Only the 101 compression rows are drawn: the confinement row is not on the strain axis.
    let line = svg_elements(&doc, "polyline", Some(("stroke", &hex(LINE_COLORS[0]))));
    let longest = line.iter().map(|n| points(n).len()).max().unwrap_or(0);
    assert_eq!(longest, 101, "sigma_1 polyline has one point per compression row");
    let texts: Vec<String> = svg_elements(&doc, "text", None)
        .iter()
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect();
    for want in ["axial stress σ₁ (MPa)", "axial strain ε₁ (-)"] {
        assert!(
            texts.iter().any(|t| t.contains(want)),
            "axis title {want:?} in {texts:?}"
        );
    }
    assert!(
        texts.iter().any(|t| t.starts_with("volumetric strain")),
        "the twin axis has its title"
    );
}

/// The start of the top wall (issue 36, item 14): a spike of one row at 20 MPa, above the
/// peak, is drawn row by row in a light color under the mean over 0.002 strain whose top is
/// the summary's peak, marked and labelled with it; the stress axis spans the rows instead
/// of starting at 0; no text shows a literal underscore (it showed in "ε_z").
#[test]
fn stress_strain_curve_marks_the_peak_of_the_mean_over_a_start_spike() {
    let mut rows: Vec<SeriesRow> = (0..=1000)
        .map(|k| {
            let e = 2e-5 * k as f64;
            SeriesRow {
                phase: "compression".into(),
                strain_axial: e,
                sigma1_pa: if e < 0.01 {
                    8e6 + 7e8 * e
                } else {
                    12e6 + 3e6 * (-(e - 0.01) / 0.005).exp()
                },
                volumetric_strain: 0.2 * e,
                ..Default::default()
            }
        })
        .collect();
    rows[1].sigma1_pa = 20e6;
    let (peak, at) = cdlab::measure::derived::moving_peak(&rows, 0.002);
    assert!(peak < 15e6, "{peak}");
    let fig = StressStrainFigure {
        rows: &rows,
        title: "spike".into(),
    };
    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    let longest = |c: RGBColor| {
        svg_elements(&doc, "polyline", Some(("stroke", &hex(c))))
            .iter()
            .map(|n| points(n).len())
            .max()
            .unwrap_or(0)
    };
    assert_eq!(longest(cdlab::figures::curves::ROW_COLOR), 1001, "rows");
    assert_eq!(longest(LINE_COLORS[0]), 1001, "window means");
    let texts: Vec<String> = svg_elements(&doc, "text", None)
        .iter()
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect();
    let label = format!("peak {:.3} MPa at strain {:.4}", peak / 1e6, at);
    assert!(texts.contains(&label), "{label:?} in {texts:?}");
    assert!(!texts.iter().any(|t| t.contains('_')), "{texts:?}");
    // Tick labels: strains below 0.03, volumetric strains below 0.005, stresses from about
    // 3.4 MPa (8 MPa, less the margin and the legend's room below): none at 0 or 2.
    let stress_ticks: Vec<f64> = texts
        .iter()
        .filter_map(|t| t.parse::<f64>().ok())
        .filter(|v| *v > 0.5)
        .collect();
    assert!(!stress_ticks.is_empty(), "{texts:?}");
    assert!(
        stress_ticks.iter().all(|v| *v >= 3.0) && stress_ticks.iter().any(|v| *v >= 19.0),
        "the stress axis spans the rows, spike included: {stress_ticks:?}"
    );
}

#[test]
fn contact_counts_draw_three_curves() {
    let rows = series();
    let fig = ContactsFigure {
        rows: &rows,
        title: "synthetic".into(),
    };
    let img = Img::decode(&render_png(&fig).unwrap().0);
    for c in [LINE_COLORS[0], LINE_COLORS[3], LINE_COLORS[2]] {
        let n = img.count(c);
        assert!(n > 500, "curve color {c:?}: {n} pixels, expected > 500");
    }
    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    for c in [LINE_COLORS[0], LINE_COLORS[3], LINE_COLORS[2]] {
        let lines = svg_elements(&doc, "polyline", Some(("stroke", &hex(c))));
        // One 101-point curve and one 2-point legend sample per class.
        let lens: Vec<usize> = lines.iter().map(|n| points(n).len()).collect();
        assert!(lens.contains(&101), "color {c:?}: polylines of {lens:?} points");
    }
    // No compression row, no strain axis: an error, not an empty figure.
    let e = render_png(&ContactsFigure {
        rows: &rows[..1],
        title: String::new(),
    })
    .unwrap_err();
    assert!(e.to_string().contains("compression"), "{e}");
}

const NX: usize = 4;
const NY: usize = 6;

/// 4 x 6 touching disks of radius 1 m, centres (2i, 2j), disk k = 4j + i. Displacement
/// magnitude 0.01 k m; rotation since the reference 0.1 (k - 5) rad except disk 1 at -1.8
/// rad (so the range is +-1.8 and disk 5 sits at 0); disk 10 moves at 1 m/s along +x and
/// disk 3 at 0.5 m/s along +y, the others rest. Horizontal neighbours touch: row 0 rolling
/// with forces 1, 2, 4 kN/m, row 1 sliding, row 2 zero-force, row 3 open, rows 4-5 rolling
/// at 1 kN/m; disk 0 presses on the bottom wall (2 kN/m, rolling).
fn grid() -> (Snapshot, Snapshot) {
    let mut disks = Vec::new();
    for k in 0..NX * NY {
        let (i, j) = ((k % NX) as f64, (k / NX) as f64);
        disks.push(DiskRecord {
            x: 2.0 * i,
            y: 2.0 * j,
            r: 1.0,
            theta: 0.5 + if k == 1 { -1.8 } else { 0.1 * (k as f64 - 5.0) },
            dy: -0.01 * k as f64,
            vx: if k == 10 { 1.0 } else { 0.0 },
            vy: if k == 3 { 0.5 } else { 0.0 },
            ..Default::default()
        });
    }
    let mut contacts = Vec::new();
    for j in 0..NY {
        for i in 0..NX - 1 {
            let (a, b) = ((j * NX + i + 1) as u32, (j * NX + i) as u32);
            let (class, f_n) = match j {
                0 => (2, 1000.0 * (1 << i) as f64),
                1 => (3, 500.0),
                2 => (1, 0.0),
                3 => (0, 0.0),
                _ => (2, 1000.0),
            };
            contacts.push(ContactRecord {
                i: a,
                j: b,
                nx: 1.0,
                ny: 0.0,
                f_n,
                f_t: 0.0,
                class,
            });
        }
    }
    contacts.push(ContactRecord {
        i: 0,
        j: (NX * NY) as u32, // wall 0
        nx: 0.0,
        ny: 1.0,
        f_n: 2000.0,
        f_t: 0.0,
        class: 2,
    });
    let snap = Snapshot {
        time_s: 2.0,
        strain: 0.05,
        disks: disks.clone(),
        contacts,
    };
    let reference = Snapshot {
        time_s: 1.0,
        strain: 0.0,
        disks: disks.iter().map(|d| DiskRecord { theta: 0.5, ..*d }).collect(),
        contacts: vec![],
    };
    (snap, reference)
}

fn centre(k: usize) -> (f64, f64) {
    (2.0 * (k % NX) as f64, 2.0 * (k / NX) as f64)
}

#[test]
fn displacement_disks_take_the_map_colors_to_scale() {
    let (snap, _) = grid();
    let fig = SnapshotFigure {
        snap: &snap,
        reference: None,
        field: Field::Displacement,
        plot_height: 600,
        shear: None,
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    assert_eq!((img.w, img.h), fig.size());
    assert!(
        (frame.sx - frame.sy).abs() / frame.sx < 0.01,
        "equal aspect: {} vs {} px/m",
        frame.sx,
        frame.sy
    );
    // The sample is 12.5 m tall on 600 px: about 48 px/m.
    assert!((frame.sx - 600.0 / 12.48).abs() < 1.0, "scale {} px/m", frame.sx);
    // Disk 0 has no displacement (map's 0), disk 23 the largest (map's 1).
    let (x, y) = frame.to_pixel(centre(0).0, centre(0).1);
    assert_eq!(img.at(x, y), SEQUENTIAL.at(0.0), "disk 0 at pixel ({x}, {y})");
    let (x, y) = frame.to_pixel(centre(23).0, centre(23).1);
    assert_eq!(img.at(x, y), SEQUENTIAL.at(1.0), "disk 23 at pixel ({x}, {y})");
    // Drawn to scale: 0.9 radius from a centre (diagonally) is still the disk, 1.1 radii is
    // the gap between disks 12, 13, 16 and 17.
    let (cx, cy) = centre(12);
    let diag = std::f64::consts::FRAC_1_SQRT_2;
    let (x, y) = frame.to_pixel(cx + 0.9 * diag, cy + 0.9 * diag);
    assert_eq!(img.at(x, y), SEQUENTIAL.at(12.0 / 23.0), "inside disk 12");
    let (x, y) = frame.to_pixel(cx + 1.1 * diag, cy + 1.1 * diag);
    assert_ne!(img.at(x, y), SEQUENTIAL.at(12.0 / 23.0), "outside disk 12");
    // The colorbar, right of the sample (beyond x = 8 m), shows both end colors.
    let right = frame.to_pixel(8.0, 0.0).0 as u32 + 10;
    for t in [0.0, 1.0] {
        let n = img.count_in(SEQUENTIAL.at(t), (right, img.w), (0, img.h));
        assert!(n > 50, "colorbar end {t}: {n} pixels, expected > 50");
    }

    let (svg, _) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    // Disks are the only polygons of this figure (the colorbar is made of rects).
    assert_eq!(
        svg_elements(&doc, "polygon", None).len(),
        NX * NY,
        "one polygon per disk"
    );
    let end = svg_elements(&doc, "rect", Some(("fill", &hex(SEQUENTIAL.at(1.0)))));
    assert_eq!(end.len(), 1, "the colorbar's top step has the map's 1 color");
}

#[test]
fn rotation_is_diverging_and_counts_from_the_reference() {
    let (snap, reference) = grid();
    let fig = SnapshotFigure {
        snap: &snap,
        reference: Some(&reference),
        field: Field::Rotation,
        plot_height: 600,
        shear: None,
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    let at = |k: usize| {
        let (x, y) = frame.to_pixel(centre(k).0, centre(k).1);
        img.at(x, y)
    };
    // Relative to the reference every theta loses 0.5 rad: disk 5 is at 0 (the map's
    // near-white middle), disk 23 at +1.8 (red end), disk 1 at -1.8 (blue end).
    assert_eq!(at(5), DIVERGING.at(0.5), "zero rotation");
    assert_eq!(at(23), DIVERGING.at(1.0), "largest counterclockwise rotation");
    assert_eq!(at(1), DIVERGING.at(0.0), "largest clockwise rotation");
    // Without the reference the totals are drawn: disk 5 (0.5 rad) is no longer neutral.
    let fig = SnapshotFigure {
        reference: None,
        ..fig
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    let (x, y) = frame.to_pixel(centre(5).0, centre(5).1);
    assert_ne!(
        img.at(x, y),
        DIVERGING.at(0.5),
        "total rotation 0.5 rad is not white"
    );
}

/// The shear field: disks colored by their local shear strain (disk k at k, the range set
/// by the largest; a disk without a value in the background fill), each band's axis drawn
/// across the sample in black, and a figure asked for without the field is an error.
#[test]
fn shear_disks_take_their_strain_and_bands_their_axes() {
    let (snap, _) = grid();
    let mut values: Vec<Option<f64>> = (0..NX * NY).map(|k| Some(k as f64)).collect();
    values[7] = None;
    // A band at +30 deg from the vertical through disk 9's centre (2, 4).
    let band = cdlab::analysis::bands::Band {
        angle_deg: 30.0,
        width_diameters: 2.0,
        contrast: 0.8,
        significance: 5.0,
        peak_shear: 0.2,
        background_shear: 0.01,
        centre_x_m: 2.0,
        centre_y_m: 4.0,
    };
    let shear = ShearField {
        values,
        strain_from: 0.04,
        bands: vec![band],
    };
    let fig = SnapshotFigure {
        snap: &snap,
        reference: None,
        field: Field::Shear,
        plot_height: 600,
        shear: Some(&shear),
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    let at = |x: f64, y: f64| {
        let (px, py) = frame.to_pixel(x, y);
        img.at(px, py)
    };
    assert_eq!(at(centre(0).0, centre(0).1), SEQUENTIAL.at(0.0), "disk 0");
    assert_eq!(at(centre(23).0, centre(23).1), SEQUENTIAL.at(1.0), "disk 23");
    assert_eq!(
        at(centre(7).0, centre(7).1),
        DISK_BACKGROUND,
        "disk 7 has no value"
    );
    // Along the axis, 4 m either side of the centre: (2 +- 2, 4 +- 3.46), the line's black
    // (within a pixel of the exact point).
    let (s, c) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
    for t in [-4.0, 4.0] {
        let (px, py) = frame.to_pixel(2.0 + t * s, 4.0 + t * c);
        let hit =
            (-1..=1).any(|d| (-1..=1).any(|e| img.at(px + d as f64, py + e as f64) == RGBColor(0, 0, 0)));
        assert!(hit, "band axis at ({px}, {py})");
    }
    // Off the axis (disk 20's centre, (0, 10): 4.1 m from it), no line.
    assert_eq!(
        at(centre(20).0, centre(20).1),
        SEQUENTIAL.at(20.0 / 23.0),
        "disk 20"
    );
    let e = render_png(&SnapshotFigure { shear: None, ..fig }).unwrap_err();
    assert!(e.to_string().contains("local strain"), "{e}");
}

/// The segment of a line inside a box, from the closed forms: a vertical line through the
/// box spans its height, a 45-degree line through a corner region is cut at the sides, and a
/// line beside the box misses it.
#[test]
fn band_axes_are_clipped_to_the_box() {
    use cdlab::figures::snapshot::clip_line;
    let bx = (0.0, 4.0, 0.0, 10.0);
    let (p, q) = clip_line((1.0, 5.0), (0.0, 1.0), bx).unwrap();
    assert_eq!((p, q), ((1.0, 0.0), (1.0, 10.0)));
    let d = std::f64::consts::FRAC_1_SQRT_2;
    let (p, q) = clip_line((2.0, 5.0), (d, d), bx).unwrap();
    assert!((p.0 - 0.0).abs() < 1e-12 && (p.1 - 3.0).abs() < 1e-12, "{p:?}");
    assert!((q.0 - 4.0).abs() < 1e-12 && (q.1 - 7.0).abs() < 1e-12, "{q:?}");
    assert!(clip_line((6.0, 5.0), (0.0, 1.0), bx).is_none());
}

#[test]
fn velocity_arrows_start_at_the_moving_disks() {
    let (snap, _) = grid();
    let fig = SnapshotFigure {
        snap: &snap,
        reference: None,
        field: Field::Velocity,
        plot_height: 600,
        shear: None,
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    // Disk 10's arrow is the longest: 3 mean radii (3 m) along +x; its shaft is ARROW red.
    let (cx, cy) = centre(10);
    let (x, y) = frame.to_pixel(cx + 1.0, cy);
    let hit = (-1..=1).any(|d| img.at(x, y + d as f64) == ARROW);
    assert!(hit, "arrow shaft of disk 10 at pixel ({x}, {y})");
    // A resting disk has no arrow: its centre keeps the background fill.
    let (x, y) = frame.to_pixel(centre(0).0, centre(0).1);
    assert_eq!(img.at(x, y), DISK_BACKGROUND, "disk 0 rests");

    let (svg, _) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let heads = svg_elements(&doc, "polygon", Some(("fill", &hex(ARROW))));
    assert_eq!(heads.len(), 2, "two moving disks, two arrow heads");
    assert_eq!(
        svg_elements(&doc, "polygon", Some(("fill", &hex(DISK_BACKGROUND)))).len(),
        NX * NY,
        "every disk drawn under the arrows"
    );
}

#[test]
fn force_bars_are_classed_and_as_wide_as_their_force() {
    let (snap, _) = grid();
    let fig = SnapshotFigure {
        snap: &snap,
        reference: None,
        field: Field::Forces,
        plot_height: 600,
        shear: None,
    };
    let (png, frame) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    let mid = |a: usize, b: usize| {
        let (pa, pb) = (centre(a), centre(b));
        let (x, y) = frame.to_pixel((pa.0 + pb.0) / 2.0, (pa.1 + pb.1) / 2.0);
        img.at(x, y)
    };
    assert_eq!(mid(2, 3), ROLLING, "row 0 contacts roll");
    assert_eq!(mid(5, 6), SLIDING, "row 1 contacts slide");
    for (a, b, what) in [(9, 10, "zero-force"), (13, 14, "open")] {
        let c = mid(a, b);
        assert!(
            c != ROLLING && c != SLIDING,
            "{what} contact {a}-{b} not drawn, got {c:?}"
        );
    }
    // Disk 0 on the bottom wall: a bar from its centre down to y = -1 m.
    let (x, y) = frame.to_pixel(0.0, -0.5);
    assert_eq!(img.at(x, y), ROLLING, "disk-wall bar");

    let (svg, frame) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let rolling = svg_elements(&doc, "polygon", Some(("fill", &hex(ROLLING))));
    let sliding = svg_elements(&doc, "polygon", Some(("fill", &hex(SLIDING))));
    // Rows 0, 4, 5 (3 each) and the wall contact roll; row 1 (3) slides.
    assert_eq!(rolling.len(), 10, "rolling bars");
    assert_eq!(sliding.len(), 3, "sliding bars");
    // The largest force (4 kN/m) gets 0.8 mean radius = 0.8 m; width is proportional to
    // force, so the 1 kN/m bars of row 0 are 0.2 m wide. SVG coordinates are whole pixels:
    // 1.5 px of tolerance.
    let width = |n: &roxmltree::Node| {
        let p = points(n);
        (p[0].0 - p[3].0).hypot(p[0].1 - p[3].1)
    };
    let mut widths: Vec<f64> = rolling.iter().map(width).collect();
    widths.sort_by(f64::total_cmp);
    let widest = *widths.last().unwrap();
    assert!((widest - 0.8 * frame.sx).abs() < 1.5, "widest bar {widest} px");
    assert!(
        (widths[0] - 0.2 * frame.sx).abs() < 1.5,
        "narrowest bar {} px",
        widths[0]
    );
}

#[test]
fn bad_requests_are_errors() {
    let e = "heat".parse::<Field>().unwrap_err().to_string();
    assert!(e.contains("displacement, rotation, velocity, forces"), "{e}");
    let e = Format::from_path(Path::new("fig.jpg")).unwrap_err().to_string();
    assert!(e.contains(".png or .svg"), "{e}");
    let (snap, _) = grid();
    let fig = SnapshotFigure {
        snap: &snap,
        reference: None,
        field: Field::Forces,
        plot_height: 300,
        shear: None,
    };
    let bad = Path::new("/nonexistent-cdlab-dir/fig.png");
    let e = save(&fig, bad).unwrap_err().to_string();
    assert!(
        e.contains("/nonexistent-cdlab-dir/fig.png"),
        "the error names the path: {e}"
    );
    let empty = Snapshot::default();
    let e = render_png(&SnapshotFigure { snap: &empty, ..fig }).unwrap_err();
    assert!(e.to_string().contains("no disk"), "{e}");
}

/// A report over four frictions and three confining stresses with mu_macro =
/// 0.9 - 0.7 exp(-3 mu) at the peak and 0.6 - 0.4 exp(-2 mu) at the residual.
fn report() -> Report {
    let mut points = Vec::new();
    for mu in [0.1f64, 0.3, 1.0, 3.0] {
        let (m, mr) = (0.9 - 0.7 * (-3.0 * mu).exp(), 0.6 - 0.4 * (-2.0 * mu).exp());
        for s3 in [1.0, 4.0, 8.0] {
            let s1 = |t: f64| s3 * (1.0 + t.atan().sin()) / (1.0 - t.atan().sin());
            points.push(TestPoint {
                dir: PathBuf::new(),
                mu,
                sigma3_mpa: s3,
                sigma1_peak_mpa: s1(m),
                sigma1_residual_mpa: Some(s1(mr)),
                ..Default::default()
            });
        }
    }
    analyse(&points, vec![])
}

#[test]
fn envelopes_show_every_point_and_line() {
    let rep = report();
    let fig = EnvelopeFigure { report: &rep };
    let img = Img::decode(&render_png(&fig).unwrap().0);
    assert!(img.distinct_colors() > 10, "a drawn figure, not a blank page");
    for k in 0..4 {
        let n = img.count(friction_color(k, 4));
        assert!(
            n > 200,
            "friction {k}: {n} pixels of its color, expected > 200 (lines and markers)"
        );
    }
    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    for k in 0..4 {
        let c = hex(friction_color(k, 4));
        // Three filled peak markers plus the legend's marker.
        let filled = svg_elements(&doc, "circle", Some(("fill", &c)));
        assert_eq!(filled.len(), 4, "friction {k} peak markers");
        // Three open residual markers.
        let open = svg_elements(&doc, "circle", Some(("stroke", &c)))
            .into_iter()
            .filter(|n| n.attribute("fill") == Some("none"))
            .count();
        assert_eq!(open, 3, "friction {k} residual markers");
    }
}

#[test]
fn mu_macro_against_friction_shows_points_and_fits() {
    let rep = report();
    let fig = MuMacroFigure { report: &rep };
    let img = Img::decode(&render_png(&fig).unwrap().0);
    for c in [LINE_COLORS[0], LINE_COLORS[1]] {
        let n = img.count(c);
        assert!(
            n > 300,
            "color {c:?}: {n} pixels, expected > 300 (curve and markers)"
        );
    }
    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    // The fitted curves are sampled at 200 frictions.
    for c in [LINE_COLORS[0], LINE_COLORS[1]] {
        let lens: Vec<usize> = svg_elements(&doc, "polyline", Some(("stroke", &hex(c))))
            .iter()
            .map(|n| points(n).len())
            .collect();
        assert!(lens.contains(&200), "fit curve of {c:?}: polylines {lens:?}");
    }
    // Four peak points plus the legend marker.
    let peak = svg_elements(&doc, "circle", Some(("fill", &hex(LINE_COLORS[0]))));
    assert_eq!(peak.len(), 5, "peak markers");
    let texts: Vec<&str> = svg_elements(&doc, "text", None)
        .iter()
        .filter_map(|n| n.text())
        .collect();
    assert!(
        texts.iter().any(|t| t.contains("0.900 - 0.700 exp(-3.000 μ)")),
        "the legend gives the fitted a, b, c: {texts:?}"
    );
}

#[test]
fn short_campaign_without_residual_still_draws() {
    // Two frictions, tests stopped before strain 0.05: no residual, no saturation fit.
    let tests: Vec<TestPoint> = [0.1, 0.5]
        .into_iter()
        .flat_map(|mu| {
            [1.0, 4.0].map(|s3| TestPoint {
                dir: PathBuf::new(),
                mu,
                sigma3_mpa: s3,
                sigma1_peak_mpa: 2.5 * s3,
                sigma1_residual_mpa: None,
                ..Default::default()
            })
        })
        .collect();
    let rep = analyse(&tests, vec![]);
    let (svg, ()) = render_svg(&EnvelopeFigure { report: &rep }).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let open = svg_elements(&doc, "circle", None)
        .into_iter()
        .filter(|n| n.attribute("fill") == Some("none"))
        .count();
    assert_eq!(open, 1, "no residual marker, only the legend's open circle");
    let (svg, ()) = render_svg(&MuMacroFigure { report: &rep }).unwrap();
    let doc = roxmltree::Document::parse(&svg).unwrap();
    let peak = svg_elements(&doc, "circle", Some(("fill", &hex(LINE_COLORS[0])))).len();
    assert_eq!(peak, 3, "two peak markers and the legend's");
    let fits = svg_elements(&doc, "polyline", Some(("stroke", &hex(LINE_COLORS[0]))))
        .iter()
        .filter(|n| points(n).len() == 200)
        .count();
    assert_eq!(fits, 0, "two frictions give no saturation fit, so no curve");
}

/// Writes a synthetic run (record only) with snapshots at strains 0, 0.05 and 0.1.
fn synthetic_run(dir: &Path, with_snapshots: bool) {
    let config = cdlab::config::Config::default();
    let mut rec = cdlab::record::Recorder::create(dir, &config).unwrap();
    for row in series() {
        rec.series(&row).unwrap();
    }
    if with_snapshots {
        let (snap, reference) = grid();
        for s in [0.0, 0.05, 0.1] {
            let base = if s == 0.0 { &reference } else { &snap };
            rec.snapshot(&Snapshot {
                strain: s,
                ..base.clone()
            })
            .unwrap();
        }
    }
    rec.finish().unwrap();
}

#[test]
fn render_command_draws_the_nearest_snapshot_and_the_curves() {
    let dir = scratch("render");
    let run = dir.join("run");
    synthetic_run(&run, true);
    let run_s = run.to_str().unwrap();
    // The two snapshots nearest 0.09 hold the same positions: the shear field is zero
    // everywhere, without a band, and still drawn.
    for field in ["displacement", "rotation", "velocity", "forces", "shear"] {
        // SVG first: the PNG's check compares its size with the SVG's.
        for ext in ["svg", "png"] {
            let out = dir.join(format!("{field}.{ext}"));
            let (ok, text) = cdlab(&[
                "render",
                run_s,
                "--at",
                "0.09",
                "--field",
                field,
                "-o",
                out.to_str().unwrap(),
            ]);
            assert!(ok, "{text}");
            // 0.09 is nearest the snapshot at 0.1, and the command says so.
            assert!(text.contains("axial strain 0.10000"), "{text}");
            check_snapshot_file(&out, field);
        }
    }
    let curves = dir.join("curves");
    let (ok, text) = cdlab(&["render", run_s, "--curves", "-o", curves.to_str().unwrap()]);
    assert!(ok, "{text}");
    // The curves of the record's series: 101 compression rows, one point each.
    let doc_text = std::fs::read_to_string(curves.join("stress_strain.svg")).unwrap();
    let doc = roxmltree::Document::parse(&doc_text).expect("well-formed SVG");
    let longest = |doc: &roxmltree::Document, c: RGBColor| {
        svg_elements(doc, "polyline", Some(("stroke", &hex(c))))
            .iter()
            .map(|n| points(n).len())
            .max()
            .unwrap_or(0)
    };
    assert_eq!(longest(&doc, LINE_COLORS[0]), 101, "sigma_1 curve");
    assert_eq!(longest(&doc, LINE_COLORS[1]), 101, "volumetric strain curve");
    let texts = svg_texts(&doc);
    for want in [
        "axial stress σ₁ (MPa)",
        "axial strain ε₁ (-)",
        "volumetric strain",
    ] {
        assert!(texts.iter().any(|t| t.contains(want)), "{want:?} in {texts:?}");
    }
    let doc_text = std::fs::read_to_string(curves.join("contacts.svg")).unwrap();
    let doc = roxmltree::Document::parse(&doc_text).expect("well-formed SVG");
    let curves_101 = svg_elements(&doc, "polyline", None)
        .iter()
        .filter(|n| points(n).len() == 101)
        .count();
    assert_eq!(curves_101, 3, "contact counts: three curves of 101 rows");
    for f in ["stress_strain.png", "contacts.png"] {
        let img = Img::decode(&std::fs::read(curves.join(f)).unwrap());
        assert!(
            img.count(LINE_COLORS[0]) > 500,
            "{f}: the first curve's color covers {} pixels",
            img.count(LINE_COLORS[0])
        );
        assert!(img.dark_in_rows(img.h - 35, img.h) > 100, "{f}: no x-axis title");
    }
    let fig = dir.join("x.png");
    let fig = fig.to_str().unwrap();
    for (args, want) in [
        (
            vec!["--at", "0.05", "--field", "heat", "-o", fig],
            "one of displacement",
        ),
        (vec!["--at", "0.05", "-o", "x.jpg"], ".png or .svg"),
        (
            vec!["--at", "0", "--field", "shear", "-o", fig],
            "needs a snapshot before",
        ),
        (
            vec!["--at", "0.05", "-o", "/nonexistent-cdlab-dir/x.png"],
            "/nonexistent-cdlab-dir/x.png",
        ),
    ] {
        let (ok, text) = cdlab(&[&["render", run_s][..], &args].concat());
        assert!(!ok && text.contains(want), "{args:?}: {text}");
        assert!(!text.contains("panicked"), "{text}");
    }
    let bare = dir.join("bare");
    synthetic_run(&bare, false);
    let (ok, text) = cdlab(&["render", bare.to_str().unwrap(), "--at", "0.05", "-o", fig]);
    assert!(!ok && text.contains("no snapshot"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Long key labels (two runs told apart by their directories' names) widen the key column
/// instead of being cut at the figure's edge, where they could no longer be told apart;
/// the title keeps a margin above it (issue 36, item 18: the title's top and the labels'
/// ends were cut).
#[test]
fn compare_keeps_long_labels_and_its_title_whole() {
    let a: Vec<SeriesRow> = series()
        .into_iter()
        .map(|r| SeriesRow { sigma3_pa: 8e6, ..r })
        .collect();
    let long = |k: usize| format!("σ₃ = 8 MPa (a_very_long_directory_name_of_run_number_{k})");
    let fig = CompareFigure {
        runs: vec![(long(1), &a[..]), (long(2), &a[..])],
        title: "μ = 0.3, σ₃ = 8 MPa, 5000 disks, dt = 0.5 ms, 2 runs".into(),
    };
    let (w, h) = fig.size();
    assert!(w > cdlab::figures::curves::COMPARE_SIZE.0 + 100, "{w}");
    let (png, ()) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    assert_eq!((img.w, img.h), (w, h));
    let dark_in_columns = |x0: u32, x1: u32| {
        (0..img.h)
            .flat_map(|y| (x0..x1).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let c = img.at(x as f64, y as f64);
                (c.0 as u32 + c.1 as u32 + c.2 as u32) < 3 * 100
            })
            .count()
    };
    assert_eq!(dark_in_columns(w - 8, w), 0, "a label reaches the right edge");
    assert!(dark_in_columns(w - 200, w - 8) > 50, "the labels' ends are drawn");
    assert_eq!(img.dark_in_rows(0, 8), 0, "the title touches the top");
    assert!(img.dark_in_rows(8, 45) > 50, "the title is drawn");
}

/// Two runs compared, the second at half the confining stress and half the axial stress
/// of the first: their stress ratios are equal, so their upper polylines coincide point for
/// point, while their volumetric strains differ and so do their lower ones. Each run's
/// color has one polyline per panel with a point per compression row, and a key entry.
#[test]
fn compared_runs_share_the_stress_ratio_axis() {
    let a: Vec<SeriesRow> = series()
        .into_iter()
        .map(|r| SeriesRow { sigma3_pa: 8e6, ..r })
        .collect();
    let b: Vec<SeriesRow> = a
        .iter()
        .map(|r| SeriesRow {
            sigma1_pa: r.sigma1_pa / 2.0,
            sigma3_pa: 4e6,
            volumetric_strain: r.volumetric_strain / 2.0,
            ..r.clone()
        })
        .collect();
    let fig = CompareFigure {
        runs: vec![("σ₃ = 8 MPa".into(), &a[..]), ("σ₃ = 4 MPa".into(), &b[..])],
        title: "two runs".into(),
    };
    let (svg, ()) = render_svg(&fig).unwrap();
    let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    let curves = |k: usize| -> Vec<Vec<(f64, f64)>> {
        svg_elements(&doc, "polyline", Some(("stroke", &hex(friction_color(k, 2)))))
            .iter()
            .map(points)
            .filter(|p| p.len() == 101)
            .collect()
    };
    let (ca, cb) = (curves(0), curves(1));
    assert!(
        ca.len() == 2 && cb.len() == 2,
        "{} and {} curves",
        ca.len(),
        cb.len()
    );
    assert_eq!(ca[0], cb[0], "equal stress ratios draw the same upper curve");
    assert_ne!(
        ca[1], cb[1],
        "different volumetric strains draw different lower curves"
    );
    let texts: Vec<String> = svg_elements(&doc, "text", None)
        .iter()
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect();
    for want in ["σ₃ = 8 MPa", "σ₃ = 4 MPa", "stress ratio σ₁/σ₃ (-)", "two runs"] {
        assert!(texts.iter().any(|t| t == want), "{want:?} in {texts:?}");
    }
    let (png, ()) = render_png(&fig).unwrap();
    let img = Img::decode(&png);
    for k in 0..2 {
        let n = img.count(friction_color(k, 2));
        assert!(n > 500, "run {k}: {n} pixels of its color");
    }
    // Without a confining stress there is no ratio to draw: an error, not a NaN curve.
    let bare = series();
    let fig = CompareFigure {
        runs: vec![("no sigma3".into(), &bare[..])],
        title: String::new(),
    };
    let e = render_png(&fig).unwrap_err().to_string();
    assert!(e.contains("no sigma3") && e.contains("confining stress"), "{e}");
}

/// `cdlab compare` on tests of the shipped archive: one figure, the runs counted; a bad
/// output name or a directory that holds no run is an error naming it.
#[test]
fn compare_command_draws_archived_tests() {
    let archive = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/results/campaign5000");
    let runs =
        ["seed1_mu3_s8MPa", "seed1_mu0.3_s8MPa"].map(|n| archive.join(n).to_str().unwrap().to_string());
    let dir = scratch("compare");
    let out = dir.join("cmp.png");
    let (ok, text) = cdlab(&["compare", &runs[0], &runs[1], "-o", out.to_str().unwrap()]);
    assert!(ok && text.contains("2 runs"), "{text}");
    let img = Img::decode(&std::fs::read(&out).unwrap());
    // Sorted by friction: 0.3 takes the first color, 3 the second.
    for k in 0..2 {
        assert!(img.count(friction_color(k, 2)) > 500, "run {k}");
    }
    let (ok, text) = cdlab(&["compare", &runs[0], "-o", "cmp.jpg"]);
    assert!(!ok && text.contains(".png or .svg"), "{text}");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (ok, text) = cdlab(&[
        "compare",
        &runs[0],
        empty.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("empty") && !text.contains("panicked"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A test of the shipped 5000-disk archive (configuration, summary and thinned series, no
/// record) draws its curves from the thinned series, over the whole compression to the
/// summary's final strain; snapshot figures say the record is missing and why.
#[test]
fn archived_test_draws_its_curves_and_explains_the_rest() {
    let run = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/results/campaign5000/seed1_mu0.3_s8MPa");
    let (rows, _) = cdlab::record::read_series(&run).unwrap();
    let thinned = std::fs::read_to_string(run.join("series_thinned.csv")).unwrap();
    assert_eq!(rows.len(), thinned.lines().count() - 1);
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap()).unwrap();
    let last = rows.iter().rev().find(|r| r.phase == "compression").unwrap();
    // The thinned series keeps the last row: the summary's final strain (0.10).
    assert_eq!(last.strain_axial, summary["strain_final"].as_f64().unwrap());
    let dir = scratch("archived-curves");
    let (ok, text) = cdlab(&[
        "render",
        run.to_str().unwrap(),
        "--curves",
        "-o",
        dir.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let img = Img::decode(&std::fs::read(dir.join("stress_strain.png")).unwrap());
    for c in [LINE_COLORS[0], LINE_COLORS[1]] {
        assert!(img.count(c) > 500, "curve color {c:?}: {} pixels", img.count(c));
    }
    let fig = dir.join("x.png");
    let (ok, text) = cdlab(&[
        "render",
        run.to_str().unwrap(),
        "--at",
        "0.09",
        "-o",
        fig.to_str().unwrap(),
    ]);
    assert!(
        !ok && text.contains("archived test") && text.contains("--curves"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A snapshot figure written by `cdlab render` (the synthetic grid at axial strain 0.1):
/// the SVG is well formed and says what it shows, of which snapshot and how many disks;
/// the PNG has the SVG's size and dark text in its title rows.
fn check_snapshot_file(out: &Path, field: &str) {
    let title = match field {
        "displacement" => "displacement since the start of compression",
        "rotation" => "rotation since",
        "velocity" => "velocity field",
        "forces" => "force network",
        _ => "local shear strain since axial strain",
    };
    let svg_path = out.with_extension("svg");
    if out.extension().is_some_and(|e| e == "svg") {
        let svg = std::fs::read_to_string(out).unwrap();
        let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
        let texts = svg_texts(&doc);
        for want in [title, "axial strain 0.10000", &format!("{} disks", NX * NY)] {
            assert!(
                texts.iter().any(|t| t.contains(want)),
                "{}: {want:?} in {texts:?}",
                out.display()
            );
        }
    } else {
        let img = Img::decode(&std::fs::read(out).unwrap());
        assert!(img.dark_in_rows(0, 30) > 50, "{}: no title", out.display());
        assert!(img.distinct_colors() > 10, "{}: a blank page", out.display());
        // Both formats come from one drawing code: the same size.
        let svg = std::fs::read_to_string(&svg_path).expect("the SVG is written first");
        let doc = roxmltree::Document::parse(&svg).unwrap();
        let root = doc.root_element();
        let size = |a: &str| root.attribute(a).and_then(|v| v.parse::<u32>().ok());
        assert_eq!(
            (size("width"), size("height")),
            (Some(img.w), Some(img.h)),
            "{}",
            out.display()
        );
    }
}

/// The texts of an SVG, trimmed.
fn svg_texts(doc: &roxmltree::Document) -> Vec<String> {
    svg_elements(doc, "text", None)
        .iter()
        .filter_map(|n| n.text().map(|t| t.trim().to_string()))
        .collect()
}

#[test]
fn report_command_writes_its_figures() {
    let dir = scratch("report");
    for mu in [0.1, 0.3, 1.0] {
        for s3 in [1.0, 8.0] {
            let d = dir.join(format!("mu{mu}_s{s3}"));
            std::fs::create_dir_all(&d).unwrap();
            let s1 = s3 * (2.0 + mu);
            let json = format!(
                "{{\"mu\": {mu}, \"sigma3_mpa\": {s3}, \"sigma1_peak_mpa\": {s1}, \"sigma1_residual_mpa\": {}}}",
                0.8 * s1
            );
            std::fs::write(d.join("summary.json"), json).unwrap();
        }
    }
    let (ok, text) = cdlab(&["report", dir.to_str().unwrap()]);
    assert!(ok, "{text}");
    // Three frictions, two pressures each: per friction two filled peak markers and the
    // legend's, two open residual markers.
    let svg = std::fs::read_to_string(dir.join("envelope.svg")).unwrap();
    let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    for k in 0..3 {
        let c = hex(friction_color(k, 3));
        assert_eq!(
            svg_elements(&doc, "circle", Some(("fill", &c))).len(),
            3,
            "friction {k}: peak markers"
        );
        let open = svg_elements(&doc, "circle", Some(("stroke", &c)))
            .into_iter()
            .filter(|n| n.attribute("fill") == Some("none"))
            .count();
        assert_eq!(open, 2, "friction {k}: residual markers");
    }
    let img = Img::decode(&std::fs::read(dir.join("envelope.png")).unwrap());
    for k in 0..3 {
        let n = img.count(friction_color(k, 3));
        assert!(n > 100, "envelope.png, friction {k}: {n} pixels of its color");
    }
    // mu_macro: one peak point per friction plus the legend's marker.
    let svg = std::fs::read_to_string(dir.join("mu_macro.svg")).unwrap();
    let doc = roxmltree::Document::parse(&svg).expect("well-formed SVG");
    let peaks = svg_elements(&doc, "circle", Some(("fill", &hex(LINE_COLORS[0])))).len();
    assert_eq!(peaks, 4, "mu_macro peak markers: 3 frictions and the legend");
    let img = Img::decode(&std::fs::read(dir.join("mu_macro.png")).unwrap());
    assert!(img.count(LINE_COLORS[0]) > 100, "mu_macro.png: no peak color");
    let _ = std::fs::remove_dir_all(&dir);
}
