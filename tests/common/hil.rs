//! Helpers of the combination tests (tests/combinations.rs, tests/run_scene.rs): the binary run
//! in a directory or started in the background, a vehicle simulation's states tagged with GPS
//! time and sent over loopback UDP at their instants on the host's GPS clock, and loopback
//! receivers.
// Each test target uses only some of these.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::thread;
use std::time::{Duration, Instant};

#[path = "udp_rx.rs"]
mod udp_rx;

use imu_emu::realtime::hostclock::GpsClock;
use imu_emu::timebase::LeapTable;

/// A rig scene on the circle: `nav`, an LN-200 at 400 Hz in its frames; `tac`, an HG1700 at
/// 100 Hz as CSV, 1.2 m aft and 0.3 m below.
pub const TWO_UNITS: &str = r#"[trajectory]
scene = "circle"
[[imu]]
name = "nav"
model = "ln200"
format = "ln200"
[[imu]]
name = "tac"
model = "hg1700"
format = "csv"
rate_hz = 100.0
lever_arm_m = [-1.2, 0.0, 0.3]
"#;

/// Nanoseconds in a GPS week.
pub const WEEK_NS: i128 = 604_800_000_000_000;

/// `imu-emu ARGS` run in `dir`.
pub fn imu_emu(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run imu-emu")
}

/// The run succeeded: its stderr (else the assertion shows it).
pub fn ok(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}

/// The run failed: its stderr.
pub fn failed(out: &Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "expected a failure; stderr:\n{err}");
    err
}

/// A loopback UDP port nobody listens on now.
pub fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A run started in the background, and its stderr lines.
pub struct Started {
    child: Child,
    /// Its stderr lines up to the one saying it follows its input.
    early: Vec<String>,
    lines: mpsc::Receiver<String>,
}

/// Starts `imu-emu ARGS` in `dir` and waits until it follows its live input.
pub fn start(dir: &Path, args: &[&str]) -> Started {
    let mut child = Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = child.stderr.take().unwrap();
    let (tx, lines) = mpsc::channel();
    thread::spawn(move || {
        for l in BufReader::new(err).lines() {
            let Ok(l) = l else { break };
            if tx.send(l).is_err() {
                break;
            }
        }
    });
    let mut seen = Vec::new();
    loop {
        // A loaded machine may take long to start the emulator.
        match lines.recv_timeout(Duration::from_secs(60)) {
            Ok(l) => {
                let following = l.contains("following udp://");
                seen.push(l);
                if following {
                    break;
                }
            }
            Err(_) => panic!("the run did not start:\n{}", seen.join("\n")),
        }
    }
    Started {
        child,
        early: seen,
        lines,
    }
}

impl Started {
    /// Waits for the run to end successfully: its stderr.
    pub fn finish(self) -> String {
        let out = self.child.wait_with_output().unwrap();
        let err: Vec<String> = self.early.into_iter().chain(self.lines.iter()).collect();
        let err = err.join("\n");
        assert!(out.status.success(), "{err}");
        err
    }
}

/// The survey scene's states every 10 ms over `seconds` from its start: the rows of
/// `imu-emu trajectory` after their time column (`lat,lon,h,vn,ve,vd,roll,pitch,yaw`).
pub fn survey_rows(dir: &Path, seconds: f64) -> Vec<String> {
    let out = imu_emu(
        dir,
        &[
            "trajectory",
            "--scene",
            "survey",
            "--rate",
            "100",
            "--duration",
            &seconds.to_string(),
        ],
    );
    ok(&out);
    let text = String::from_utf8(out.stdout).unwrap();
    let mut rows = text.lines().filter(|l| !l.starts_with('#'));
    assert_eq!(rows.next(), Some("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw"));
    rows.map(|r| r.split_once(',').unwrap().1.to_string())
        .collect()
}

/// States tagged with GPS time, 10 ms apart.
pub struct Tagged {
    /// The GPS week of every tag.
    pub week: u32,
    /// GPS time of the first state (ns since the GPS epoch).
    pub first_ns: i128,
    /// The states after their time (`lat,…,yaw`).
    pub rows: Vec<String>,
}

impl Tagged {
    /// `rows` tagged from the first whole 10 ms at least `lead_s` after the host's GPS time
    /// now, in one GPS week.
    pub fn from_now(rows: Vec<String>, lead_s: f64) -> Tagged {
        let now = GpsClock::new(LeapTable::builtin()).now_gps_ns();
        let mut first_ns = (now + (lead_s * 1e9) as i128) / 10_000_000 * 10_000_000 + 10_000_000;
        let span = rows.len() as i128 * 10_000_000;
        if first_ns.div_euclid(WEEK_NS) != (first_ns + span).div_euclid(WEEK_NS) {
            // Not across a week's end: start with the next week.
            first_ns = (first_ns + span).div_euclid(WEEK_NS) * WEEK_NS;
        }
        Tagged {
            week: first_ns.div_euclid(WEEK_NS) as u32,
            first_ns,
            rows,
        }
    }

    /// GPS time of state `i` (ns since the GPS epoch).
    pub fn tag_ns(&self, i: usize) -> i128 {
        self.first_ns + i as i128 * 10_000_000
    }

    /// Seconds of the week of the newest state, as the run reads it.
    pub fn newest_sow(&self) -> f64 {
        self.sow(self.rows.len() - 1).parse().unwrap()
    }

