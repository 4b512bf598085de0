//! Real-time pacing: `cargo bench --bench latency` (LATENCY_SECS=2 for a quick run, default
//! 10 s per case; LATENCY_FIFO=0 skips the SCHED_FIFO rows).
//!
//! The emulator's own pipeline (producer thread → bounded channel → pacer thread → sink) runs
//! kvh1750 frames of the survey scene with the LN-200 error model to a pty and to UDP
//! loopback. A reader thread on the other side (the pty slave, a UDP socket) timestamps each
//! frame's arrival with CLOCK_MONOTONIC; lateness = arrival − deadline, the deadline being
//! start + k·Δt. Frames are identified by their counter (unwrapped), so a dropped frame does
//! not shift the others. In the SCHED_FIFO rows the reader is SCHED_FIFO too. Drift: median
//! lateness of the last tenth of the frames minus that of the first tenth (it would grow with
//! the run if deadlines accumulated error).
//!
//! Then throughput: an unpaced run through the whole pipeline (producer thread, channel,
//! pacer, file sink into a discarding writer) against `engine::run` (what `generate` runs) on
//! the same scene.

use std::io::Read;
use std::net::UdpSocket;
use std::os::fd::AsFd;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use imu_emu::engine::{self, Encoding, Producer, SourceSpec};
use imu_emu::errors::{ErrorChain, template};
use imu_emu::generator::DEFAULT_NODES;
use imu_emu::motion::sampled::ModelSettings;
use imu_emu::output::Format;
use imu_emu::protocol::{EncoderState, Plan, StreamDecoder, load};
use imu_emu::realtime::clock::monotonic_ns;
use imu_emu::realtime::pacer::{self, Clocking, Pacing, Routed, Status};
use imu_emu::realtime::pty::PtySink;
use imu_emu::realtime::sink::{FileSink, Sink};
use imu_emu::realtime::stats::Lateness;
use imu_emu::realtime::udp::UdpSink;
use imu_emu::realtime::{self, FrameBlock};
use imu_emu::scenes::SceneParams;

fn producer(rate: f64, secs: f64, plan: &Plan) -> Producer {
    let source = SourceSpec::Scene("survey".into(), SceneParams::defaults_for("survey"));
    let motion = engine::build_motion(&source, ModelSettings::default()).expect("survey");
    let grid = engine::plan(&motion, rate, None, Some(secs)).expect("span");
    let ln200 = template::load("ln200").expect("built in");
    let chain = ErrorChain::new(&ln200, rate, 1);
    let encoding = Encoding::Frames {
        plan: Box::new(plan.clone()),
        state: EncoderState::default(),
        temperature: 25.0,
        side: Format::Csv,
    };
    Producer::new(motion, grid, DEFAULT_NODES, encoding, Some(chain), false).expect("producer")
}

/// Runs producer + pacer to `sink`; returns the pacer's status.
fn pipeline(p: Producer, frames_per_s: f64, pacing: Pacing, sink: Box<dyn Sink>) -> Status {
    let (tx, rx) = tokio::sync::mpsc::channel::<FrameBlock>(realtime::CHANNEL_BLOCKS);
    let (rtx, rrx) = tokio::sync::mpsc::channel(realtime::CHANNEL_BLOCKS);
    let block = realtime::block_len(frames_per_s);
    let prod = std::thread::spawn(move || produce(p, block, tx, rrx));
    let status = Arc::new(Mutex::new(Status::default()));
    let st = std::thread::Builder::new()
        .name("imu-pacer".into())
        .spawn(move || {
            pacer::run(
                rx,
                rtx,
                vec![Routed::main(sink)],
                pacing,
                Arc::new(AtomicBool::new(false)),
                status,
            )
        })
        .unwrap()
        .join()
        .unwrap()
        .expect("pacer");
    prod.join().unwrap();
    st
}

/// The producer side of a paced run of one stream: the IMU's frames as a source
/// (`imu_emu::run::sources::imu::ImuFrames`), windows of `block` records into blocks.
fn produce(
    p: Producer,
    block: usize,
    tx: tokio::sync::mpsc::Sender<FrameBlock>,
    mut recycled: tokio::sync::mpsc::Receiver<FrameBlock>,
) {
    use imu_emu::engine::frames::{Part, Until, WindowSource};
    let grid = p.grid();
    let mut src =
        imu_emu::run::sources::imu::ImuFrames::new(p, 1, Default::default(), grid.t0, false);
    let window = (block as f64 / grid.rate_hz * 1e9) as i64;
    let (mut until, mut first) = (0i64, 0u64);
    let mut parts = vec![Part::default()];
    while !src.done() {
        until += window;
        parts[0].clear();
        src.fill(Until::ns(grid.t0, until), &mut parts)
            .expect("finite records");
        let mut b = recycled.try_recv().unwrap_or_default();
        let part = std::mem::take(&mut parts[0]);
        b.first = first;
        first += part.ends.len() as u64;
        b.streams = vec![(part.bytes, part.ends)];
        b.emit_ns = part.emit_ns;
        if tx.blocking_send(b).is_err() {
            return;
        }
    }
}

