//! Every flag of `imu-emu run`, read from `imu-emu run --help` (a new flag cannot be left out),
//! against every mode of a run — offline to files, paced, lockstep live, real-time live,
//! triggered, a rig — is either used or refused: added to the mode's flags, `run --describe`
//! either prints another description (the flag took effect: every setting that changes a run
//! changes it, src/run/describe.rs) or fails naming the flag, before anything runs. A flag
//! accepted without changing the description is silently ignored, and fails this test.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::{Command, Output};

#[path = "common/hil.rs"]
mod hil;

const BIN: &str = env!("CARGO_BIN_EXE_imu-emu");

/// `imu-emu ARGS` in `dir`.
fn imu_emu(dir: &Path, args: &[String]) -> Output {
    Command::new(BIN)
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

/// The long flags `imu-emu run --help` lists (`--scene`, …), in its order.
fn flags_of_help(dir: &Path) -> Vec<String> {
    let out = imu_emu(dir, &["run".into(), "--help".into()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut seen = Vec::new();
    for line in text.lines() {
        let l = line.trim_start();
        let l = l.strip_prefix("-v, ").unwrap_or(l);
        if let Some(rest) = l.strip_prefix("--") {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            if !name.is_empty() && !seen.contains(&format!("--{name}")) {
                seen.push(format!("--{name}"));
            }
        }
    }
    seen
}

/// Values to try for each flag, other than its default (a default given changes nothing):
/// the first one the mode does not already give is used. `None`: a switch.
fn values(flag: &str) -> Option<&'static [&'static str]> {
    Some(match flag {
        "--scene" => &["straight"],
        "--trajectory" => &["traj.csv"],
        "--motion-def" => &["mission.toml"],
        "--imu" => &["hg1700"],
        "--rate" => &["200"],
        "--duration" => &["2", "3"],
        "--start" => &["0.5"],
        "--format" => &["csv"],
        "--protocol-file" => &["kvh1750.toml"],
        "--gps-time" => &["2300,100"],
        "--fault" => &["drop@0.5"],
        "--seed" => &["7"],
        "--quadrature" => &["2"],
        "--interp" => &["cubic"],
        "--stencil" => &["5"],
        "--motion" => &["udp://127.0.0.1:47999", "udp://127.0.0.1:47998"],
        "--input-format" => &["bin"],
        "--time-mode" => &["lockstep", "realtime"],
        "--output-delay" => &["0.05"],
        "--max-extrapolation" => &["0.1"],
        "--correction-horizon" => &["0.05"],
        "--on-timeout" => &["hold"],
        "--record-input" => &["rec.bin"],
        "--input-timeout" => &["3"],
        "--pty" => &["link"],
        "--serial" => &["/dev/ttyX9"],
        "--baud" => &["115200"],
        "--framing" => &["7E1"],
        "--udp" => &["127.0.0.1:10", "127.0.0.1:11"],
        "--file" => &["f.bin", "g.bin"],
        "--unit-sink" => &["nav=udp:127.0.0.1:12"],
        "--gnss" => &["nmea:udp:127.0.0.1:13"],
        "--odometer" => &["udp:127.0.0.1:14"],
        "--baro" => &["udp:127.0.0.1:15"],
        "--magnetometer" => &["udp:127.0.0.1:16"],
        "--udp-batch" => &["4"],
        "--speed" => &["2", "3"],
        "--start-at" => &["next-second"],
        "--time-base" => &["gps"],
        "--time-marks" => &["marks.csv"],
        "--pulse" => &["rts:pps"],
        "--pulse-port" => &["/dev/ttyX8"],
        "--pulse-unit" => &["tac"],
        "--pps-in" => &["udp://127.0.0.1:47997"],
        "--trigger" => &["udp://127.0.0.1:47996", "udp://127.0.0.1:47995"],
        "--max-behind-ms" => &["50", "60"],
        "--take-over" | "--realtime" => return None,
        f => panic!("{f}: a flag of `run --help` this walk has no value for; add one"),
    })
}

/// The modes: a name and the flags that make it.
fn modes() -> Vec<(&'static str, Vec<&'static str>)> {
    vec![
        ("offline", vec!["--duration", "1", "--file", "off.bin"]),
        (
            "paced",
            vec!["--duration", "1", "--speed", "1", "--udp", "127.0.0.1:9"],
        ),
        (
            "lockstep",
            vec![
                "--motion",
                "-",
                "--time-mode",
                "lockstep",
                "--file",
                "ls.bin",
            ],
        ),
        (
            "real time",
            vec!["--motion", "udp://127.0.0.1:47990", "--udp", "127.0.0.1:9"],
        ),
        (
            "triggered",
            vec![
                "--duration",
                "1",
                "--speed",
                "1",
                "--trigger",
                "udp://127.0.0.1:47991",
                "--udp",
                "127.0.0.1:9",
            ],
        ),
        (
            "rig",
            vec![
                "rig.toml",
                "--speed",
                "1",
                "--unit-sink",
                "nav=udp:127.0.0.1:9",
                "--unit-sink",
                "tac=udp:127.0.0.1:9",
            ],
        ),
    ]
}

/// The files the values name, in `dir`.
fn setup(dir: &Path) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let traj = Command::new(BIN)
        .args(["trajectory", "--scene", "survey", "--rate", "100"])
        .args(["--duration", "20"])
        .output()
        .unwrap();
    assert!(traj.status.success());
    std::fs::write(dir.join("traj.csv"), traj.stdout).unwrap();
    std::fs::copy(root.join("examples/mission.toml"), dir.join("mission.toml")).unwrap();
    std::fs::copy(
        root.join("protocols/kvh1750.toml"),
        dir.join("kvh1750.toml"),
    )
    .unwrap();
    let rig = format!("{}[output]\nduration_s = 1.0\n", hil::TWO_UNITS);
    std::fs::write(dir.join("rig.toml"), rig).unwrap();
}

/// The mode's flags with `flag` (and its value) added; a flag the mode gives is replaced.
fn with(mode: &[&str], flag: &str) -> Vec<String> {
    let mut args: Vec<String> = vec!["run".into()];
    let value = values(flag).map(|vs| {
        let taken: BTreeSet<&str> = mode.iter().copied().collect();
        *vs.iter().find(|v| !taken.contains(**v)).unwrap()
    });
    let mut i = 0;
    while i < mode.len() {
        if mode[i] == flag {
            // The mode's own value is replaced by the one tried.
            i += 1 + usize::from(value.is_some());
            continue;
        }
        args.push(mode[i].into());
        i += 1;
    }
    args.push(flag.into());
    args.extend(value.map(String::from));
    args.push("--describe".into());
    args
}

/// Each flag in each mode: used (the description changes) or refused naming the flag.
#[test]
fn every_flag_is_used_or_refused_in_every_mode() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    let flags = flags_of_help(d);
    // The walk found the flags: a broken parse would walk nothing.
    assert!(flags.len() >= 45, "{flags:?}");
    let mut ignored = Vec::new();
    for (name, mode) in modes() {
        let (mut used, mut refused) = (0, 0);
        let mut base: Vec<String> = vec!["run".into()];
        base.extend(mode.iter().map(|s| s.to_string()));
        base.push("--describe".into());
        let out = imu_emu(d, &base);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "mode {name}: {err}");
        let baseline = String::from_utf8(out.stdout).unwrap();
        for flag in &flags {
            // Not settings of the run: what the command prints.
            if ["--help", "--describe", "--verbose"].contains(&flag.as_str()) {
                continue;
            }
            let args = with(&mode, flag);
            let out = imu_emu(d, &args);
            let err = String::from_utf8_lossy(&out.stderr);
            if out.status.success() {
                used += 1;
                if String::from_utf8_lossy(&out.stdout) == baseline {
                    ignored.push(format!("{name}: {} ({err})", args[1..].join(" ")));
                }
            } else {
                refused += 1;
                let first = err.lines().next().unwrap_or("");
                println!("  {name} + {flag}: {first}");
                if !err.contains(flag.as_str()) {
                    ignored.push(format!(
                        "{name}: {} refused without naming {flag}: {first}",
                        args[1..].join(" ")
                    ));
                }
                assert!(!err.contains("panicked"), "{err}");
            }
        }
        println!("{name}: {used} flags used, {refused} refused");
    }
    assert!(
        ignored.is_empty(),
        "silently ignored or refused without their name:\n{}",
        ignored.join("\n")
    );
}

/// `--verbose` changes what is printed, not the run: the description's lines are logged at
/// info level as the run starts (`-v`), not without it.
#[test]
fn verbose_logs_the_description() {
    let dir = tempfile::tempdir().unwrap();
    let run = |v: bool| {
        let mut args: Vec<String> = ["run", "--duration", "0.1", "--file", "x.bin"]
            .map(String::from)
            .into();
        if v {
            args.push("-v".into());
        }
        let out = imu_emu(dir.path(), &args);
        assert!(out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    assert!(run(true).contains("clock: unpaced"));
    assert!(!run(false).contains("clock: unpaced"));
}
