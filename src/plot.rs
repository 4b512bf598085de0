//! Line plots with optional confidence bands, in one or more panels, written as PNG or SVG by
//! `plotters` with an embedded font (DejaVu Sans, `assets/`), so no system library or font is
//! needed. Axes are linear or logarithmic per panel; log axes label their ticks as plain
//! numbers or powers of ten. The panels are plain data; drawing them needs the `plot` feature.

use std::path::PathBuf;

#[cfg(feature = "plot")]
use plotters::coord::Shift;
#[cfg(feature = "plot")]
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
#[cfg(feature = "plot")]
use plotters::prelude::*;

#[cfg(feature = "plot")]
/// The family name the embedded font is registered under.
const FONT: &str = "sans-serif";

/// One curve.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Legend text (empty: not in the legend).
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates.
    pub y: Vec<f64>,
    /// Lower and upper band edges at the same abscissae, shaded.
    pub band: Option<(Vec<f64>, Vec<f64>)>,
    /// Index into the palette.
    pub color: usize,
    /// Dashed line (e.g. theory) instead of solid.
    pub dashed: bool,
}

/// One panel: axes, labels and curves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Panel {
    /// Title above the panel.
    pub title: String,
    /// Abscissa label with unit.
    pub x_label: String,
    /// Ordinate label with unit.
    pub y_label: String,
    /// Logarithmic abscissa.
    pub log_x: bool,
    /// Logarithmic ordinate.
    pub log_y: bool,
    /// The curves.
    pub series: Vec<Series>,
}

/// A plot that could not be written.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// The output name does not end in .png or .svg.
    #[error("{0}: plot file must end in .png or .svg")]
    Extension(PathBuf),
    /// Drawing failed.
    #[error("{path}: {message}")]
    Draw {
        /// Output file.
        path: PathBuf,
        /// What failed.
        message: String,
    },
    /// The finished picture could not be written (the reason is the error's `source()`, not
    /// repeated in the message, so a chain printed with `{:#}` names it once).
    #[error("{path}: cannot write the plot")]
    Write {
        /// Output file.
        path: PathBuf,
        /// The system's reason.
        source: std::io::Error,
    },
}

#[cfg(feature = "plot")]
/// Colours of the palette (the first three for x, y, z).
const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(0, 0, 0),
];

#[cfg(feature = "plot")]
fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is a compile-time constant known to parse; a failure would only lose text.
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

#[cfg(feature = "plot")]
/// Renders `panels` in a grid of `columns` columns into `path` (.png or .svg) of `size` pixels.
/// The picture is made in memory and written with [`crate::output::AtomicFile`]: a file that
/// cannot be written is an I/O error naming it and the system's reason, and a failed write
/// leaves no partial file.
pub fn render(
    path: &std::path::Path,
    panels: &[Panel],
    columns: usize,
    size: (u32, u32),
) -> Result<(), PlotError> {
    register_font();
    let err = |e: String| PlotError::Draw {
        path: path.to_path_buf(),
        message: e,
    };
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let bytes = match ext.as_deref() {
        Some("png") => {
            let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
                draw(&root, panels, columns).map_err(err)?;
                root.present().map_err(|e| err(e.to_string()))?;
            }
            png(&rgb, size).map_err(err)?
        }
        Some("svg") => {
            let mut text = String::new();
            {
                let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
                draw(&root, panels, columns).map_err(err)?;
                root.present().map_err(|e| err(e.to_string()))?;
            }
            text.into_bytes()
        }
        _ => return Err(PlotError::Extension(path.to_path_buf())),
    };
    write_atomically(path, &bytes).map_err(|source| PlotError::Write {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(feature = "plot")]
/// An RGB picture of `size` pixels as PNG bytes.
fn png(rgb: &[u8], size: (u32, u32)) -> Result<Vec<u8>, String> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new(&mut out)
        .write_image(rgb, size.0, size.1, image::ColorType::Rgb8)
        .map_err(|e| format!("encoding the PNG: {e}"))?;
    Ok(out)
}

#[cfg(feature = "plot")]
fn write_atomically(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    use std::io::Write;
    let mut f = crate::output::AtomicFile::create(path)?;
    f.write_all(bytes)?;
    f.commit()
}

