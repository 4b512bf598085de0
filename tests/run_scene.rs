//! A scene file holds a whole run: its `[run]` table (clock, time base, streams and their
//! sinks, sync lines, link settings, a live input in `[run.input]`) and `[imu] sink` describe
//! the run that the same flags describe, it runs with no flag at all, and flags override it.
//! A refused value the file gave is named by its file and key.

use std::path::Path;

#[path = "common/hil.rs"]
mod hil;
use hil::{failed, imu_emu, joined, marks, ok, receive};

/// The signal: the circle for 1 s, an HG1700 at 400 Hz (with `imu_extra` in its table), a
/// GNSS receiver and an odometer.
fn signal(imu_extra: &str) -> String {
    format!(
        r#"[trajectory]
scene = "circle"
[output]
duration_s = 1.0
[imu]
model = "hg1700"
rate_hz = 400.0
{imu_extra}
[gnss]
rate_hz = 5.0
seed = 3
[odometer]
rate_hz = 10.0
"#
    )
}

/// The whole run in the scene file: frames to UDP (two per datagram) and in a second
/// protocol to a file, the truth, NMEA to UDP, the GNSS truth and the odometer to files, time
/// marks, paced at 4× real time.
fn whole(imu_to: &str, gnss_to: &str) -> String {
    let sinks = format!(r#"sink = ["udp:{imu_to}", "file:imu.kvh,protocol=kvh1750"]"#);
    format!(
        r#"{}[run]
speed = 4
max_behind_ms = 10000
time_base = "sim"
truth = "file:truth.bin"
gnss = "nmea:udp:{gnss_to}"
gnss_truth = "file:gnss-truth.csv"
odometer = "file:odo.csv"
time_marks = "marks.csv"
udp_batch = 2
"#,
        signal(&sinks)
    )
}

/// Writes `text` to `dir/name`; `name`.
fn scene(dir: &Path, name: &str, text: &str) -> String {
    std::fs::write(dir.join(name), text).unwrap();
    name.to_string()
}

/// The run the scene file describes is the run the flags describe; it runs with no flag, and
/// every stream is what `generate` writes for the same scene and seeds (the UDP frames two
/// per datagram); flags replace the file's settings (speed, batching, the IMU's sinks).
#[test]
fn a_scene_file_holds_the_whole_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (imu_to, imu_rx) = receive();
    let (gnss_to, gnss_rx) = receive();
    let file = scene(d, "whole.toml", &whole(&imu_to, &gnss_to));
    let bare = scene(d, "bare.toml", &signal(""));
    let flags = [
        "--udp",
        &imu_to,
        "--file",
        "imu.kvh,protocol=kvh1750",
        "--speed",
        "4",
        "--max-behind-ms",
        "10000",
        "--time-base",
        "sim",
        "--gnss",
        &format!("nmea:udp:{gnss_to}"),
        "--odometer",
        "file:odo.csv",
        "--time-marks",
        "marks.csv",
        "--udp-batch",
        "2",
    ];
    let describe = |args: &[&str]| {
        let out = imu_emu(d, args);
        ok(&out);
        String::from_utf8(out.stdout).unwrap()
    };
    // The truth streams have no flag of `run`: compared without them.
    let no_truth = |s: String| {
        s.lines()
            .filter(|l| !l.contains("truth"))
            .collect::<Vec<_>>()
            .join("\n")
    };
    let from_file = describe(&["run", &file, "--describe"]);
    let mut args = vec!["run", bare.as_str()];
    args.extend(flags);
    args.push("--describe");
    assert_eq!(no_truth(from_file.clone()), no_truth(describe(&args)));
    assert!(from_file.contains("stream imu truth"), "{from_file}");

    let ran = ok(&imu_emu(d, &["run", &file]));
    let g = |args: &[&str]| {
        let mut all = vec!["generate", bare.as_str(), "--seed", "20261124"];
        all.extend(args);
        ok(&imu_emu(d, &all));
    };
    g(&["--format", "ln200", "-o", "g.ln200", "--truth", "g.truth"]);
    g(&["--format", "kvh1750", "--rate", "400", "-o", "g.kvh"]);
    g(&[
        "-o",
        "g.csv",
        "--gnss-truth",
        "g-gnss.csv",
        "--odometer",
        "g-odo.csv",
    ]);
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    // `generate` of the whole file writes the signal's files, saying it sets `run`'s aside.
    let err = ok(&imu_emu(
        d,
        &["generate", &file, "-o", "w.csv", "--seed", "20261124"],
    ));
    assert!(err.contains("note: whole.toml: the [run] table"), "{err}");
    assert_eq!(read("w.csv"), read("g.csv"));
    let datagrams = imu_rx.join().unwrap();
    assert_eq!(joined(&datagrams), read("g.ln200"), "{ran}");
    assert!(
        datagrams.iter().all(|x| x.1.len() == 2 * 26),
        "two frames a datagram"
    );
    assert_eq!(read("imu.kvh"), read("g.kvh"));
    assert_eq!(read("truth.bin"), read("g.truth"));
    assert_eq!(read("gnss-truth.csv"), read("g-gnss.csv"));
    assert_eq!(read("odo.csv"), read("g-odo.csv"));
    assert_eq!(marks(&d.join("marks.csv")).len(), 400);
    let nmea = String::from_utf8(joined(&gnss_rx.join().unwrap())).unwrap();
    assert_eq!(
        nmea.matches("$GPGGA").count(),
        read("g-gnss.csv")
            .split(|&b| b == b'\n')
            .filter(|l| !l.is_empty())
            .count()
            - 1
    );

    // Flags override the file: another IMU sink (the file's two are replaced), one frame a
    // datagram, a faster clock.
    let (other_to, other_rx) = receive();
    let (unused_to, unused_rx) = receive();
    let file = scene(d, "whole.toml", &whole(&unused_to, &gnss_to));
    let args = [
        "run",
        &file,
        "--udp",
        &other_to,
        "--udp-batch",
        "1",
        "--speed",
        "8",
    ];
    let described = describe(&[&args[..], &["--describe"]].concat());
    assert!(described.contains("paced at 8×"), "{described}");
    assert!(!described.contains(&unused_to), "{described}");
    // The stream flags replace the file's keys of the same name.
    let more = [
        "--gnss",
        "nmea:udp:127.0.0.1:19",
        "--odometer",
        "file:o2.csv",
    ];
    let described =
        describe(&[&args[..], &more, &["--time-marks", "m2.csv", "--describe"]].concat());
    for (now, was) in [
        ("127.0.0.1:19", gnss_to.as_str()),
        ("o2.csv", "odo.csv"),
        ("m2.csv", "marks.csv"),
    ] {
        assert!(
            described.contains(now) && !described.contains(was),
            "{described}"
        );
    }
    ok(&imu_emu(d, &args));
    let datagrams = other_rx.join().unwrap();
    assert_eq!(joined(&datagrams), read("g.ln200"));
    assert!(
        datagrams.iter().all(|x| x.1.len() == 26),
        "one frame a datagram"
    );
    drop(unused_rx);
    // A sink the file gives that cannot be made is named by its file and key.
    let text = whole(&unused_to, &gnss_to).replace("protocol=kvh1750", "protocol=nope");
    let bad = scene(d, "bad.toml", &text);
    let err = failed(&imu_emu(d, &["run", &bad, "--describe"]));
    assert!(
        err.contains("bad.toml: `imu.sink[1]`: sink protocol `nope`"),
        "{err}"
    );
}

