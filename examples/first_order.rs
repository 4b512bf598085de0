//! How far a first-order integration of a motion definition drifts from the exact one, on a
//! 90° turn (`examples/turn90.csv`: 10 m/s, −15°/s for 6 s, the manoeuvre of gnss-ins-sim's
//! 90° turn demo) or any file of type-1 yaw-rate commands at a constant body speed:
//!
//! * "gnss-ins-sim scheme": the commands stepped the way gnss-ins-sim's `pathgen.py` does
//!   (a first-order low-pass of the commanded rates with coefficient 0.9 per step, then Euler
//!   steps of attitude, body velocity and latitude/longitude), written here from its
//!   description;
//! * "Euler steps of the exact velocity": our own v^n(t) integrated by forward Euler, which
//!   isolates the integration error from the different smoothing of the commands.
//!
//! Both are compared with imu-emu's exact end position. Run:
//! `cargo run --release --example first_order -- [FILE [PICTURE.png]]`; the picture is the
//! horizontal distance of the gnss-ins-sim scheme from the exact position over the trip at
//! each rate.

use imu_emu::earth;
use imu_emu::motion::Motion;

/// A trip of yaw-rate commands at a constant body speed.
struct YawTrip {
    /// Body speed along x (m/s).
    speed: f64,
    /// Yaw at the start (rad).
    yaw0: f64,
    /// Each command's yaw rate (rad/s) and duration (s).
    commands: Vec<(f64, f64)>,
}

/// The trip of a gnss-ins-sim motion-definition file whose commands are all of type 1 with
/// only a yaw rate; `None` for any other file.
fn yaw_rate_commands(text: &str) -> Option<YawTrip> {
    let rows: Vec<Vec<f64>> = (text.lines().filter(|l| !l.trim().is_empty()))
        .enumerate()
        .filter(|(i, _)| *i == 1 || *i >= 3)
        .map(|(_, l)| {
            l.split(',')
                .map(|c| c.trim().parse().unwrap_or(0.0))
                .collect()
        })
        .collect();
    let start = rows.first().filter(|r| r.len() >= 7)?;
    let mut commands = Vec::new();
    for r in &rows[1..] {
        let only_yaw = r.len() >= 8 && r[0] == 1.0 && r[2..7].iter().all(|v| *v == 0.0);
        if !only_yaw {
            return None;
        }
        commands.push((r[1].to_radians(), r[7]));
    }
    Some(YawTrip {
        speed: start[3],
        yaw0: start[6].to_radians(),
        commands,
    })
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .unwrap_or_else(|| concat!(env!("CARGO_MANIFEST_DIR"), "/examples/turn90.csv").into());
    let fail = |e: String| -> ! {
        eprintln!("error: {e}");
        std::process::exit(1)
    };
    let exact = imu_emu::motiondef::open(std::path::Path::new(&path))
        .unwrap_or_else(|e| fail(e.to_string()));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| fail(format!("{path}: {e}")));
    let Some(YawTrip {
        speed,
        yaw0,
        commands,
    }) = yaw_rate_commands(&text)
    else {
        fail(format!(
            "{path}: this example steps type-1 commands of a yaw rate only (a gnss-ins-sim \
             motion-definition CSV)"
        ))
    };
    let end = exact.pose(exact.end());
    let start = exact.pose(0.0);
    let (rn, re) = (
        earth::radius_meridian(start.lat.sin()),
        earth::radius_prime_vertical(start.lat.sin()),
    );
    // Metres north and east between two geodetic positions near the start.
    let metres =
        |lat: f64, lon: f64| ((lat - end.lat) * rn, (lon - end.lon) * re * start.lat.cos());
    println!(
        "| rate (Hz) | gnss-ins-sim scheme: end position − exact (m) | Euler steps of the exact velocity (m) |"
    );
    println!("| --- | --- | --- |");
    let mut series = Vec::new();
    for rate in [10.0f64, 100.0, 1000.0] {
        let dt = 1.0 / rate;
        // gnss-ins-sim's scheme for the file's type-1 commands, at its speed along body x.
        let (mut lat, mut lon, mut yaw, mut yaw_dot) = (start.lat, start.lon, yaw0, 0.0);
        let (mut k, mut ts, mut ds) = (0usize, vec![0.0], vec![0.0]);
        for &(cmd, duration) in &commands {
            for _ in 0..(duration * rate).round() as usize {
                yaw_dot = 0.9 * yaw_dot + 0.1 * cmd;
                let (vn, ve) = (speed * yaw.cos(), speed * yaw.sin());
                lat += vn / rn * dt;
                lon += ve / (re * lat.cos()) * dt;
                yaw += yaw_dot * dt;
                k += 1;
                let p = exact.pose(k as f64 * dt);
                ts.push(k as f64 * dt);
                ds.push(((lat - p.lat) * rn).hypot((lon - p.lon) * re * start.lat.cos()));
            }
        }
        series.push(imu_emu::plot::Series {
            label: format!("{rate} Hz"),
            x: ts,
            y: ds,
            color: series.len(),
            ..Default::default()
        });
        let scheme = metres(lat, lon);
        // Forward Euler on our own velocity.
        let (mut lat, mut lon) = (start.lat, start.lon);
        let n = (exact.end() * rate).round() as usize;
        for k in 0..n {
            let p = exact.pose(k as f64 * dt);
            lat += p.v_n[0] / (earth::radius_meridian(p.lat.sin()) + p.h) * dt;
            lon +=
                p.v_n[1] / ((earth::radius_prime_vertical(p.lat.sin()) + p.h) * p.lat.cos()) * dt;
        }
        let euler = metres(lat, lon);
        println!(
            "| {rate} | north {:+.4}, east {:+.4} ({:.4}) | north {:+.4}, east {:+.4} ({:.4}) |",
            scheme.0,
            scheme.1,
            scheme.0.hypot(scheme.1),
            euler.0,
            euler.1,
            euler.0.hypot(euler.1)
        );
    }
    if let Some(png) = std::env::args().nth(2) {
        let panel = imu_emu::plot::Panel {
            title: "gnss-ins-sim's first-order scheme − exact, 90° turn".into(),
            x_label: "time (s)".into(),
            y_label: "horizontal position difference (m)".into(),
            series,
            ..Default::default()
        };
        imu_emu::plot::render(std::path::Path::new(&png), &[panel], 1, (900, 500)).unwrap_or_else(
            |e| {
                eprintln!("error: {e}");
                std::process::exit(1)
            },
        );
        println!("{png}");
    }
}