#[cfg(feature = "plot")]
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panels: &[Panel],
    columns: usize,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let areas = root.split_evenly((rows, columns));
    // A panel with neither title nor curves is a blank cell of the grid.
    for (area, p) in areas
        .iter()
        .zip(panels)
        .filter(|(_, p)| !(p.title.is_empty() && p.series.is_empty()))
    {
        let (x0, x1) = extent(p, |s| &s.x, |_| None, p.log_x);
        let (y0, y1) = extent(p, |s| &s.y, |s| s.band.as_ref(), p.log_y);
        match (p.log_x, p.log_y) {
            (true, true) => panel(area, p, (x0..x1).log_scale(), (y0..y1).log_scale()),
            (true, false) => panel(area, p, (x0..x1).log_scale(), y0..y1),
            (false, true) => panel(area, p, x0..x1, (y0..y1).log_scale()),
            (false, false) => panel(area, p, x0..x1, y0..y1),
        }?;
    }
    Ok(())
}

#[cfg(feature = "plot")]
/// Range of the finite (and, on a log axis, positive) values, padded; (1, 10) when empty.
fn extent(
    p: &Panel,
    values: impl Fn(&Series) -> &Vec<f64>,
    band: impl Fn(&Series) -> Option<&(Vec<f64>, Vec<f64>)>,
    log: bool,
) -> (f64, f64) {
    let ok = |v: &f64| v.is_finite() && (!log || *v > 0.0);
    let all = p.series.iter().flat_map(|s| {
        let b = band(s).into_iter().flat_map(|(lo, hi)| lo.iter().chain(hi));
        values(s).iter().chain(b)
    });
    let (lo, hi) = all
        .filter(|v| ok(v))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if lo > hi {
        return (1.0, 10.0);
    }
    if log {
        let (l, h) = (lo.log10().floor(), hi.log10().ceil());
        let h = if h <= l { l + 1.0 } else { h };
        (10f64.powf(l), 10f64.powf(h))
    } else {
        let pad = if hi > lo { 0.05 * (hi - lo) } else { 1.0 };
        (lo - pad, hi + pad)
    }
}

/// A tick label: plain for 1e-3 ≤ |v| < 1e4, else a power of ten / scientific.
pub fn tick_label(v: f64) -> String {
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if (1e-3..1e4).contains(&a) {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        let e = a.log10().round();
        if (a / 10f64.powf(e) - 1.0).abs() < 1e-9 {
            format!("{}1e{}", if v < 0.0 { "-" } else { "" }, e as i32)
        } else {
            format!("{v:.1e}")
        }
    }
}

#[cfg(feature = "plot")]
fn panel<DB, X, Y>(area: &DrawingArea<DB, Shift>, p: &Panel, x: X, y: Y) -> Result<(), String>
where
    DB: DrawingBackend,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, (FONT, 22))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(80)
        .build_cartesian_2d(x, y)
        .map_err(e)?;
    let fmt = |v: &f64| tick_label(*v);
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style((FONT, 14))
        .axis_desc_style((FONT, 16))
        .x_label_formatter(&fmt)
        .y_label_formatter(&fmt)
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(e)?;
    let mut legend = false;
    for s in &p.series {
        let color = PALETTE[s.color % PALETTE.len()];
        if let Some((lo, hi)) = &s.band {
            let mut poly: Vec<(f64, f64)> = s.x.iter().copied().zip(hi.iter().copied()).collect();
            poly.extend(s.x.iter().copied().zip(lo.iter().copied()).rev());
            poly.retain(|(x, y)| x.is_finite() && y.is_finite() && (!p.log_y || *y > 0.0));
            chart
                .draw_series(std::iter::once(Polygon::new(
                    poly,
                    color.mix(0.18).filled(),
                )))
                .map_err(e)?;
        }
        let pts: Vec<(f64, f64)> = s
            .x
            .iter()
            .copied()
            .zip(s.y.iter().copied())
            .filter(|(x, y)| {
                x.is_finite() && y.is_finite() && (!p.log_x || *x > 0.0) && (!p.log_y || *y > 0.0)
            })
            .collect();
        // Dense series (noise over time) 1 px wide: the miter joins of a thicker polyline
        // through a zigzag spike far outside the data.
        let style = color.stroke_width(if pts.len() > 1000 { 1 } else { 2 });
        let anno = if s.dashed {
            chart
                .draw_series(DashedLineSeries::new(pts, 8, 5, style))
                .map_err(e)?
        } else {
            chart.draw_series(LineSeries::new(pts, style)).map_err(e)?
        };
        if !s.label.is_empty() {
            legend = true;
            anno.label(s.label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], style));
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .label_font((FONT, 14))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(160, 160, 160))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(e)?;
    }
    Ok(())
}

