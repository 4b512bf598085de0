//! A tabulated Earth magnetic field: north, east and down components on a latitude/longitude
//! grid (for example sampled from a spherical-harmonic model such as the IGRF or WMM at one
//! epoch), interpolated bilinearly in latitude and longitude.
//!
//! Text format (CSV): an optional `#` comment lines, a header
//! `lat_deg,lon_deg,north_nt,east_nt,down_nt`, then one row per grid node in any order. The
//! nodes must form a full rectangle: every latitude of the table with every longitude, each
//! once, at least two of each. The field does not depend on height (a table is one surface).

use crate::math::Vec3;

/// The header line a field table starts with.
pub const HEADER: &str = "lat_deg,lon_deg,north_nt,east_nt,down_nt";

/// Something wrong in a field table's text, at a 1-based line and a column name.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error("line {line}: `{field}`: {message}")]
pub struct TableError {
    /// Line of the text (1-based; the last line for a grid that is not complete).
    pub line: usize,
    /// The column (or `grid`).
    pub field: &'static str,
    /// What is wrong.
    pub message: String,
}

/// A position outside the table's grid.
#[derive(Debug, thiserror::Error, PartialEq)]
#[error(
    "position {lat_deg}° N, {lon_deg}° E is outside the magnetic field table \
     ({lat_min}…{lat_max}° N, {lon_min}…{lon_max}° E)"
)]
pub struct OutsideTable {
    /// The latitude asked for (deg).
    pub lat_deg: f64,
    /// The longitude asked for (deg).
    pub lon_deg: f64,
    /// Grid's southern edge (deg).
    pub lat_min: f64,
    /// Grid's northern edge (deg).
    pub lat_max: f64,
    /// Grid's western edge (deg).
    pub lon_min: f64,
    /// Grid's eastern edge (deg).
    pub lon_max: f64,
}

/// A rectangular grid of NED field vectors (T).
#[derive(Clone, Debug, PartialEq)]
pub struct FieldTable {
    /// Node latitudes and longitudes (rad), ascending.
    lats: Vec<f64>,
    lons: Vec<f64>,
    /// The grid's edges as given (deg): south, north, west, east.
    edges_deg: [f64; 4],
    /// Row-major by latitude: `field[i * lons.len() + j]` at (lats[i], lons[j]).
    field: Vec<Vec3>,
}

const COLUMNS: [&str; 5] = ["lat_deg", "lon_deg", "north_nt", "east_nt", "down_nt"];

impl FieldTable {
    /// Parses a table's text (format in the module documentation).
    pub fn parse(text: &str) -> Result<FieldTable, TableError> {
        let mut rows: Vec<(usize, [f64; 5])> = Vec::new();
        let mut header = false;
        let mut last = 0;
        for (i, raw) in text.lines().enumerate() {
            let (n, line) = (i + 1, raw.trim());
            last = n;
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            if !header {
                if line.replace(' ', "") != HEADER {
                    return Err(err(
                        n,
                        "header",
                        format!("expected `{HEADER}`, got `{line}`"),
                    ));
                }
                header = true;
                continue;
            }
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != 5 {
                return Err(err(
                    n,
                    COLUMNS[cells.len().min(4)],
                    format!("expected 5 values, got {}", cells.len()),
                ));
            }
            let mut v = [0.0; 5];
            for (k, c) in cells.iter().enumerate() {
                v[k] = c
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| err(n, COLUMNS[k], format!("`{c}` is not a finite number")))?;
            }
            if v[0].abs() > 90.0 {
                return Err(err(n, "lat_deg", format!("{} is outside ±90°", v[0])));
            }
            if v[1].abs() > 180.0 {
                return Err(err(n, "lon_deg", format!("{} is outside ±180°", v[1])));
            }
            rows.push((n, v));
        }
        if !header {
            return Err(err(last.max(1), "header", format!("no `{HEADER}` line")));
        }
        let axis = |k: usize| {
            let mut a: Vec<f64> = rows.iter().map(|r| r.1[k]).collect();
            a.sort_by(f64::total_cmp);
            a.dedup();
            a
        };
        let (lats, lons) = (axis(0), axis(1));
        if lats.len() < 2 || lons.len() < 2 {
            return Err(err(
                last,
                "grid",
                format!(
                    "{} latitude(s) × {} longitude(s): at least 2 × 2 nodes are needed",
                    lats.len(),
                    lons.len()
                ),
            ));
        }
        let mut field = vec![None; lats.len() * lons.len()];
        for (n, v) in &rows {
            let i = lats.partition_point(|x| *x < v[0]);
            let j = lons.partition_point(|x| *x < v[1]);
            let slot = &mut field[i * lons.len() + j];
            if slot.is_some() {
                return Err(err(
                    *n,
                    "lat_deg",
                    format!("node {}° N, {}° E given twice", v[0], v[1]),
                ));
            }
            *slot = Some(Vec3::new(v[2], v[3], v[4]) * 1e-9);
        }
        if let Some(k) = field.iter().position(Option::is_none) {
            let (i, j) = (k / lons.len(), k % lons.len());
            return Err(err(
                last,
                "grid",
                format!(
                    "node {}° N, {}° E is missing: every latitude needs every longitude",
                    lats[i], lons[j]
                ),
            ));
        }
        Ok(FieldTable {
            edges_deg: [lats[0], lats[lats.len() - 1], lons[0], lons[lons.len() - 1]],
            lats: lats.iter().map(|x| x.to_radians()).collect(),
            lons: lons.iter().map(|x| x.to_radians()).collect(),
            field: field.into_iter().flatten().collect(),
        })
    }

    /// The NED field (T) at latitude `lat` and longitude `lon` (rad), bilinear between the
    /// four surrounding nodes: B = Σ w_ij B_ij with w = (1−u)(1−v), u(1−v), (1−u)v, uv, u and
    /// v the fractions of the cell in latitude and longitude.
    pub fn field_n(&self, lat: f64, lon: f64) -> Result<Vec3, OutsideTable> {
        let (i, u) = cell(&self.lats, lat);
        let (j, v) = cell(&self.lons, lon);
        let (Some(i), Some(j)) = (i, j) else {
            return Err(OutsideTable {
                lat_deg: lat.to_degrees(),
                lon_deg: lon.to_degrees(),
                lat_min: self.edges_deg[0],
                lat_max: self.edges_deg[1],
                lon_min: self.edges_deg[2],
                lon_max: self.edges_deg[3],
            });
        };
        let w = self.lons.len();
        let at = |a: usize, b: usize| self.field[a * w + b];
        Ok(at(i, j) * ((1.0 - u) * (1.0 - v))
            + at(i + 1, j) * (u * (1.0 - v))
            + at(i, j + 1) * ((1.0 - u) * v)
            + at(i + 1, j + 1) * (u * v))
    }
}

