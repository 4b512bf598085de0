//! Fuzzing every input decoder (issue 23): the live CSV line, binary datagram and MAVLink
//! decoders and the stream framing in front of them, every built-in protocol's frame decoder,
//! and the scene, template, protocol-spec and motion-definition TOML readers, each fed random
//! bytes and mutations of valid input (fixed proptest seed, so a run is reproducible; about
//! 10 s in all in `cargo test --release` on 2 cores, the case counts below set it). The
//! properties:
//! * no panic, whatever the input;
//! * memory bounded: no message or frame longer than its format allows, nothing kept beyond
//!   what was fed;
//! * every refusal names its place: the byte inside the message for the live decoders, the
//!   file for the TOML readers;
//! * a live state taken into the causal motion model never makes the motion non-finite
//!   (issue 23 item 1, where one such state stopped the run).

use std::io::Read;
use std::path::Path;

use imu_emu::live::binary::{self, Datagram};
use imu_emu::live::transport::Receiver;
use imu_emu::live::{Decoder, InputFormat, csv::MAX_LINE_BYTES, mavlink};
use imu_emu::math::all_finite;
use imu_emu::motion::causal::{CausalMotion, LiveSample};
use imu_emu::motion::sampled::ModelSettings;
use imu_emu::motion::{Motion, Pose};
use imu_emu::protocol::{self, EncoderState, StreamDecoder};
use imu_emu::record::Record;
use imu_emu::sim::Simulation;
use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};

fn config(cases: u32) -> Config {
    Config {
        cases,
        rng_seed: RngSeed::Fixed(23),
        failure_persistence: None,
        ..Config::default()
    }
}

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The circle scene's pose every 10 ms from 0 to 0.6 s (a turning vehicle: every state
/// shapes the motion).
fn circle() -> Vec<Pose> {
    let m = Simulation::builder().scene("circle").build().unwrap();
    (0..60).map(|k| m.motion().pose(k as f64 * 0.01)).collect()
}

/// Values a hostile or broken sender puts in a field.
fn nasty_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(1e300),
        Just(-1e300),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::MIN_POSITIVE / 4.0),
        Just(1e10),
        Just(-0.0),
        Just(90.000001),
        any::<f64>(),
        -1e6..1e6f64,
    ]
}

/// Which state gets which field replaced by which value: `(state, field, value)`.
fn damage(fields: usize) -> impl Strategy<Value = Vec<(usize, usize, f64)>> {
    prop::collection::vec((0..60usize, 0..fields, nasty_f64()), 0..6)
}

/// Feeds decoded states into a causal model; after each one it takes, the motion over the
/// newest piece is finite.
struct Follower {
    model: CausalMotion,
    newest: f64,
}

impl Follower {
    fn new() -> Follower {
        Follower {
            model: CausalMotion::new(ModelSettings::default()),
            newest: f64::NAN,
        }
    }

    fn take(&mut self, s: &LiveSample) -> Result<(), TestCaseError> {
        if self.model.push(s).is_err() {
            return Ok(());
        }
        let (t0, t1) = (self.newest, self.model.newest());
        self.newest = t1;
        // Before the first two knots there is no piece to look at (NaN compares false).
        if t0.is_nan() || t1 <= t0 {
            return Ok(());
        }
        for f in [0.0, 0.3, 0.7, 1.0] {
            let t = t0 + f * (t1 - t0);
            let got = self.model.sense(self.model.piece_at(t, 0), t);
            prop_assert!(
                all_finite(&got.omega_ib_b) && all_finite(&got.f_b),
                "t = {t}: {got:?} after {s:?}"
            );
        }
        Ok(())
    }
}

/// A live decoder's refusal points inside the message.
fn check_refusal(d: &mut Decoder, msg: &[u8]) -> Result<Option<LiveSample>, TestCaseError> {
    match d.decode(msg) {
        Ok(s) => Ok(s.map(|s| s.state)),
        Err(e) => {
            prop_assert!(
                e.offset <= msg.len(),
                "offset {} of {} bytes",
                e.offset,
                msg.len()
            );
            prop_assert!(!e.message.is_empty());
            Ok(None)
        }
    }
}

