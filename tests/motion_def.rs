//! Motion definitions (`imu_emu::motiondef`): gnss-ins-sim's motion-definition format read as
//! it is, each command type against its closed form on files of this repository's own (written
//! below), continuity of the sensed signal at every piece boundary, bad files refused with
//! file, line and column; and gnss-ins-sim's own demo files navigated closed when the public
//! data sets are at hand (tests/common/public_data.rs).

use std::path::{Path, PathBuf};

use imu_emu::earth;
use imu_emu::engine;
use imu_emu::motion::Motion;
use imu_emu::motiondef::{self, DefinedMotion};
use imu_emu::nav::{Settings, close};
use imu_emu::source::AnyMotion;

#[path = "common/public_data.rs"]
mod public_data;

/// The first header line of the format (the start state's columns).
const H1: &str = "ini lat (deg),ini lon (deg),ini alt (m),ini vx_body (m/s),ini vy_body (m/s),ini vz_body (m/s),ini yaw (deg),ini pitch (deg),ini roll (deg)";
/// The second header line (the commands' columns, GNSS visibility last).
const H2: &str = "command type,yaw (deg),pitch (deg),roll (deg),vx_body (m/s),vy_body (m/s),vz_body (m/s),command duration (s),GPS visibility";

/// A file of the format: the start state (lat, lon, h, body velocity, yaw, pitch, roll), then
/// the commands, one line each.
fn file_text(start: &str, commands: &[&str]) -> String {
    let mut t = format!("{H1}\n{start}\n{H2}\n");
    for c in commands {
        t.push_str(c);
        t.push('\n');
    }
    t
}

/// A 90° turn at 10 m/s heading east: 1 s straight, −15°/s for 6 s, 3 s straight.
fn turn_text() -> String {
    file_text(
        "41.27,1.98,0,10,0,0,90,0,0",
        &[
            "1,0,0,0,0,0,0,1,1",
            "1,-15,0,0,0,0,0,6,1",
            "1,0,0,0,0,0,0,3,1",
        ],
    )
}

/// Forward body acceleration of 10 m/s² for 10 s from rest.
fn accel_text() -> String {
    file_text("41.27,1.98,0,0,0,0,0,0,0", &["1,0,0,0,10,0,0,10,1"])
}

/// Targets of type 2 (absolute) from rest: 10 s at rest, forward to 10 m/s, back to rest,
/// sideways to 10 m/s (body y), back to rest, each given 20 s.
fn targets_text() -> String {
    file_text(
        "41.27,1.98,0,0,0,0,0,0,0",
        &[
            "1,0,0,0,0,0,0,10,1",
            "2,0,0,0,10,0,0,20,1",
            "2,0,0,0,0,0,0,20,1",
            "2,0,0,0,0,10,0,20,1",
            "2,0,0,0,0,0,0,20,1",
        ],
    )
}

/// Types 5 and 3: at rest 10 s, climb at 45° and 10 m/s (type 5: pitch relative, speed
/// absolute), level off turning +90° (type 3: both relative), fly on.
fn climb_text() -> String {
    file_text(
        "41.27,1.98,0,0,0,0,0,0,0",
        &[
            "1,0,0,0,0,0,0,10,1",
            "5,0,45,0,10,0,0,250,1",
            "1,0,0,0,0,0,0,10,1",
            "3,90,-45,0,0,0,0,25,1",
            "1,0,0,0,0,0,0,50,1",
        ],
    )
}

/// A drive with an outage: GNSS is lost for the third and fourth commands (lines 6 and 7).
fn outage_text() -> String {
    file_text(
        "41.27,1.98,0,0,0,0,0,0,0",
        &[
            "1,0,0,0,0,0,0,20,1",
            "5,0,0,0,10,0,0,15,1",
            "1,0,0,0,0,0,0,30,0",
            "3,90,0,0,0,0,0,15,0",
            "1,0,0,0,0,0,0,30,1",
            "5,0,0,0,0,0,0,15,1",
        ],
    )
}

/// A long drive of the repository's own: 24 blocks of setting off, a turn left or right, a
/// straight, a change of speed and a stop, every command type of a road trip (1, 2, 3, 5).
fn drive_text() -> String {
    let mut c: Vec<String> = vec!["1,0,0,0,0,0,0,10,1".into()];
    for i in 0..24 {
        let turn = if i % 3 == 2 { -90 } else { 90 };
        let speed = 8 + (i % 5) * 3;
        c.push(format!("5,0,0,0,{speed},0,0,15,1"));
        c.push(format!("3,{turn},0,0,0,0,0,12,1"));
        c.push(format!("1,0,0,0,0,0,0,{},1", 5 + i % 4));
        c.push(format!("2,{},0,0,{},0,0,10,1", 0, speed / 2));
        c.push("1,0,0,0,-0.5,0,0,4,1".into());
        c.push("5,0,0,0,0,0,0,15,1".into());
    }
    let c: Vec<&str> = c.iter().map(String::as_str).collect();
    file_text("41.27,1.98,120,0,0,0,30,0,0", &c)
}