/// Reader-side lateness of every frame, from (arrival ns, bytes) chunks.
struct Arrivals {
    dec: StreamDecoder,
    k: u64,
    last_counter: Option<u64>,
    lateness: Vec<(u64, i128)>,
}

impl Arrivals {
    fn new(plan: Plan) -> Arrivals {
        Arrivals {
            dec: StreamDecoder::new(plan),
            k: 0,
            last_counter: None,
            lateness: Vec::new(),
        }
    }

    fn feed(&mut self, bytes: &[u8], at: i128, clocking: &Clocking, start: i128) {
        let modulo = self.dec.plan().counter().map_or(1 << 62, |c| c.0);
        let (mut k, mut last, mut out) = (self.k, self.last_counter, Vec::new());
        self.dec.feed(bytes, |d| {
            let c = d
                .get(imu_emu::protocol::spec::Source::Counter)
                .unwrap_or(0.0) as u64;
            k += match last {
                None => c + 1,
                Some(l) => (c + modulo - l) % modulo,
            };
            last = Some(c);
            out.push((k, at - clocking.deadline(start, k)));
        });
        (self.k, self.last_counter) = (k, last);
        self.lateness.extend(out);
    }

    fn row(&self, writer: &Status, expected: u64) -> String {
        let mut h = Lateness::default();
        for &(_, l) in &self.lateness {
            h.add(l);
        }
        let tenth = (self.lateness.len() / 10).max(1);
        let median = |s: &[(u64, i128)]| {
            let mut v: Vec<i128> = s.iter().map(|x| x.1).collect();
            v.sort_unstable();
            v[v.len() / 2] as f64 / 1000.0
        };
        let n = self.lateness.len();
        let drift = if n > 0 {
            median(&self.lateness[n - tenth..]) - median(&self.lateness[..tenth])
        } else {
            f64::NAN
        };
        let q = |p| h.quantile_us(p).unwrap_or(f64::NAN);
        let dropped: u64 = writer
            .sinks
            .iter()
            .map(|s| s.1.dropped + s.1.no_reader)
            .sum();
        format!(
            "{:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {:.0} | {drift:+.0} | {}/{expected} | {} | {}",
            writer.lateness.quantile_us(0.5).unwrap_or(f64::NAN),
            writer.lateness.quantile_us(0.99).unwrap_or(f64::NAN),
            q(0.5),
            q(0.99),
            q(0.999),
            h.max_us(),
            writer.lateness.max_us(),
            n,
            dropped,
            writer.skipped
        )
    }
}

/// In the SCHED_FIFO rows the reader runs SCHED_FIFO too (one priority below the pacer), as a
/// HIL consumer would: otherwise the figure is the reader's scheduling on a loaded machine,
/// not the emulator's.
fn reader_priority(fifo: bool) {
    if fifo {
        let p = libc::sched_param { sched_priority: 49 };
        // SAFETY: plain syscall on the calling thread with a valid parameter block.
        if unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO, &p) } != 0 {
            eprintln!("reader: SCHED_FIFO refused, reader at normal priority");
        }
    }
}

fn pty_case(rate: f64, secs: f64, fifo: bool, plan: &Plan) -> String {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("imu");
    let sink = PtySink::open(Some(&link), false).expect("pty");
    let mut reader = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&link)
        .expect("open slave");
    let mut t = nix::sys::termios::tcgetattr(reader.as_fd()).unwrap();
    nix::sys::termios::cfmakeraw(&mut t);
    nix::sys::termios::tcsetattr(reader.as_fd(), nix::sys::termios::SetArg::TCSANOW, &t).unwrap();
    let start = monotonic_ns() + 200_000_000;
    let clocking = Clocking::new(rate, Some(start), fifo).unwrap();
    let c2 = clocking.clone();
    let plan2 = plan.clone();
    let expected = (rate * secs).round() as u64;
    let rd = std::thread::spawn(move || {
        reader_priority(fifo);
        let mut a = Arrivals::new(plan2);
        let mut buf = [0u8; 65536];
        while a.k < expected {
            match reader.read(&mut buf) {
                Ok(0) | Err(_) => break,
                Ok(n) => a.feed(&buf[..n], monotonic_ns(), &c2, start),
            }
        }
        a
    });
    let p = producer(rate, secs, plan);
    let st = pipeline(p, rate, Pacing::Paced(clocking), Box::new(sink));
    let a = rd.join().unwrap();
    a.row(&st, expected)
}