/// The fields of the trajectory CSV line of `p` (as `imu-emu trajectory` writes it), then
/// `wx..ad` (zeros).
fn csv_fields(p: &Pose) -> Vec<String> {
    let (r, pi, y) = imu_emu::math::euler_from_quat(p.q_b_n);
    let mut line = String::new();
    let rpy = (r.to_degrees(), pi.to_degrees(), y.to_degrees());
    let (lat, lon) = (p.lat.to_degrees(), p.lon.to_degrees());
    imu_emu::trajectory::format_row(&mut line, p.t, lat, lon, p.h, p.v_n, rpy);
    let mut f: Vec<String> = line.trim_end().split(',').map(String::from).collect();
    f.resize(16, "0".into());
    f
}

/// A stream that hands out its bytes in reads of the given sizes (cycled).
struct Chunked {
    bytes: Vec<u8>,
    at: usize,
    sizes: Vec<usize>,
    k: usize,
}

impl Read for Chunked {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let want = self.sizes[self.k % self.sizes.len()].max(1);
        self.k += 1;
        let n = want.min(buf.len()).min(self.bytes.len() - self.at);
        buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
        self.at += n;
        Ok(n)
    }
}

/// The longest message a stream of `format` can hand on.
fn longest(format: InputFormat) -> usize {
    match format {
        InputFormat::Csv => MAX_LINE_BYTES + 1,
        InputFormat::Binary => binary::LEN,
        // Header, the largest payload, CRC and signature.
        InputFormat::Mavlink => mavlink::HEADER + 255 + 2 + 13,
    }
}

