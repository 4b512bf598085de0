//! `imu-emu run --trigger` end to end over loopback: a rig on a software sync line (UDP edge
//! messages) gives every unit one frame per edge, each over the interval since the previous
//! edge — units sharing an evaluation, a unit with an output filter and a unit with timing
//! errors alike — on a known motion (paced) and on a live motion in real time; one IMU with
//! an output filter on a trigger averages over each interval (KVH's units under external
//! sync). Bounds hold on a loaded 2-core machine; each is derived where it is asserted.

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use imu_emu::protocol::{self, StreamDecoder};

#[path = "common/loopback.rs"]
mod loopback;
#[path = "common/realtime_run.rs"]
mod realtime_run;
use loopback::{receive, send_states, survey_csv, utc_now_ns};

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// An ideal unit with a 4-tap moving average from 400 Hz to 100 Hz.
const AVERAGED: &str = "name = \"avg\"\n[output_filter]\ninternal_rate_hz = 400\nkind = \"moving_average\"\ntaps = 4\n";

/// An ideal unit with its own clock and latency, which the trigger replaces.
const CLOCKED: &str =
    "name = \"clocked\"\n[timing]\nclock_offset = \"100 ppm\"\nlatency = \"2 ms\"\n";

/// A free UDP port on loopback.
fn free_port() -> u16 {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.local_addr().unwrap().port()
}

/// Reads `child`'s standard error until a line contains `what`; the text so far.
fn wait_for(err: &mut BufReader<std::process::ChildStderr>, what: &str) -> String {
    let mut text = String::new();
    while !text.contains(what) {
        let mut line = String::new();
        assert!(err.read_line(&mut line).unwrap() > 0, "no `{what}`: {text}");
        text += &line;
    }
    text
}

/// Sends an edge message (its CLOCK_REALTIME instant, little-endian i64 ns) to `port` at each
/// of `at_ms` after `t0` (CLOCK_REALTIME ns).
fn send_edges(port: u16, t0: i128, at_ms: &[f64]) {
    let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
    for ms in at_ms {
        let edge = t0 + (ms * 1e6) as i128;
        while utc_now_ns() < edge {
            std::thread::sleep(Duration::from_micros(200));
        }
        tx.send_to(&(edge as i64).to_le_bytes(), ("127.0.0.1", port))
            .unwrap();
    }
}

/// Waits for `child`; its remaining standard error, asserting success.
fn finish(mut child: Child, mut err: BufReader<std::process::ChildStderr>) -> String {
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    assert!(child.wait().unwrap().success(), "{rest}");
    rest
}

/// The numeric rows of a CSV file (a header line, if any, skipped).
fn rows(path: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    (text.lines())
        .filter(|l| l.starts_with(|c: char| c.is_ascii_digit()))
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect()
}

/// Checks a triggered unit's CSV rows (`t`, then `channels` rates, then as many increments)
/// against the edges' offsets `at_ms` from the first edge: one row per edge after the first;
/// row k tagged at the edge's offset from t₀ (the first edge) within `tol_s`; its increments
/// its rates times the interval since the previous tag, to round-off.
fn check_rows(name: &str, r: &[Vec<f64>], at_ms: &[f64], channels: usize, tol_s: f64) {
    assert_eq!(r.len(), at_ms.len() - 1, "unit {name}: {r:?}");
    let mut prev = 0.0;
    for (k, row) in r.iter().enumerate() {
        let want = at_ms[k + 1] * 1e-3;
        assert!(
            (row[0] - want).abs() < tol_s,
            "unit {name} row {k}: t {} vs edge {want}",
            row[0]
        );
        let span = row[0] - prev;
        for j in 0..channels {
            let (rate, inc) = (row[1 + j], row[1 + channels + j]);
            if rate != 0.0 {
                assert!(
                    (inc / rate - span).abs() <= 1e-9 * span,
                    "unit {name} row {k} channel {j}: increment/rate {} vs interval {span}",
                    inc / rate
                );
            }
        }
        prev = row[0];
    }
}