fn udp_case(rate: f64, secs: f64, fifo: bool, plan: &Plan) -> String {
    let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
    rx.set_read_timeout(Some(std::time::Duration::from_secs(2)))
        .unwrap();
    let sink = UdpSink::open(&rx.local_addr().unwrap().to_string(), 1).unwrap();
    let start = monotonic_ns() + 200_000_000;
    let clocking = Clocking::new(rate, Some(start), fifo).unwrap();
    let c2 = clocking.clone();
    let plan2 = plan.clone();
    let expected = (rate * secs).round() as u64;
    let rd = std::thread::spawn(move || {
        reader_priority(fifo);
        let mut a = Arrivals::new(plan2);
        let mut buf = [0u8; 2048];
        while a.k < expected {
            match rx.recv(&mut buf) {
                Ok(n) => a.feed(&buf[..n], monotonic_ns(), &c2, start),
                Err(_) => break,
            }
        }
        a
    });
    let p = producer(rate, secs, plan);
    let st = pipeline(p, rate, Pacing::Paced(clocking), Box::new(sink));
    rd.join().unwrap().row(&st, expected)
}

fn main() {
    let secs: f64 = std::env::var("LATENCY_SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10.0);
    let fifo = std::env::var("LATENCY_FIFO").map_or(true, |v| v != "0");
    let (_, plan) = load("kvh1750").expect("built in");
    println!(
        "Frame lateness, {secs} s per case, kvh1750 frames ({} B), survey scene, LN-200 errors (µs)\n",
        plan.len()
    );
    println!(
        "| sink | rate Hz | frames/wake-up | SCHED_FIFO | writer p50 | writer p99 | reader p50 | reader p99 | reader p99.9 | reader max | writer max | drift | frames read | dropped | skipped |"
    );
    println!("|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for rate in [400.0, 1000.0, 2000.0, 10_000.0] {
        let batch = Clocking::new(rate, None, false).unwrap().batch;
        for rt in [false, true] {
            if rt && (!fifo || rate != 1000.0) {
                continue;
            }
            let f = if rt { "yes" } else { "no" };
            println!(
                "| pty | {rate} | {batch} | {f} | {} |",
                pty_case(rate, secs, rt, &plan)
            );
            println!(
                "| udp | {rate} | {batch} | {f} | {} |",
                udp_case(rate, secs, rt, &plan)
            );
        }
    }

    // Throughput of an unpaced run against generate's engine::run, same scene and settings.
    let rate = 1000.0;
    let dur = 600.0;
    let count = (rate * dur) as u64;
    let mut best = [f64::INFINITY; 2];
    for _ in 0..3 {
        let t = Instant::now();
        let p = producer(rate, dur, &plan);
        let sink = FileSink::writer("null".into(), Box::new(std::io::sink()), false);
        let st = pipeline(p, rate, Pacing::Unpaced, Box::new(sink));
        assert_eq!(st.frames, count);
        best[0] = best[0].min(t.elapsed().as_secs_f64());

        let t = Instant::now();
        let source = SourceSpec::Scene("survey".into(), SceneParams::defaults_for("survey"));
        let motion = engine::build_motion(&source, ModelSettings::default()).unwrap();
        let grid = engine::plan(&motion, rate, None, Some(dur)).unwrap();
        let ln200 = template::load("ln200").unwrap();
        let encoding = Encoding::Frames {
            plan: Box::new(plan.clone()),
            state: EncoderState::default(),
            temperature: 25.0,
            side: Format::Csv,
        };
        engine::run(
            motion,
            grid,
            DEFAULT_NODES,
            encoding,
            Some(ErrorChain::new(&ln200, rate, 1)),
            &mut std::io::sink(),
            None,
            None,
            |_| {},
        )
        .unwrap();
        best[1] = best[1].min(t.elapsed().as_secs_f64());
    }
    println!(
        "\nUnpaced throughput, survey scene, LN-200 errors, kvh1750 frames, {count} records, best of 3\n"
    );
    println!("| path | records/s | relative |");
    println!("|---|---:|---:|");
    println!(
        "| run --speed max (producer thread → channel → pacer → sink) | {:.3e} | {:.2} |",
        count as f64 / best[0],
        best[1] / best[0]
    );
    println!(
        "| generate (engine::run, one thread) | {:.3e} | 1.00 |",
        count as f64 / best[1]
    );
}