proptest! {
    #![proptest_config(config(4000))]

    /// Live CSV: states of a turning vehicle with some fields replaced by huge, tiny,
    /// non-finite or random values, after the header that names the extra columns.
    #[test]
    fn live_csv_states(damage in damage(16)) {
        let poses = circle();
        let mut d = Decoder::new(InputFormat::Csv);
        let head = b"t,lat,lon,h,vn,ve,vd,roll,pitch,yaw,wx,wy,wz,an,ae,ad";
        prop_assert!(check_refusal(&mut d, head)?.is_none());
        let mut f = Follower::new();
        for (k, p) in poses.iter().enumerate() {
            let mut fields = csv_fields(p);
            for &(s, c, v) in &damage {
                if s == k {
                    fields[c] = format!("{v:e}");
                }
            }
            let line = fields.join(",");
            if let Some(s) = check_refusal(&mut d, line.as_bytes())? {
                f.take(&s)?;
            }
        }
    }

    /// Live binary datagrams with damaged values and a correct CRC (so that the values, not
    /// the CRC, are what is judged), any flags.
    #[test]
    fn live_binary_datagrams(damage in damage(22), flags in 0u8..8) {
        let mut d = Decoder::new(InputFormat::Binary);
        let mut f = Follower::new();
        for (k, p) in circle().iter().enumerate() {
            let mut v = [
                p.t, p.lat.to_degrees(), p.lon.to_degrees(), p.h, p.v_n.x, p.v_n.y, p.v_n.z,
                0.0, 0.0, 0.0, p.q_b_n.w, p.q_b_n.i, p.q_b_n.j, p.q_b_n.k, 0.01, 0.0, 0.0,
                0.0, 0.0, 0.0, 0.0, 0.0,
            ];
            for &(s, c, x) in &damage {
                if s == k {
                    v[c] = x;
                }
            }
            let g = Datagram {
                seq: k as u32,
                week: binary::NO_WEEK,
                time: v[0],
                flags,
                pos: [v[1], v[2], v[3]],
                vel: [v[4], v[5], v[6]],
                acc: [v[7], v[8], v[9]],
                quat: [v[10], v[11], v[12], v[13]],
                rate: [v[14], v[15], v[16]],
            };
            if let Some(s) = check_refusal(&mut d, &binary::encode(&g))? {
                f.take(&s)?;
            }
        }
    }

    /// MAVLink HIL_STATE_QUATERNION frames with damaged fields (any float bits, any integers).
    #[test]
    fn live_mavlink_frames(
        damage in prop::collection::vec((0..60usize, 0..11usize, any::<u32>()), 0..6),
    ) {
        let mut d = Decoder::new(InputFormat::Mavlink);
        let mut f = Follower::new();
        for (k, p) in circle().iter().enumerate() {
            let mut q = [p.q_b_n.w as f32, p.q_b_n.i as f32, p.q_b_n.j as f32, p.q_b_n.k as f32];
            let mut rates = [0.01f32, 0.0, 0.0];
            let mut pos = [
                (p.lat.to_degrees() * 1e7) as i32,
                (p.lon.to_degrees() * 1e7) as i32,
                (p.h * 1e3) as i32,
            ];
            let mut vel = [(p.v_n.x * 100.0) as i16, (p.v_n.y * 100.0) as i16, (p.v_n.z * 100.0) as i16];
            for &(s, c, x) in &damage {
                if s == k {
                    match c {
                        0..=3 => q[c] = f32::from_bits(x),
                        4..=6 => rates[c - 4] = f32::from_bits(x),
                        7..=9 => pos[c - 7] = x as i32,
                        _ => vel[0] = x as i16,
                    }
                }
            }
            let frame = mavlink::encode(k as u8, k as u64 * 10_000, q, rates, pos, vel);
            if let Some(s) = check_refusal(&mut d, &frame)? {
                f.take(&s)?;
            }
        }
    }

    /// Any bytes as one message, to each live decoder (CSV after any header it saw).
    #[test]
    fn live_decoders_take_any_bytes(
        msgs in prop::collection::vec(prop::collection::vec(any::<u8>(), 0..400), 1..8),
        magic in any::<bool>(),
    ) {
        for format in [InputFormat::Csv, InputFormat::Binary, InputFormat::Mavlink] {
            let mut d = Decoder::new(format);
            for m in &msgs {
                let mut m = m.clone();
                // Past the first gate now and then: the magic, or MAVLink's start byte.
                if magic && format == InputFormat::Binary && m.len() >= binary::LEN {
                    m[..4].copy_from_slice(&binary::MAGIC);
                    m[4] = binary::VERSION;
                }
                if magic && format == InputFormat::Mavlink && !m.is_empty() {
                    m[0] = mavlink::STX;
                }
                check_refusal(&mut d, &m)?;
            }
        }
    }

    /// The stream framing of each format over random bytes with valid messages among them,
    /// read in random sizes: every message within its format's length, and no byte counted
    /// twice.
    #[test]
    fn live_stream_framing(
        parts in prop::collection::vec((prop::collection::vec(any::<u8>(), 0..300), any::<bool>()), 1..12),
        sizes in prop::collection::vec(1usize..5000, 1..5),
        long in prop_oneof![Just(0usize), 0usize..200_000],
    ) {
        let p = &circle()[3];
        let valid = [
            (InputFormat::Csv, format!("{}\n", csv_fields(p)[..10].join(",")).into_bytes()),
            (InputFormat::Binary, binary::encode(&Datagram {
                seq: 1, week: binary::NO_WEEK, time: 1.0, flags: 0, pos: [45.0, 7.0, 10.0],
                vel: [0.0; 3], acc: [0.0; 3], quat: [1.0, 0.0, 0.0, 0.0], rate: [0.0; 3],
            }).to_vec()),
            (InputFormat::Mavlink, mavlink::encode(1, 5, [1.0, 0.0, 0.0, 0.0], [0.0; 3], [1, 2, 3], [0; 3])),
        ];
        for (format, good) in valid {
            // A run without a line end (or a frame start) longer than any line, up front.
            let mut bytes = vec![b'x'; long];
            for (junk, with) in &parts {
                bytes.extend_from_slice(junk);
                if *with {
                    bytes.extend_from_slice(&good);
                }
            }
            let total = bytes.len();
            let stream = Chunked { bytes, at: 0, sizes: sizes.clone(), k: 0 };
            let mut r = Receiver::from_stream(Box::new(stream), format, "fuzz");
            let mut held = 0;
            while let Some(m) = r.next_message().unwrap() {
                prop_assert!(m.bytes.len() <= longest(format), "{format:?}: {} bytes", m.bytes.len());
                held += m.bytes.len();
            }
            prop_assert!(held as u64 + r.skipped_bytes() <= total as u64, "{format:?}");
        }
    }
}