/// Writes `text` to a file of the scratch folder `dir` named `name` and returns its path.
fn written(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The motion of a file of the format whose text is `text`.
fn load_text(text: &str) -> DefinedMotion {
    let dir = tempfile::tempdir().unwrap();
    let p = written(dir.path(), "m.csv", text);
    motiondef::open(&p).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Every demo file of gnss-ins-sim runs, and the reference navigator fed its error-free
/// records at 100 Hz closes the whole trip within 1 mm (the bound); on its two road
/// demos the sensed signal is continuous at every boundary, as on [`drive_text`].
#[test]
fn every_gnss_ins_sim_demo_closes_within_a_millimetre() {
    let Some(dir) = public_data::set(
        "gnss-ins-sim",
        "every_gnss_ins_sim_demo_closes_within_a_millimetre",
    ) else {
        return;
    };
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".csv"))
        .collect();
    names.sort();
    assert_eq!(names.len(), 11, "{names:?}");
    let load = |name: &str| motiondef::open(&dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
    for name in names {
        let m = AnyMotion::Defined(load(&name));
        let grid = engine::plan(&m, 100.0, None, None).unwrap();
        let c = close(&m, &grid, Settings::default(), None, 100).unwrap();
        println!(
            "{name:>40}: {:>7.1} s, position {:.2e} m (max {:.2e}), velocity max {:.2e} m/s, attitude max {:.2e} rad",
            grid.count as f64 / 100.0,
            c.last.pos_ned.norm(),
            c.max_pos,
            c.max_vel,
            c.max_att
        );
        assert!(c.max_pos <= 1e-3, "{name}: {:.3e} m", c.max_pos);
    }
    for name in ["motion_def-long_drive.csv", "motion_def-Holland_tunnel.csv"] {
        continuous(name, &load(name));
    }
    // The tunnel demo loses GNSS in the tunnel (its command on line 35).
    let m = load("motion_def-Holland_tunnel.csv");
    let s = m.segments();
    assert!(s[0].gnss_visible && !s[31].gnss_visible && s[42].gnss_visible);
    assert_eq!(s[31].line, 35);
}

/// North distance (m) between two latitudes at height h: ∫R_N dφ by Simpson's rule on 64
/// panels (exact to ~1e-16 relative over the few arc-seconds of these tests).
fn meridian_arc(lat0: f64, lat1: f64, h: f64) -> f64 {
    let n = 64;
    let step = (lat1 - lat0) / n as f64;
    let f = |k: usize| earth::radius_meridian((lat0 + k as f64 * step).sin()) + h;
    let mut s = f(0) + f(n);
    for k in 1..n {
        s += if k % 2 == 1 { 4.0 } else { 2.0 } * f(k);
    }
    s * step / 3.0
}

/// Type 1, body acceleration: [`accel_text`] holds 10 m/s² for 10 s; after the 0.5 s blend the speed
/// is 2.5 + 10(t − 0.5) m/s (the blend gains half the new acceleration times its length), and
/// the distance run between t = 1 s and 10 s is ∫(10t − 2.5)dt = 472.5 m.
#[test]
fn type_1_acceleration_against_its_closed_form() {
    let m = load_text(&accel_text());
    for t in [0.5, 1.0, 3.3, 7.77, 9.999] {
        let p = m.pose(t);
        let v = 10.0 * t - 2.5;
        assert!((p.v_n[0] - v).abs() < 1e-11, "t {t}: {} vs {v}", p.v_n[0]);
        assert!(p.v_n[1].abs() < 1e-12 && p.v_n[2].abs() < 1e-12);
    }
    let (a, b) = (m.pose(1.0), m.pose(10.0));
    let d = meridian_arc(a.lat, b.lat, 0.0);
    // A pose's latitude is an f64 near 0.56 rad, held to 1.1e-16 rad = 0.7 nm: the two ends
    // bound the distance's resolution at ±1.4 nm (measured 1.7e-9 m, about 2 ulp).
    assert!((d - 472.5).abs() < 3e-9, "{d}");
}

/// Type 1, Euler-angle rate: the 90° turn at 10 m/s ([`turn_text`]). In the held part the yaw is linear,
/// 90° − 3.75° − 15°/s·(t − 1.5 s) (half the blend lost), the speed stays 10 m/s and the
/// velocity points along the yaw (no side-slip); the whole turn is −90° exactly.
#[test]
fn type_1_turn_against_its_closed_form() {
    let m = load_text(&turn_text());
    let worst = (0..=400)
        .map(|i| 1.5 + 5.5 * i as f64 / 400.0)
        .map(|t| {
            let p = m.pose(t);
            let (_, _, yaw) = imu_emu::math::euler_from_quat(p.q_b_n);
            let expect = (90.0 - 3.75 - 15.0 * (t - 1.5)).to_radians();
            assert!((yaw - expect).abs() < 1e-13, "t {t}: yaw {yaw} vs {expect}");
            let (s, c) = expect.sin_cos();
            (p.v_n[0] - 10.0 * c).abs().max((p.v_n[1] - 10.0 * s).abs())
        })
        .fold(0.0, f64::max);
    // The velocity is the knot quintic's: exact at knots, within its interpolation error
    // v·ω⁵·Δt⁶/46080 ≈ 2e-10 m/s between them (ω = 0.26 rad/s, Δt = 0.25 s).
    println!("turn: largest velocity departure {worst:.2e} m/s");
    assert!(worst < 1e-9, "{worst:e}");
    let end = m.pose(m.end());
    let (_, _, yaw) = imu_emu::math::euler_from_quat(end.q_b_n);
    assert!(yaw.abs() < 1e-14, "{yaw}");
}

/// Types 2–5: a target reached rest to rest follows the minimum-jerk step
/// v = Δv(10s³ − 15s⁴ + 6s⁵), s = τ/T, with T = 1.875Δv/a_max (18.75 s for 10 m/s at
/// 1 m/s²): [`targets_text`]'s first type-2 command, forward to 10 m/s, then its sideways one.
#[test]
fn type_2_target_against_its_closed_form() {
    let m = load_text(&targets_text());
    let segs = m.segments();
    assert_eq!(segs[1].span, (10.0, 28.75));
    for s in [0.1f64, 0.5, 0.8, 1.0] {
        let t = 10.0 + 18.75 * s;
        let v = 10.0 * (10.0 * s * s * s - 15.0 * s.powi(4) + 6.0 * s.powi(5));
        let p = m.pose(t.min(m.end()));
        assert!((p.v_n[0] - v).abs() < 1e-10, "s {s}: {} vs {v}", p.v_n[0]);
    }
    // The fourth command moves along body y (east at yaw 0) with the attitude unchanged.
    let (a, b) = segs[3].span;
    let p = m.pose(0.5 * (a + b));
    assert!(
        (p.v_n[1] - 5.0).abs() < 1e-10 && p.v_n[0].abs() < 1e-10,
        "{:?}",
        p.v_n
    );
}

/// Relative and absolute targets (types 3 and 5): [`climb_text`] climbs at 45° (type 5,
/// pitch +45° relative, 10 m/s absolute), then turns +90° and pitches −45° (type 3).
#[test]
fn types_3_and_5_reach_their_targets() {
    let m = load_text(&climb_text());
    let s = m.segments();
    let after = |i: usize| {
        let p = m.pose(s[i].span.1);
        let (r, pt, y) = imu_emu::math::euler_from_quat(p.q_b_n);
        (r.to_degrees(), pt.to_degrees(), y.to_degrees(), p.v_n)
    };
    let (_, pitch, _, v) = after(1);
    assert!((pitch - 45.0).abs() < 1e-10, "{pitch}");
    let h = std::f64::consts::FRAC_1_SQRT_2 * 10.0;
    assert!((v[0] - h).abs() < 1e-9 && (v[2] + h).abs() < 1e-9, "{v:?}");
    let (_, pitch, yaw, v) = after(3);
    assert!(
        pitch.abs() < 1e-10 && (yaw - 90.0).abs() < 1e-10,
        "{pitch} {yaw}"
    );
    assert!((v[1] - 10.0).abs() < 1e-9, "{v:?}");
}

/// Angular rate and specific force have no jump at any piece boundary (knots, blends,
/// command changes) of a long drive ([`drive_text`]): the left piece's value at the boundary
/// against the right one's.
#[test]
fn sensed_signal_is_continuous_at_every_boundary() {
    continuous("drive", &load_text(&drive_text()));
}

/// The number of piece boundaries of `m` and the largest jump of ω (rad/s) and f (m/s²) at
/// them: the left piece's value at the boundary against the right one's.
fn jumps(m: &DefinedMotion) -> (usize, f64, f64) {
    let (mut dw, mut df, mut n) = (0.0f64, 0.0f64, 0);
    while m.piece_end(n).is_finite() {
        let t = m.piece_end(n);
        let (a, b) = (m.sense(n, t), m.sense(n + 1, t));
        dw = dw.max((a.omega_ib_b - b.omega_ib_b).amax());
        df = df.max((a.f_b - b.f_b).amax());
        n += 1;
    }
    (n, dw, df)
}

/// The sensed signal of `m` has no jump at any of its (over 1000) piece boundaries.
fn continuous(name: &str, m: &DefinedMotion) {
    let (n, dw, df) = jumps(m);
    println!("{name}: {n} boundaries, largest jump ω {dw:.2e} rad/s, f {df:.2e} m/s²");
    assert!(n > 1000, "{name}: {n} boundaries");
    assert!(dw < 1e-12 && df < 1e-9, "{name}: {dw:e} {df:e}");
}

/// GNSS visibility is kept per command: [`outage_text`] loses GNSS for its third and fourth
/// commands.
#[test]
fn gnss_visibility_is_kept_per_segment() {
    let m = load_text(&outage_text());
    let s = m.segments();
    assert_eq!(s.len(), 6);
    assert!(s[1].gnss_visible && !s[2].gnss_visible && !s[3].gnss_visible && s[4].gnss_visible);
    assert_eq!((s[2].line, s[3].line), (6, 7));
    let mid = 0.5 * (s[2].span.0 + s[2].span.1);
    assert!(!m.gnss_visible(mid) && m.gnss_visible(1.0));
    assert!(m.gnss_visible(0.5 * (s[4].span.0 + s[4].span.1)));
}

fn refused(text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("imu-emu-motiondef-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(format!("bad-{}.csv", text.len()));
    std::fs::write(&p, text).unwrap();
    let e = motiondef::open(&p).map(|_| ()).unwrap_err().to_string();
    std::fs::remove_file(&p).unwrap();
    e
}

#[test]
fn bad_files_are_refused_with_line_and_column() {
    let e = refused(&format!(
        "{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n7,0,0,0,0,0,0,1,0\n"
    ));
    assert!(
        e.contains(":4: column 1 (`command type`)") && e.contains("1 to 5"),
        "{e}"
    );
    let e = refused(&format!(
        "{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,0,x,0,0,0,0,1,0\n"
    ));
    assert!(e.contains(":4: column 3 (`pitch`)"), "{e}");
    let e = refused(&format!(
        "{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,-1,0\n"
    ));
    assert!(e.contains(":4: column 8 (`command duration`)"), "{e}");
    let e = refused(&format!(
        "{H1}\n95,120,0,0,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,1,0\n"
    ));
    assert!(e.contains(":2: column 1 (`ini lat`)"), "{e}");
    let e = refused("32,120,0,0,0,0,0,0,0\n");
    assert!(e.contains(":1:") && e.contains("header"), "{e}");
    let e = refused(&format!("{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n"));
    assert!(e.contains("no command takes any time"), "{e}");
    let e = refused(&format!(
        "{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,1\n1,2\n"
    ));
    assert!(e.contains(":5:") && e.contains("2 columns"), "{e}");
    let e = refused(&format!(
        "{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,1e9,0,0,0,0,0,1,0\n"
    ));
    assert!(
        e.contains(":4: column 2 (`yaw`)") && e.contains("limits"),
        "{e}"
    );
}

fn native(text: &str) -> Result<DefinedMotion, String> {
    motiondef::native::parse(text, Path::new("m.toml")).map_err(|e| e.to_string())
}

fn mission() -> DefinedMotion {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/mission.toml");
    motiondef::open(&p).unwrap()
}

/// The native example mission (take-off roll, climb, turns, figure-eight, a 360° roll,
/// descent; 740 s) closes within 1 mm, and its sensed signal is continuous at every boundary.
#[test]
fn native_mission_closes_and_is_continuous() {
    let m = mission();
    let (i, dw, df) = jumps(&m);
    println!("mission: {i} boundaries, largest jump ω {dw:.2e} rad/s, f {df:.2e} m/s²");
    assert!(dw < 1e-12 && df < 1e-9, "{dw:e} {df:e}");
    let m = AnyMotion::Defined(m);
    let grid = engine::plan(&m, 200.0, None, None).unwrap();
    let c = close(&m, &grid, Settings::default(), None, 100).unwrap();
    println!(
        "mission: {} s, position {:.2e} m (max {:.2e}), velocity max {:.2e} m/s",
        grid.count as f64 / 200.0,
        c.last.pos_ned.norm(),
        c.max_pos,
        c.max_vel
    );
    assert!(c.max_pos <= 1e-3, "{:.3e} m", c.max_pos);
}

/// A coordinated turn at 3°/s and 50 m/s: bank atan(V·ψ̇/g), the yaw linear in the held part
/// and the whole turn exactly 90°; a climb ends exactly at its height.
#[test]
fn native_turn_and_climb_against_their_closed_forms() {
    let m = native(
        "[motion]\nstart = { lat_deg = 45, h_m = 100, speed_m_s = 50 }\n\
         segments = [{ turn_deg = 90, rate_deg_s = 3 }, { climb_to_m = 400, rate_m_s = 5 }]\n",
    )
    .unwrap();
    let g = earth::normal_gravity(45f64.to_radians().sin(), 100.0);
    let r = 3f64.to_radians();
    let bank = (50.0 * r / g).atan();
    let (t0, t1) = m.segments()[0].span;
    // Roll-in time: the bank's minimum-jerk move within 60°/s and 60°/s², or 0.5 s.
    let t_in = (1.875 * bank / 60f64.to_radians())
        .max((5.7735 * bank / 60f64.to_radians()).sqrt())
        .max(0.5);
    for s in [0.1, 0.5, 0.9] {
        let t = t0 + t_in + s * (t1 - t0 - 2.0 * t_in);
        let (roll, _, yaw) = imu_emu::math::euler_from_quat(m.pose(t).q_b_n);
        assert!((roll - bank).abs() < 1e-13, "{roll} {bank}");
        assert!(
            (yaw - r * (t - t0 - 0.5 * t_in)).abs() < 1e-12,
            "t {t}: {yaw}"
        );
    }
    let end = m.pose(t1);
    let (roll, _, yaw) = imu_emu::math::euler_from_quat(end.q_b_n);
    assert!((yaw - 90f64.to_radians()).abs() < 1e-13 && roll.abs() < 1e-15);
    let h = m.pose(m.end()).h;
    assert!((h - 400.0).abs() < 1e-8, "{h}");
}

/// Limits are refused naming the segment and its line; so are unknown keys and segments that
/// give two kinds or none.
#[test]
fn native_limits_and_mistakes_are_refused() {
    let start = "[motion]\nstart = { speed_m_s = 50 }\nlimits = { max_bank_deg = 30 }\n";
    let e = native(&format!(
        "{start}segments = [\n {{ hold_s = 1 }},\n {{ turn_deg = 90, bank_deg = 40 }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.starts_with("m.toml:6: `motion.segments[1]`: bank 40° is beyond max_bank_deg = 30°"),
        "{e}"
    );
    let e = native(&format!(
        "{start}segments = [{{ turn_deg = 90, rate_deg_s = 30 }}]\n"
    ))
    .unwrap_err();
    assert!(e.contains("segments[0]") && e.contains("bank"), "{e}");
    let e = native(&format!(
        "{start}segments = [{{ turn_deg = 2, rate_deg_s = 3 }}]\n"
    ))
    .unwrap_err();
    assert!(e.contains("shorter than its roll-in"), "{e}");
    let e = native(&format!(
        "{start}segments = [{{ roll_deg = 360, duration_s = 1 }}]\n"
    ))
    .unwrap_err();
    assert!(e.contains("beyond max_rate_deg_s"), "{e}");
    let e = native(&format!(
        "{start}segments = [{{ climb_to_m = 10, rate_m_s = 60 }}]\n"
    ))
    .unwrap_err();
    assert!(e.contains("rate_m_s"), "{e}");
    let e = native(&format!(
        "{start}segments = [{{ hold_s = 1, turn_deg = 3 }}]\n"
    ))
    .unwrap_err();
    assert!(e.contains("exactly one"), "{e}");
    let e = native(&format!("{start}segments = [\n{{ hold = 1 }}]\n")).unwrap_err();
    assert!(e.starts_with("m.toml:5:") && e.contains("hold"), "{e}");
    let e =
        native("[motion]\nstart = { lat_deg = 91 }\nsegments = [{ hold_s = 1 }]\n").unwrap_err();
    assert!(e.contains("motion.start.lat_deg"), "{e}");
    let e = native("[imu]\nrate_hz = 1\n").unwrap_err();
    assert!(e.contains("no `[motion]` table"), "{e}");
}

fn bin(args: &[&str], cwd: &Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_imu-emu"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("imu-emu-md-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The command line: `trajectory` and `generate` take `--motion-def`; a scene file takes
/// `trajectory.motion_def` (relative to itself) or an embedded `[motion]` table; a bad file
/// fails with its line and leaves no output behind.
#[test]
fn command_line_and_scene_files() {
    let dir = scratch("cli");
    let turn = written(&dir, "the-turn.csv", &turn_text());
    let turn = turn.to_str().unwrap();
    let out = bin(
        &[
            "trajectory",
            "--motion-def",
            turn,
            "--rate",
            "10",
            "-o",
            "t.csv",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.join("t.csv")).unwrap();
    assert_eq!(
        text.lines().filter(|l| !l.starts_with('#')).count(),
        1 + 101
    );
    let out = bin(
        &[
            "generate",
            "--motion-def",
            turn,
            "--rate",
            "100",
            "-o",
            "g.csv",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::copy(turn, dir.join("turn.csv")).unwrap();
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    std::fs::write(
        dir.join("sub/scene.toml"),
        "[trajectory]\nmotion_def = \"../turn.csv\"\n[output]\nduration_s = 2\n",
    )
    .unwrap();
    let out = bin(
        &["generate", "sub/scene.toml", "--rate", "10", "-o", "s.csv"],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(
        dir.join("embedded.toml"),
        "[imu]\nrate_hz = 50\n[motion]\nstart = { speed_m_s = 20 }\nsegments = [{ turn_deg = 45, rate_deg_s = 5 }]\n",
    )
    .unwrap();
    let out = bin(&["generate", "embedded.toml", "-o", "e.csv"], &dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    std::fs::write(
        dir.join("bad.csv"),
        format!("{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,1,0\n9,0,0,0,0,0,0,1,0\n"),
    )
    .unwrap();
    let out = bin(
        &["generate", "--motion-def", "bad.csv", "-o", "b.csv"],
        &dir,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.csv:5: column 1"),
        "{err}"
    );
    assert!(!dir.join("b.csv").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// After the example mission's 360° roll (roll = 2π), its next turn banks from wings level
/// instead of rolling back a full turn: |roll| never exceeds the turn's bank.
#[test]
fn a_turn_after_a_full_roll_banks_from_wings_level() {
    let m = mission();
    let (a, b) = m.segments()[12].span;
    let worst = (0..=400)
        .map(|i| {
            let (roll, _, _) =
                imu_emu::math::euler_from_quat(m.pose(a + (b - a) * i as f64 / 400.0).q_b_n);
            roll.abs()
        })
        .fold(0.0, f64::max);
    // 3°/s at 60 m/s: bank atan(60·0.0524/9.80) ≈ 17.8°.
    assert!(
        worst < 18f64.to_radians() && worst > 17f64.to_radians(),
        "{}",
        worst.to_degrees()
    );
}

/// GNSS visibility reaches the outputs: a file whose middle command (1 s to 3 s) has
/// visibility 0 gives `generate --truth` a `gnss_visible` column that is 0 at exactly the
/// records with 1 ≤ t < 3, and the GNSS stream an outage (no fix, 0 satellites) at exactly
/// the epochs in that span; a scene's truth file has no such column.
#[test]
fn gnss_visibility_in_truth_and_gnss_outages() {
    let dir = scratch("vis");
    std::fs::write(
        dir.join("vis.csv"),
        format!(
            "{H1}\n32,120,0,10,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,1,1\n1,0,0,0,0,0,0,2,0\n1,0,0,0,0,0,0,1,1\n"
        ),
    )
    .unwrap();
    let m = motiondef::open(&dir.join("vis.csv")).unwrap();
    assert_eq!(m.gnss_outages(), vec![[1.0, 3.0]]);
    let out = bin(
        &[
            "generate",
            "--motion-def",
            "vis.csv",
            "--rate",
            "10",
            "-o",
            "imu.csv",
            "--truth",
            "truth.csv",
            "--gnss",
            "nmea:g.nmea",
            "--gnss-truth",
            "g.csv",
        ],
        &dir,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let truth = std::fs::read_to_string(dir.join("truth.csv")).unwrap();
    let mut lines = truth.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t,gyro_x,gyro_y,gyro_z,accel_x,accel_y,accel_z,dtheta_x,dtheta_y,dtheta_z,dv_x,dv_y,dv_z,gnss_visible"
    );
    let mut rows = 0;
    for l in lines {
        let c: Vec<&str> = l.split(',').collect();
        assert_eq!(c.len(), 14, "{l}");
        let t: f64 = c[0].parse().unwrap();
        let want = if (1.0..3.0).contains(&t) { "0" } else { "1" };
        assert_eq!(c[13], want, "t = {t}");
        rows += 1;
    }
    assert_eq!(rows, 40);
    let gnss = std::fs::read_to_string(dir.join("g.csv")).unwrap();
    let mut epochs = 0;
    for l in gnss.lines().skip(1) {
        let c: Vec<&str> = l.split(',').collect();
        let t: f64 = c[1].parse().unwrap();
        let outage = (1.0..3.0).contains(&t);
        assert_eq!(c[4] == "0", outage, "t = {t}: {l}");
        epochs += 1;
    }
    assert_eq!(epochs, 21);
    // Without a motion definition the truth file keeps the record's columns only.
    let out = bin(
        &[
            "generate",
            "--scene",
            "static",
            "--duration",
            "1",
            "--rate",
            "10",
            "-o",
            "s.csv",
            "--truth",
            "st.csv",
        ],
        &dir,
    );
    assert!(out.status.success());
    let st = std::fs::read_to_string(dir.join("st.csv")).unwrap();
    assert!(st.starts_with("t,gyro_x,") && st.lines().next().unwrap().ends_with(",dv_z"));
    std::fs::remove_dir_all(&dir).unwrap();
}

fn waypoints() -> DefinedMotion {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/waypoints.toml");
    motiondef::open(&p).unwrap()
}

/// NED offset (m) of a pose from a geodetic origin, through ECEF (independent of the
/// waypoint code's conversion, which goes the other way).
fn ned_offset(origin: [f64; 3], p: &imu_emu::motion::Pose) -> [f64; 3] {
    use imu_emu::earth::Geodetic;
    let o = Geodetic::from_radians(origin[0], origin[1], origin[2]);
    let d = Geodetic::from_radians(p.lat, p.lon, p.h).to_ecef() - o.to_ecef();
    let (sp, cp, sl, cl) = (o.sin_lat, o.cos_lat, o.sin_lon, o.cos_lon);
    [
        -sp * cl * d[0] - sp * sl * d[1] + cp * d[2],
        -sl * d[0] + cl * d[1],
        -cp * cl * d[0] - cp * sl * d[1] - sp * d[2],
    ]
}

/// The example waypoint path is at every waypoint at its time (NED offsets through ECEF to
/// 1e-8 m: ECEF coordinates of 6.4e6 m carry 1e-9 m of round-off; lat/lon/h to an ulp), has
/// the velocity given where one is, heads along its velocity with the roll at 0, joins without
/// a jump of ω or f at any knot, and the reference navigator closes it within 1 mm.
#[test]
fn waypoints_pass_their_points_continuously_and_close() {
    let m = waypoints();
    let origin = [47.4f64.to_radians(), 8.55f64.to_radians(), 420.0];
    let ned = [
        (0.0, [0.0, 0.0, 0.0]),
        (20.0, [300.0, 0.0, 0.0]),
        (35.0, [420.0, 120.0, -5.0]),
        (50.0, [400.0, 300.0, -10.0]),
        (70.0, [150.0, 420.0, -10.0]),
    ];
    for (t, want) in ned {
        let got = ned_offset(origin, &m.pose(t));
        for k in 0..3 {
            assert!(
                (got[k] - want[k]).abs() < 1e-8,
                "t {t}: {got:?} vs {want:?}"
            );
        }
    }
    let end = m.pose(90.0);
    assert!(
        (end.lat - 47.4004f64.to_radians()).abs() < 2e-16,
        "{}",
        end.lat
    );
    assert!(
        (end.lon - 8.5562f64.to_radians()).abs() < 4e-16,
        "{}",
        end.lon
    );
    assert!((end.h - 425.0).abs() < 1e-12, "{}", end.h);
    for (t, v) in [(0.0, [15.0, 0.0, 0.0]), (90.0, [-12.0, -6.0, 0.0])] {
        let p = m.pose(t);
        for (k, want) in v.iter().enumerate() {
            assert!((p.v_n[k] - want).abs() < 1e-9, "t {t}: {:?}", p.v_n);
        }
    }
    for t in [0.0, 12.5, 35.0, 61.3, 90.0] {
        let p = m.pose(t);
        let (roll, pitch, yaw) = imu_emu::math::euler_from_quat(p.q_b_n);
        let v = p.v_n;
        let hz = v[0].hypot(v[1]);
        // At the knots the attitude is the velocity's direction to round-off; between them
        // the quintic's interpolation error of the angle, ≈ ψ⁽⁶⁾Δt⁶/46080, stays below 1e-9.
        assert!((yaw - v[1].atan2(v[0])).abs() < 1e-9, "t {t}: yaw {yaw}");
        assert!(
            (pitch - (-v[2]).atan2(hz)).abs() < 1e-9,
            "t {t}: pitch {pitch}"
        );
        assert!(roll.abs() < 1e-15, "t {t}: roll {roll}");
    }
    let mut i = 0;
    let (mut dw, mut df) = (0.0f64, 0.0f64);
    while m.piece_end(i).is_finite() {
        let t = m.piece_end(i);
        let (a, b) = (m.sense(i, t), m.sense(i + 1, t));
        dw = dw.max((a.omega_ib_b - b.omega_ib_b).amax());
        df = df.max((a.f_b - b.f_b).amax());
        i += 1;
    }
    println!("waypoints: {i} knots, largest jump ω {dw:.2e} rad/s, f {df:.2e} m/s²");
    assert!(i == 359 && dw < 1e-12 && df < 1e-9, "{i} {dw:e} {df:e}");
    assert!(!m.gnss_visible(55.0) && m.gnss_visible(45.0) && m.gnss_visible(75.0));
    let m = AnyMotion::Defined(m);
    let grid = engine::plan(&m, 200.0, None, None).unwrap();
    let c = close(&m, &grid, Settings::default(), None, 100).unwrap();
    println!(
        "waypoints: position {:.2e} m (max {:.2e})",
        c.last.pos_ned.norm(),
        c.max_pos
    );
    assert!(c.max_pos <= 1e-3, "{:.3e} m", c.max_pos);
}

/// Closed forms of the path: between two waypoints with no velocity given, latitude is linear
/// in time (the spline through two points is a line); through three heights 300, 310, 300 m
/// at 0, 10, 20 s the natural cubic spline has ḧ(10) = 3(y₂ − 2y₁ + y₀)/(2Δt²) = −0.3 m/s²
/// and h(5) = 300 + 1.5·5 − 0.3·5³/(6·10) = 306.875 m; Euler angles given at every waypoint are
/// met there, with the roll the spline's.
#[test]
fn waypoints_against_closed_forms() {
    let head = "[motion]\nstart = { lat_deg = 10, lon_deg = 20, h_m = 300 }\n";
    let m = native(&format!(
        "{head}waypoints = [{{ t_s = 0, north_m = 0 }}, {{ t_s = 8, north_m = 100 }}]\n"
    ))
    .unwrap();
    let (a, b) = (m.pose(0.0).lat, m.pose(8.0).lat);
    for t in [1.0, 3.7, 6.25] {
        let want = a + (b - a) * t / 8.0;
        assert!((m.pose(t).lat - want).abs() < 4e-16, "t {t}");
    }
    let m = native(&format!(
        "{head}waypoints = [{{ t_s = 0, lat_deg = 10, lon_deg = 20, h_m = 300 }}, \
         {{ t_s = 10, lat_deg = 10.001, lon_deg = 20, h_m = 310 }}, \
         {{ t_s = 20, lat_deg = 10.002, lon_deg = 20, h_m = 300 }}]\n"
    ))
    .unwrap();
    assert!((m.pose(5.0).h - 306.875).abs() < 1e-11, "{}", m.pose(5.0).h);
    // On [10, 20] s: ḣ(10) = 0 by symmetry, ḧ(10) = −0.3, third derivative (m₂ − m₁)/Δt =
    // 0.03, so v_d(10 + τ) = −ḣ = 0.3τ − 0.015τ².
    for tau in [0.0, 2.0, 7.5] {
        let vd = m.pose(10.0 + tau).v_n[2];
        let want = 0.3 * tau - 0.015 * tau * tau;
        assert!((vd - want).abs() < 1e-12, "τ {tau}: {vd} vs {want}");
    }
    let m = native(&format!(
        "{head}waypoints = [{{ t_s = 0, north_m = 0, yaw_deg = 350, roll_deg = 5 }}, \
         {{ t_s = 10, north_m = 100, yaw_deg = 10 }}, {{ t_s = 20, north_m = 150, yaw_deg = 30 }}]\n"
    ))
    .unwrap();
    for (t, yaw, roll) in [(0.0, -10.0, 5.0), (10.0, 10.0, 0.0), (20.0, 30.0, 0.0)] {
        let (r, p, y) = imu_emu::math::euler_from_quat(m.pose(t).q_b_n);
        assert!(
            (y - f64::to_radians(yaw)).abs() < 1e-14,
            "t {t}: yaw {}",
            y.to_degrees()
        );
        assert!(
            (r - f64::to_radians(roll)).abs() < 1e-14 && p.abs() < 1e-15,
            "t {t}"
        );
    }
    // The yaw goes the short way, through 0°, not back round through 180°.
    let (_, _, y) = imu_emu::math::euler_from_quat(m.pose(5.0).q_b_n);
    assert!(y.abs() < 10f64.to_radians(), "{}", y.to_degrees());
}

/// Waypoint mistakes are refused naming the waypoint and its line.
#[test]
fn waypoint_mistakes_are_refused() {
    let head = "[motion]\nstart = { lat_deg = 10 }\nwaypoints = [\n";
    let e = native(&format!(
        "{head} {{ t_s = 0, north_m = 0 }},\n {{ t_s = 5, north_m = 50 }},\n {{ t_s = 5, north_m = 90 }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.contains("m.toml:6: `motion.waypoints[2]`") && e.contains("must increase"),
        "{e}"
    );
    // 1 km in 2 s from rest and back to rest: about 1500 m/s² at the ends.
    let e = native(&format!(
        "{head} {{ t_s = 0, north_m = 0, velocity_m_s = [1, 0, 0] }},\n {{ t_s = 2, north_m = 1000, velocity_m_s = [1, 0, 0] }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.contains("m.toml:4: `motion.waypoints[0]`") && e.contains("beyond max_g"),
        "{e}"
    );
    let e = native(&format!(
        "{head} {{ t_s = 0, north_m = 0, yaw_deg = 0 }},\n {{ t_s = 5, north_m = 50 }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.contains("`motion.waypoints[1]`") && e.contains("at every waypoint or at none"),
        "{e}"
    );
    let e = native(&format!(
        "{head} {{ t_s = 0, north_m = 0, lat_deg = 3, lon_deg = 4 }},\n {{ t_s = 5, north_m = 50 }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.contains("`motion.waypoints[0]`") && e.contains("not both"),
        "{e}"
    );
    let e = native(&format!(
        "{head} {{ t_s = 0, north_m = 0 }},\n {{ t_s = 5, north_m = 0, east_m = 0 }},\n]\n"
    ))
    .unwrap_err();
    assert!(
        e.contains("`motion.waypoints[0]`") && e.contains("horizontal speed"),
        "{e}"
    );
    let e = native(&format!("{head} {{ t_s = 0, north_m = 0 }},\n]\n")).unwrap_err();
    assert!(e.contains("at least two waypoints"), "{e}");
    let e = native(
        "[motion]\nstart = { speed_m_s = 3 }\nwaypoints = [{ t_s = 0, north_m = 0 }, { t_s = 1, north_m = 1 }]\n",
    )
    .unwrap_err();
    assert!(e.contains("`motion.start.speed_m_s`"), "{e}");
}

fn ok(out: std::process::Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `--motion-def` in every command: `run` into a file sink sends the same frames as
/// `generate` writes; `navigate` closes generated error-free records against it within 1 mm;
/// `compare` scores an ideal IMU at under 1 mm; `validate` adds its closure row, and a bad
/// file makes it fail naming the line.
#[test]
fn every_command_takes_a_motion_definition() {
    let dir = scratch("cmds");
    let turn = written(&dir, "turn.csv", &turn_text());
    let turn = turn.to_str().unwrap();
    let common = ["--motion-def", turn, "--imu", "ideal"];
    let frames = ["--format", "kvh1750", "--duration", "2"];
    ok(bin(
        &[&["run"][..], &common, &frames, &["--file", "run.kvh"]].concat(),
        &dir,
    ));
    ok(bin(
        &[&["generate"][..], &common, &frames, &["-o", "g.kvh"]].concat(),
        &dir,
    ));
    let (a, b) = (
        std::fs::read(dir.join("run.kvh")).unwrap(),
        std::fs::read(dir.join("g.kvh")).unwrap(),
    );
    assert!(
        a.len() == 2000 * 36 && a == b,
        "{} vs {} bytes",
        a.len(),
        b.len()
    );
    ok(bin(
        &[
            &["generate"][..],
            &common,
            &["--rate", "100", "-o", "full.csv"],
        ]
        .concat(),
        &dir,
    ));
    ok(bin(
        &[
            "navigate",
            "full.csv",
            "--motion-def",
            turn,
            "--errors",
            "e.csv",
        ],
        &dir,
    ));
    let e = std::fs::read_to_string(dir.join("e.csv")).unwrap();
    let last: Vec<f64> = e
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|x| x.parse().unwrap())
        .collect();
    assert!(last[0] == 10.0 && last[10] < 1e-3, "{last:?}");
    let out = ok(bin(
        &[&["compare"][..], &common, &["--runs", "1", "--rate", "100"]].concat(),
        &dir,
    ));
    let ideal = out.lines().find(|l| l.starts_with("ideal")).unwrap();
    let median: f64 = ideal.split_whitespace().nth(3).unwrap().parse().unwrap();
    assert!(median < 1e-3, "{out}");
    ok(bin(
        &[
            "validate",
            "--imu",
            "ideal",
            "--motion-def",
            turn,
            "--out",
            "v",
        ],
        &dir,
    ));
    let report = std::fs::read_to_string(dir.join("v/report.md")).unwrap();
    let row = report
        .lines()
        .find(|l| l.starts_with(&format!("| {turn} |")))
        .unwrap();
    assert!(row.ends_with("| pass |"), "{row}");
    std::fs::write(
        dir.join("bad.csv"),
        format!("{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n1,0,0,0,0,0,0,-1,0\n"),
    )
    .unwrap();
    let out = bin(
        &[
            "validate",
            "--imu",
            "ideal",
            "--motion-def",
            "bad.csv",
            "--out",
            "v2",
        ],
        &dir,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("bad.csv:4: column 8"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The specific force over every segment, transitions included, is checked against max_g:
/// accelerating at 5 m/s² passes the acceleration limit (5 ≤ 1.05 g) but the specific force
/// peaks at √(g² + 5²) ≈ 1.12 g, beyond max_g = 1.05 (the message gives the first sample
/// beyond it); the same acceleration within max_g = 1.2 is accepted.
#[test]
fn specific_force_beyond_max_g_is_refused_naming_the_segment() {
    let seg = "segments = [\n { hold_s = 1 },\n { accelerate_to_m_s = 30, accel_m_s2 = 5 },\n]\n";
    let e = native(&format!(
        "[motion]\nstart = {{ speed_m_s = 10 }}\nlimits = {{ max_g = 1.05 }}\n{seg}"
    ))
    .unwrap_err();
    assert!(
        e.contains("m.toml:6: `motion.segments[1]`: the specific force reaches 1.0")
            && e.contains("beyond max_g = 1.05"),
        "{e}"
    );
    native(&format!(
        "[motion]\nstart = {{ speed_m_s = 10 }}\nlimits = {{ max_g = 1.2 }}\n{seg}"
    ))
    .unwrap();
}

/// gnss-ins-sim's type 2–5 limits set by the user: `[motion] gnss_ins_sim = FILE` with
/// `gnss_ins_sim_limits`. A type-2 command to 10 m/s from rest is a minimum-jerk move of
/// 1.875·Δv/a: 18.75 s at the default 1 m/s², 9.375 s at 2 m/s²; a zero limit is refused
/// naming the key.
#[test]
fn gnss_ins_sim_limits_are_settable() {
    let dir = scratch("lim");
    let csv =
        format!("{H1}\n32,120,0,0,0,0,0,0,0\n{H2}\n2,0,0,0,10,0,0,100,1\n1,0,0,0,0,0,0,1,1\n");
    std::fs::write(dir.join("to10.csv"), csv).unwrap();
    let span = |limits: &str| {
        std::fs::write(
            dir.join("m.toml"),
            format!("[motion]\ngnss_ins_sim = \"to10.csv\"\n{limits}"),
        )
        .unwrap();
        motiondef::open(&dir.join("m.toml")).map(|m| m.segments()[0].span.1)
    };
    let t1 = span("").unwrap();
    assert!((t1 - 18.75).abs() < 1e-9, "{t1}");
    let t2 = span("gnss_ins_sim_limits = { max_accel_m_s2 = 2 }\n").unwrap();
    assert!((t2 - 9.375).abs() < 1e-9, "{t2}");
    let e = span("gnss_ins_sim_limits = { max_rate_deg_s = 0 }\n")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("m.toml") && e.contains("`motion.gnss_ins_sim_limits.max_rate_deg_s`"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
