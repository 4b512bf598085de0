//! A campaign's rows as text: the median/95 % table `compare` prints, the growth CSV and the
//! growth plot's panels. Pure formatting, no I/O.

use std::fmt::Write;

use super::Row;
use crate::nav::montecarlo::Point;
use crate::plot::{Panel, Series};

/// The row's label in the table, the CSV and the plot: the unit, and the outage when the
/// campaign has several lengths.
fn label(r: &Row, several: bool) -> String {
    match (several, r.outage_s) {
        (true, Some(s)) => format!("{} {s}s", r.unit),
        _ => r.unit.clone(),
    }
}

fn several_outages(rows: &[Row]) -> bool {
    rows.iter().any(|r| r.outage_s != rows[0].outage_s)
}

/// The table: per row the errors at the window's end (median and 95 %); aided with outages,
/// the position error at the outage start too.
pub fn table(rows: &[Row]) -> String {
    let mut s = String::new();
    let starts = rows.iter().any(|r| r.at_start().is_some());
    let several = several_outages(rows);
    let extra = |a: &str, b: &str| match starts {
        true => format!("  {a:>23}"),
        false => b.to_string(),
    };
    let _ = writeln!(
        s,
        "{:<15} {:<11} {:>7}  {:>23}  {:>23}  {:>23}{}",
        "unit",
        "grade",
        "samples",
        "position m",
        "velocity m/s",
        "attitude deg",
        extra("position at start m", "")
    );
    let _ = writeln!(
        s,
        "{:<15} {:<11} {:>7}  {:>11} {:>11}  {:>11} {:>11}  {:>11} {:>11}{}",
        "",
        "",
        "",
        "median",
        "95 %",
        "median",
        "95 %",
        "median",
        "95 %",
        extra(&format!("{:>11} {:>11}", "median", "95 %"), "")
    );
    for r in rows {
        let p = r.last();
        let _ = write!(
            s,
            "{:<15} {:<11} {:>7}  {:>11.4e} {:>11.4e}  {:>11.4e} {:>11.4e}  {:>11.4e} {:>11.4e}",
            label(r, several),
            r.grade,
            r.samples,
            p.position.median,
            p.position.p95,
            p.velocity.median,
            p.velocity.p95,
            p.attitude.median.to_degrees(),
            p.attitude.p95.to_degrees()
        );
        if let Some(a) = r.at_start() {
            let _ = write!(
                s,
                "  {:>11.4e} {:>11.4e}",
                a.position.median, a.position.p95
            );
        }
        s.push('\n');
    }
    s
}

/// Header of the growth CSV.
pub const GROWTH_HEADER: &str = "t_s,template,grade,position_median_m,position_p95_m,velocity_median_m_s,velocity_p95_m_s,attitude_median_deg,attitude_p95_deg\n";

/// The growth CSV: one line per row and sample time (the `template` column is the row's
/// label: the unit, with the outage when there are several).
pub fn growth_csv(rows: &[Row]) -> String {
    let mut s = String::from(GROWTH_HEADER);
    let mut f = ryu::Buffer::new();
    let several = several_outages(rows);
    for r in rows {
        for p in &r.growth {
            s.push_str(f.format(p.t));
            s.push(',');
            s.push_str(&label(r, several));
            s.push(',');
            s.push_str(&r.grade);
            for v in [
                p.position.median,
                p.position.p95,
                p.velocity.median,
                p.velocity.p95,
                p.attitude.median.to_degrees(),
                p.attitude.p95.to_degrees(),
            ] {
                s.push(',');
                s.push_str(f.format(v));
            }
            s.push('\n');
        }
    }
    s
}

/// Error-growth panels (position, velocity, attitude against time since the window's start,
/// log ordinate): per row the median, shaded up to the 95th percentile.
pub fn growth_panels(rows: &[Row], what: &str) -> Vec<Panel> {
    type Pick = fn(&Point) -> (f64, f64);
    let quantities: [(&str, &str, Pick); 3] = [
        ("position", "position error (m)", |p| {
            (p.position.median, p.position.p95)
        }),
        ("velocity", "velocity error (m/s)", |p| {
            (p.velocity.median, p.velocity.p95)
        }),
        ("attitude", "attitude error (deg)", |p| {
            (p.attitude.median.to_degrees(), p.attitude.p95.to_degrees())
        }),
    ];
    let several = several_outages(rows);
    quantities
        .iter()
        .map(|(name, y_label, pick)| Panel {
            title: format!("{name} error growth, {what}"),
            x_label: "time since start (s)".into(),
            y_label: (*y_label).into(),
            log_x: false,
            log_y: true,
            series: rows
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    // A log axis cannot show an exact zero.
                    let pts: Vec<_> = r.growth.iter().filter(|p| pick(p).0 > 0.0).collect();
                    let med: Vec<f64> = pts.iter().map(|p| pick(p).0).collect();
                    let p95: Vec<f64> = pts.iter().map(|p| pick(p).1).collect();
                    Series {
                        label: format!("{} ({})", label(r, several), r.grade),
                        x: pts.iter().map(|p| p.t).collect(),
                        band: Some((med.clone(), p95)),
                        y: med,
                        color: i,
                        dashed: false,
                    }
                })
                .collect(),
        })
        .collect()
}

/// What the runs were, for the table's first line: the mission's name `name`, the rates, the
/// mode (free-inertial or aided, the outages and how many per run), runs and seed.
pub fn header(c: &super::Campaign, rows: &[Row], name: &str) -> String {
    let mut rates: Vec<String> = c.missions[0]
        .units
        .iter()
        .map(|(_, g)| g.rate_hz.to_string())
        .collect();
    rates.dedup();
    // Windows per run of each outage length (the first unit's rows).
    let unit0 = rows.first().map(|r| r.unit.as_str()).unwrap_or_default();
    let windows: Vec<String> = (rows.iter().filter(|r| r.unit == unit0))
        .map(|r| format!("{} × {} s", r.windows, r.outage_s.unwrap_or(0.0)))
        .collect();
    let windows = windows.join(", ");
    let aided = c.missions[0].gnss.is_some();
    let mode = match (aided, c.spec.outages_s.is_empty()) {
        (false, true) => "free-inertial from the true state over the run".to_string(),
        (false, false) => {
            format!("outages back to back, {windows} per run (reset to the truth at each start)")
        }
        (true, true) => "GNSS-aided over the run".to_string(),
        (true, false) => format!(
            "GNSS-aided, outages of {windows} per run, each after {} s of fixes",
            c.spec.aided_s
        ),
    };
    format!(
        "compare: {name}, {} Hz, {mode}; {} runs per unit, seed {}",
        rates.join("/"),
        c.spec.runs,
        c.seed
    )
}

/// The plot's subtitle: free inertial, GNSS-aided, or the outage lengths.
pub fn plot_title(c: &super::Campaign) -> String {
    let aided = c.missions[0].gnss.is_some();
    match (c.spec.outages_s.is_empty(), aided) {
        (true, false) => "free inertial".to_string(),
        (true, true) => "GNSS-aided".to_string(),
        (false, aided) => {
            let s: Vec<String> = c.spec.outages_s.iter().map(|s| s.to_string()).collect();
            let before = if aided { ", GNSS-aided before" } else { "" };
            format!("{} s outages{before}", s.join("/"))
        }
    }
}