/// A record for frames.
fn record(k: usize) -> Record {
    let x = k as f64;
    Record {
        t: (k + 1) as f64 / 400.0,
        gyro: imu_emu::math::Vec3::new(0.01 * x.sin(), -0.02, 0.03),
        accel: imu_emu::math::Vec3::new(0.1, -0.2, -9.8),
        dtheta: imu_emu::math::Vec3::new(2.5e-5, -5e-5, 7.5e-5),
        dv: imu_emu::math::Vec3::new(2.5e-4, -5e-4, -0.0245),
        flags: 0,
    }
}

proptest! {
    #![proptest_config(config(800))]

    /// Every built-in protocol's stream decoder on its own frames with random bytes flipped,
    /// inserted and cut, read in random sizes: no panic, no frame longer than the protocol's
    /// longest, never more frames than the bytes could hold.
    #[test]
    fn protocol_decoders(
        flips in prop::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..30),
        cuts in prop::collection::vec((any::<prop::sample::Index>(), 0usize..40), 0..4),
        junk in prop::collection::vec(any::<u8>(), 0..200),
        chunk in 1usize..500,
    ) {
        for name in protocol::builtin_names() {
            let (_, plan) = protocol::load(name).unwrap();
            let mut bytes = junk.clone();
            // N-channel frames take no three-axis record: noise alone for them.
            if plan.channels().is_none() {
                let mut st = EncoderState::default();
                for k in 0..12 {
                    plan.encode(&record(k), 25.0, &mut st, &mut bytes);
                }
            }
            for (at, x) in &flips {
                if !bytes.is_empty() {
                    let i = at.index(bytes.len());
                    bytes[i] ^= x;
                }
            }
            for (at, n) in &cuts {
                if !bytes.is_empty() {
                    let i = at.index(bytes.len());
                    let end = (i + n).min(bytes.len());
                    bytes.drain(i..end);
                }
            }
            let mut d = StreamDecoder::new(plan.clone());
            let (mut frames, mut ok) = (0u64, true);
            let mut each = |f: &protocol::Decoded| {
                frames += 1;
                ok &= f.len <= plan.max_len();
            };
            for c in bytes.chunks(chunk) {
                d.feed(c, &mut each);
            }
            d.finish_frames(&mut each);
            prop_assert!(ok, "{name}: a frame longer than the protocol's");
            prop_assert!(
                frames * plan.shortest().max(1) as u64 <= bytes.len() as u64,
                "{name}: {frames} frames in {} bytes",
                bytes.len()
            );
            prop_assert_eq!(d.stats().frames, frames, "{}", name);
        }
    }
}

/// Values that break a TOML file in ways a user's typo might.
const TOKENS: &[&str] = &[
    "1e300",
    "-1e300",
    "nan",
    "inf",
    "-inf",
    "0",
    "-1",
    "1e-320",
    "\"\"",
    "\"x\"",
    "[]",
    "[1e300, 1e300, 1e300]",
    "[0.0]",
    "{}",
    "true",
    "18446744073709551615",
    "-9223372036854775808",
    "\"1e300 deg/h\"",
    "\"nan deg/s\"",
    "\"-5 %\"",
    "\"5 furlong\"",
    "[[1, 2], [3]]",
    "\"../../../etc/passwd\"",
];

/// Edits to a text: `(line, kind, token)` applied in order.
fn edits() -> impl Strategy<Value = Vec<(prop::sample::Index, u8, prop::sample::Index)>> {
    prop::collection::vec(
        (
            any::<prop::sample::Index>(),
            0u8..5,
            any::<prop::sample::Index>(),
        ),
        1..4,
    )
}

/// `text` with `edits` applied: a line deleted, doubled, its value replaced by a token, cut
/// in half, or a token inserted as a new line.
fn mutate(text: &str, edits: &[(prop::sample::Index, u8, prop::sample::Index)]) -> String {
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    for (at, kind, tok) in edits {
        if lines.is_empty() {
            break;
        }
        let i = at.index(lines.len());
        let token = TOKENS[tok.index(TOKENS.len())];
        match kind {
            0 => {
                lines.remove(i);
            }
            1 => lines.insert(i, lines[i].clone()),
            2 => {
                if let Some((key, _)) = lines[i].split_once('=') {
                    lines[i] = format!("{key}= {token}");
                }
            }
            3 => {
                let cut = lines[i]
                    .char_indices()
                    .nth(lines[i].chars().count() / 2)
                    .map_or(0, |c| c.0);
                lines[i].truncate(cut);
            }
            _ => lines.insert(i, format!("x{i} = {token}")),
        }
    }
    lines.join("\n")
}