/// A rig on a software trigger (UDP edge messages on loopback, paced at `--speed 1`): an
/// ideal unit, an ideal unit with an output filter, an ideal unit with its own
/// clock and latency, a skew-redundant unit (all to CSV files) and an LN-200 in KVH 1750
/// frames over UDP each write one record per edge after the first (5 for 6 edges; their
/// counts reached, the run completes). Standing still, every record's rates are the
/// constant Earth rate and gravity and its increments those rates times its own interval.
/// Every unit's record k carries the same time tag, the edge's offset from the first edge:
/// within 1 µs (every edge's CLOCK_REALTIME stamp goes through the run's one reading of the
/// clocks' offset, so their differences are exact to the ns; 1 µs covers the tags' rounding
/// to seconds in an f64 and in the CSV).
#[test]
fn every_unit_samples_once_per_edge() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let avg = write(d, "avg.toml", AVERAGED);
    let clocked = write(d, "clocked.toml", CLOCKED);
    let scene = write(
        d,
        "rig.toml",
        &format!(
            "[trajectory]\nscene = \"static\"\n[output]\nduration_s = 0.05\n\
             [[imu]]\nname = \"a\"\nrate_hz = 100.0\n\
             [[imu]]\nname = \"f\"\nmodel = \"{}\"\nrate_hz = 100.0\n\
             [[imu]]\nname = \"c\"\nmodel = \"{}\"\nrate_hz = 100.0\n\
             [[imu]]\nname = \"k\"\nmodel = \"ln200\"\nformat = \"kvh1750\"\nrate_hz = 100.0\n\
             [[imu]]\nname = \"s\"\nrate_hz = 100.0\n\
             [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n[[imu.gyro]]\naxis = [0.0, 0.6, 0.8]\n\
             [[imu.accel]]\naxis = [0.0, 0.0, 1.0]\n",
            avg.display(),
            clocked.display()
        ),
    );
    let port = free_port();
    let (frames_to, frames) = receive();
    let mut c = Command::new(BIN);
    c.arg("run").arg(&scene).args([
        "--trigger",
        &format!("udp://127.0.0.1:{port}"),
        "--speed",
        "1",
    ]);
    for n in ["a", "f", "c", "s"] {
        c.arg("--unit-sink")
            .arg(format!("{n}=file:{}", d.join(format!("{n}.csv")).display()));
    }
    c.arg("--unit-sink").arg(format!("k=udp:{frames_to}"));
    // Units a (sharing the edges' evaluation) and f (a producer of its own) also in LN-200
    // frames: the same records in a further protocol.
    for n in ["a", "f"] {
        c.arg("--unit-sink").arg(format!(
            "{n}=file:{},protocol=ln200",
            d.join(format!("{n}.ln200")).display()
        ));
    }
    let mut child = c
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    wait_for(&mut err, "waiting for the first trigger edge");
    let at_ms = [0.0, 7.0, 19.5, 23.0, 61.0, 70.0];
    send_edges(port, utc_now_ns() + 20_000_000, &at_ms);
    let rest = finish(child, err);
    let tol = 1e-6;
    let units: Vec<Vec<Vec<f64>>> = ["a", "f", "c"]
        .iter()
        .map(|n| rows(&d.join(format!("{n}.csv"))))
        .collect();
    for (n, r) in ["a", "f", "c"].iter().zip(&units) {
        check_rows(n, r, &at_ms, 6, tol);
    }
    let s = rows(&d.join("s.csv"));
    check_rows("s", &s, &at_ms, 3, tol);
    for k in 0..at_ms.len() - 1 {
        let t = units[0][k][0];
        assert!(
            units.iter().all(|u| u[k][0] == t) && s[k][0] == t,
            "record {k}: tags differ"
        );
        for (n, u) in ["f", "c"].iter().zip(&units[1..]) {
            for j in 1..7 {
                let (x, want) = (u[k][j], units[0][0][j]);
                assert!(
                    (x - want).abs() <= 1e-12 * want.abs().max(1e-4),
                    "unit {n} record {k} column {j}: {x} vs {want}"
                );
            }
        }
    }
    // The LN-200's frames: one per edge after the first, decoded with continuous counters.
    let (_, plan) = protocol::load("kvh1750").unwrap();
    let mut dec = StreamDecoder::new(plan);
    let mut n = 0;
    for (_, bytes) in frames.join().unwrap() {
        dec.feed(&bytes, |_| n += 1);
    }
    dec.finish();
    assert_eq!(n, at_ms.len() - 1, "{rest}");
    assert_eq!(dec.stats().check_failures, 0);
    assert!(rest.contains("unit k: 5 of 5 records"), "{rest}");
    // The further protocol's frames carry each record's increments: one frame per record,
    // each within one LSB of the CSV's (the carry quantizer's per-frame error is below one
    // step: 2^-19 rad, 2^-14 m/s).
    let (_, plan) = protocol::load("ln200").unwrap();
    for (n, r) in ["a", "f"].iter().zip(&units) {
        let mut dec = StreamDecoder::new(plan.clone());
        let mut got = Vec::new();
        dec.feed(&std::fs::read(d.join(format!("{n}.ln200"))).unwrap(), |f| {
            got.push(f.contract(None))
        });
        dec.finish();
        assert_eq!(
            (got.len(), dec.stats().check_failures),
            (r.len(), 0),
            "unit {n}"
        );
        for (k, (f, row)) in got.iter().zip(r).enumerate() {
            for (col, lsb) in [
                (7, 2f64.powi(-19)),
                (9, 2f64.powi(-19)),
                (12, 2f64.powi(-14)),
            ] {
                let x = f[col].unwrap();
                assert!(
                    (x - row[col]).abs() <= lsb,
                    "unit {n} record {k} column {col}: {x} vs {}",
                    row[col]
                );
            }
        }
    }
}