/// Positions this far (rad, about 6 µm) outside the grid are on its edge: a node's degrees
/// converted to radians and back through a position may land an ulp outside.
const EDGE_RAD: f64 = 1e-12;

/// The cell of sorted `axis` holding `x` (its lower node) and the fraction across it; `None`
/// outside the axis.
fn cell(axis: &[f64], x: f64) -> (Option<usize>, f64) {
    let last = axis.len() - 1;
    if !(axis[0] - EDGE_RAD..=axis[last] + EDGE_RAD).contains(&x) {
        return (None, 0.0);
    }
    let i = axis.partition_point(|a| *a <= x).clamp(1, last) - 1;
    let u = (x - axis[i]) / (axis[i + 1] - axis[i]);
    (Some(i), u.clamp(0.0, 1.0))
}

fn err(line: usize, field: &'static str, message: String) -> TableError {
    TableError {
        line,
        field,
        message,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A field bilinear in latitude and longitude (with a cross term) on an uneven grid is
    /// reproduced exactly between the nodes; swapped weights or a dropped cross term would
    /// miss it by nanoteslas.
    fn bilinear(la: f64, lo: f64) -> [f64; 3] {
        [
            20_000.0 + 150.0 * la - 40.0 * lo + 3.0 * la * lo,
            -1_000.0 + 25.0 * lo - 7.0 * la + 0.5 * la * lo,
            40_000.0 + 300.0 * la + 10.0 * lo - 2.0 * la * lo,
        ]
    }

    fn table() -> String {
        let mut s = format!("# test grid\n{HEADER}\n");
        // Rows deliberately out of order.
        for lo in [10.0, -5.0, 2.5] {
            for la in [50.0, 30.0, 41.0, 45.5] {
                let b = bilinear(la, lo);
                s.push_str(&format!("{la},{lo},{},{},{}\n", b[0], b[1], b[2]));
            }
        }
        s
    }

    #[test]
    fn bilinear_field_is_reproduced_exactly() {
        let t = FieldTable::parse(&table()).unwrap();
        for (la, lo) in [
            (30.0, -5.0),
            (50.0, 10.0),
            (41.3, 2.5),
            (42.7, 7.1),
            (33.3, -1.2),
            (49.9, 9.99),
        ] {
            let b = t.field_n(f64::to_radians(la), f64::to_radians(lo)).unwrap();
            let e = bilinear(la, lo);
            for k in 0..3 {
                // Round-off: a few ulps of ~6·10⁻⁵ T (~10⁻²⁰ T) plus the radian conversion's
                // ~10⁻¹⁴° times a slope under 10³ nT/deg; a wrong weight misses by nT.
                assert!(
                    (b[k] - e[k] * 1e-9).abs() < 1e-18,
                    "{la} {lo} {k}: {b:?} {e:?}"
                );
            }
        }
        let out = t.field_n(f64::to_radians(51.0), 0.0).unwrap_err();
        assert_eq!((out.lat_min, out.lat_max, out.lon_max), (30.0, 50.0, 10.0));
    }

    #[test]
    fn bad_tables_name_the_line_and_column() {
        let good = table();
        let e = FieldTable::parse(&good.replace("45.5,10,", "45.5,x,")).unwrap_err();
        assert_eq!((e.line, e.field), (6, "lon_deg"), "{e}");
        let e = FieldTable::parse(&good.replace("lat_deg,lon", "lat,lon")).unwrap_err();
        assert_eq!((e.line, e.field), (2, "header"));
        let dropped: String = good
            .lines()
            .filter(|l| !l.starts_with("41,2.5,"))
            .map(|l| format!("{l}\n"))
            .collect();
        let e = FieldTable::parse(&dropped).unwrap_err();
        assert!(
            e.field == "grid" && e.message.contains("41° N, 2.5° E is missing"),
            "{e}"
        );
        let e = FieldTable::parse(&format!("{good}30,-5,1,2,3\n")).unwrap_err();
        assert!(e.line == 15 && e.message.contains("given twice"), "{e}");
        let e = FieldTable::parse(&format!("{HEADER}\n95,0,1,2,3\n")).unwrap_err();
        assert_eq!((e.line, e.field), (2, "lat_deg"));
        let e = FieldTable::parse(&format!("{HEADER}\n0,0,1,2\n")).unwrap_err();
        assert_eq!((e.line, e.field), (2, "down_nt"));
        let e = FieldTable::parse(&format!("{HEADER}\n0,0,1,2,3\n")).unwrap_err();
        assert_eq!(e.field, "grid");
    }
}
