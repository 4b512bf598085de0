//! Outputs that fail (issue 38, "nothing lost without a word"): the reader of a pipe or a FIFO
//! that leaves, a full disk (`/dev/full`). A failing sink fails the run with exit 1 and a
//! message naming its flag and file, and no other output of the run is left as if whole —
//! unless a live link (UDP here) carries the run: then it goes on, the summary counts what the
//! failed sink lost, and the exit is 1 after it. Standard output as the only output, its
//! reader gone, ends the command quietly with 141 (tests/stdout_errors.rs).

use std::fs::File;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

#[path = "common/realtime_run.rs"]
mod realtime_run;
#[path = "common/udp_rx.rs"]
mod udp_rx;

/// `imu-emu` with the words of `line` as arguments (paths follow with `.arg`).
fn imu_emu(line: &str) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_imu-emu"));
    c.args(line.split_whitespace());
    c
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Standard output on a pipe whose reader has gone (what `| head` leaves once head has its
/// bytes: every write fails with EPIPE).
fn closed_pipe() -> Stdio {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    Stdio::from(writer)
}

/// Standard output on a full disk.
fn full() -> Stdio {
    Stdio::from(File::options().write(true).open("/dev/full").unwrap())
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Exit 1 with `what` in the message, never a panic.
fn fails_saying(o: &Output, what: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains(what), "`{what}` in {err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// `generate --truth FIFO` whose reader takes 100 bytes and leaves: exit 1 naming `--truth`
/// and the FIFO, and `-o` is not left behind, whole or partial (it was exit 0 with no `-o`).
#[test]
fn a_truth_fifo_whose_reader_leaves_fails_generate() {
    let dir = tempfile::TempDir::new().unwrap();
    let fifo = dir.path().join("truth.fifo");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    let reader = {
        let f = fifo.clone();
        std::thread::spawn(move || {
            let mut head = [0u8; 100];
            let mut r = File::open(&f).unwrap();
            let _ = r.read_exact(&mut head);
        })
    };
    // 10 000 truth rows, about 2.5 MB: far more than the pipe holds after the reader left.
    let o = imu_emu("generate --scene circle --rate 100 --duration 100")
        .arg("-o")
        .arg(dir.path().join("out.csv"))
        .arg("--truth")
        .arg(&fifo)
        .output()
        .unwrap();
    if !reader.is_finished() {
        // The run never opened the FIFO: let the reader's open return.
        let _ = File::options().write(true).open(&fifo);
    }
    reader.join().unwrap();
    fails_saying(
        &o,
        &format!("--truth: writing file {}: Broken pipe", fifo.display()),
    );
    assert_eq!(names(dir.path()), ["truth.fifo"]);
}

/// A full disk under one output keeps none of the others: the truth file fails only when its
/// buffer is flushed at the end, after `-o` was written whole (which was then kept, beside
/// exit 1).
#[test]
fn a_full_disk_under_one_output_keeps_none() {
    let dir = tempfile::TempDir::new().unwrap();
    let generate = |out: &Path, truth: &Path| {
        imu_emu("generate --scene circle --rate 100 --duration 10")
            .arg("-o")
            .arg(out)
            .arg("--truth")
            .arg(truth)
            .output()
            .unwrap()
    };
    let (file, dev) = (dir.path().join("x.csv"), Path::new("/dev/full"));
    let o = generate(&file, dev);
    fails_saying(
        &o,
        "--truth: writing file /dev/full: No space left on device",
    );
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
    let o = generate(dev, &file);
    fails_saying(
        &o,
        "--output: writing file /dev/full: No space left on device",
    );
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

/// Standard output whose reader left, beside another output, is a failure like any other:
/// exit 1 naming standard output, and the run's files are not left as if whole.
#[test]
fn standard_output_beside_another_output_fails_the_command() {
    let dir = tempfile::TempDir::new().unwrap();
    let d = |n: &str| dir.path().join(n);
    let rec = d("rec.csv");
    let made = imu_emu("generate --scene circle --imu ln200 --rate 100 --duration 30 -o")
        .arg(&rec)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    let rec = rec.to_str().unwrap();
    let file = |n: &str| d(n).to_str().unwrap().to_string();
    let cases = [
        (
            vec![
                "generate",
                "--scene",
                "circle",
                "--duration",
                "100",
                "-o",
                "-",
            ],
            ["--truth".into(), file("t.csv")],
            "--output: writing stdout: Broken pipe",
        ),
        (
            vec!["trajectory", "--scene", "circle", "--duration", "100"],
            ["--plot".into(), file("p.svg")],
            "writing the trajectory to standard output: Broken pipe",
        ),
        (
            vec!["analyze", rec],
            ["--csv".into(), file("c.csv")],
            "writing the report to standard output: Broken pipe",
        ),
        (
            vec!["navigate", rec, "--scene", "circle", "-o", "-"],
            ["--errors".into(), file("e.csv")],
            "writing the trajectory to standard output: Broken pipe",
        ),
    ];
    for (args, more, what) in cases {
        let o = (imu_emu("").args(&args).args(more))
            .stdout(closed_pipe())
            .output()
            .unwrap();
        fails_saying(&o, what);
        // The files a command finished before it met standard output are whole; the others
        // are not there at all.
        for n in ["t.csv", "e.csv"] {
            assert!(!d(n).exists(), "{args:?}: {n}");
        }
    }
}

/// A paced run of files only: one on a full disk fails the run, naming it, and the file
/// written beside it (live, so that a reader could follow it) is removed.
#[test]
fn a_paced_run_of_files_fails_whole() {
    let _one = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let x = dir.path().join("x.bin");
    let o = imu_emu("run --scene circle --duration 0.5 --speed 1 --file /dev/full --file")
        .arg(&x)
        .output()
        .unwrap();
    fails_saying(
        &o,
        "--file /dev/full: writing file /dev/full: No space left on device",
    );
    assert!(names(dir.path()).is_empty(), "{:?}", names(dir.path()));
}

/// The run's summary line of sink `label`.
fn sink_line<'a>(err: &'a str, label: &str) -> &'a str {
    let key = format!("    {label}: ");
    (err.lines().find(|l| l.starts_with(&key)))
        .unwrap_or_else(|| panic!("a line for {label} in {err}"))
}

/// A paced run with a UDP link, a file and standard output whose reader left: the run goes on
/// for the link and the file (every frame on both, the same bytes), the summary counts the
/// 800 frames standard output lost and names it, and the exit is 1 after the summary (it was
/// exit 0, the UDP frames stopped uncounted, no summary).
#[test]
fn a_paced_rig_goes_on_without_a_failed_sink() {
    let _one = realtime_run::serial();
    let dir = tempfile::TempDir::new().unwrap();
    let x = dir.path().join("x.bin");
    let rx = udp_rx::UdpRx::start();
    let dest = rx.dest.clone();
    let o = imu_emu("run --scene circle --duration 2 --max-behind-ms 60000 --file - --udp")
        .arg(&dest)
        .arg("--file")
        .arg(&x)
        .stdout(closed_pipe())
        .output()
        .unwrap();
    let got = udp_rx::joined(&rx.stop());
    fails_saying(
        &o,
        "a sink failed while the run went on for its other sinks: --file -: writing stdout: Broken pipe (os error 32); 800 frames lost",
    );
    let err = stderr(&o);
    assert!(
        sink_line(&err, &format!("udp {}", dest))
            .starts_with(&format!("    udp {}: 800 sent, 0 dropped", dest)),
        "{err}"
    );
    assert!(
        sink_line(&err, "stdout").ends_with("0 bytes, 800 lost (the sink failed)"),
        "{err}"
    );
    let file = std::fs::read(&x).unwrap();
    assert_eq!(file.len(), 800 * 26, "{err}");
    assert_eq!(got, file);
}

/// The same in lockstep (the sinks written as each state comes, no pacer): standard output
/// on a full disk fails when its buffer is flushed at the end, and every frame it took is
/// counted as lost; the UDP link had them all.
#[test]
fn a_lockstep_rig_goes_on_without_a_failed_sink() {
    let dir = tempfile::TempDir::new().unwrap();
    let states: PathBuf = dir.path().join("states.csv");
    let made = imu_emu("trajectory --scene circle --rate 100 --duration 5 -o")
        .arg(&states)
        .output()
        .unwrap();
    assert!(made.status.success(), "{}", stderr(&made));
    let rx = udp_rx::UdpRx::start();
    let dest = rx.dest.clone();
    let o = imu_emu("run --time-mode lockstep --file - --motion")
        .arg(&states)
        .arg("--udp")
        .arg(&dest)
        .stdout(full())
        .output()
        .unwrap();
    let got = rx.stop();
    let err = stderr(&o);
    let udp = sink_line(&err, &format!("udp {}", dest));
    let frames: usize = udp
        .split(": ")
        .nth(1)
        .and_then(|c| c.split(' ').next())
        .unwrap()
        .parse()
        .unwrap();
    // A 4 MiB loopback buffer loses none of them.
    assert_eq!(got.len(), frames, "{err}");
    assert!(frames > 1900, "{frames} frames: {err}");
    assert!(udp.contains(" 0 dropped (slow consumer)"), "{err}");
    fails_saying(
        &o,
        &format!(
            "--file -: writing stdout: No space left on device (os error 28); {frames} frames lost"
        ),
    );
    assert!(
        sink_line(&err, "stdout").ends_with(&format!("0 bytes, {frames} lost (the sink failed)")),
        "{err}"
    );
}

/// Waits (a hang guard of 60 s) until a thread of process `pid` sleeps in the kernel at a
/// place whose name contains one of `places` (/proc/PID/task/*/wchan).
fn wait_blocked_in(pid: u32, places: &[&str]) {
    let t0 = std::time::Instant::now();
    loop {
        let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).unwrap();
        let blocked = tasks.filter_map(|t| t.ok()).any(|t| {
            let w = std::fs::read_to_string(t.path().join("wchan")).unwrap_or_default();
            places.iter().any(|p| w.contains(p))
        });
        if blocked {
            return;
        }
        assert!(
            t0.elapsed().as_secs() < 60,
            "not blocked in {places:?} after 60 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// A stop reaches a run whose thread is blocked in an output call it never returns from —
/// a write into a pipe nobody reads, the open of a FIFO nobody opens — where the run itself
/// cannot see it: the command ends with the signal's status, says an output was blocked and
/// leaves no file (it once waited for the reader for ever, deaf to SIGINT and SIGTERM).
#[test]
fn a_stop_ends_a_run_blocked_in_its_output() {
    let dir = tempfile::TempDir::new().unwrap();
    let fifo = dir.path().join("truth.fifo");
    nix::unistd::mkfifo(&fifo, nix::sys::stat::Mode::S_IRWXU).unwrap();
    let (reader, writer) = std::io::pipe().unwrap();
    let pipe_writer =
        imu_emu("generate --scene static --rate 1000 --duration 1e6 --format bin -o -")
            .stdout(writer)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
    let mut fifo_writer = imu_emu("generate --scene circle --rate 100 --duration 100");
    fifo_writer
        .arg("-o")
        .arg(dir.path().join("out.csv"))
        .arg("--truth")
        .arg(&fifo)
        .stderr(Stdio::piped());
    let cases = [
        ("-INT", 130, Some(pipe_writer), &["pipe_write"][..]),
        ("-TERM", 143, None, &["fifo", "wait_for_partner"][..]),
    ];
    for (signal, code, child, places) in cases {
        // One at a time: the second's files are not the first's to leave.
        let child = child.unwrap_or_else(|| fifo_writer.spawn().unwrap());
        wait_blocked_in(child.id(), places);
        let kill = Command::new("kill")
            .args([signal, &child.id().to_string()])
            .status()
            .unwrap();
        assert!(kill.success());
        // The hang guard: a run deaf to the stop is killed after 60 s, failing the test.
        let pid = child.id();
        let guard = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_secs(60));
            let _ = Command::new("kill")
                .args(["-KILL", &pid.to_string()])
                .status();
        });
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "{signal}: {err}");
        assert!(err.contains("an output was blocked"), "{err}");
        assert_eq!(names(dir.path()), ["truth.fifo"]);
        drop(guard);
    }
    drop(reader);
}
