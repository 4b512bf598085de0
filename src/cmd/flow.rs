//! Running a built run from the command line: its notes and warnings printed as they come,
//! Ctrl-C and SIGTERM turned into a stop, a status line (paced runs) or a progress bar (long
//! offline runs) on a terminal, then the summary; a run stopped by a signal exits 128 + its
//! number, one that lost a sink on the way exits 1 after its summary.

use std::io::IsTerminal;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::Result;

use imu_emu::output::unfinished;
use imu_emu::realtime::signal::Interrupted;
use imu_emu::run::{Clock, Control, Run, RunReport};

/// How long after a stop an output call that has not returned (nor any other since) counts
/// as blocked for good: a write into a pipe nobody reads, a FIFO's open with no reader.
const STUCK_AFTER: Duration = Duration::from_millis(100);

/// Ends the process for a stop its run cannot see, its thread blocked in an output call:
/// the unfinished files removed, the stop said, the signal's exit status. `_exit`, because
/// the blocked thread may hold the locks an orderly exit takes (stdout's).
fn abandon(i: Interrupted) -> ! {
    unfinished::remove_all();
    let msg = format!(
        "imu-emu: {i}: an output was blocked (a pipe or FIFO nobody reads); unfinished output \
         files removed\n"
    );
    // SAFETY: writing a buffer we own to stderr, then ending the process without unwinding.
    unsafe {
        libc::write(2, msg.as_ptr().cast(), msg.len());
        libc::_exit(i.exit_code())
    }
}

/// Runs `run`, printing as it goes; `quiet`: print only warnings, faults and the stop (an
/// offline run whose outputs speak for themselves).
pub fn run(run: Run, quiet: bool) -> Result<RunReport> {
    for w in run.warnings() {
        eprintln!("imu-emu: warning: {w}");
    }
    for line in run.describe().lines() {
        tracing::info!("{line}");
    }
    let caught = imu_emu::realtime::signal::watch()?;
    let ctl = Control::with_notes(|n| eprintln!("imu-emu: {n}"));
    let paced = !matches!(run.clock(), Clock::Free | Clock::Lockstep);
    let streams = run.streams().to_vec();
    let planned: u64 = streams.iter().filter_map(|s| s.planned).max().unwrap_or(0);
    let tty = std::io::stderr().is_terminal();
    let bar = if tty && !paced && planned >= 500_000 {
        indicatif::ProgressBar::new(planned)
    } else {
        indicatif::ProgressBar::hidden()
    };
    let started = Instant::now();
    let (result, sig) = std::thread::scope(|scope| {
        let worker = scope.spawn(|| run.execute(&ctl));
        let mut last_line = Instant::now();
        let mut stopped: Option<(Instant, u64)> = None;
        while !worker.is_finished() {
            std::thread::sleep(Duration::from_millis(50));
            let sig = caught.load(Ordering::Relaxed);
            if sig != 0 {
                ctl.stop();
                let (at, mark) =
                    *stopped.get_or_insert_with(|| (Instant::now(), unfinished::progress()));
                if at.elapsed() >= STUCK_AFTER && unfinished::stuck_since(mark) {
                    abandon(Interrupted(sig));
                }
            }
            let s = ctl.status();
            bar.set_position(s.streams.first().map_or(0, |c| c.frames));
            if tty && paced && last_line.elapsed() >= Duration::from_secs(1) && s.started {
                last_line = Instant::now();
                match &s.live {
                    Some(l) => eprintln!("imu-emu: {}", l.line()),
                    None => eprint!("\r\x1b[2K{}", s.line(&streams)),
                }
            }
        }
        if tty && paced {
            eprint!("\r\x1b[2K");
        }
        let r = worker.join().unwrap_or_else(|_| {
            Err(imu_emu::run::RunError::io(
                "the run",
                std::io::Error::other("the run's thread panicked"),
            ))
        });
        (r, caught.load(Ordering::Relaxed))
    });
    bar.finish_and_clear();
    let interrupted = (sig != 0).then_some(Interrupted(sig));
    let report = match result {
        Ok(r) => r,
        Err(e) => {
            if let Some(i) = interrupted {
                eprintln!("imu-emu: {i}: stopped before the end, unfinished output files removed");
                return Err(i.into());
            }
            return Err(e.into());
        }
    };
    let prefix = interrupted.map_or(String::new(), |i| format!("{i}: "));
    if quiet {
        if let Some(f) = &report.faults {
            eprintln!("imu-emu: faults injected: {}", f.summary());
        }
        if let Some(i) = interrupted {
            eprintln!("imu-emu: {i}: stopped before the end, unfinished output files removed");
        } else if tty && planned >= 500_000 {
            let s = started.elapsed().as_secs_f64();
            eprintln!(
                "{planned} records in {s:.2} s ({:.3e} records/s)",
                planned as f64 / s
            );
        }
    } else {
        eprintln!("imu-emu: {prefix}{}", report.summary());
        if report.stopped && !paced {
            // An unpaced run's files are whole or absent: a stop before the end removes them.
            eprintln!("imu-emu: stopped before the end, unfinished output files removed");
        }
    }
    match interrupted {
        Some(i) => Err(i.into()),
        // The run went on for its live links, but not every output is whole.
        None if !report.failures.is_empty() => Err(anyhow::anyhow!(
            "{} while the run went on for its other sinks: {}",
            match report.failures.len() {
                1 => "a sink failed".to_string(),
                n => format!("{n} sinks failed"),
            },
            report.failures.join(" | ")
        )),
        None => Ok(report),
    }
}

/// Runs `run` with its full summary.
pub fn execute(run: Run) -> Result<()> {
    self::run(run, false).map(drop)
}