/// An error and its sources, as `{:#}` prints them.
fn chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut src = e.source();
    while let Some(x) = src {
        s += &format!(": {x}");
        src = x.source();
    }
    s
}

proptest! {
    #![proptest_config(config(1000))]

    /// Scene files (every example) with typos: the simulation (or rig) builds, or the error
    /// names the file.
    #[test]
    fn scene_files(file in 0usize..5, edits in edits()) {
        let names = ["survey.toml", "rig.toml", "rig_aided.toml", "skew6-rig.toml", "survey.toml"];
        let text = std::fs::read_to_string(root().join("examples").join(names[file])).unwrap();
        let dir = tempfile::TempDir::new().unwrap();
        let path = dir.path().join("typo.toml");
        std::fs::write(&path, mutate(&text, &edits)).unwrap();
        let built = Simulation::builder().scene_file(&path).and_then(|b| {
            if b.is_rig() { b.build_rig().map(|_| ()) } else { b.build().map(|_| ()) }
        });
        if let Err(e) = built {
            let msg = chain(&e);
            prop_assert!(msg.contains("typo.toml"), "{}: {msg}", names[file]);
        }
    }

    /// Templates (every built-in, and the example with an output filter) with typos: the
    /// model loads, or the error names the file.
    #[test]
    fn template_files(file in any::<prop::sample::Index>(), edits in edits()) {
        let mut names: Vec<_> = std::fs::read_dir(root().join("templates")).unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        names.sort();
        names.push(root().join("examples/filtered.toml"));
        let src = &names[file.index(names.len())];
        let text = std::fs::read_to_string(src).unwrap();
        let path = Path::new("typo.toml");
        if let Err(e) = imu_emu::errors::template::parse(&mutate(&text, &edits), path) {
            let msg = chain(&e);
            prop_assert!(msg.contains("typo.toml"), "{}: {msg}", src.display());
        }
    }

    /// Protocol specs with typos: the plan compiles, encodes records and decodes its frames
    /// and noise without a panic, or the error names the file.
    #[test]
    fn protocol_specs(
        file in any::<prop::sample::Index>(),
        edits in edits(),
        noise in prop::collection::vec(any::<u8>(), 0..300),
    ) {
        let mut names: Vec<_> = std::fs::read_dir(root().join("protocols")).unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        names.sort();
        let src = &names[file.index(names.len())];
        let text = std::fs::read_to_string(src).unwrap();
        let path = Path::new("typo.toml");
        match imu_emu::protocol::load::compile_text(&mutate(&text, &edits), path) {
            Ok((_, plan)) => {
                let mut bytes = Vec::new();
                if plan.channels().is_none() {
                    let mut st = EncoderState::default();
                    for k in 0..3 {
                        plan.encode(&record(k), 25.0, &mut st, &mut bytes);
                    }
                }
                bytes.extend_from_slice(&noise);
                let mut d = StreamDecoder::new(plan);
                d.feed(&bytes, |_| ());
                d.finish_frames(|_| ());
            }
            Err(e) => {
                let msg = chain(&e);
                prop_assert!(msg.contains("typo.toml"), "{}: {msg}", src.display());
            }
        }
    }

    /// Motion definitions (the native mission and the waypoints) with typos: the motion is
    /// defined and finite at its start, middle and end, or the error names the file.
    #[test]
    fn motion_definitions(file in 0usize..2, edits in edits()) {
        let names = ["mission.toml", "waypoints.toml"];
        let text = std::fs::read_to_string(root().join("examples").join(names[file])).unwrap();
        let path = Path::new("typo.toml");
        match imu_emu::motiondef::native::parse(&mutate(&text, &edits), path) {
            Ok(m) => {
                for t in [m.start(), 0.5 * (m.start() + m.end()), m.end()] {
                    let p = m.pose(t);
                    prop_assert!(
                        [p.lat, p.lon, p.h].iter().all(|x| x.is_finite()) && all_finite(&p.v_n),
                        "{}: pose at {t}: {p:?}",
                        names[file]
                    );
                }
            }
            Err(e) => {
                let msg = chain(&e);
                prop_assert!(msg.contains("typo.toml"), "{}: {msg}", names[file]);
            }
        }
    }
}