/// `[run.input]` makes the scene file a live run: lockstep over a states file writes the
/// bytes the same flags write; `--motion` replaces the file's source.
#[test]
fn a_scene_file_holds_a_live_run() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rows = hil::survey_rows(d, 2.0);
    let tags = hil::Tagged::from_now(rows, 0.0);
    std::fs::write(d.join("in.csv"), tags.csv().join("\n") + "\n").unwrap();
    std::fs::write(d.join("other.csv"), tags.csv()[..100].join("\n") + "\n").unwrap();
    let text = r#"[imu]
model = "hg1700"
sink = "file:from-file.bin"
[run]
time_base = "gps"
[run.input]
source = "in.csv"
mode = "lockstep"
timeout_s = 3
"#;
    std::fs::write(d.join("live.toml"), text).unwrap();
    ok(&imu_emu(d, &["run", "live.toml"]));
    let flags = [
        "run",
        "--imu",
        "hg1700",
        "--motion",
        "in.csv",
        "--time-mode",
        "lockstep",
        "--input-timeout",
        "3",
        "--time-base",
        "gps",
        "--file",
        "from-flags.bin",
    ];
    ok(&imu_emu(d, &flags));
    let read = |f: &str| std::fs::read(d.join(f)).unwrap();
    assert!(!read("from-file.bin").is_empty());
    assert_eq!(read("from-file.bin"), read("from-flags.bin"));
    // The flag's source replaces the file's: the shorter input, fewer frames.
    ok(&imu_emu(
        d,
        &[
            "run",
            "live.toml",
            "--motion",
            "other.csv",
            "--file",
            "short.bin",
        ],
    ));
    assert!(read("short.bin").len() < read("from-flags.bin").len());
    // The file's other input keys stay: the same bytes as the flags' lockstep run of it.
    let mut again = flags;
    again[4] = "other.csv";
    again[12] = "short-flags.bin";
    ok(&imu_emu(d, &again));
    assert_eq!(read("short.bin"), read("short-flags.bin"));
    // An input flag without --motion amends the file's input.
    let out = imu_emu(
        d,
        &["run", "live.toml", "--time-mode", "realtime", "--describe"],
    );
    ok(&out);
    let described = String::from_utf8(out.stdout).unwrap();
    assert!(
        described.contains("clock: real time behind the input"),
        "{described}"
    );
    // A refused value the file gave is named by its file and key.
    std::fs::write(
        d.join("bad.toml"),
        text.replace("timeout_s = 3", "output_delay_s = 0.1"),
    )
    .unwrap();
    let err = failed(&imu_emu(d, &["run", "bad.toml"]));
    assert!(
        err.contains("bad.toml: `run.input.output_delay_s`"),
        "{err}"
    );
    // `generate` has no live input: refused, named.
    let err = failed(&imu_emu(d, &["generate", "live.toml", "-o", "x.csv"]));
    assert!(err.contains("live.toml: `run.input`"), "{err}");
    assert!(!d.join("x.csv").exists());
}
