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
        "--tcp" => &["127.0.0.1:17"],
        "--tcp-listen" => &["127.0.0.1:18"],
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

/// The keys of a struct of src/config/run.rs (`RunSection`, `InputSection`): its `pub` fields.
fn keys_of(source: &str, name: &str) -> Vec<String> {
    let start = source.find(&format!("pub struct {name} {{")).unwrap();
    let body = &source[start..start + source[start..].find("\n}").unwrap()];
    (body.lines().skip(1))
        .filter_map(|l| l.trim().strip_prefix("pub "))
        .filter_map(|l| l.split_once(':').map(|(k, _)| k.trim().to_string()))
        .collect()
}

/// A value (TOML) for each key of `[run]` and `[run.input]` (`input.KEY`), other than its
/// default, and the flag that gives the same setting (a mode giving that flag overrides the
/// key, so the pair is skipped there).
fn key_value(key: &str) -> (&'static str, Option<&'static str>) {
    match key {
        "speed" => ("2", Some("--speed")),
        "start_at" => ("\"next-second\"", Some("--start-at")),
        "time_base" => ("\"gps\"", Some("--time-base")),
        "max_behind_ms" => ("50", Some("--max-behind-ms")),
        "realtime_priority" => ("true", Some("--realtime")),
        "truth" => ("\"file:t.bin\"", None),
        "truth_errors" => ("\"file:e.bin\"", None),
        "gnss" => ("\"nmea:udp:127.0.0.1:13\"", Some("--gnss")),
        "gnss_truth" => ("\"file:gt.csv\"", None),
        "odometer" => ("\"udp:127.0.0.1:14\"", Some("--odometer")),
        "baro" => ("\"udp:127.0.0.1:15\"", Some("--baro")),
        "magnetometer" => ("\"udp:127.0.0.1:16\"", Some("--magnetometer")),
        "time_marks" => ("\"marks.csv\"", Some("--time-marks")),
        "pulse" => ("\"rts:pps\"", Some("--pulse")),
        "pulse_port" => ("\"/dev/ttyX8\"", Some("--pulse-port")),
        "pulse_unit" => ("\"tac\"", Some("--pulse-unit")),
        "pps_in" => ("\"udp://127.0.0.1:47997\"", Some("--pps-in")),
        "trigger" => ("\"udp://127.0.0.1:47996\"", Some("--trigger")),
        "baud" => ("115200", Some("--baud")),
        "framing" => ("\"7E1\"", Some("--framing")),
        "udp_batch" => ("4", Some("--udp-batch")),
        "take_over" => ("true", Some("--take-over")),
        "input.source" => ("\"udp://127.0.0.1:47999\"", Some("--motion")),
        "input.format" => ("\"bin\"", Some("--input-format")),
        "input.mode" => ("\"lockstep\"", Some("--time-mode")),
        "input.output_delay_s" => ("0.05", Some("--output-delay")),
        "input.max_extrapolation_s" => ("0.1", Some("--max-extrapolation")),
        "input.correction_horizon_s" => ("0.05", Some("--correction-horizon")),
        "input.on_timeout" => ("\"hold\"", Some("--on-timeout")),
        "input.timeout_s" => ("3", Some("--input-timeout")),
        "input.record" => ("\"rec.bin\"", Some("--record-input")),
        k => panic!("`run.{k}`: a key of src/config/run.rs this walk has no value for; add one"),
    }
}

/// The scene file of `mode` with `run` as its `[run]` tables: the rig's units for the rig
/// mode, nothing else for the others; its name.
fn scene_with(dir: &Path, mode: &str, run: &str) -> String {
    let name = format!("s-{}.toml", mode.replace(' ', "-"));
    let signal = if mode == "rig" {
        format!("{}[output]\nduration_s = 1.0\n", hil::TWO_UNITS)
    } else {
        String::new()
    };
    std::fs::write(dir.join(&name), format!("{signal}{run}")).unwrap();
    name
}

/// `imu-emu run SCENE MODE… --describe`: its success, stdout and stderr.
fn describe_with(dir: &Path, scene: &str, mode: &[&str]) -> (bool, String, String) {
    let mut args = vec!["run".to_string(), scene.to_string()];
    args.extend(
        mode.iter()
            .filter(|a| **a != "rig.toml")
            .map(|a| a.to_string()),
    );
    args.push("--describe".into());
    let out = imu_emu(dir, &args);
    let text = |b: Vec<u8>| String::from_utf8_lossy(&b).into_owned();
    (out.status.success(), text(out.stdout), text(out.stderr))
}

/// Each key of a scene file's `[run]` and `[run.input]` tables (read from src/config/run.rs,
/// so a new key cannot be left out) in each mode: the description changes, or the run is
/// refused naming the file's key. A `[run.input]` key is tried beside a `source`, against
/// the run with the source alone.
#[test]
fn every_run_key_is_used_or_refused_in_every_mode() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    setup(d);
    let source =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("src/config/run.rs"))
            .unwrap();
    let mut keys: Vec<String> = (keys_of(&source, "RunSection").into_iter())
        .filter(|k| k != "input")
        .collect();
    keys.extend(
        keys_of(&source, "InputSection")
            .iter()
            .map(|k| format!("input.{k}")),
    );
    assert!(keys.len() >= 30, "{keys:?}");
    let mut ignored = Vec::new();
    for (name, mode) in modes() {
        for key in &keys {
            let (value, flag) = key_value(key);
            if flag.is_some_and(|f| mode.contains(&f)) {
                continue;
            }
            let (table, base) = match key.strip_prefix("input.") {
                Some("source") => ("[run.input]\n".to_string(), String::new()),
                Some(_) => {
                    let s = "[run.input]\nsource = \"udp://127.0.0.1:47999\"\n".to_string();
                    (s.clone(), s)
                }
                None => ("[run]\n".to_string(), "[run]\n".to_string()),
            };
            let k = key.strip_prefix("input.").unwrap_or(key);
            let base = scene_with(d, name, &base);
            let (base_ok, base_out, _) = describe_with(d, &base, &mode);
            if !base_ok {
                // The mode refuses a live input (`run.input.source`, walked on its own).
                continue;
            }
            let with_key = scene_with(d, name, &format!("{table}{k} = {value}\n"));
            let (ok, out, err) = describe_with(d, &with_key, &mode);
            let shown = format!("{name}: `run.{key}` = {value}");
            if ok {
                if out == base_out {
                    ignored.push(format!("{shown}: the description did not change"));
                }
            } else {
                assert!(!err.contains("panicked"), "{err}");
                if !err.contains(&format!("`run.{key}`")) {
                    let first = err.lines().next().unwrap_or("");
                    ignored.push(format!("{shown}: refused without naming the key: {first}"));
                }
            }
        }
    }
    assert!(
        ignored.is_empty(),
        "silently ignored or refused without their key:\n{}",
        ignored.join("\n")
    );
}