/// Time tags a hostile or broken sender puts on its states: a clock in µs or ns read as
/// seconds, GPS or Unix times among simulation seconds, tiny and huge offsets, NaN, ±∞.
fn nasty_time() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(1e9),
        Just(-1e9),
        Just(1.4e9),
        Just(1e-9),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(3.0e5),
        -10.0..10.0f64,
        0.0..1e6f64,
        any::<f64>(),
    ]
}

proptest! {
    #![proptest_config(config(200))]

    /// A lockstep run (issue 38) fed the circle's states at 100 Hz with some time tags
    /// replaced by [`nasty_time`] ones, some states repeated (bursts) and some swapped
    /// (reorders), as CSV lines on a stream: it ends, every record is finite and within what
    /// the circle can give (its specific force about 10 m/s², its rate 0.1 rad/s; bounds ten
    /// times that, far below the 1e80 m/s² one stray tag once made), and it writes no record
    /// past the newest sound state's time plus one step it may bridge (1 s at 100 Hz): the
    /// work, and the memory, are the input's, whatever the tags.
    #[test]
    fn lockstep_time_tags_from_anywhere(
        tags in prop::collection::vec((0..60usize, nasty_time()), 0..5),
        repeats in prop::collection::vec(0..60usize, 0..4),
        swaps in prop::collection::vec((0..60usize, 0..60usize), 0..3),
    ) {
        let poses = circle();
        let mut lines: Vec<Vec<String>> = poses.iter().map(csv_fields).collect();
        for &(k, t) in &tags {
            lines[k][0] = format!("{t:e}");
        }
        for &(a, b) in &swaps {
            lines.swap(a, b);
        }
        for &k in repeats.iter().rev() {
            let l = lines[k].clone();
            lines.insert(k, l);
        }
        let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw,wx,wy,wz,an,ae,ad\n");
        for l in &lines {
            text.push_str(&l.join(","));
            text.push('\n');
        }
        let mut rx = Receiver::from_stream(
            Box::new(std::io::Cursor::new(text.into_bytes())),
            InputFormat::Csv,
            "stream",
        );
        let rate = 100.0;
        let b = Simulation::builder().rate(rate).imu("ideal").format("csv");
        let run = imu_emu::run::lockstep::Lockstep::new(b, InputFormat::Csv).unwrap();
        let mut out = Vec::new();
        let Ok(s) = run.run(&mut rx, &mut out, None, |_| ()) else {
            // Too few sound states to start: nothing written.
            prop_assert!(out.is_empty());
            return Ok(());
        };
        let text = String::from_utf8(out).unwrap();
        let mut n = 0u64;
        for line in text.lines().filter(|l| l.starts_with(|c: char| c.is_ascii_digit() || c == '-')) {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            prop_assert!(v.iter().all(|x| x.is_finite()), "{line}");
            // t, ω (rad/s), f (m/s²), then the increments.
            let w = (v[1] * v[1] + v[2] * v[2] + v[3] * v[3]).sqrt();
            let f = (v[4] * v[4] + v[5] * v[5] + v[6] * v[6]).sqrt();
            prop_assert!(w < 1.0 && f < 100.0, "{line}: {w} rad/s, {f} m/s²");
            n += 1;
        }
        prop_assert_eq!(n, s.records);
        // The newest sound state is at most 0.59 s, or one bridged step (≤ 1 s) past a tag
        // the input moved: at most 0.59 s + 1 s of bridging past the last sound tag there.
        let sound_end = poses.last().unwrap().t;
        prop_assert!(s.newest <= sound_end + 1.0 + 1e-9 || tags.iter().any(|&(_, t)| (s.newest - t).abs() < 1.0 + 1e-9),
            "newest {} s", s.newest);
        prop_assert!(s.records as f64 <= (s.newest - s.grid.t0) * rate + 1.0);
    }
}