/// The panels of a mission plot from poses sampled along a trajectory: the ground track
/// (north and east from the first pose, metres on the local sphere of radii R_N, R_E there),
/// height, attitude and NED velocity against time.
pub fn mission_panels(poses: &[crate::motion::Pose]) -> Vec<Panel> {
    let Some(first) = poses.first() else {
        return Vec::new();
    };
    let s0 = first.lat.sin();
    let (rn, re) = (
        crate::earth::radius_meridian(s0) + first.h,
        crate::earth::radius_prime_vertical(s0) + first.h,
    );
    let t: Vec<f64> = poses.iter().map(|p| p.t).collect();
    let column =
        |f: &dyn Fn(&crate::motion::Pose) -> f64| poses.iter().map(f).collect::<Vec<f64>>();
    let series = |label: &str, y: Vec<f64>, color: usize| Series {
        label: label.into(),
        x: t.clone(),
        y,
        color,
        ..Series::default()
    };
    let euler: Vec<(f64, f64, f64)> = poses
        .iter()
        .map(|p| crate::math::euler_from_quat(p.q_b_n))
        .collect();
    // Angles unwrapped (steps over ±180° removed) so that a turn or a roll is one curve.
    let angle = |k: usize| {
        let mut out: Vec<f64> = Vec::with_capacity(euler.len());
        for e in &euler {
            let mut a = [e.0, e.1, e.2][k].to_degrees();
            if let Some(prev) = out.last() {
                a += 360.0 * ((prev - a) / 360.0).round();
            }
            out.push(a);
        }
        out
    };
    let track = Series {
        label: String::new(),
        x: column(&|p| (p.lon - first.lon) * re * first.lat.cos()),
        y: column(&|p| (p.lat - first.lat) * rn),
        ..Series::default()
    };
    vec![
        Panel {
            title: "ground track".into(),
            x_label: "east (m)".into(),
            y_label: "north (m)".into(),
            series: vec![track],
            ..Panel::default()
        },
        Panel {
            title: "height".into(),
            x_label: "t (s)".into(),
            y_label: "h (m)".into(),
            series: vec![series("", column(&|p| p.h), 0)],
            ..Panel::default()
        },
        Panel {
            title: "attitude".into(),
            x_label: "t (s)".into(),
            y_label: "angle (deg)".into(),
            series: vec![
                series("roll", angle(0), 0),
                series("pitch", angle(1), 1),
                series("yaw", angle(2), 2),
            ],
            ..Panel::default()
        },
        Panel {
            title: "velocity".into(),
            x_label: "t (s)".into(),
            y_label: "v (m/s)".into(),
            series: (0..3)
                .map(|k| series(["north", "east", "down"][k], column(&|p| p.v_n[k]), k))
                .collect(),
            ..Panel::default()
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(0.01), "0.01");
        assert_eq!(tick_label(100.0), "100");
        assert_eq!(tick_label(1e-6), "1e-6");
        assert_eq!(tick_label(1e5), "1e5");
        assert_eq!(tick_label(2.5e-7), "2.5e-7");
        assert_eq!(tick_label(0.0), "0");
    }

    #[cfg(feature = "plot")]
    #[test]
    fn unknown_extension_is_refused() {
        let e = render(std::path::Path::new("x.jpg"), &[], 1, (10, 10)).unwrap_err();
        assert!(e.to_string().contains(".png or .svg"));
    }
}