/// Writes `text` to `dir/name`.
fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// One IMU whose template has an output filter, on a trigger (it was refused before: the
/// triggered path bypassed the filter): one CSV record per edge after the first, each the
/// uniform average over its interval — standing still, the constant rates, with increments
/// the rates times the interval since the previous edge (where the unit's own filter would
/// give 10 ms worth for every record). The run says, when it is built, that the template's
/// filter kind and taps give way to the averager.
#[test]
fn one_filtered_imu_averages_over_each_interval() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let avg = write(d, "avg.toml", AVERAGED);
    let out = d.join("out.csv");
    let port = free_port();
    let mut child = Command::new(BIN)
        .args(["run", "--scene", "static", "--imu"])
        .arg(&avg)
        .args([
            "--rate",
            "100",
            "--duration",
            "0.05",
            "--format",
            "csv",
            "--speed",
            "1",
        ])
        .args(["--trigger", &format!("udp://127.0.0.1:{port}"), "--file"])
        .arg(format!("{}", out.display()))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let said = wait_for(&mut err, "waiting for the first trigger edge");
    // The template's filter kind and taps give way to the averager: said, not left silent.
    assert!(
        said.contains("output filter of template `avg` is a uniform average over each interval"),
        "{said}"
    );
    let at_ms = [0.0, 4.0, 17.0, 20.0, 33.5, 51.0];
    send_edges(port, utc_now_ns() + 20_000_000, &at_ms);
    finish(child, err);
    let r = rows(&out);
    check_rows("imu", &r, &at_ms, 6, 1e-6);
    for (k, row) in r.iter().enumerate() {
        for j in 1..7 {
            let want = r[0][j];
            assert!(
                (row[j] - want).abs() <= 1e-12 * want.abs().max(1e-4),
                "row {k} column {j}"
            );
        }
    }
}