    /// Seconds of the week of state `i`, as the states' text writes it (exact to 10 ms).
    pub fn sow(&self, i: usize) -> String {
        let ns = self.tag_ns(i) - self.week as i128 * WEEK_NS;
        format!(
            "{}.{:02}",
            ns / 1_000_000_000,
            ns % 1_000_000_000 / 10_000_000
        )
    }

    /// The states as GPS-tagged CSV lines (docs/live-input.md), header first.
    pub fn csv(&self) -> Vec<String> {
        let mut out = vec!["gps_week,gps_sow,lat,lon,h,vn,ve,vd,roll,pitch,yaw".to_string()];
        for (i, r) in self.rows.iter().enumerate() {
            out.push(format!("{},{},{r}", self.week, self.sow(i)));
        }
        out
    }

    /// The same states as a trajectory file whose time column is the seconds of the week.
    pub fn trajectory(&self, path: &Path) {
        let mut text = String::from("t,lat,lon,h,vn,ve,vd,roll,pitch,yaw\n");
        for (i, r) in self.rows.iter().enumerate() {
            text += &format!("{},{r}\n", self.sow(i));
        }
        std::fs::write(path, text).unwrap();
    }

    /// Sends the header, then each state when the host's GPS clock reaches its tag, as CSV
    /// datagrams to `port` on loopback.
    pub fn send(&self, port: u16) {
        self.send_ahead(port, 0);
    }

    /// [`Tagged::send`], each state `ahead_ns` before its tag (a simulator running ahead).
    pub fn send_ahead(&self, port: u16, ahead_ns: i128) {
        let s = UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = ("127.0.0.1", port);
        let (g0, i0) = gps_now();
        let lines = self.csv();
        s.send_to(lines[0].as_bytes(), to).unwrap();
        for (i, l) in lines[1..].iter().enumerate() {
            sleep_to(i0, g0, self.tag_ns(i) - ahead_ns);
            s.send_to(l.as_bytes(), to).unwrap();
        }
    }
}

/// The host's GPS time now (ns) and the same instant on the monotonic clock: later GPS
/// instants are `Instant`s from them.
pub fn gps_now() -> (i128, Instant) {
    (
        GpsClock::new(LeapTable::builtin()).now_gps_ns(),
        Instant::now(),
    )
}

/// GPS time (ns since the GPS epoch) of a UTC instant (ns since the Unix epoch).
pub fn gps_of_utc(utc_ns: i128) -> i128 {
    LeapTable::builtin().utc_to_gps_ns(utc_ns)
}

/// Sleeps until GPS time `at_ns`, with (`g0`, `i0`) from [`gps_now`].
pub fn sleep_to(i0: Instant, g0: i128, at_ns: i128) {
    let at = i0 + Duration::from_nanos((at_ns - g0).max(0) as u64);
    if let Some(d) = at.checked_duration_since(Instant::now()) {
        thread::sleep(d);
    }
}

/// Datagrams, each with the host's GPS time of its arrival (ns).
pub type Datagrams = Vec<(i128, Vec<u8>)>;

/// A loopback UDP receiver ([`udp_rx::UdpRx`]: kernel arrival stamps, a large buffer): its
/// address, and a handle whose `join`, called once the sender has exited, gives every datagram
/// with the host's GPS time of its arrival (ns).
pub fn receive() -> (String, Receiving) {
    let rx = udp_rx::UdpRx::start();
    (rx.dest.clone(), Receiving(rx))
}

/// A receiver started by [`receive`].
pub struct Receiving(udp_rx::UdpRx);

impl Receiving {
    /// Everything received, with GPS arrival times (call once the sender has exited).
    pub fn join(self) -> thread::Result<Datagrams> {
        let leaps = LeapTable::builtin();
        Ok((self.0.stop().into_iter())
            .map(|(utc, b)| (leaps.utc_to_gps_ns(utc), b))
            .collect())
    }
}

/// The datagrams' bytes back to back.
pub fn joined(d: &[(i128, Vec<u8>)]) -> Vec<u8> {
    d.iter().flat_map(|x| x.1.iter().copied()).collect()
}

/// The number right after `key` in `text` (`"from t = "` in a summary).
pub fn number_after(text: &str, key: &str) -> f64 {
    let i = text
        .find(key)
        .unwrap_or_else(|| panic!("`{key}` in {text}"))
        + key.len();
    let word: String = text[i..]
        .chars()
        .take_while(|c| c.is_ascii_digit() || ".e-+".contains(*c))
        .collect();
    word.parse()
        .unwrap_or_else(|_| panic!("a number after `{key}` in {text}"))
}

/// The number right before `key` in `text` (`"records at"` in a summary).
pub fn number_before(text: &str, key: &str) -> f64 {
    let i = text
        .find(key)
        .unwrap_or_else(|| panic!("`{key}` in {text}"));
    let word = text[..i].trim_end().rsplit([' ', '(']).next().unwrap();
    word.parse()
        .unwrap_or_else(|_| panic!("a number before `{key}` in {text}"))
}

/// A time-mark CSV file's rows: index, ToV after t₀ (ns), ToV, due and emission instants
/// (UTC ns).
pub fn marks(path: &Path) -> Vec<[i128; 5]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(imu_emu::realtime::timemark::CSV_HEADER));
    lines
        .map(|l| {
            let v: Vec<i128> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4]]
        })
        .collect()
}