/// A rig following live states in real time on a trigger: the survey's states over UDP at
/// 100 Hz (one datagram every 10 ms), and from 1 s on, edges over UDP 5 to 15 ms apart. Each
/// edge is mapped to simulation time through the clock map less the output delay, as for one
/// IMU, and every unit — an ideal one, one with an output filter at a lever arm, a
/// skew-redundant one — takes one record over each interval between mapped edges: the
/// same number of records for every unit (one fewer than the edges, or fewer still if an
/// early edge mapped before the run's start), the same tags, increments equal to the rates
/// times the interval since the previous tag (to round-off), and tag differences equal to
/// the edges' spacing within 1 ms (the clock map's slope is the sender's rate against the
/// host's; its error over 15 ms is far below that; the stamps' conversion to CLOCK_MONOTONIC
/// adds up to the 2 ms of the paced check, counted once per difference of two edges read
/// the same way, here bounded at 1 ms as both stamps of a difference share the offset).
#[test]
fn a_live_rig_samples_on_a_trigger_in_real_time() {
    let _rt = realtime_run::serial();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let avg = write(d, "avg.toml", AVERAGED);
    let scene = write(
        d,
        "rig.toml",
        &format!(
            "[trajectory]\nscene = \"survey\"\n[output]\nduration_s = 30.0\n\
             [[imu]]\nname = \"a\"\nrate_hz = 100.0\n\
             [[imu]]\nname = \"f\"\nmodel = \"{}\"\nrate_hz = 100.0\nlever_arm_m = [1.5, -0.4, 0.3]\n\
             [[imu]]\nname = \"s\"\nrate_hz = 100.0\n\
             [[imu.gyro]]\naxis = [1.0, 0.0, 0.0]\n[[imu.gyro]]\naxis = [0.0, 0.6, 0.8]\n",
            avg.display()
        ),
    );
    let (port, trigger) = (free_port(), free_port());
    let mut c = Command::new(BIN);
    c.arg("run").arg(&scene).args([
        "--motion",
        &format!("udp://127.0.0.1:{port}"),
        "--input-timeout",
        "0.5",
        "--trigger",
        &format!("udp://127.0.0.1:{trigger}"),
        "--max-behind-ms",
        "2000",
    ]);
    for n in ["a", "f", "s"] {
        c.arg("--unit-sink")
            .arg(format!("{n}=file:{}", d.join(format!("{n}.csv")).display()));
    }
    let mut child = c
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let said = wait_for(&mut err, "following udp://");
    // Known before the first state: unit f's filter gives way to the averager, said.
    assert!(
        said.contains("output filter of unit `f` is a uniform average over each interval"),
        "{said}"
    );
    let states = survey_csv(3.0);
    let sender = std::thread::spawn(move || send_states(port, &states));
    let mut at_ms = vec![0.0];
    for i in 0..60 {
        at_ms.push(at_ms[i] + 5.0 + ((i * 7) % 11) as f64);
    }
    // The edges start once the states are flowing (1 s of them at their pace); an edge the
    // run maps before it follows its input closes no interval, and the run says how many.
    std::thread::sleep(Duration::from_millis(1000));
    send_edges(trigger, utc_now_ns() + 10_000_000, &at_ms);
    sender.join().unwrap();
    let rest = finish(child, err);
    let (a, f, s) = (
        rows(&d.join("a.csv")),
        rows(&d.join("f.csv")),
        rows(&d.join("s.csv")),
    );
    eprintln!("{rest}");
    // One record per edge after the first, but for those the run says closed none.
    let unused = if rest.contains("trigger edges closed no interval") {
        number_before(&rest, "trigger edges closed no interval") as usize
    } else {
        0
    };
    assert_eq!(
        a.len(),
        at_ms.len() - 1 - unused,
        "{} records for {} edges: {rest}",
        a.len(),
        at_ms.len()
    );
    assert_eq!((f.len(), s.len()), (a.len(), a.len()));
    // The first record's interval starts at an edge that gave none: its tag difference is
    // checked from the second record on, against the spacing of the edges it lies between.
    let skipped = at_ms.len() - 1 - a.len();
    for k in 0..a.len() {
        assert!(
            a[k][0] == f[k][0] && a[k][0] == s[k][0],
            "record {k}: tags differ"
        );
        if k > 0 {
            let got = a[k][0] - a[k - 1][0];
            let want = (at_ms[k + 1 + skipped] - at_ms[k + skipped]) * 1e-3;
            assert!(
                (got - want).abs() < 1e-3,
                "record {k}: {got} s apart, edges {want} s"
            );
            for (name, r, ch) in [("a", &a, 6), ("f", &f, 6), ("s", &s, 2)] {
                for j in 0..ch {
                    let (rate, inc) = (r[k][1 + j], r[k][1 + ch + j]);
                    if rate != 0.0 {
                        assert!(
                            (inc / rate - got).abs() <= 1e-9 * got,
                            "unit {name} record {k} channel {j}"
                        );
                    }
                }
            }
        }
    }
}

/// The number right before `key` in `text`.
fn number_before(text: &str, key: &str) -> f64 {
    let i = text
        .find(key)
        .unwrap_or_else(|| panic!("`{key}` in {text}"));
    let word = text[..i].trim_end().rsplit([' ', '(', ';']).next().unwrap();
    word.parse()
        .unwrap_or_else(|_| panic!("a number before `{key}` in {text}"))
}
